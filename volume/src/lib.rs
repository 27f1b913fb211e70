#![doc = include_str!("../README.md")]

pub mod accumulator;
pub mod encode;
pub mod error;
pub mod fill;
pub mod grid;
pub mod lookup;
pub mod volume;

pub use accumulator::Accumulator;
pub use encode::{EncodedVolume, Encoding, encode, irradiance_error};
pub use error::{FileFormat, VolumeError};
pub use fill::FillReport;
pub use grid::{GridSpec, Placement};
pub use volume::{BakeMetadata, IrradianceVolume};
