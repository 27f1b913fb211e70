#![doc = include_str!("../README.md")]

pub mod atlas;
pub mod bake;
pub mod error;
pub mod exr;
pub mod geometry;
pub mod key;
pub mod map;
pub mod map_dir;
pub mod reference;
pub mod shaded_view;
pub mod shard_io;
pub mod storage;
pub mod tangent;
pub mod texel;

#[cfg(test)]
mod tests;

pub use atlas::{Atlas, MAX_ATLAS_SIZE, atlas_size};
pub use bake::{
    SurfaceBake, SurfaceReport, SurfaceSettings, SurfaceTexels, TexelRecord, assemble_surface, bake_surface,
    bake_surface_texels,
};
pub use error::SurfaceError;
pub use exr::{read_surface_exr, write_surface_exr};
pub use geometry::{SurfaceGeometry, SurfaceObject};
pub use map::{CoefficientMap, InvalidCounts};
pub use reference::reference_surface_irradiance;
pub use tangent::TangentFrame;

use lightvol_hemibasis::{BasisFamily, HemiBasis};

/// Which glTF texture coordinate set holds the lightmap UVs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UvSet {
    /// `TEXCOORD_1`, the usual secondary (lightmap) set.
    #[default]
    Lightmap,
    /// `TEXCOORD_0` (`--uv 0`), for objects whose base UVs are already unique and in `[0, 1]`.
    Base,
}

impl UvSet {
    /// The glTF attribute name.
    #[must_use]
    pub fn attribute(self) -> &'static str {
        match self {
            Self::Lightmap => "TEXCOORD_1",
            Self::Base => "TEXCOORD_0",
        }
    }

    /// Parses an attribute name.
    #[must_use]
    pub fn from_attribute(s: &str) -> Option<Self> {
        match s {
            "TEXCOORD_1" => Some(Self::Lightmap),
            "TEXCOORD_0" => Some(Self::Base),
            _ => None,
        }
    }
}

impl std::fmt::Display for UvSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.attribute())
    }
}

/// What the coefficients reconstruct.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Quantity {
    /// Irradiance `E(n) = ∫_H L(ω) max(0, n·ω) dω` (W/m²): SH bands convolved with
    /// `A_l = π, 2π/3, π/4` (lightvol-sh `cosine_lobe_factor`). Under a uniform sky of
    /// radiance `L` a flat surface reconstructs `π L` at its normal.
    #[default]
    Irradiance,
    /// `E / π`, the exit radiance of a white Lambertian surface, with the normalised factors
    /// `1, 2/3, 1/4` of \[Ish11\] Eq. 2.3 (the thesis's convention; a sky `L` gives `L`).
    Radiosity,
}

impl Quantity {
    /// The name stored in files: `"irradiance"` or `"radiosity"`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Irradiance => "irradiance",
            Self::Radiosity => "radiosity",
        }
    }

    /// Parses [`name`](Self::name).
    #[must_use]
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "irradiance" => Some(Self::Irradiance),
            "radiosity" => Some(Self::Radiosity),
            _ => None,
        }
    }

    /// The factor applied to an irradiance: 1 or 1/π.
    #[must_use]
    pub fn scale(self) -> f64 {
        match self {
            Self::Irradiance => 1.0,
            Self::Radiosity => std::f64::consts::FRAC_1_PI,
        }
    }
}

/// How texels whose sample points see back faces are treated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InvalidTexels {
    /// The domain of interest of \[KL06\] §5: samples are re-drawn in the valid part of the
    /// texel's footprint; texels with no valid part are dilated from valid neighbours.
    #[default]
    Fix,
    /// No treatment (ablation): invalid points keep their dark samples.
    Keep,
}

/// A hemispherical basis by its command-line name: `sh4`, `sh9`, `hl2`, `hsh4`, `hsh9`,
/// `makhotkin4`, `makhotkin9`, `zernike3`, `zernike6`, `hbasis4`, `hbasis6`, `hbasis_mod4`,
/// `hbasis_mod6`, or any other size [`lightvol_hemibasis::by_name`] accepts (`hsh16`, ...).
/// Only bases whose lightvol-hemibasis feature is enabled parse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BasisChoice {
    family: BasisFamily,
    count: usize,
}

impl BasisChoice {
    /// Parses a basis name (trailing digits are the coefficient count; `hl2` has 3).
    ///
    /// # Errors
    /// [`SurfaceError::UnknownBasis`] when no enabled basis has that name and size.
    pub fn parse(s: &str) -> Result<Self, SurfaceError> {
        let unknown = || SurfaceError::UnknownBasis(s.to_owned());
        let (name, count) = if s == "hl2" {
            ("hl2", 3)
        } else {
            let split = s.trim_end_matches(|c: char| c.is_ascii_digit()).len();
            (&s[..split], s[split..].parse::<usize>().map_err(|_| unknown())?)
        };
        let family = name.parse::<BasisFamily>().map_err(|_| unknown())?;
        if lightvol_hemibasis::by_family(family, count).is_none() {
            return Err(unknown());
        }
        Ok(Self { family, count })
    }

    /// The name stored in files and printed (`hbasis_mod6`; `hl2` without its count), which
    /// [`Self::parse`] reads back.
    #[must_use]
    pub fn tag(&self) -> String {
        self.to_string()
    }

    /// The basis family.
    #[must_use]
    pub fn family(&self) -> BasisFamily {
        self.family
    }

    /// Number of coefficients per colour channel.
    #[must_use]
    pub fn coeffs(&self) -> usize {
        self.count
    }

    /// The basis.
    #[must_use]
    pub fn basis(&self) -> Box<dyn HemiBasis> {
        lightvol_hemibasis::by_family(self.family, self.count).expect("checked when parsed")
    }
}

/// The name [`BasisChoice::parse`] reads.
impl std::fmt::Display for BasisChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.family {
            BasisFamily::Hl2 => f.write_str("hl2"),
            family => write!(f, "{family}{}", self.count),
        }
    }
}

impl std::str::FromStr for BasisChoice {
    type Err = SurfaceError;
    fn from_str(s: &str) -> Result<Self, SurfaceError> {
        Self::parse(s)
    }
}

/// The surface bases lightvol bakes (lightvol-hemibasis's `LIGHTMAP_BASES`), all of which
/// build when every lightvol-hemibasis feature is on.
pub fn basis_choices() -> impl Iterator<Item = BasisChoice> {
    lightvol_hemibasis::LIGHTMAP_BASES.into_iter().map(|(family, count)| BasisChoice { family, count })
}
