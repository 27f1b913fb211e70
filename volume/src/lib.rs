#![doc = include_str!("../README.md")]

pub mod accumulator;
pub mod adaptive;
pub mod bricks;
pub mod checksum;
pub mod encode;
pub mod engine_lookup;
pub mod error;
pub mod export;
pub mod field;
pub mod fill;
pub mod fixed;
pub mod frame;
pub mod gradient;
pub mod grid;
pub mod info;
pub mod io;
pub mod light_groups;
pub mod lookup;
mod lookup_params;
pub mod metadata;
pub mod reach;
pub mod rgb9e5;
pub mod slab;
pub mod up_axis;
pub mod validity;
pub mod volume;

pub use accumulator::Accumulator;
pub use adaptive::build::{BuildError, Candidates, LevelSamples, build_adaptive};
pub use adaptive::{AdaptiveVolume, LevelStats, OctreeParams, OctreeSettings};
pub use encode::{EncodedVolume, Encoding, encode, irradiance_error};
pub use engine_lookup::EngineLookup;
pub use error::{FileFormat, VolumeError};
pub use field::{AnyVolume, GradientField, VolumeField, open};
pub use fill::FillReport;
pub use gradient::{GradientLookup, VolumeGradients};
pub use grid::{GridSpec, Placement};
pub use light_groups::GroupedVolume;
pub use metadata::{
    BakeMetadata, BakeRecord, FitRecord, NoiseRecord, OctreeRegion, RegionKind, TargetRecord,
};
pub use reach::NodeReach;
pub use validity::ValidityMask;
pub use volume::IrradianceVolume;
