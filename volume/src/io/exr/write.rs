//! Writing the native EXR volume ([`super`]'s module docs): one part per coefficient, the
//! weight part, the optional validity, reach and gradient parts, and the `lightvol.*` image
//! attributes ending with the checksum of the volume as it will be decoded.

use std::path::Path;

use exr::image::{AnyChannel, AnyChannels, Encoding as ExrEncoding, FlatSamples, Layer};
use exr::math::Vec2;
use exr::meta::attribute::{AttributeValue, Compression, IntegerBounds};
use exr::meta::header::{ImageAttributes, LayerAttributes};
use exr::prelude::SmallVec;

use lightvol_sh::index::sh_lm;

use super::image::{ExrLayer, encode_image, text};
use super::layout::{GRAD_CHANNELS, REACH_CHANNELS, REACH_PART, VALIDITY_PART, grad_layer_name, layer_name};
use crate::checksum::{through_f16, to_hex, volume_checksum};
use crate::encode::Encoding;
use crate::error::VolumeError;
use crate::gradient::VolumeGradients;
use crate::io::sidecar::{QUANTITY, SH_CONVENTION, format_version};
use crate::io::util::write_atomic;
use crate::volume::IrradianceVolume;

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
    put("lightvol.bake.samples", AttributeValue::Text(text(&meta.sampling_rays.to_string())?))?;
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

/// An f64 array as JSON (exact through serde_json's shortest round-trip printing).
fn json<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string(v).expect("plain arrays serialise")
}

/// Writes `vol` to `path` as multi-part EXR (temporary file and rename).
pub fn write_exr(path: &Path, vol: &IrradianceVolume, options: &ExrOptions) -> Result<(), VolumeError> {
    write_atomic(path, &exr_to_bytes(vol, options)?)
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
