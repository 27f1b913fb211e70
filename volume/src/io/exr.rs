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
//! gradient of that coefficient, [`VolumeGradients`] layout), in the same slice layout, and
//! the image attribute `lightvol.gradients` (i32, 1). Files without gradients are written
//! as before (same parts and attributes), and every reader here reads both kinds ([`read_exr`] ignores
//! the gradient parts). Readers older than this extension reject files that carry
//! gradients (they check the part count). The checksum covers the volume, not the
//! gradients (stored f32, lossless).
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
//! does it decode pixels. Every problem is a [`VolumeError`]; panics inside the `exr` crate
//! on hostile input are caught and reported as malformed data.

use std::collections::HashMap;
use std::io::Cursor;
use std::path::Path;

use exr::image::{AnyChannel, AnyChannels, Encoding as ExrEncoding, FlatSamples, Image, Layer};
use exr::math::Vec2;
use exr::meta::attribute::{AttributeValue, Compression, IntegerBounds, SampleType, Text};
use exr::meta::header::{ImageAttributes, LayerAttributes};
use exr::prelude::{ReadChannels, ReadLayers, SmallVec, WritableImage};

use lightvol_sh::index::sh_lm;

use crate::checksum::{through_f16, to_hex, verify, volume_checksum};
use crate::encode::Encoding;
use crate::error::{FileFormat, VolumeError, check_finite};
use crate::gradient::VolumeGradients;
use crate::grid::{GridSpec, Placement};
use crate::io::sidecar::{
    FORMAT_VERSION, QUANTITY, REACH_VERSION, SETTINGS_VERSION, SH_CONVENTION, VALIDITY_VERSION,
    format_version,
};
use crate::io::util::{guard, read_bounded, write_atomic};
use crate::metadata::BakeMetadata;
use crate::reach::NodeReach;
use crate::validity::ValidityMask;
use crate::volume::{IrradianceVolume, check_coeffs};

const F: FileFormat = FileFormat::Exr;

/// Sample type of the coefficient channels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExrSample {
    /// 32-bit float: bit-exact.
    #[default]
    F32,
    /// 16-bit float: half the size; values beyond ±65504 are an error.
    F16,
}

/// Lossless compression of the parts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExrCompression {
    /// ZIP, 16 scan lines per block (small files).
    #[default]
    Zip,
    /// PIZ wavelet compression.
    Piz,
    /// No compression.
    None,
}

/// Options of [`write_exr`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ExrOptions {
    /// Coefficient sample type (the weight channel is always f32).
    pub sample: ExrSample,
    /// Compression.
    pub compression: ExrCompression,
}

pub(crate) fn text(s: &str) -> Result<Text, VolumeError> {
    Text::new_or_none(s).ok_or_else(|| {
        VolumeError::InvalidData(format!("{s:?} has characters EXR text attributes cannot hold"))
    })
}

fn layer_name(j: usize) -> String {
    format!("sh{j:02}")
}

/// Name of the validity part.
const VALIDITY_PART: &str = "validity";

/// Name of the reach part.
const REACH_PART: &str = "reach";

/// Channel names of the reach part, in the exr crate's sorted order, with their
/// [`crate::reach::REACH_DIRECTIONS`] index.
const REACH_CHANNELS: [(&str, usize); 6] = [("+x", 0), ("+y", 2), ("+z", 4), ("-x", 1), ("-y", 3), ("-z", 5)];

/// The slot a channel table (`GRAD_CHANNELS`, `REACH_CHANNELS`) gives channel `name`, or
/// malformed data for a channel it does not list.
fn channel_slot(table: &[(&str, usize)], name: &str) -> Result<usize, VolumeError> {
    table
        .iter()
        .find(|(c, _)| *c == name)
        .map(|&(_, slot)| slot)
        .ok_or_else(|| VolumeError::malformed(F, format!("channel {name:?}")))
}

fn grad_layer_name(j: usize) -> String {
    format!("grad{j:02}")
}

/// Channel names of a gradient part, in the exr crate's sorted order, with their
/// `[rgb][xyz]` offset.
const GRAD_CHANNELS: [(&str, usize); 9] = [
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

/// Serialises `vol` as a multi-part EXR file in memory.
pub fn exr_to_bytes(vol: &IrradianceVolume, options: &ExrOptions) -> Result<Vec<u8>, VolumeError> {
    exr_to_bytes_with_gradients(vol, None, options)
}

/// [`exr_to_bytes`] plus, when given, the gradient parts (module docs); errors if the
/// gradients do not belong to `vol`.
pub fn exr_to_bytes_with_gradients(
    vol: &IrradianceVolume,
    grad: Option<&VolumeGradients>,
    options: &ExrOptions,
) -> Result<Vec<u8>, VolumeError> {
    let (layers, ia) = base_layers(vol, grad, options)?;
    encode_image(ia, layers)
}

/// The parts and image attributes of the native format (what
/// [`exr_to_bytes_with_gradients`] writes), for extensions that add parts
/// ([`crate::io::adaptive`]).
pub(crate) fn base_layers(
    vol: &IrradianceVolume,
    grad: Option<&VolumeGradients>,
    options: &ExrOptions,
) -> Result<(Vec<ExrLayer>, ImageAttributes), VolumeError> {
    if let Some(g) = grad
        && (g.nodes() != vol.spec().node_count() || g.coeffs() != vol.coeffs())
    {
        return Err(VolumeError::Mismatch("gradients do not belong to the volume".into()));
    }
    let spec = vol.spec();
    let [nx, ny, nz] = spec.res();
    let size = Vec2(nx as usize, ny as usize * nz as usize);
    let n = spec.node_count();
    let coeffs = vol.coeffs();
    let k = coeffs * 3;
    let encoding = ExrEncoding {
        compression: match options.compression {
            ExrCompression::Zip => Compression::ZIP16,
            ExrCompression::Piz => Compression::PIZ,
            ExrCompression::None => Compression::Uncompressed,
        },
        ..ExrEncoding::SMALL_LOSSLESS
    };
    let mut layers: Vec<Layer<AnyChannels<FlatSamples>>> = Vec::with_capacity(coeffs + 1);
    for j in 0..coeffs {
        let channel = |ch: usize| -> Result<FlatSamples, VolumeError> {
            let vals = (0..n).map(|node| vol.data()[node * k + 3 * j + ch]);
            Ok(match options.sample {
                ExrSample::F32 => FlatSamples::F32(vals.collect()),
                ExrSample::F16 => FlatSamples::F16(
                    vals.map(|v| {
                        let h = half::f16::from_f32(v);
                        if h.is_finite() {
                            Ok(h)
                        } else {
                            Err(VolumeError::InvalidData(format!("coefficient {v} exceeds the f16 range")))
                        }
                    })
                    .collect::<Result<_, _>>()?,
                ),
            })
        };
        let channels = AnyChannels::sort(SmallVec::from_vec(vec![
            AnyChannel::new("R", channel(0)?),
            AnyChannel::new("G", channel(1)?),
            AnyChannel::new("B", channel(2)?),
        ]));
        let mut attrs = LayerAttributes::named(text(&layer_name(j))?);
        let (l, m) = sh_lm(j);
        attrs.other.insert(text("lightvol.sh_index")?, AttributeValue::I32(j as i32));
        attrs.other.insert(text("lightvol.sh_l")?, AttributeValue::I32(l as i32));
        attrs.other.insert(text("lightvol.sh_m")?, AttributeValue::I32(m));
        layers.push(Layer::new(size, attrs, encoding, channels));
    }
    let weights = AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
        "Y",
        FlatSamples::F32(vol.weights().to_vec()),
    )]));
    layers.push(Layer::new(size, LayerAttributes::named(text("weight")?), encoding, weights));
    if let Some(mask) = vol.validity() {
        let flags = mask.as_slice().iter().map(|&v| f32::from(u8::from(v))).collect();
        let channels =
            AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new("Y", FlatSamples::F32(flags))]));
        layers.push(Layer::new(size, LayerAttributes::named(text(VALIDITY_PART)?), encoding, channels));
    }
    if let Some(reach) = vol.reach() {
        let channels = REACH_CHANNELS
            .iter()
            .map(|&(name, d)| {
                AnyChannel::new(name, FlatSamples::F32((0..n).map(|i| reach.node(i)[d]).collect()))
            })
            .collect::<Vec<_>>();
        let channels = AnyChannels::sort(SmallVec::from_vec(channels));
        layers.push(Layer::new(size, LayerAttributes::named(text(REACH_PART)?), encoding, channels));
    }
    if let Some(g) = grad {
        for j in 0..coeffs {
            let channels = GRAD_CHANNELS
                .iter()
                .map(|&(name, o)| {
                    let vals = (0..n).map(|node| g.data()[(node * coeffs + j) * 9 + o]).collect();
                    AnyChannel::new(name, FlatSamples::F32(vals))
                })
                .collect::<Vec<_>>();
            let channels = AnyChannels::sort(SmallVec::from_vec(channels));
            layers.push(Layer::new(
                size,
                LayerAttributes::named(text(&grad_layer_name(j))?),
                encoding,
                channels,
            ));
        }
    }

    let mut ia = ImageAttributes::new(IntegerBounds::from_dimensions(size));
    let meta = vol.metadata();
    let (min, max) = spec.bounds();
    let enc_name = match options.sample {
        ExrSample::F32 => Encoding::F32.name(),
        ExrSample::F16 => Encoding::F16.name(),
    };
    let mut put = |key: &str, value: AttributeValue| -> Result<(), VolumeError> {
        ia.other.insert(text(key)?, value);
        Ok(())
    };
    // (lightvol.checksum is added last, below.)
    put("lightvol.version", AttributeValue::I32(format_version(vol) as i32))?;
    put("lightvol.dims", AttributeValue::IntVec3((nx as i32, ny as i32, nz as i32)))?;
    put("lightvol.bounds_min", AttributeValue::Text(text(&json(&min))?))?;
    put("lightvol.bounds_max", AttributeValue::Text(text(&json(&max))?))?;
    if let Some(p) = spec.placement() {
        put("lightvol.to_world", AttributeValue::Text(text(&json(&p.to_world_matrix()))?))?;
    }
    put("lightvol.sh_coeffs", AttributeValue::I32(coeffs as i32))?;
    if grad.is_some() {
        put("lightvol.gradients", AttributeValue::I32(1))?;
    }
    if vol.validity().is_some() {
        put("lightvol.validity", AttributeValue::I32(1))?;
    }
    if vol.reach().is_some() {
        put("lightvol.reach", AttributeValue::I32(1))?;
    }
    put("lightvol.sh_bands", AttributeValue::I32(vol.bands() as i32))?;
    put("lightvol.convention", AttributeValue::Text(text(SH_CONVENTION)?))?;
    put("lightvol.quantity", AttributeValue::Text(text(QUANTITY)?))?;
    put("lightvol.encoding", AttributeValue::Text(text(enc_name)?))?;
    put("lightvol.units", AttributeValue::Text(text(&meta.units)?))?;
    put("lightvol.bake.method", AttributeValue::Text(text(&meta.method)?))?;
    put("lightvol.frame", AttributeValue::Text(text(meta.frame.name())?))?;
    put("lightvol.bake.scene_hash", AttributeValue::Text(text(&meta.scene_hash)?))?;
    put("lightvol.bake.samples", AttributeValue::Text(text(&meta.samples.to_string())?))?;
    put("lightvol.bake.seed", AttributeValue::Text(text(&meta.seed.to_string())?))?;
    if let Some(record) = &meta.settings {
        let json = serde_json::to_string(record).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
        put("lightvol.bake.settings", AttributeValue::Text(text(&json)?))?;
    }
    put(
        "lightvol.bake.shard",
        AttributeValue::IntVec2(Vec2(meta.shard_index as i32, meta.shard_count as i32)),
    )?;

    let decoded = match options.sample {
        ExrSample::F32 => volume_checksum(vol),
        ExrSample::F16 => volume_checksum(&through_f16(vol, false)?),
    };
    ia.other.insert(text("lightvol.checksum")?, AttributeValue::Text(text(&to_hex(decoded))?));
    Ok((layers, ia))
}

/// One part of an EXR file with flat (not deep) channels.
pub type ExrLayer = Layer<AnyChannels<FlatSamples>>;

/// A whole EXR file of flat parts, as [`decode_image`] reads it.
pub type ExrImage = Image<exr::image::Layers<AnyChannels<FlatSamples>>>;

/// Encodes parts into EXR bytes, single-threaded, attributes in the canonical order
/// ([`canonical_attribute_order`]): the write pipeline of every lightvol EXR file (volumes,
/// surface maps, plates, views), so that equal images give equal bytes.
///
/// # Errors
/// [`VolumeError::InvalidData`] if the encoder refuses the parts.
pub fn encode_image(ia: ImageAttributes, layers: Vec<ExrLayer>) -> Result<Vec<u8>, VolumeError> {
    let image = Image::from_layers(ia, layers);
    let mut out = Cursor::new(Vec::new());
    image
        .write()
        .non_parallel()
        .to_buffered(&mut out)
        .map_err(|e| VolumeError::InvalidData(format!("EXR encoder: {e}")))?;
    let mut bytes = out.into_inner();
    canonical_attribute_order(&mut bytes)?;
    Ok(bytes)
}

/// Decodes every flat part of an EXR file, all channels and attributes, single-threaded and
/// pedantic (a damaged file is an error, not a guess): the read pipeline of every lightvol
/// EXR reader, run after the reader has checked the headers it expects.
///
/// # Errors
/// The `exr` crate's error for data it cannot decode.
pub fn decode_image(bytes: &[u8]) -> Result<ExrImage, exr::error::Error> {
    exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .non_parallel()
        .pedantic()
        .from_buffered(Cursor::new(bytes))
}

/// Puts the attributes of every header of an EXR file in a fixed order, in place, so that
/// equal images give equal bytes.
///
/// The `exr` crate keeps custom attributes in a `std` `HashMap`
/// (`ImageAttributes::other`, `LayerAttributes::other`) and writes them in that map's
/// iteration order, which the randomly seeded hasher makes differ from map to map and from
/// run to run: two writes of the same volume came out with the same attributes in different
/// orders. Here every header keeps the standard attributes (the names of
/// `exr::meta::header::standard_names`) first, in the order the crate wrote them (fixed by
/// its code), and the custom ones follow, sorted by name (bytewise). Attributes only move
/// within their header and every header keeps its length, so the offset tables, which hold
/// absolute file positions, stay valid and the pixel data is untouched.
///
/// Every writer of EXR files in lightvol (volumes, adaptive volumes, surface maps, plates)
/// calls this on the encoder's output. Errors (leaving `bytes` unchanged) if `bytes` is not
/// an EXR file whose headers parse.
pub fn canonical_attribute_order(bytes: &mut [u8]) -> Result<(), VolumeError> {
    for header in header_layout(bytes)? {
        let name = |a: &RawAttribute| &bytes[a.name.clone()];
        let whole = |a: &RawAttribute| &bytes[a.bytes.clone()];
        let (standard, mut custom): (Vec<&RawAttribute>, Vec<&RawAttribute>) =
            header.attributes.iter().partition(|a| is_standard_attribute(name(a)));
        // By name; by the whole attribute if a (malformed) header repeats a name.
        custom.sort_by(|a, b| name(a).cmp(name(b)).then_with(|| whole(a).cmp(whole(b))));
        let mut ordered = Vec::with_capacity(header.bytes.len());
        for a in standard.into_iter().chain(custom) {
            ordered.extend_from_slice(whole(a));
        }
        debug_assert_eq!(ordered.len(), header.bytes.len(), "a header's attributes fill it exactly");
        bytes[header.bytes].copy_from_slice(&ordered);
    }
    Ok(())
}

/// The attribute names of every header of an EXR file, in file order (what
/// [`canonical_attribute_order`] arranges); errors if the headers do not parse.
pub fn header_attribute_names(bytes: &[u8]) -> Result<Vec<Vec<String>>, VolumeError> {
    Ok(header_layout(bytes)?
        .into_iter()
        .map(|h| {
            h.attributes
                .iter()
                .map(|a| String::from_utf8_lossy(&bytes[a.name.clone()]).into_owned())
                .collect()
        })
        .collect())
}

/// Whether `name` is one of the attribute names the OpenEXR standard defines.
fn is_standard_attribute(name: &[u8]) -> bool {
    exr::meta::header::standard_names::ALL.contains(&name)
}

/// One attribute of a header: its bytes (name, type, size, value) and its name's bytes.
struct RawAttribute {
    bytes: std::ops::Range<usize>,
    name: std::ops::Range<usize>,
}

/// One header: the bytes of its attributes (without the terminating zero byte) and each
/// attribute.
struct RawHeader {
    bytes: std::ops::Range<usize>,
    attributes: Vec<RawAttribute>,
}

/// Where the headers and their attributes lie in an EXR file (the OpenEXR file layout:
/// magic number, version and flags, then one header, or for multi-part files headers up to
/// an empty one; a header is a list of `name\0 type\0 size value` ended by a zero byte).
fn header_layout(bytes: &[u8]) -> Result<Vec<RawHeader>, VolumeError> {
    let bad = |what: &str| VolumeError::InvalidData(format!("EXR headers: {what}"));
    const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
    const MULTIPART: u32 = 0x1000;
    if bytes.len() < 8 || bytes[..4] != MAGIC {
        return Err(bad("not an EXR file"));
    }
    let multipart = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) & MULTIPART != 0;
    // The zero-terminated string at `*pos`, without its terminator.
    let cstr = |pos: &mut usize| -> Result<std::ops::Range<usize>, VolumeError> {
        let len = bytes
            .get(*pos..)
            .and_then(|rest| rest.iter().position(|&b| b == 0))
            .ok_or_else(|| bad("unterminated name"))?;
        let r = *pos..*pos + len;
        *pos += len + 1;
        Ok(r)
    };
    let mut headers = Vec::new();
    let mut pos = 8usize;
    loop {
        if multipart && bytes.get(pos) == Some(&0) {
            break; // the empty header that ends a multi-part file's header list
        }
        let start = pos;
        let mut attributes = Vec::new();
        loop {
            let at = pos;
            let name = cstr(&mut pos)?;
            if name.is_empty() {
                break;
            }
            cstr(&mut pos)?; // the type name
            let size = bytes.get(pos..pos + 4).ok_or_else(|| bad("truncated attribute size"))?;
            let size = usize::try_from(i32::from_le_bytes([size[0], size[1], size[2], size[3]]))
                .map_err(|_| bad("negative attribute size"))?;
            pos = pos
                .checked_add(4 + size)
                .filter(|&end| end <= bytes.len())
                .ok_or_else(|| bad("truncated attribute value"))?;
            attributes.push(RawAttribute { bytes: at..pos, name });
        }
        headers.push(RawHeader { bytes: start..pos - 1, attributes });
        if !multipart {
            break;
        }
    }
    Ok(headers)
}

/// An f64 array as JSON (exact through serde_json's shortest round-trip printing).
fn json<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string(v).expect("plain arrays serialise")
}

/// Writes `vol` to `path` as multi-part EXR (temporary file and rename).
pub fn write_exr(path: &Path, vol: &IrradianceVolume, options: &ExrOptions) -> Result<(), VolumeError> {
    write_atomic(path, &exr_to_bytes(vol, options)?)
}

/// Reads a volume written by [`write_exr`] (or [`write_exr_with_gradients`], ignoring the
/// gradients).
pub fn read_exr(path: &Path) -> Result<IrradianceVolume, VolumeError> {
    exr_from_bytes(&read_bounded(path)?)
}

/// Writes `vol` and its gradients (module docs; temporary file and rename).
pub fn write_exr_with_gradients(
    path: &Path,
    vol: &IrradianceVolume,
    grad: &VolumeGradients,
    options: &ExrOptions,
) -> Result<(), VolumeError> {
    write_atomic(path, &exr_to_bytes_with_gradients(vol, Some(grad), options)?)
}

/// Reads a volume and, if the file has them, its gradients.
pub fn read_exr_with_gradients(
    path: &Path,
) -> Result<(IrradianceVolume, Option<VolumeGradients>), VolumeError> {
    exr_from_bytes_with_gradients(&read_bounded(path)?)
}

/// Typed access to the `lightvol.*` attributes.
struct Attrs<'a>(&'a HashMap<Text, AttributeValue>);

impl Attrs<'_> {
    fn get(&self, key: &str) -> Result<&AttributeValue, VolumeError> {
        self.0
            .iter()
            .find(|(k, _)| k.as_slice() == key.as_bytes())
            .map(|(_, v)| v)
            .ok_or_else(|| VolumeError::malformed(F, format!("missing attribute {key}")))
    }
    fn opt(&self, key: &str) -> Option<&AttributeValue> {
        self.0.iter().find(|(k, _)| k.as_slice() == key.as_bytes()).map(|(_, v)| v)
    }
    fn text(&self, key: &str) -> Result<String, VolumeError> {
        match self.get(key)? {
            AttributeValue::Text(t) => Ok(t.to_string()),
            _ => Err(VolumeError::malformed(F, format!("attribute {key} is not text"))),
        }
    }
    fn i32(&self, key: &str) -> Result<i32, VolumeError> {
        match self.get(key)? {
            AttributeValue::I32(v) => Ok(*v),
            _ => Err(VolumeError::malformed(F, format!("attribute {key} is not an i32"))),
        }
    }
    fn u64(&self, key: &str) -> Result<u64, VolumeError> {
        self.text(key)?
            .parse()
            .map_err(|_| VolumeError::malformed(F, format!("attribute {key} is not a u64")))
    }
    fn json<T: serde::de::DeserializeOwned>(&self, key: &str) -> Result<T, VolumeError> {
        serde_json::from_str(&self.text(key)?)
            .map_err(|e| VolumeError::malformed(F, format!("attribute {key}: {e}")))
    }
}

/// Everything the header declares, validated.
struct Declared {
    spec: GridSpec,
    coeffs: usize,
    sample: SampleType,
    meta: BakeMetadata,
    checksum: String,
    gradients: bool,
    validity: bool,
    reach: bool,
}

fn declared(attrs: &HashMap<Text, AttributeValue>) -> Result<Declared, VolumeError> {
    let a = Attrs(attrs);
    let version = a.i32("lightvol.version")?;
    if version < 1 || version as u32 > FORMAT_VERSION {
        return Err(VolumeError::unsupported(F, format!("lightvol.version {version}")));
    }
    let dims = match a.get("lightvol.dims")? {
        AttributeValue::IntVec3((x, y, z)) => [*x, *y, *z],
        _ => return Err(VolumeError::malformed(F, "lightvol.dims is not an int vec3")),
    };
    let res = dims.map(|d| u32::try_from(d).unwrap_or(0));
    let min: [f64; 3] = a.json("lightvol.bounds_min")?;
    let max: [f64; 3] = a.json("lightvol.bounds_max")?;
    let mut spec = GridSpec::new(min, max, res)?;
    if a.opt("lightvol.to_world").is_some() {
        spec = spec.with_placement(Placement::new(a.json("lightvol.to_world")?)?);
    }
    let coeffs = usize::try_from(a.i32("lightvol.sh_coeffs")?).unwrap_or(0);
    check_coeffs(coeffs)?;
    if usize::try_from(a.i32("lightvol.sh_bands")?).ok() != Some(coeffs.isqrt()) {
        return Err(VolumeError::malformed(F, "lightvol.sh_bands does not match lightvol.sh_coeffs"));
    }
    if a.text("lightvol.convention")? != SH_CONVENTION {
        return Err(VolumeError::unsupported(F, "SH convention differs from lightvol's"));
    }
    if a.text("lightvol.quantity")? != QUANTITY {
        return Err(VolumeError::unsupported(F, "stored quantity is not radiance"));
    }
    let sample = match a.text("lightvol.encoding")?.as_str() {
        "f32" => SampleType::F32,
        "f16" => SampleType::F16,
        other => return Err(VolumeError::unsupported(F, format!("encoding {other:?}"))),
    };
    let (shard_index, shard_count) = match a.get("lightvol.bake.shard")? {
        AttributeValue::IntVec2(v) => {
            (u32::try_from(v.0).unwrap_or(u32::MAX), u32::try_from(v.1).unwrap_or(0))
        }
        _ => return Err(VolumeError::malformed(F, "lightvol.bake.shard is not an int vec2")),
    };
    if shard_count == 0 || shard_index >= shard_count {
        return Err(VolumeError::malformed(F, format!("shard {shard_index} of {shard_count}")));
    }
    let meta = BakeMetadata {
        method: a.text("lightvol.bake.method")?,
        samples: a.u64("lightvol.bake.samples")?,
        seed: a.u64("lightvol.bake.seed")?,
        shard_index,
        shard_count,
        scene_hash: a.text("lightvol.bake.scene_hash")?,
        units: a.text("lightvol.units")?,
        frame: match a.opt("lightvol.frame") {
            None => crate::up_axis::UpAxis::INTERNAL,
            Some(_) => {
                let f = a.text("lightvol.frame")?;
                crate::up_axis::UpAxis::parse(&f)
                    .ok_or_else(|| VolumeError::malformed(F, format!("lightvol.frame {f:?}")))?
            }
        },
        settings: match a.opt("lightvol.bake.settings") {
            None => None,
            Some(_) if (version as u32) < SETTINGS_VERSION => {
                return Err(VolumeError::malformed(
                    F,
                    format!(
                        "lightvol.bake.settings in a version {version} file (it needs version {SETTINGS_VERSION})"
                    ),
                ));
            }
            Some(_) => Some(
                serde_json::from_str(&a.text("lightvol.bake.settings")?)
                    .map_err(|e| VolumeError::malformed(F, format!("lightvol.bake.settings: {e}")))?,
            ),
        },
    };
    let checksum = a.text("lightvol.checksum")?;
    let gradients = match a.opt("lightvol.gradients") {
        None => false,
        Some(AttributeValue::I32(1)) => true,
        Some(_) => return Err(VolumeError::malformed(F, "lightvol.gradients is not the i32 1")),
    };
    let validity = match a.opt("lightvol.validity") {
        None => false,
        Some(AttributeValue::I32(1)) if version as u32 >= VALIDITY_VERSION => true,
        Some(AttributeValue::I32(1)) => {
            return Err(VolumeError::malformed(
                F,
                format!(
                    "lightvol.validity in a version {version} file (masks need version {VALIDITY_VERSION})"
                ),
            ));
        }
        Some(_) => return Err(VolumeError::malformed(F, "lightvol.validity is not the i32 1")),
    };
    let reach = match a.opt("lightvol.reach") {
        None => false,
        Some(AttributeValue::I32(1)) if version as u32 >= REACH_VERSION => true,
        Some(AttributeValue::I32(1)) => {
            return Err(VolumeError::malformed(
                F,
                format!("lightvol.reach in a version {version} file (a reach needs version {REACH_VERSION})"),
            ));
        }
        Some(_) => return Err(VolumeError::malformed(F, "lightvol.reach is not the i32 1")),
    };
    Ok(Declared { spec, coeffs, sample, meta, checksum, gradients, validity, reach })
}

/// Parses a multi-part EXR volume from memory (see the module docs for what is checked).
pub fn exr_from_bytes(bytes: &[u8]) -> Result<IrradianceVolume, VolumeError> {
    Ok(exr_from_bytes_with_gradients(bytes)?.0)
}

/// Parses a volume and its optional gradient parts from memory.
pub fn exr_from_bytes_with_gradients(
    bytes: &[u8],
) -> Result<(IrradianceVolume, Option<VolumeGradients>), VolumeError> {
    guard(F, || exr_from_bytes_inner(bytes, false)).map(|(v, g, _, _)| (v, g))
}

/// A part that is not one of the native format's (an extension's), as read: name, size and
/// channels (name, samples) in the file's channel order.
pub(crate) struct ExtraPart {
    pub(crate) name: String,
    pub(crate) size: (usize, usize),
    pub(crate) channels: Vec<(String, FlatSamples)>,
}

/// Whether a part name belongs to the adaptive extension ([`crate::io::adaptive`]).
pub(crate) fn is_octree_part(name: &str) -> bool {
    name.starts_with("octree") || name.starts_with("split")
}

/// The image attribute that marks an adaptive octree file.
pub(crate) const OCTREE_ATTRIBUTE: &str = "lightvol.octree";

/// A volume, its extra parts and its image attributes.
pub(crate) type VolumeWithExtras = (IrradianceVolume, Vec<ExtraPart>, HashMap<Text, AttributeValue>);

/// Parses a native file; with `extensions`, parts named by [`is_octree_part`] are returned
/// unchecked instead of rejected, and the image attributes come back too.
pub(crate) fn exr_from_bytes_ext(bytes: &[u8], extensions: bool) -> Result<VolumeWithExtras, VolumeError> {
    guard(F, || exr_from_bytes_inner(bytes, extensions)).map(|(v, _, e, a)| (v, e, a))
}

type Parsed = (IrradianceVolume, Option<VolumeGradients>, Vec<ExtraPart>, HashMap<Text, AttributeValue>);

fn exr_from_bytes_inner(bytes: &[u8], extensions: bool) -> Result<Parsed, VolumeError> {
    let e = |err: exr::error::Error| VolumeError::malformed(F, err.to_string());
    // 1. Headers only.
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), true).map_err(e)?;
    let first = meta.headers.first().ok_or_else(|| VolumeError::malformed(F, "no parts"))?;
    // Custom image attributes are written into every header; readers of the exr crate
    // file unknown attributes under the part's own attributes, so look in both.
    let mut attrs = first.shared_attributes.other.clone();
    attrs.extend(first.own_attributes.other.iter().map(|(k, v)| (k.clone(), v.clone())));
    if !extensions && attrs.keys().any(|k| k.as_slice() == OCTREE_ATTRIBUTE.as_bytes()) {
        return Err(VolumeError::unsupported(
            F,
            "this is an adaptive octree volume (lightvol.octree); read it with io::adaptive::read_adaptive_exr",
        ));
    }
    let d = declared(&attrs)?;
    let [nx, ny, nz] = d.spec.res().map(|v| v as usize);
    let size = Vec2(nx, ny * nz);
    let part_name = |h: &exr::meta::header::Header| {
        h.own_attributes.layer_name.as_ref().map(ToString::to_string).unwrap_or_default()
    };
    let extra =
        if extensions { meta.headers.iter().filter(|h| is_octree_part(&part_name(h))).count() } else { 0 };
    // Slots: the coefficients, the weight, the validity (if any), the reach (if any), the
    // gradients (if any).
    let v = usize::from(d.validity);
    let reach_slot = d.coeffs + 1 + v;
    let grad_base = reach_slot + usize::from(d.reach);
    let reach_want: Vec<(&str, SampleType)> =
        REACH_CHANNELS.iter().map(|&(c, _)| (c, SampleType::F32)).collect();
    let parts = grad_base + if d.gradients { d.coeffs } else { 0 } + extra;
    if meta.headers.len() != parts {
        return Err(VolumeError::malformed(F, format!("{} parts, expected {parts}", meta.headers.len())));
    }
    let mut seen = vec![false; parts];
    let grad_want: Vec<(&str, SampleType)> =
        GRAD_CHANNELS.iter().map(|&(c, _)| (c, SampleType::F32)).collect();
    for h in &meta.headers {
        let name = part_name(h);
        if extensions && is_octree_part(&name) {
            continue;
        }
        let grad_slot = (0..d.coeffs).find(|&j| d.gradients && grad_layer_name(j) == name);
        let (slot, want): (usize, &[(&str, SampleType)]) = if name == "weight" {
            (d.coeffs, &[("Y", SampleType::F32)])
        } else if d.validity && name == VALIDITY_PART {
            (d.coeffs + 1, &[("Y", SampleType::F32)])
        } else if d.reach && name == REACH_PART {
            (reach_slot, &reach_want)
        } else if let Some(j) = grad_slot {
            (grad_base + j, &grad_want)
        } else {
            let j = (0..d.coeffs)
                .find(|&j| layer_name(j) == name)
                .ok_or_else(|| VolumeError::malformed(F, format!("unexpected part {name:?}")))?;
            (j, &[("B", d.sample), ("G", d.sample), ("R", d.sample)])
        };
        if std::mem::replace(&mut seen[slot], true) {
            return Err(VolumeError::malformed(F, format!("duplicate part {name:?}")));
        }
        if h.deep || h.layer_size != size {
            return Err(VolumeError::malformed(
                F,
                format!("part {name:?} is {:?} (deep: {}), expected {size:?}", h.layer_size, h.deep),
            ));
        }
        let got: Vec<(String, SampleType)> =
            h.channels.list.iter().map(|c| (c.name.to_string(), c.sample_type)).collect();
        let want: Vec<(String, SampleType)> = want.iter().map(|(n, t)| ((*n).to_string(), *t)).collect();
        if got != want {
            return Err(VolumeError::malformed(
                F,
                format!("part {name:?} has channels {got:?}, expected {want:?}"),
            ));
        }
    }

    // 2. Pixels.
    let image = decode_image(bytes).map_err(e)?;
    let n = d.spec.node_count();
    let k = d.coeffs * 3;
    let mut data = vec![0.0f32; n * k];
    let mut weights = vec![0.0f32; n];
    let mut flags: Option<Vec<f32>> = None;
    let mut reach: Option<Vec<[f32; 6]>> = if d.reach { Some(vec![[0.0; 6]; n]) } else { None };
    let mut gdata = vec![0.0f32; if d.gradients { n * k * 3 } else { 0 }];
    let mut extras = Vec::new();
    for layer in &image.layer_data {
        let name = layer.attributes.layer_name.as_ref().map(ToString::to_string).unwrap_or_default();
        if extensions && is_octree_part(&name) {
            extras.push(ExtraPart {
                name,
                size: (layer.size.0, layer.size.1),
                channels: layer
                    .channel_data
                    .list
                    .iter()
                    .map(|c| (c.name.to_string(), c.sample_data.clone()))
                    .collect(),
            });
            continue;
        }
        for ch in &layer.channel_data.list {
            let vals: Vec<f32> = ch.sample_data.values_as_f32().collect();
            if vals.len() != n {
                return Err(VolumeError::malformed(F, format!("part {name:?} has {} samples", vals.len())));
            }
            if name == "weight" {
                weights = vals;
                continue;
            }
            if d.validity && name == VALIDITY_PART {
                flags = Some(vals);
                continue;
            }
            if let Some(r) = reach.as_mut().filter(|_| name == REACH_PART) {
                let dir = channel_slot(&REACH_CHANNELS, &ch.name.to_string())?;
                for (node, v) in vals.into_iter().enumerate() {
                    r[node][dir] = v;
                }
                continue;
            }
            if let Some(j) = (0..d.coeffs).find(|&j| d.gradients && grad_layer_name(j) == name) {
                let o = channel_slot(&GRAD_CHANNELS, &ch.name.to_string())?;
                for (node, v) in vals.into_iter().enumerate() {
                    gdata[(node * d.coeffs + j) * 9 + o] = v;
                }
                continue;
            }
            let j = (0..d.coeffs)
                .find(|&j| layer_name(j) == name)
                .ok_or_else(|| VolumeError::malformed(F, "part"))?;
            let c = match ch.name.to_string().as_str() {
                "R" => 0,
                "G" => 1,
                _ => 2,
            };
            for (node, v) in vals.into_iter().enumerate() {
                data[node * k + 3 * j + c] = v;
            }
        }
    }
    check_finite("EXR coefficients", &data)?;
    check_finite("EXR weights", &weights)?;
    let mut vol = IrradianceVolume::new(d.spec, d.coeffs, data, weights)?.with_metadata(d.meta);
    if let Some(flags) = flags {
        if let Some(i) = flags.iter().position(|&f| f != 0.0 && f != 1.0) {
            return Err(VolumeError::malformed(
                F,
                format!("validity {} at node {i} is neither 1 (valid) nor 0 (invalid)", flags[i]),
            ));
        }
        vol.set_validity(Some(ValidityMask::new(flags.iter().map(|&f| f == 1.0).collect())))?;
    }
    if let Some(r) = reach {
        let r = NodeReach::new(r).map_err(|e| VolumeError::malformed(F, e.to_string()))?;
        vol.set_reach(Some(r))?;
    }
    verify(F, Some(&d.checksum), &vol)?;
    let grad = if d.gradients { Some(VolumeGradients::new(&vol, gdata)?) } else { None };
    Ok((vol, grad, extras, attrs))
}
