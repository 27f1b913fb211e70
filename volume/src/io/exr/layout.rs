//! The names the native EXR layout gives its parts and channels ([`super`]'s module docs),
//! shared by the writer ([`super::write`]) and the reader ([`super::read`]).

use crate::error::FileFormat;

/// The format every error of these modules names.
pub(crate) const F: FileFormat = FileFormat::Exr;

/// Name of the part of coefficient `j`: `sh00`, `sh01`, ….
pub(crate) fn layer_name(j: usize) -> String {
    format!("sh{j:02}")
}

/// Name of the validity part.
pub(crate) const VALIDITY_PART: &str = "validity";

/// Name of the reach part.
pub(crate) const REACH_PART: &str = "reach";

/// Channel names of the reach part, in the exr crate's sorted order, with their
/// [`crate::reach::REACH_DIRECTIONS`] index.
pub(crate) const REACH_CHANNELS: [(&str, usize); 6] =
    [("+x", 0), ("+y", 2), ("+z", 4), ("-x", 1), ("-y", 3), ("-z", 5)];

/// Name of the gradient part of coefficient `j`: `grad00`, `grad01`, ….
pub(crate) fn grad_layer_name(j: usize) -> String {
    format!("grad{j:02}")
}

/// Channel names of a gradient part, in the exr crate's sorted order, with their
/// `[rgb][xyz]` offset.
pub(crate) const GRAD_CHANNELS: [(&str, usize); 9] = [
    ("B.x", 6),
    ("B.y", 7),
    ("B.z", 8),
    ("G.x", 3),
    ("G.y", 4),
    ("G.z", 5),
    ("R.x", 0),
    ("R.y", 1),
    ("R.z", 2),
];

/// Whether a part name belongs to the adaptive extension ([`crate::io::adaptive`]).
pub(crate) fn is_octree_part(name: &str) -> bool {
    name.starts_with("octree") || name.starts_with("split")
}

/// The image attribute that marks an adaptive octree file.
pub(crate) const OCTREE_ATTRIBUTE: &str = "lightvol.octree";
