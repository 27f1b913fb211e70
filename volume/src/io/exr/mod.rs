//! The native file format: a multi-part OpenEXR file (the `exr` crate).
//!
//! ## Layout
//! - One part per SH coefficient `j`, named `sh00`, `sh01`, …, with channels `R`, `G`, `B`
//!   and the part attributes `lightvol.sh_index`, `lightvol.sh_l`, `lightvol.sh_m`.
//! - One part named `weight` with a single channel `Y` (the node weights).
//! - Every part is an `nx × (ny·nz)` image: the z-slices of the grid stacked vertically,
//!   pixel `(x, y + ny·z)` = node `(x, y, z)`. Any EXR viewer shows each coefficient as a
//!   strip of slices.
//! - Image attributes (shared by all parts): `lightvol.version` (i32), `lightvol.dims`
//!   (int vec3), `lightvol.bounds_min` / `lightvol.bounds_max` / `lightvol.to_world` (text:
//!   JSON arrays of f64, exact), `lightvol.sh_coeffs`, `lightvol.sh_bands` (i32),
//!   `lightvol.convention`, `lightvol.quantity`, `lightvol.encoding`, `lightvol.units`,
//!   `lightvol.bake.method`, `lightvol.bake.scene_hash`, `lightvol.frame` (text; the source
//!   file's frame, `y-up` or `z-up`, see `crate::frame`; absent in older files: `z-up`), `lightvol.bake.samples`,
//!   `lightvol.bake.seed` (text, decimal u64), `lightvol.bake.shard` (int vec2: index,
//!   count).
//!
//! Samples are f32 (bit-exact round trip) or f16 ([`ExrSample`]); compression is lossless.
//!
//! Every header lists its attributes in a fixed order: the standard EXR ones as the `exr`
//! crate writes them, then the `lightvol.*` ones sorted by name
//! ([`canonical_attribute_order`]). With the single-threaded encoder, equal volumes give
//! byte-identical files, run after run.
//!
//! ## Optional gradient parts (SH gradients of \[Oat05\])
//! [`write_exr_with_gradients`] adds, after the `weight` part, one part per coefficient
//! named `grad00`, `grad01`, … with nine f32 channels `R.x R.y R.z G.x … B.z` (the world
//! gradient of that coefficient, [`VolumeGradients`](crate::gradient::VolumeGradients)
//! layout), in the same slice layout, and the image attribute `lightvol.gradients` (i32, 1).
//! Files without gradients are written as before (same parts and attributes), and every
//! reader here reads both kinds ([`read_exr`] ignores the gradient parts). Readers older
//! than this extension reject files that carry gradients (they check the part count). The
//! checksum covers the volume, not the gradients (stored f32, lossless).
//!
//! ## Optional validity part
//! A volume with a validity mask ([`crate::validity`]) adds, after the `weight` part, a
//! part named `validity` with a single f32 channel `Y` (1.0 valid, 0.0 invalid; any other
//! value is malformed), in the same slice layout, and the image attribute
//! `lightvol.validity` (i32, 1); such files are `lightvol.version` 2
//! ([`crate::io::sidecar::format_version`]), so readers of version 1 refuse them as newer
//! instead of reading them without their mask. Files of volumes without a mask are version
//! 1 and unchanged, and version-1 files read as volumes without a mask. The checksum covers
//! the mask.
//!
//! ## Optional reach part
//! A volume with a node reach ([`crate::reach`]) adds, after the `weight` part and the
//! validity part (if any), a part named `reach` with six f32 channels `+x -x +y -y +z -z`
//! (each node's reach along that grid axis in cells, in `[0, 1]`; anything else is
//! malformed), in the same slice layout, and the image attribute `lightvol.reach` (i32, 1);
//! such files are `lightvol.version` 4, so older readers refuse them as newer instead of
//! reading them without their reach. The checksum covers the reach.
//!
//! ## Reading
//! The reader first parses only the headers and checks the attributes, part names, channel
//! lists, sample types and data-window sizes against the declared dimensions; only then
//! does it decode pixels. Every problem is a [`VolumeError`](crate::VolumeError); panics
//! inside the `exr` crate on hostile input are caught and reported as malformed data.
//!
//! ## Inside
//! The generic EXR image pipelines and the canonical attribute order (`image`, for every
//! lightvol EXR file) sit below the volume format: the part and channel names (`layout`),
//! the writer (`write`) and the reader (`read`). Everything public is re-exported here.

mod image;
mod layout;
mod read;
mod write;

pub(crate) use image::text;
pub use image::{
    ExrImage, ExrLayer, canonical_attribute_order, decode_image, encode_image, header_attribute_names,
};
pub(crate) use layout::OCTREE_ATTRIBUTE;
pub(crate) use read::{ExtraPart, exr_from_bytes_ext};
pub use read::{exr_from_bytes, exr_from_bytes_with_gradients, read_exr, read_exr_with_gradients};
pub(crate) use write::base_layers;
pub use write::{
    ExrCompression, ExrOptions, ExrSample, exr_to_bytes, exr_to_bytes_with_gradients, write_exr,
    write_exr_with_gradients,
};
