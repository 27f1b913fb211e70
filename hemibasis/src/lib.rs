#![doc = include_str!("../README.md")]

pub mod basis;
pub mod convert;
pub mod encode;
pub mod family;
pub mod imse;
pub mod map;
pub mod program;
pub mod project;
pub mod quad;
pub mod render;
mod sep;
pub mod sh_basis;
pub mod shader;

#[cfg(feature = "bc")]
pub mod bc;
#[cfg(feature = "hbasis")]
pub mod lod;
#[cfg(feature = "ktx2")]
pub mod plane_ktx2;

#[cfg(feature = "hbasis")]
pub mod hbasis;
#[cfg(feature = "hl2")]
pub mod hl2;
#[cfg(feature = "hsh")]
pub mod hsh;
#[cfg(feature = "makhotkin")]
pub mod makhotkin;
#[cfg(feature = "zernike")]
pub mod zernike;

#[cfg(test)]
mod test_util;

pub use basis::HemiBasis;
pub use family::{BasisFamily, LIGHTMAP_BASES, by_family, by_name};
#[cfg(feature = "hbasis")]
pub use hbasis::HBasis;
#[cfg(feature = "hl2")]
pub use hl2::Hl2;
#[cfg(feature = "hsh")]
pub use hsh::Hsh;
#[cfg(feature = "makhotkin")]
pub use makhotkin::Makhotkin;
pub use map::{CoeffMap, Plane};
pub use project::{Matrix, Projector};
pub use quad::HemiRule;
pub use sh_basis::ShBasis;
#[cfg(feature = "zernike")]
pub use zernike::Zernike;
