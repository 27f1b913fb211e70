//! Reading the native EXR volume ([`super`]'s module docs): the headers first, every
//! attribute, part name, channel list, sample type and data-window size checked against the
//! declared dimensions, then the pixels, then the checksum.

use std::collections::HashMap;
use std::io::Cursor;
use std::path::Path;

use exr::image::FlatSamples;
use exr::math::Vec2;
use exr::meta::attribute::{AttributeValue, SampleType, Text};

use super::image::decode_image;
use super::layout::{
    F, GRAD_CHANNELS, OCTREE_ATTRIBUTE, REACH_CHANNELS, REACH_PART, VALIDITY_PART, grad_layer_name,
    is_octree_part, layer_name,
};
use crate::checksum::verify;
use crate::error::{VolumeError, check_finite};
use crate::gradient::VolumeGradients;
use crate::grid::{GridSpec, Placement};
use crate::io::groups::{GROUPS_ATTRIBUTE, is_group_part};
use crate::io::sidecar::{
    FORMAT_VERSION, QUANTITY, REACH_VERSION, SETTINGS_VERSION, SH_CONVENTION, VALIDITY_VERSION,
};
use crate::io::util::{guard, read_bounded};
use crate::metadata::BakeMetadata;
use crate::reach::NodeReach;
use crate::validity::ValidityMask;
use crate::volume::{IrradianceVolume, check_coeffs};

/// Reads a volume written by [`write_exr`](super::write_exr) (or
/// [`write_exr_with_gradients`](super::write_exr_with_gradients), ignoring the
/// gradients).
pub fn read_exr(path: &Path) -> Result<IrradianceVolume, VolumeError> {
    exr_from_bytes(&read_bounded(path)?)
}

/// Reads a volume and, if the file has them, its gradients.
pub fn read_exr_with_gradients(
    path: &Path,
) -> Result<(IrradianceVolume, Option<VolumeGradients>), VolumeError> {
    exr_from_bytes_with_gradients(&read_bounded(path)?)
}

/// The slot a channel table (`GRAD_CHANNELS`, `REACH_CHANNELS`) gives channel `name`, or
/// malformed data for a channel it does not list.
fn channel_slot(table: &[(&str, usize)], name: &str) -> Result<usize, VolumeError> {
    table
        .iter()
        .find(|(c, _)| *c == name)
        .map(|&(_, slot)| slot)
        .ok_or_else(|| VolumeError::malformed(F, format!("channel {name:?}")))
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
        sampling_rays: a.u64("lightvol.bake.samples")?,
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
    // Extension parts: the octree's, read by its own reader only, and the light groups',
    // which a reader of the whole bake skips (crate::io::groups).
    let groups = attrs.keys().any(|k| k.as_slice() == GROUPS_ATTRIBUTE.as_bytes());
    let is_extra = |name: &str| (extensions && is_octree_part(name)) || (groups && is_group_part(name));
    let extra = meta.headers.iter().filter(|h| is_extra(&part_name(h))).count();
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
        if is_extra(&name) {
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
        if is_extra(&name) {
            if !extensions {
                continue;
            }
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
