//! Source frames: which axis points up in the scene file a volume was baked from.
//!
//! lightvol's internal frame is right-handed with +Z up; a file with +Y up (glTF 2.0 §3.4,
//! most OBJ exports) is rotated into it by +90° about X, `(x, y, z) → (x, −z, y)`. The
//! rotation keeps handedness and winding, and it maps heights in the file (`y`) to internal
//! heights (`z`) unchanged. Volumes record the frame of their scene ([`UpAxis::name`], in
//! [`BakeMetadata::frame`](crate::metadata::BakeMetadata::frame)); grids and volumes are
//! described in that frame by [`crate::frame`].

use serde::{Deserialize, Serialize};

/// The axis that points up in a source file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum UpAxis {
    /// +Y up (glTF 2.0, most OBJ exports), the default for loading files: internal
    /// `(x, y, z) = (x_f, −z_f, y_f)`.
    #[default]
    #[serde(rename = "y-up")]
    Y,
    /// +Z up: the internal frame itself (built-in scenes, Z-up OBJ exports).
    #[serde(rename = "z-up")]
    Z,
}

impl UpAxis {
    /// The frame of volumes with no recorded frame (older files, built-in scenes).
    pub const INTERNAL: UpAxis = UpAxis::Z;

    /// A file-frame point or direction in the internal frame (a rotation).
    #[must_use]
    #[inline]
    pub fn to_world(self, p: [f64; 3]) -> [f64; 3] {
        match self {
            Self::Y => [p[0], -p[2], p[1]],
            Self::Z => p,
        }
    }

    /// The inverse of [`Self::to_world`]: an internal point or direction in the file's axes.
    #[must_use]
    #[inline]
    pub fn to_file(self, p: [f64; 3]) -> [f64; 3] {
        match self {
            Self::Y => [p[0], p[2], -p[1]],
            Self::Z => p,
        }
    }

    /// An internal axis-aligned box `[lo, hi]` as the file-frame box it becomes (the
    /// rotation is a signed axis permutation, so the image is again axis-aligned).
    #[must_use]
    pub fn box_to_file(self, lo: [f64; 3], hi: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let (a, b) = (self.to_file(lo), self.to_file(hi));
        (std::array::from_fn(|i| a[i].min(b[i])), std::array::from_fn(|i| a[i].max(b[i])))
    }

    /// A file-frame axis-aligned box as the internal box it becomes.
    #[must_use]
    pub fn box_to_world(self, lo: [f64; 3], hi: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let (a, b) = (self.to_world(lo), self.to_world(hi));
        (std::array::from_fn(|i| a[i].min(b[i])), std::array::from_fn(|i| a[i].max(b[i])))
    }

    /// For each file axis, the internal axis it comes from and its sign:
    /// `file[a] = sign · internal[axis]`.
    #[must_use]
    pub fn file_axes(self) -> [(usize, f64); 3] {
        match self {
            Self::Y => [(0, 1.0), (2, 1.0), (1, -1.0)],
            Self::Z => [(0, 1.0), (1, 1.0), (2, 1.0)],
        }
    }

    /// The name files and JSON use: `y-up` or `z-up`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Y => "y-up",
            Self::Z => "z-up",
        }
    }

    /// Parses [`Self::name`] (also `y`, `z`).
    #[must_use]
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "y-up" | "y" | "Y" => Some(Self::Y),
            "z-up" | "z" | "Z" => Some(Self::Z),
            _ => None,
        }
    }
}
