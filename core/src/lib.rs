#![doc = include_str!("../README.md")]

pub mod color;
pub mod fs;
pub mod hash;
#[cfg(feature = "ktx2")]
pub mod ktx2;
pub mod metric;
pub mod progress;
pub mod samples;
pub mod shard;
