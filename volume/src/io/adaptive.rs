//! The adaptive octree volume in the native EXR file: a documented extension of
//! [`crate::io::exr`]'s layout.
//!
//! ## Layout
//! - The base volume (level 0) as the native format writes it: parts `sh00` … and `weight`,
//!   f32, with all `lightvol.*` image attributes and the base checksum.
//! - One part `octree01`, `octree02`, … per level `l` in `1..=max_level`: the level's stored
//!   nodes in key order (`(k, j, i)` lexicographic), one node per pixel, row-major in rows of
//!   [`ROW`] pixels (a single row when fewer): u32 channels `i`, `j`, `k` (the node's
//!   coordinates in the level grid) and f32 channels `c00.R`, `c00.G`, `c00.B`, `c01.R`, …
//!   (the surpluses). Pixels after the last node are zero.
//! - One part `split00`, `split01`, … per level `l` in `0..max_level`: the split cells of
//!   level `l`, same row layout, u32 channels `i`, `j`, `k`.
//! - The image attribute `lightvol.octree` (text, JSON): `version` ([`OCTREE_VERSION`]),
//!   `params` (min/max level, cull tolerance, memory budget), `value_scale` (exact f64),
//!   `stats` (the [`LevelStats`] per level, which give each part's node count), `row`, and
//!   `checksum` (FNV-1a over the keys, surplus bits and split keys; hex).
//!
//! [`crate::io::exr::read_exr`] rejects such a file with [`VolumeError::Unsupported`] naming
//! this reader (a reader of uniform volumes must not silently drop the fine levels);
//! [`is_adaptive_exr`] tells the two kinds apart from the headers. Every inconsistency
//! (part sizes, channel lists, counts, unsorted or out-of-range keys, non-zero padding,
//! checksum) is a [`VolumeError`], never a panic. f32 round trips are bit-exact.

use std::io::Cursor;
use std::path::Path;

use exr::image::{AnyChannel, AnyChannels, FlatSamples, Layer};
use exr::math::Vec2;
use exr::meta::attribute::{AttributeValue, SampleType};
use exr::meta::header::LayerAttributes;
use exr::prelude::SmallVec;
use serde::{Deserialize, Serialize};

use crate::adaptive::{AdaptiveVolume, LevelStats, LevelTable, OctreeParams, pack_key, unpack_key};
use crate::checksum::{Fnv1a, from_hex, to_hex};
use crate::error::{FileFormat, VolumeError};
use crate::io::exr::{ExtraPart, OCTREE_ATTRIBUTE, base_layers, encode_image, exr_from_bytes_ext, text};
use crate::io::util::{read_bounded, write_atomic};

const F: FileFormat = FileFormat::Exr;

/// Version of the octree extension.
pub const OCTREE_VERSION: u32 = 1;

/// Pixels per row of the node-list parts.
pub const ROW: usize = 256;

/// The JSON of the `lightvol.octree` attribute.
#[derive(Serialize, Deserialize)]
struct OctreeHeader {
    version: u32,
    params: ParamsJson,
    value_scale: f64,
    stats: Vec<LevelStats>,
    row: usize,
    checksum: String,
}

#[derive(Serialize, Deserialize)]
struct ParamsJson {
    min_level: u32,
    max_level: u32,
    cull_tolerance: f64,
    memory_budget: Option<usize>,
    budget_tolerance: f64,
}

fn octree_name(l: usize) -> String {
    format!("octree{l:02}")
}

fn split_name(l: usize) -> String {
    format!("split{l:02}")
}

/// `(width, height)` of a part holding `count` entries.
fn part_size(count: usize) -> (usize, usize) {
    let w = count.clamp(1, ROW);
    (w, count.max(1).div_ceil(w))
}

fn coeff_channel(j: usize, ch: usize) -> String {
    format!("c{j:02}.{}", ["R", "G", "B"][ch])
}

/// FNV-1a over everything the extension parts hold.
fn octree_checksum(tables: &[LevelTable], split: &[Vec<u64>]) -> u64 {
    let mut h = Fnv1a::default();
    h.write_str("lightvol octree checksum v1");
    for t in tables {
        h.write(&(t.keys.len() as u64).to_le_bytes());
        for k in &t.keys {
            h.write(&k.to_le_bytes());
        }
        for v in &t.data {
            h.write(&v.to_bits().to_le_bytes());
        }
    }
    for s in split {
        h.write(&(s.len() as u64).to_le_bytes());
        for k in s {
            h.write(&k.to_le_bytes());
        }
    }
    h.finish()
}

/// Serialises an adaptive volume (module docs) in memory.
pub fn adaptive_exr_to_bytes(vol: &AdaptiveVolume) -> Result<Vec<u8>, VolumeError> {
    let (mut layers, mut ia) = base_layers(&vol.base, None, &crate::io::exr::ExrOptions::default())?;
    let encoding = layers[0].encoding;
    let coeffs = vol.coeffs();
    let k = coeffs * 3;
    let coords_channels = |keys: &[u64]| -> Vec<AnyChannel<FlatSamples>> {
        let (w, h) = part_size(keys.len());
        (0..3)
            .map(|a| {
                let mut v: Vec<u32> = keys.iter().map(|&key| unpack_key(key)[a]).collect();
                v.resize(w * h, 0);
                AnyChannel::new(["i", "j", "k"][a], FlatSamples::U32(v))
            })
            .collect()
    };
    for (l, t) in vol.tables.iter().enumerate() {
        let (w, h) = part_size(t.keys.len());
        let mut ch = coords_channels(&t.keys);
        for j in 0..coeffs {
            for c in 0..3 {
                let mut v: Vec<f32> = t.data.chunks_exact(k).map(|d| d[3 * j + c]).collect();
                v.resize(w * h, 0.0);
                ch.push(AnyChannel::new(coeff_channel(j, c).as_str(), FlatSamples::F32(v)));
            }
        }
        let attrs = LayerAttributes::named(text(&octree_name(l + 1))?);
        layers.push(Layer::new(Vec2(w, h), attrs, encoding, AnyChannels::sort(SmallVec::from_vec(ch))));
    }
    for (l, s) in vol.split.iter().enumerate() {
        let (w, h) = part_size(s.len());
        let attrs = LayerAttributes::named(text(&split_name(l))?);
        let ch = coords_channels(s);
        layers.push(Layer::new(Vec2(w, h), attrs, encoding, AnyChannels::sort(SmallVec::from_vec(ch))));
    }
    let p = vol.params;
    let header = OctreeHeader {
        version: OCTREE_VERSION,
        params: ParamsJson {
            min_level: p.min_level,
            max_level: p.max_level,
            cull_tolerance: p.cull_tolerance,
            memory_budget: p.memory_budget,
            budget_tolerance: p.budget_tolerance,
        },
        value_scale: vol.value_scale,
        stats: vol.stats.clone(),
        row: ROW,
        checksum: to_hex(octree_checksum(&vol.tables, &vol.split)),
    };
    let json = serde_json::to_string(&header).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
    ia.other.insert(text(OCTREE_ATTRIBUTE)?, AttributeValue::Text(text(&json)?));
    encode_image(ia, layers)
}

/// Writes an adaptive volume (temporary file and rename).
pub fn write_adaptive_exr(path: &Path, vol: &AdaptiveVolume) -> Result<(), VolumeError> {
    write_atomic(path, &adaptive_exr_to_bytes(vol)?)
}

/// Reads a file written by [`write_adaptive_exr`].
pub fn read_adaptive_exr(path: &Path) -> Result<AdaptiveVolume, VolumeError> {
    adaptive_exr_from_bytes(&read_bounded(path)?)
}

/// Whether the EXR volume at `path` is adaptive (reads the headers only). Errors if the
/// file cannot be read or is not an EXR file.
pub fn is_adaptive_exr(path: &Path) -> Result<bool, VolumeError> {
    let bytes = read_bounded(path)?;
    let meta = crate::io::util::guard(F, || {
        exr::meta::MetaData::read_from_buffered(Cursor::new(&bytes), true)
            .map_err(|e| VolumeError::malformed(F, e.to_string()))
    })?;
    let first = meta.headers.first().ok_or_else(|| VolumeError::malformed(F, "no parts"))?;
    let key = OCTREE_ATTRIBUTE.as_bytes();
    Ok(first
        .shared_attributes
        .other
        .keys()
        .chain(first.own_attributes.other.keys())
        .any(|k| k.as_slice() == key))
}

fn sample_type(s: &FlatSamples) -> SampleType {
    match s {
        FlatSamples::F16(_) => SampleType::F16,
        FlatSamples::F32(_) => SampleType::F32,
        FlatSamples::U32(_) => SampleType::U32,
    }
}

/// Takes the part `name` out of `extras`.
fn take_part(extras: &mut Vec<ExtraPart>, name: &str) -> Result<ExtraPart, VolumeError> {
    let i = extras
        .iter()
        .position(|p| p.name == name)
        .ok_or_else(|| VolumeError::malformed(F, format!("missing part {name:?}")))?;
    Ok(extras.swap_remove(i))
}

/// Checks a part's size and channel list and returns its `count` keys plus the named f32
/// channels (each `count` long); padding must be zero.
fn part_entries(
    part: &ExtraPart,
    count: usize,
    float_channels: &[String],
) -> Result<(Vec<u64>, Vec<Vec<f32>>), VolumeError> {
    let name = &part.name;
    if part.size != part_size(count) {
        return Err(VolumeError::malformed(
            F,
            format!("part {name:?} is {:?}, expected {:?}", part.size, part_size(count)),
        ));
    }
    let mut want: Vec<(String, SampleType)> =
        ["i", "j", "k"].iter().map(|c| ((*c).to_string(), SampleType::U32)).collect();
    want.extend(float_channels.iter().map(|c| (c.clone(), SampleType::F32)));
    want.sort_by(|a, b| a.0.cmp(&b.0));
    let got: Vec<(String, SampleType)> =
        part.channels.iter().map(|(n, s)| (n.clone(), sample_type(s))).collect();
    if got != want {
        return Err(VolumeError::malformed(
            F,
            format!("part {name:?} has channels {got:?}, expected {want:?}"),
        ));
    }
    let get = |c: &str| &part.channels.iter().find(|(n, _)| n == c).expect("channel checked above").1;
    let coords: Vec<&Vec<u32>> = ["i", "j", "k"]
        .iter()
        .map(|c| match get(c) {
            FlatSamples::U32(v) => Ok(v),
            _ => Err(VolumeError::malformed(F, "coordinate channel is not u32")),
        })
        .collect::<Result<_, _>>()?;
    let floats: Vec<&Vec<f32>> = float_channels
        .iter()
        .map(|c| match get(c) {
            FlatSamples::F32(v) => Ok(v),
            _ => Err(VolumeError::malformed(F, "coefficient channel is not f32")),
        })
        .collect::<Result<_, _>>()?;
    let total = part.size.0 * part.size.1;
    if coords.iter().any(|v| v.len() != total) || floats.iter().any(|v| v.len() != total) {
        return Err(VolumeError::malformed(F, format!("part {name:?} has the wrong sample count")));
    }
    let padding_zero = coords.iter().all(|v| v[count..].iter().all(|&x| x == 0))
        && floats.iter().all(|v| v[count..].iter().all(|&x| x.to_bits() == 0));
    if !padding_zero {
        return Err(VolumeError::malformed(F, format!("part {name:?} has non-zero padding")));
    }
    if coords.iter().any(|v| v[..count].iter().any(|&x| x >= 1 << 21)) {
        return Err(VolumeError::malformed(F, format!("part {name:?} has a coordinate beyond 2^21")));
    }
    let keys = (0..count).map(|n| pack_key([coords[0][n], coords[1][n], coords[2][n]])).collect();
    Ok((keys, floats.iter().map(|v| v[..count].to_vec()).collect()))
}

/// Parses an adaptive volume from memory (module docs).
pub fn adaptive_exr_from_bytes(bytes: &[u8]) -> Result<AdaptiveVolume, VolumeError> {
    let (base, mut extras, attrs) = exr_from_bytes_ext(bytes, true)?;
    let json = match attrs.iter().find(|(k, _)| k.as_slice() == OCTREE_ATTRIBUTE.as_bytes()).map(|(_, v)| v) {
        Some(AttributeValue::Text(t)) => t.to_string(),
        Some(_) => return Err(VolumeError::malformed(F, "lightvol.octree is not text")),
        None => {
            return Err(VolumeError::malformed(F, "not an adaptive volume (no lightvol.octree attribute)"));
        }
    };
    let h: OctreeHeader = serde_json::from_str(&json)
        .map_err(|e| VolumeError::malformed(F, format!("lightvol.octree: {e}")))?;
    if h.version != OCTREE_VERSION {
        return Err(VolumeError::unsupported(F, format!("octree extension version {}", h.version)));
    }
    if h.row != ROW {
        return Err(VolumeError::unsupported(F, format!("octree row width {}", h.row)));
    }
    let params = OctreeParams {
        min_level: h.params.min_level,
        max_level: h.params.max_level,
        cull_tolerance: h.params.cull_tolerance,
        memory_budget: h.params.memory_budget,
        budget_tolerance: h.params.budget_tolerance,
    };
    params.validate().map_err(|e| VolumeError::malformed(F, e.to_string()))?;
    let ml = params.max_level as usize;
    if h.stats.len() != ml + 1 || extras.len() != 2 * ml {
        return Err(VolumeError::malformed(
            F,
            format!("{} level stats and {} octree parts for max level {ml}", h.stats.len(), extras.len()),
        ));
    }
    let coeffs = base.coeffs();
    let names: Vec<String> = (0..coeffs).flat_map(|j| (0..3).map(move |c| coeff_channel(j, c))).collect();
    let mut tables = Vec::with_capacity(ml);
    for l in 1..=ml {
        let part = take_part(&mut extras, &octree_name(l))?;
        let count = h.stats[l].stored_nodes;
        let (keys, floats) = part_entries(&part, count, &names)?;
        let mut data = Vec::with_capacity(count * coeffs * 3);
        for n in 0..count {
            data.extend(floats.iter().map(|v| v[n]));
        }
        tables.push(LevelTable { keys, data });
    }
    let mut split = Vec::with_capacity(ml);
    for l in 0..ml {
        let part = take_part(&mut extras, &split_name(l))?;
        split.push(part_entries(&part, h.stats[l].split, &[])?.0);
    }
    let stored = from_hex(&h.checksum).ok_or_else(|| VolumeError::malformed(F, "bad octree checksum"))?;
    let got = octree_checksum(&tables, &split);
    if stored != got {
        return Err(VolumeError::malformed(
            F,
            format!("octree checksum mismatch (stored {stored:016x}, data {got:016x}): the file is damaged"),
        ));
    }
    AdaptiveVolume::from_parts(base, params, h.value_scale, tables, split, h.stats)
        .map_err(|e| VolumeError::malformed(F, e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adaptive::build::build_adaptive;
    use crate::adaptive::tests::{base_from, base_spec, point_bake, step_field, step_volume};
    use crate::metadata::BakeMetadata;

    fn meta() -> BakeMetadata {
        BakeMetadata {
            method: "doi".into(),
            sampling_rays: 77,
            seed: 5,
            scene_hash: "abc".into(),
            ..Default::default()
        }
    }

    #[test]
    fn round_trip_is_bit_exact_and_dispatchable() {
        let v = step_volume().with_metadata(meta());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.lvol.exr");
        write_adaptive_exr(&path, &v).unwrap();
        let r = read_adaptive_exr(&path).unwrap();
        assert_eq!(r, v);
        assert_eq!(r.metadata(), &meta());
        let mut a = [0.0f32; 12];
        let mut b = [0.0f32; 12];
        v.coeffs_at([1.3, 0.7, 0.4], &mut a);
        r.coeffs_at([1.3, 0.7, 0.4], &mut b);
        assert_eq!(a, b);
        assert!(is_adaptive_exr(&path).unwrap());
        // The uniform reader refuses, naming the adaptive reader.
        let e = crate::io::exr::read_exr(&path).unwrap_err();
        assert!(
            matches!(e, VolumeError::Unsupported { .. }) && e.to_string().contains("read_adaptive_exr"),
            "{e}"
        );
        // A plain file is not adaptive, and the adaptive reader refuses it clearly.
        let plain = dir.path().join("p.lvol.exr");
        crate::io::exr::write_exr(&plain, v.base(), &Default::default()).unwrap();
        assert!(!is_adaptive_exr(&plain).unwrap());
        assert_eq!(&crate::io::exr::read_exr(&plain).unwrap(), v.base());
        assert!(read_adaptive_exr(&plain).unwrap_err().to_string().contains("lightvol.octree"));
        // Only the target is left (temporary file renamed).
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn empty_levels_round_trip() {
        let spec = base_spec();
        let v = build_adaptive(
            base_from(&spec, &step_field),
            &OctreeParams { max_level: 2, ..OctreeParams::default() },
            |c| Ok::<_, VolumeError>(vec![0.0; c.cells().len()]),
            point_bake(&spec, &step_field, |_, _| false),
        )
        .unwrap();
        assert_eq!(v.stored_nodes(), spec.node_count());
        let back = adaptive_exr_from_bytes(&adaptive_exr_to_bytes(&v).unwrap()).unwrap();
        assert_eq!(back, v);
    }

    #[test]
    fn damaged_files_are_errors() {
        let bytes = adaptive_exr_to_bytes(&step_volume()).unwrap();
        // Truncation anywhere.
        for cut in [0, 8, 100, bytes.len() / 3, bytes.len() / 2, bytes.len() - 7, bytes.len() - 1] {
            assert!(adaptive_exr_from_bytes(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let replace = |from: &str, to: &str| -> Vec<u8> {
            assert_eq!(from.len(), to.len());
            let pos =
                bytes.windows(from.len()).position(|w| w == from.as_bytes()).expect("attribute text present");
            let mut b = bytes.clone();
            b[pos..pos + to.len()].copy_from_slice(to.as_bytes());
            b
        };
        // A newer extension version: unsupported.
        let e = adaptive_exr_from_bytes(&replace("\"version\":1", "\"version\":7")).unwrap_err();
        assert!(matches!(e, VolumeError::Unsupported { .. }), "{e}");
        // A row width this reader does not know: unsupported.
        let e = adaptive_exr_from_bytes(&replace("\"row\":256", "\"row\":255")).unwrap_err();
        assert!(matches!(e, VolumeError::Unsupported { .. }), "{e}");
        // Garbage JSON.
        let e = adaptive_exr_from_bytes(&replace("{\"version\"", "[\"version\"")).unwrap_err();
        assert!(matches!(e, VolumeError::Malformed { .. }), "{e}");
        // A checksum that does not match the data.
        let pos = bytes.windows(12).position(|w| w == b"\"checksum\":\"").unwrap() + 12;
        let mut b = bytes.clone();
        b[pos] = if b[pos] == b'0' { b'1' } else { b'0' };
        let e = adaptive_exr_from_bytes(&b).unwrap_err();
        assert!(e.to_string().contains("checksum"), "{e}");
        // A renamed attribute: not adaptive.
        let e = adaptive_exr_from_bytes(&replace("lightvol.octree", "lightvol.octreX")).unwrap_err();
        assert!(matches!(e, VolumeError::Malformed { .. }), "{e}");
    }
}
