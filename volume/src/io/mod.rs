//! Every file format of a volume: the native EXR ([`exr`]), the adaptive octree's EXR
//! ([`adaptive`]), the engine exports ([`ktx2`] and its light groups' texture ([`ktx2_groups`]), [`dds`], [`bevy`], [`three`] and their JSON
//! [`sidecar`]), the shard accumulator ([`accumulator`]), and the shared file edges
//! ([`util`]: atomic writes, bounded reads, the parser panic guard).

pub mod accumulator;
pub mod adaptive;
pub mod bevy;
pub mod bricks;
pub mod dds;
pub mod exr;
pub mod groups;
pub mod ktx2;
pub mod ktx2_groups;
pub mod sidecar;
pub mod three;
pub mod util;
