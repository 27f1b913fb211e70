//! A volume split by light group ([`crate::light_groups`]) in the native EXR file: a
//! documented extension of [`crate::io::exr`]'s layout.
//!
//! ## Layout
//! - The whole bake as the native format writes it (every part, attribute and the base
//!   checksum), so that a reader that knows nothing of groups reads the whole bake.
//! - Per group `g` and coefficient `j`, a part named `group{g:02}.sh{j:02}` with f32
//!   channels `R`, `G`, `B` in the same slice layout as `sh{j:02}` (always f32, also when
//!   the whole bake is stored as f16, so that the groups round-trip bit for bit).
//! - The image attribute `lightvol.light_groups` (text, JSON): `names` (the groups in
//!   order) and `checksum` (FNV-1a over the group count and every group value's f32 bits in
//!   group, node, coefficient, channel order; hex), and with a sky transfer `sky`, the
//!   baked sky's SH coefficients (`[[r, g, b], …]`, exact JSON numbers).
//! - `lightvol.version` is [`GROUPS_VERSION`], so readers older than the extension refuse
//!   the file as newer rather than misread it. Readers of this crate read the whole bake
//!   from it with [`crate::io::exr::read_exr`] (the group parts are skipped) and the
//!   groups with [`read_grouped_exr`].

use std::path::Path;

use exr::image::{AnyChannel, AnyChannels, FlatSamples, Layer};
use exr::math::Vec2;
use exr::meta::attribute::AttributeValue;
use exr::meta::header::LayerAttributes;
use exr::prelude::SmallVec;
use lightvol_core::hash::Fnv1a;
use serde::{Deserialize, Serialize};

use crate::checksum::{from_hex, to_hex};
use crate::error::{FileFormat, VolumeError};
use crate::io::exr::{ExrOptions, ExtraPart, base_layers, encode_image, exr_from_bytes_ext, text};
use crate::io::util::{read_bounded, write_atomic};
use crate::light_groups::GroupedVolume;

const F: FileFormat = FileFormat::Exr;

/// The image attribute that marks a file with light groups.
pub const GROUPS_ATTRIBUTE: &str = "lightvol.light_groups";

/// The `lightvol.version` of a file with light groups.
pub const GROUPS_VERSION: u32 = crate::io::sidecar::GROUPS_VERSION;

/// The name of group `g`'s part of coefficient `j`.
#[must_use]
pub fn group_part_name(g: usize, j: usize) -> String {
    format!("group{g:02}.sh{j:02}")
}

/// Whether a part name belongs to this extension.
pub(crate) fn is_group_part(name: &str) -> bool {
    name.starts_with("group") && name.contains(".sh")
}

#[derive(Serialize, Deserialize)]
struct GroupsHeader {
    names: Vec<String>,
    checksum: String,
    /// The baked sky's SH coefficients, with a sky transfer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sky: Option<Vec<[f64; 3]>>,
}

fn groups_checksum(layers: &[&[f32]]) -> u64 {
    let mut h = Fnv1a::default();
    h.write(&(layers.len() as u64).to_le_bytes());
    for l in layers {
        for v in *l {
            h.write(&v.to_bits().to_le_bytes());
        }
    }
    h.finish()
}

/// Serialises a grouped volume (module docs) in memory; `options` apply to the whole bake.
pub fn grouped_exr_to_bytes(vol: &GroupedVolume, options: &ExrOptions) -> Result<Vec<u8>, VolumeError> {
    let total = vol.total();
    let (mut layers, mut ia) = base_layers(total, None, options)?;
    let encoding = layers[0].encoding;
    let [nx, ny, nz] = total.spec().res().map(|v| v as usize);
    let size = Vec2(nx, ny * nz);
    let coeffs = total.coeffs();
    let k = coeffs * 3;
    for g in 0..vol.names().len() {
        let data = vol.layer(g);
        for j in 0..coeffs {
            let ch = |c: usize| FlatSamples::F32(data.chunks_exact(k).map(|node| node[3 * j + c]).collect());
            let channels = AnyChannels::sort(SmallVec::from_vec(vec![
                AnyChannel::new("R", ch(0)),
                AnyChannel::new("G", ch(1)),
                AnyChannel::new("B", ch(2)),
            ]));
            let attrs = LayerAttributes::named(text(&group_part_name(g, j))?);
            layers.push(Layer::new(size, attrs, encoding, channels));
        }
    }
    let all: Vec<&[f32]> = (0..vol.names().len()).map(|g| vol.layer(g)).collect();
    let header = GroupsHeader {
        names: vol.names().to_vec(),
        checksum: to_hex(groups_checksum(&all)),
        sky: vol.baked_sky().map(<[_]>::to_vec),
    };
    let json = serde_json::to_string(&header).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
    ia.other.insert(text(GROUPS_ATTRIBUTE)?, AttributeValue::Text(text(&json)?));
    ia.other.insert(text("lightvol.version")?, AttributeValue::I32(GROUPS_VERSION as i32));
    encode_image(ia, layers)
}

/// Writes a grouped volume to `path` (temporary file and rename).
pub fn write_grouped_exr(path: &Path, vol: &GroupedVolume, options: &ExrOptions) -> Result<(), VolumeError> {
    write_atomic(path, &grouped_exr_to_bytes(vol, options)?)
}

/// Reads a grouped volume from `path`.
pub fn read_grouped_exr(path: &Path) -> Result<GroupedVolume, VolumeError> {
    grouped_exr_from_bytes(&read_bounded(path)?)
}

/// Parses a grouped volume (module docs) from memory; a file without groups is an error
/// that says so.
pub fn grouped_exr_from_bytes(bytes: &[u8]) -> Result<GroupedVolume, VolumeError> {
    let (total, mut extras, attrs) = exr_from_bytes_ext(bytes, true)?;
    let json = match attrs.iter().find(|(k, _)| k.as_slice() == GROUPS_ATTRIBUTE.as_bytes()).map(|(_, v)| v) {
        Some(AttributeValue::Text(t)) => t.to_string(),
        Some(_) => return Err(VolumeError::malformed(F, "lightvol.light_groups is not text")),
        None => {
            return Err(VolumeError::InvalidData(
                "the volume has no light groups (bake it with --light-groups)".into(),
            ));
        }
    };
    let h: GroupsHeader = serde_json::from_str(&json)
        .map_err(|e| VolumeError::malformed(F, format!("lightvol.light_groups: {e}")))?;
    let n = total.spec().node_count();
    let [nx, ny, nz] = total.spec().res().map(|v| v as usize);
    let coeffs = total.coeffs();
    let k = coeffs * 3;
    let mut layers = Vec::with_capacity(h.names.len());
    for g in 0..h.names.len() {
        let mut data = vec![0.0f32; n * k];
        for j in 0..coeffs {
            let name = group_part_name(g, j);
            let part = take(&mut extras, &name)?;
            if part.size != (nx, ny * nz) {
                return Err(VolumeError::malformed(F, format!("part {name:?} is {:?}", part.size)));
            }
            let names: Vec<&str> = part.channels.iter().map(|c| c.0.as_str()).collect();
            if names != ["B", "G", "R"] {
                return Err(VolumeError::malformed(F, format!("part {name:?} has channels {names:?}")));
            }
            for (c, (_, samples)) in part.channels.iter().rev().enumerate() {
                let FlatSamples::F32(v) = samples else {
                    return Err(VolumeError::malformed(F, format!("part {name:?} is not f32")));
                };
                for (node, &x) in v.iter().enumerate() {
                    data[node * k + 3 * j + c] = x;
                }
            }
        }
        layers.push(data);
    }
    if let Some(p) = extras.first() {
        return Err(VolumeError::malformed(F, format!("unexpected part {:?}", p.name)));
    }
    let all: Vec<&[f32]> = layers.iter().map(Vec::as_slice).collect();
    if from_hex(&h.checksum) != Some(groups_checksum(&all)) {
        return Err(VolumeError::malformed(F, "light group checksum mismatch"));
    }
    let g =
        GroupedVolume::new(total, h.names, layers).map_err(|e| VolumeError::malformed(F, e.to_string()))?;
    match h.sky {
        Some(sky) => g.with_baked_sky(sky).map_err(|e| VolumeError::malformed(F, e.to_string())),
        None => Ok(g),
    }
}

/// Whether the EXR volume in `bytes` carries light groups (reads the headers only).
pub fn has_groups(bytes: &[u8]) -> Result<bool, VolumeError> {
    let meta = crate::io::util::guard(F, || {
        exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), true)
            .map_err(|e| VolumeError::malformed(F, e.to_string()))
    })?;
    let first = meta.headers.first().ok_or_else(|| VolumeError::malformed(F, "no parts"))?;
    let key = GROUPS_ATTRIBUTE.as_bytes();
    Ok(first
        .shared_attributes
        .other
        .keys()
        .chain(first.own_attributes.other.keys())
        .any(|k| k.as_slice() == key))
}

fn take(extras: &mut Vec<ExtraPart>, name: &str) -> Result<ExtraPart, VolumeError> {
    let i = extras
        .iter()
        .position(|p| p.name == name)
        .ok_or_else(|| VolumeError::malformed(F, format!("missing part {name:?}")))?;
    Ok(extras.swap_remove(i))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSpec;
    use crate::volume::IrradianceVolume;

    fn grouped() -> GroupedVolume {
        let spec = GridSpec::new([0.0; 3], [1.0, 2.0, 1.0], [2, 3, 2]).unwrap();
        let n = 12 * 27;
        let a: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin()).collect();
        let b: Vec<f32> = (0..n).map(|i| (i as f32 * 0.11).cos()).collect();
        let total: Vec<f32> = a.iter().zip(&b).map(|(x, y)| x + y).collect();
        let vol = IrradianceVolume::new(spec, 9, total, vec![1.0; 12]).unwrap();
        GroupedVolume::new(vol, vec!["sky".into(), "lamps".into()], vec![a, b]).unwrap()
    }

    #[test]
    fn groups_round_trip_bit_for_bit_and_plain_readers_read_the_total() {
        let g = grouped();
        let bytes = grouped_exr_to_bytes(&g, &ExrOptions::default()).unwrap();
        assert!(has_groups(&bytes).unwrap());
        let back = grouped_exr_from_bytes(&bytes).unwrap();
        assert_eq!(back.names(), g.names());
        for i in 0..2 {
            let (x, y) = (back.layer(i), g.layer(i));
            assert!(x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()));
        }
        assert_eq!(back.total().data(), g.total().data());
        let plain = crate::io::exr::exr_from_bytes(&bytes).unwrap();
        assert_eq!(plain.data(), g.total().data());
        // Same volume, same bytes.
        assert_eq!(grouped_exr_to_bytes(&back, &ExrOptions::default()).unwrap(), bytes);
        // A plain file is not grouped, and says so.
        let plain_bytes = crate::io::exr::exr_to_bytes(g.total(), &ExrOptions::default()).unwrap();
        assert!(!has_groups(&plain_bytes).unwrap());
        let e = grouped_exr_from_bytes(&plain_bytes).unwrap_err().to_string();
        assert!(e.contains("no light groups"), "{e}");
    }

    #[test]
    fn a_changed_group_value_fails_the_checksum() {
        let g = grouped();
        let mut layers: Vec<Vec<f32>> = (0..2).map(|i| g.layer(i).to_vec()).collect();
        let bytes = grouped_exr_to_bytes(&g, &ExrOptions::default()).unwrap();
        layers[1][5] += 1.0;
        let changed = GroupedVolume::new(g.total().clone(), g.names().to_vec(), layers).unwrap();
        let other = grouped_exr_to_bytes(&changed, &ExrOptions::default()).unwrap();
        // Swap in the original header's checksum: the reader must refuse the file.
        let (a, b) =
            (String::from_utf8_lossy(&bytes).into_owned(), String::from_utf8_lossy(&other).into_owned());
        let find = |s: &str| {
            let at = s.find("\"checksum\":\"").unwrap() + 12;
            s[at..at + 16].to_owned()
        };
        let (ca, cb) = (find(&a), find(&b));
        assert_ne!(ca, cb);
        let mut forged = other.clone();
        let at = forged.windows(16).position(|w| w == cb.as_bytes()).unwrap();
        forged[at..at + 16].copy_from_slice(ca.as_bytes());
        let e = grouped_exr_from_bytes(&forged).unwrap_err().to_string();
        assert!(e.contains("checksum"), "{e}");
    }
}
