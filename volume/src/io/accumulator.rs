//! Shard files: an [`Accumulator`] saved exactly, so that bakes split over machines or
//! resumed after an interruption can be merged later (Kontkanen & Laine Eq. 6 sums add).
//!
//! ## Format (little-endian)
//! | bytes | content |
//! | --- | --- |
//! | 8 | magic `LVACC\0`, then the format version as u16 (2, 3 with a node reach, 4 with light groups) |
//! | 4 | length `h` of the JSON header |
//! | h | JSON header: grid (as in the sidecar), coefficient count, contribution count, bake metadata |
//! | 16·(n·3c + 2n) | i128 fixed-point sums ([`crate::fixed`], units of 2^-64): numerator `[node][coeff][rgb]`, denominator `[node]`, outside `[node]` |
//! | 16·a | the auxiliary sums the header names, if any |
//! | 16·6n | the node reach's records ([`crate::accumulator`]), if the header says `"reach": true` (version 3) |
//! | 16·g·n·3c | the light groups' numerators, group by group in the numerator's layout, if the header lists `"groups"` (version 4) |
//! | 8 | FNV-1a 64 of every preceding byte |
//!
//! Version 1 stored the same sums as f64 (8 bytes each); it is still read, each sum rounded
//! to the fixed point once. The reader verifies the checksum first (any damaged byte is an
//! error), then the magic, version, header, and that the file size equals what the header's
//! grid requires, before it allocates the arrays. The sums round-trip bit-exactly, and the
//! bytes are a function of the sums and the metadata alone (no time or host), so equal bakes
//! give equal files.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::accumulator::{Accumulator, GroupLabels};
use crate::checksum::fnv1a;
use crate::error::{FileFormat, VolumeError};
use crate::grid::{GridSpec, Placement};
use crate::io::sidecar::GridJson;
use crate::io::util::{read_bounded, write_atomic};
use crate::metadata::BakeMetadata;
use crate::volume::check_coeffs;

/// First six bytes of a shard file.
pub const ACC_MAGIC: &[u8; 6] = b"LVACC\0";
/// The extension of an accumulator file (`.lvacc`), which bakes write beside their volume.
pub const ACC_EXTENSION: &str = "lvacc";
/// Current shard-file version.
pub const ACC_VERSION: u16 = 4;
/// The version of shard files with a node reach and no light groups.
const ACC_VERSION_REACH: u16 = 3;
/// The version of shard files without a node reach (they are written as before it).
const ACC_VERSION_PLAIN: u16 = 2;
/// Largest JSON header accepted (1 MiB; real headers are well under 1 KiB).
const MAX_HEADER: usize = 1 << 20;
const F: FileFormat = FileFormat::Shard;

#[derive(Debug, Serialize, Deserialize)]
struct AccHeader {
    grid: GridJson,
    coeffs: usize,
    contributions: u64,
    bake: BakeMetadata,
    /// Auxiliary sums after the outside sums (version 2): name and count.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    aux: Option<AuxHeader>,
    /// Node reach records after the auxiliary sums (version 3).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    reach: bool,
    /// Light groups' numerators after the reach (version 4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    groups: Option<GroupLabels>,
}

#[derive(Debug, Serialize, Deserialize)]
struct AuxHeader {
    name: String,
    len: u64,
}

/// Most auxiliary sums a file may declare per node: a 27-neighbour mass matrix needs 27,
/// basis-gradient systems 16 + 4 · 3 · coeffs (208 at 16 coefficients); 256 bounds what a
/// header can make the reader allocate.
const MAX_AUX_PER_NODE: u64 = 256;

/// Checks the 12 fixed bytes (magic, version, header length) and returns the version and
/// the header length.
fn parse_head(head: &[u8]) -> Result<(u16, usize), VolumeError> {
    let bad = |r: String| VolumeError::malformed(F, r);
    if &head[..6] != ACC_MAGIC {
        return Err(bad("not a lightvol accumulator (bad magic)".into()));
    }
    let version = u16::from_le_bytes([head[6], head[7]]);
    if version == 0 || version > ACC_VERSION {
        return Err(VolumeError::unsupported(F, format!("version {version}")));
    }
    let h = u32::from_le_bytes(head[8..12].try_into().expect("4 bytes")) as usize;
    if h > MAX_HEADER {
        return Err(bad(format!("header length {h} is too large")));
    }
    Ok((version, h))
}

/// Parses the JSON header and the grid it names.
fn parse_header(json: &[u8]) -> Result<(AccHeader, GridSpec), VolumeError> {
    let header: AccHeader =
        serde_json::from_slice(json).map_err(|e| VolumeError::malformed(F, e.to_string()))?;
    check_coeffs(header.coeffs)?;
    let mut spec = GridSpec::new(header.grid.min, header.grid.max, header.grid.res)?;
    if let Some(m) = header.grid.to_world {
        spec = spec.with_placement(Placement::new(m)?);
    }
    if header.bake.shard_count == 0 || header.bake.shard_index >= header.bake.shard_count {
        return Err(VolumeError::malformed(
            F,
            format!("shard {} of {}", header.bake.shard_index, header.bake.shard_count),
        ));
    }
    Ok((header, spec))
}

/// Serialises an accumulator and its bake metadata in memory. Errors if a sum is not
/// finite (a NaN radiance reached the bake: fix the source rather than persist it).
pub fn accumulator_to_bytes(acc: &Accumulator, meta: &BakeMetadata) -> Result<Vec<u8>, VolumeError> {
    let spec = acc.spec();
    let (min, max) = spec.bounds();
    let header = AccHeader {
        grid: GridJson {
            min,
            max,
            res: spec.res(),
            to_world: spec.placement().map(Placement::to_world_matrix),
        },
        coeffs: acc.coeffs(),
        contributions: acc.contributions(),
        bake: meta.clone(),
        aux: acc.aux().map(|(name, s)| AuxHeader { name: name.to_owned(), len: s.len() as u64 }),
        reach: acc.has_reach(),
        groups: acc.group_labels().cloned(),
    };
    let json = serde_json::to_vec(&header).expect("plain data");
    let parts = acc.fixed_parts().map_err(|(what, index)| VolumeError::NonFinite { what, index })?;
    let aux = acc.aux().map(|(_, s)| s);
    if let Some(index) = aux.and_then(crate::fixed::FixedSums::first_poisoned) {
        return Err(VolumeError::NonFinite { what: "auxiliary sum", index });
    }
    let arrays: Vec<&[i128]> = parts
        .into_iter()
        .chain(aux.map(crate::fixed::FixedSums::raw))
        .chain(acc.reach_raw())
        .chain(acc.groups_raw())
        .collect();
    let values: usize = arrays.iter().map(|a| a.len()).sum();
    let mut out = Vec::with_capacity(8 + 4 + json.len() + 16 * values + 8);
    out.extend_from_slice(ACC_MAGIC);
    let version = if acc.group_labels().is_some() {
        ACC_VERSION
    } else if acc.has_reach() {
        ACC_VERSION_REACH
    } else {
        ACC_VERSION_PLAIN
    };
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    for v in arrays.into_iter().flatten() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let sum = fnv1a(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    Ok(out)
}

/// Parses a shard file from memory (see the module docs for the checks).
pub fn accumulator_from_bytes(bytes: &[u8]) -> Result<(Accumulator, BakeMetadata), VolumeError> {
    let bad = |r: String| VolumeError::malformed(F, r);
    if bytes.len() < 8 + 4 + 8 {
        return Err(bad(format!("{} bytes is too short", bytes.len())));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 8);
    let stored = u64::from_le_bytes(tail.try_into().expect("8 bytes"));
    if fnv1a(body) != stored {
        return Err(bad("checksum mismatch: the file is damaged or truncated".into()));
    }
    let (version, h) = parse_head(&body[..12])?;
    if 12 + h > body.len() {
        return Err(bad(format!("header length {h} does not fit the file")));
    }
    let (header, spec) = parse_header(&body[12..12 + h])?;
    let n = spec.node_count();
    let k = header.coeffs * 3;
    let data = &body[12 + h..];
    let width: u64 = if version == 1 { 8 } else { 16 };
    let aux_len = check_aux(&header, n as u64).map_err(bad)?;
    let reach_len = check_reach(&header, version, n as u64).map_err(bad)?;
    let groups_len = check_groups(&header, version, n as u64 * k as u64).map_err(bad)?;
    let need = width * (n as u64 * k as u64 + 2 * n as u64 + aux_len + reach_len + groups_len);
    if data.len() as u64 != need {
        return Err(bad(format!("{} data bytes, the grid needs {need}", data.len())));
    }
    let acc = if version == 1 {
        let mut vals = data.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")));
        let numerator: Vec<f64> = vals.by_ref().take(n * k).collect();
        let denominator: Vec<f64> = vals.by_ref().take(n).collect();
        let outside: Vec<f64> = vals.collect();
        Accumulator::from_parts(spec, header.coeffs, numerator, denominator, outside, header.contributions)?
    } else {
        let mut vals = data.chunks_exact(16).map(|c| i128::from_le_bytes(c.try_into().expect("16 bytes")));
        let numerator: Vec<i128> = vals.by_ref().take(n * k).collect();
        let denominator: Vec<i128> = vals.by_ref().take(n).collect();
        let outside: Vec<i128> = vals.by_ref().take(n).collect();
        let mut acc = Accumulator::from_fixed_parts(
            spec,
            header.coeffs,
            numerator,
            denominator,
            outside,
            header.contributions,
        )?;
        if let Some(a) = &header.aux {
            acc.set_aux(
                &a.name,
                crate::fixed::FixedSums::from_raw(vals.by_ref().take(a.len as usize).collect()),
            );
        }
        if header.reach {
            acc.enable_reach();
        }
        if let Some(g) = &header.groups {
            acc.enable_groups(g.clone());
        }
        for (i, v) in vals.enumerate() {
            acc.add_raw_at(n * k + 2 * n + aux_len as usize + i, v);
        }
        acc
    };
    Ok((acc, header.bake))
}

/// The node reach records a header declares: 6 per node, or 0 without (a reach needs
/// version 3).
fn check_reach(header: &AccHeader, version: u16, nodes: u64) -> Result<u64, String> {
    match (header.reach, version >= ACC_VERSION_REACH) {
        (false, _) => Ok(0),
        (true, true) => Ok(6 * nodes),
        (true, false) => {
            Err(format!("a node reach in a version {version} file (it needs version {ACC_VERSION_REACH})"))
        }
    }
}

/// The light-group sums a header declares: one numerator (`numerator` sums) per group, or 0
/// without (groups need version 4; at most [`MAX_GROUPS`] of them).
fn check_groups(header: &AccHeader, version: u16, numerator: u64) -> Result<u64, String> {
    match &header.groups {
        None => Ok(0),
        Some(_) if version < ACC_VERSION => {
            Err(format!("light groups in a version {version} file (they need version {ACC_VERSION})"))
        }
        Some(g) if g.names.is_empty() || g.names.len() > MAX_GROUPS => {
            Err(format!("{} light groups (1 to {MAX_GROUPS})", g.names.len()))
        }
        Some(g) => Ok(g.names.len() as u64 * numerator),
    }
}

/// Most light groups a shard file may declare.
const MAX_GROUPS: usize = 64;

/// The auxiliary sum count a header declares (0 without), bounded per node.
fn check_aux(header: &AccHeader, nodes: u64) -> Result<u64, String> {
    match &header.aux {
        None => Ok(0),
        Some(a) if a.len <= MAX_AUX_PER_NODE * nodes => Ok(a.len),
        Some(a) => Err(format!("{} auxiliary sums '{}' for {nodes} nodes", a.len, a.name)),
    }
}

/// Merges a shard file into `into` (or into a new accumulator when `None`) as it streams
/// from disk: memory stays at one accumulator plus a 64 KiB buffer however large the file,
/// so merging N shards needs the memory of one. The same checks as
/// [`accumulator_from_bytes`] apply (the checksum is verified at the end: on any error the
/// partly merged accumulator is dropped, so nothing half-merged escapes). Errors if the
/// file's grid or coefficient count differs from `into`'s.
pub fn merge_accumulator_file(
    into: Option<Accumulator>,
    path: &Path,
) -> Result<(Accumulator, BakeMetadata), VolumeError> {
    use std::io::Read;
    let io = |e: std::io::Error| VolumeError::io(path, e);
    let bad = |r: String| VolumeError::malformed(F, r);
    let len = std::fs::metadata(path).map_err(io)?.len();
    let mut r = std::io::BufReader::with_capacity(1 << 16, std::fs::File::open(path).map_err(io)?);
    let mut hash = crate::checksum::Fnv1a::default();
    let mut read = |buf: &mut [u8], hash: &mut crate::checksum::Fnv1a| -> Result<(), VolumeError> {
        r.read_exact(buf).map_err(|e| bad(format!("truncated ({e})")))?;
        hash.write(buf);
        Ok(())
    };
    if len < 8 + 4 + 8 {
        return Err(bad(format!("{len} bytes is too short")));
    }
    let mut head = [0u8; 12];
    read(&mut head, &mut hash)?;
    let (version, h) = parse_head(&head)?;
    if 12 + h as u64 + 8 > len {
        return Err(bad(format!("header length {h} does not fit the file")));
    }
    let mut json = vec![0u8; h];
    read(&mut json, &mut hash)?;
    let (header, spec) = parse_header(&json)?;
    let n = spec.node_count() as u64;
    let k = header.coeffs as u64 * 3;
    let width: u64 = if version == 1 { 8 } else { 16 };
    let aux_len = check_aux(&header, n).map_err(bad)?;
    let total = n * k
        + 2 * n
        + aux_len
        + check_reach(&header, version, n).map_err(bad)?
        + check_groups(&header, version, n * k).map_err(bad)?;
    if len != 12 + h as u64 + width * total + 8 {
        return Err(bad(format!("{} data bytes, the grid needs {}", len - 12 - h as u64 - 8, width * total)));
    }
    let mut acc = match into {
        Some(a) => {
            if !a.spec().same_nodes(&spec) {
                return Err(VolumeError::Mismatch("cannot merge accumulators over different grids".into()));
            }
            if a.coeffs() != header.coeffs {
                return Err(VolumeError::Mismatch(format!(
                    "cannot merge accumulators with {} and {} coefficients",
                    a.coeffs(),
                    header.coeffs
                )));
            }
            a
        }
        None => {
            let mut a = Accumulator::new(spec, header.coeffs)?;
            if let Some(x) = &header.aux {
                a.set_aux(&x.name, crate::fixed::FixedSums::zeros(x.len as usize));
            }
            if header.reach {
                a.enable_reach();
            }
            if let Some(g) = &header.groups {
                a.enable_groups(g.clone());
            }
            a
        }
    };
    if acc.group_labels() != header.groups.as_ref() {
        return Err(VolumeError::Mismatch(
            "cannot merge accumulators with different light groups (names, count or baked sky)".into(),
        ));
    }
    let same_aux = match (acc.aux(), &header.aux) {
        (None, None) => true,
        (Some((name, s)), Some(x)) => name == x.name && s.len() as u64 == x.len,
        _ => false,
    };
    if !same_aux {
        return Err(VolumeError::Mismatch(
            "cannot merge accumulators with different auxiliary sums (e.g. one with a least-squares mass matrix)".into(),
        ));
    }
    if acc.has_reach() != header.reach {
        return Err(VolumeError::Mismatch(
            "cannot merge accumulators with and without a node reach (doi and another method)".into(),
        ));
    }
    const CHUNK: u64 = 4096;
    let mut buf = vec![0u8; (CHUNK * width) as usize];
    let mut i = 0u64;
    while i < total {
        let m = CHUNK.min(total - i);
        let b = &mut buf[..(m * width) as usize];
        read(b, &mut hash)?;
        for (j, c) in b.chunks_exact(width as usize).enumerate() {
            let v = if width == 8 {
                let x = f64::from_le_bytes(c.try_into().expect("8 bytes"));
                crate::fixed::to_fixed(x)
                    .ok_or(VolumeError::NonFinite { what: "sum", index: (i as usize) + j })?
            } else {
                i128::from_le_bytes(c.try_into().expect("16 bytes"))
            };
            acc.add_raw_at(i as usize + j, v);
        }
        i += m;
    }
    let mut tail = [0u8; 8];
    r.read_exact(&mut tail).map_err(|e| bad(format!("truncated ({e})")))?;
    if hash.finish() != u64::from_le_bytes(tail) {
        return Err(bad("checksum mismatch: the file is damaged or truncated".into()));
    }
    acc.add_contributions(header.contributions);
    Ok((acc, header.bake))
}

/// Reads only the bake metadata of a shard file (its JSON header), for checking a set of
/// shards before merging them. The checksum is not verified here (that needs the whole
/// file); [`merge_accumulator_file`] verifies it.
pub fn read_accumulator_metadata(path: &Path) -> Result<BakeMetadata, VolumeError> {
    use std::io::Read;
    let io = |e: std::io::Error| VolumeError::io(path, e);
    let bad = |r: String| VolumeError::malformed(F, r);
    let mut f = std::fs::File::open(path).map_err(io)?;
    let mut head = [0u8; 12];
    f.read_exact(&mut head).map_err(|e| bad(format!("truncated ({e})")))?;
    let (_, h) = parse_head(&head)?;
    let mut json = vec![0u8; h];
    f.read_exact(&mut json).map_err(|e| bad(format!("truncated ({e})")))?;
    let (header, _) = parse_header(&json)?;
    Ok(header.bake)
}

/// Writes a shard file atomically.
pub fn write_accumulator(path: &Path, acc: &Accumulator, meta: &BakeMetadata) -> Result<(), VolumeError> {
    write_atomic(path, &accumulator_to_bytes(acc, meta)?)
}

/// Reads a shard file.
pub fn read_accumulator(path: &Path) -> Result<(Accumulator, BakeMetadata), VolumeError> {
    accumulator_from_bytes(&read_bounded(path)?)
}

/// Why the headers of a set of shard files do not make one bake.
#[derive(Debug, thiserror::Error)]
pub enum ShardSetError {
    /// A file of another bake (method, seed, shard count or scene hash differ).
    #[error(
        "{} does not belong to the same bake as {} (method {} vs {}, seed {} vs {}, shards {} vs {}, scene and settings {} vs {})",
        path.display(), first_path.display(), meta.method, first.method, meta.seed, first.seed,
        meta.shard_count, first.shard_count, meta.scene_hash, first.scene_hash
    )]
    OtherBake {
        /// The file.
        path: std::path::PathBuf,
        /// Its metadata.
        meta: Box<BakeMetadata>,
        /// The set's first file.
        first_path: std::path::PathBuf,
        /// Its metadata.
        first: Box<BakeMetadata>,
    },
    /// One shard index in two files.
    #[error("shard {index} of {count} given twice ({} and {})", a.display(), b.display())]
    Twice {
        /// The index.
        index: u32,
        /// The count.
        count: u32,
        /// One file.
        a: std::path::PathBuf,
        /// The other.
        b: std::path::PathBuf,
    },
}

/// Checks that the shard files `parts` (their metadata and paths, [`read_accumulator_metadata`])
/// are of one bake, each shard once, and sorts them by shard index (the sums are exact, so
/// the order changes no bit; it fixes the messages). Returns the indices of the missing
/// shards (empty for a complete set).
///
/// # Errors
/// [`ShardSetError`] for the first file of another bake or shard given twice.
///
/// # Panics
/// If `parts` is empty.
pub fn check_shard_set(parts: &mut [(BakeMetadata, std::path::PathBuf)]) -> Result<Vec<u32>, ShardSetError> {
    parts.sort_by(|a, b| (a.0.shard_index, &a.1).cmp(&(b.0.shard_index, &b.1)));
    let (first, p0) = (&parts[0].0, &parts[0].1);
    for (m, p) in &parts[1..] {
        if m.method != first.method
            || m.shard_count != first.shard_count
            || m.seed != first.seed
            || m.scene_hash != first.scene_hash
        {
            return Err(ShardSetError::OtherBake {
                path: p.clone(),
                meta: Box::new(m.clone()),
                first_path: p0.clone(),
                first: Box::new(first.clone()),
            });
        }
    }
    for w in parts.windows(2) {
        if w[0].0.shard_index == w[1].0.shard_index {
            return Err(ShardSetError::Twice {
                index: w[0].0.shard_index,
                count: first.shard_count,
                a: w[0].1.clone(),
                b: w[1].1.clone(),
            });
        }
    }
    let have: Vec<u32> = parts.iter().map(|(m, _)| m.shard_index).collect();
    Ok((0..first.shard_count).filter(|k| !have.contains(k)).collect())
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    #[test]
    fn shard_sets_are_checked_and_sorted() {
        let m = |k: u32| BakeMetadata { shard_index: k, shard_count: 3, ..BakeMetadata::default() };
        let mut parts = vec![(m(2), PathBuf::from("c")), (m(0), PathBuf::from("a"))];
        assert_eq!(check_shard_set(&mut parts).unwrap(), [1]);
        assert_eq!(parts[0].1, PathBuf::from("a"));
        let mut twice = vec![(m(1), PathBuf::from("a")), (m(1), PathBuf::from("b"))];
        assert!(check_shard_set(&mut twice).unwrap_err().to_string().starts_with("shard 1 of 3 given twice"));
        let other = BakeMetadata { seed: 7, ..m(1) };
        let mut mixed = vec![(m(0), PathBuf::from("a")), (other, PathBuf::from("b"))];
        assert!(check_shard_set(&mut mixed).unwrap_err().to_string().contains("does not belong"));
    }

    use super::*;

    fn acc() -> Accumulator {
        let spec = GridSpec::new([0.0; 3], [1.0, 2.0, 3.0], [3, 2, 2])
            .unwrap()
            .with_placement(Placement::translation([0.5, -1.0, 1e-300]).unwrap());
        let mut a = Accumulator::new(spec, 4).unwrap();
        a.add_sample([0.3, 1.1, 2.9], [1.0 / 3.0, 2.0, -7.0], &[0.1, 0.2, -0.3, 1e-17]);
        a.add_outside(5, 0.125);
        a
    }

    #[test]
    fn round_trip_is_bit_exact() {
        let a = acc();
        let meta = BakeMetadata { shard_index: 1, shard_count: 3, ..BakeMetadata::default() };
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s1.lvacc");
        write_accumulator(&p, &a, &meta).unwrap();
        let (b, m) = read_accumulator(&p).unwrap();
        assert_eq!(b, a);
        assert_eq!(m, meta);
    }

    /// Streaming merges equal in-memory merges, in any order, and refuse damage.
    #[test]
    fn streaming_merge_equals_in_memory_merge() {
        let a = acc();
        let mut b = acc();
        b.add_sample([0.9, 0.1, 0.2], [5.0, 1.0, 0.5], &[0.4, -0.1, 0.2, 0.3]);
        let dir = tempfile::tempdir().unwrap();
        let (pa, pb) = (dir.path().join("a.lvacc"), dir.path().join("b.lvacc"));
        write_accumulator(
            &pa,
            &a,
            &BakeMetadata { shard_index: 0, shard_count: 2, ..BakeMetadata::default() },
        )
        .unwrap();
        write_accumulator(
            &pb,
            &b,
            &BakeMetadata { shard_index: 1, shard_count: 2, ..BakeMetadata::default() },
        )
        .unwrap();
        let (ab, _) =
            merge_accumulator_file(Some(merge_accumulator_file(None, &pa).unwrap().0), &pb).unwrap();
        let (ba, m) =
            merge_accumulator_file(Some(merge_accumulator_file(None, &pb).unwrap().0), &pa).unwrap();
        let mut want = a.clone();
        want.merge(&b).unwrap();
        assert_eq!(ab, want);
        assert_eq!(ba, want);
        assert_eq!(m.shard_index, 0);
        let mut bytes = std::fs::read(&pb).unwrap();
        let mid = bytes.len() / 2;
        bytes[mid] ^= 1;
        std::fs::write(&pb, &bytes).unwrap();
        assert!(merge_accumulator_file(None, &pb).unwrap_err().to_string().contains("checksum"));
        std::fs::write(&pb, &bytes[..bytes.len() - 9]).unwrap();
        assert!(merge_accumulator_file(None, &pb).is_err());
    }

    /// Auxiliary sums round-trip, merge (in memory and streamed), and refuse to merge with
    /// an accumulator that has none.
    #[test]
    fn auxiliary_sums_travel_with_the_accumulator() {
        let mut a = acc();
        let mut aux = crate::fixed::FixedSums::zeros(5);
        aux.add(3, 0.75);
        a.set_aux("test-aux", aux);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.lvacc");
        write_accumulator(&p, &a, &BakeMetadata::default()).unwrap();
        let (b, _) = read_accumulator(&p).unwrap();
        assert_eq!(b, a);
        let (c, _) = merge_accumulator_file(Some(b.clone()), &p).unwrap();
        assert_eq!(c.aux().unwrap().1.get(3), 1.5);
        let mut plain = acc();
        assert!(plain.merge(&a).is_err());
        assert!(merge_accumulator_file(Some(acc()), &p).is_err());
    }

    #[test]
    fn rejects_damage_and_nan() {
        let a = acc();
        let bytes = accumulator_to_bytes(&a, &BakeMetadata::default()).unwrap();
        for i in [0, 7, 13, bytes.len() / 2, bytes.len() - 1] {
            let mut d = bytes.clone();
            d[i] ^= 0x20;
            assert!(accumulator_from_bytes(&d).is_err(), "byte {i}");
        }
        assert!(accumulator_from_bytes(&bytes[..bytes.len() - 3]).is_err());
        let mut nan = a.clone();
        nan.add(0, 1.0, [f64::NAN, 0.0, 0.0], &[1.0, 0.0, 0.0, 0.0]);
        assert!(matches!(
            accumulator_to_bytes(&nan, &BakeMetadata::default()),
            Err(VolumeError::NonFinite { what: "numerator", .. })
        ));
    }
}
