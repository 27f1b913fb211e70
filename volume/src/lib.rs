#![doc = include_str!("../README.md")]

pub mod accumulator;
pub mod accumulator_io;
pub mod adaptive;
pub mod adaptive_build;
pub mod adaptive_io;
pub mod adaptive_lookup;
pub mod bevy;
pub mod checksum;
pub mod dds_io;
pub mod encode;
pub mod error;
pub mod exr_io;
pub mod fill;
pub mod fixed;
pub mod frame;
pub mod gradient;
pub mod grid;
pub mod io_util;
pub mod ktx2_io;
pub mod lookup;
pub mod rgb9e5;
pub mod sidecar;
pub mod slab;
pub mod validity;
pub mod volume;

pub use accumulator::Accumulator;
pub use adaptive::{AdaptiveVolume, LevelStats, OctreeParams};
pub use adaptive_build::{BuildError, Candidates, LevelSamples, build_adaptive};
pub use encode::{EncodedVolume, Encoding, encode, irradiance_error};
pub use error::{FileFormat, VolumeError};
pub use fill::FillReport;
pub use gradient::{GradientLookup, VolumeGradients};
pub use grid::{GridSpec, Placement};
pub use validity::ValidityMask;
pub use volume::{BakeMetadata, IrradianceVolume};
