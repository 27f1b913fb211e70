//! Sharded adaptive bakes: the exact sums of one refinement level, one shard of it
//! ([`LevelSums`]), and their file (`.lvref`).
//!
//! An adaptive bake (\[Oat05\], "Adaptive Octree Subdivision") is sequential in its levels:
//! which nodes level `l + 1` bakes depends on the field of levels `0..=l`. It is therefore
//! sharded **level by level**:
//!
//! 1. level 0 is an ordinary sharded bake of the base grid (exact `.lvacc` sums);
//! 2. for each level `l ≥ 1`, every shard merges the complete sets of the levels below,
//!    replays the deterministic builder up to level `l` (heuristics included), and bakes its
//!    contiguous share ([`lightvol_core::shard::shard_range`]) of the level's sorted unit list,
//!    writing the exact subset sums ([`crate::adaptive::bake_adaptive_level_shard`]);
//! 3. assembly merges every level and replays the builder once more
//!    ([`crate::adaptive::assemble_adaptive`]).
//!
//! All sums are fixed-point integers, so the assembled volume is the whole
//! [`crate::adaptive::bake_adaptive`]'s bit for bit, for any shard counts and orders.
//! Each level file records the level's **plan** (a hash of its whole unit list): a replay
//! that plans differently (other inputs) is refused instead of mixing sums.
//!
//! ## Format (little-endian)
//! | bytes | content |
//! | --- | --- |
//! | 8 | magic `LVREF\0`, then the version as u16 (1) |
//! | 4 | length `h` of the JSON header ([`LevelShardHeader`]) |
//! | h | JSON header |
//! | 8·n | touched nodes (flat indices of the level grid), ascending |
//! | 16·n·k | numerators, i128 in units of 2^-64 |
//! | 16·n | denominators |
//! | 16·n | outside sums |
//! | 8 + 8·p | count `p` of poisoned sums, then their indices (numerators first, then denominators, then outside sums) |
//! | 8 | FNV-1a 64 of every preceding byte |

use std::path::{Path, PathBuf};

use lightvol_core::hash::fnv1a;
use lightvol_volume::fixed::FixedSums;
use lightvol_volume::io::accumulator::ACC_EXTENSION;
use lightvol_volume::io::util::{read_bounded, write_atomic};
use serde::{Deserialize, Serialize};

use crate::bake::FixedSubsetSums;
use crate::error::BakeError;
use crate::stats::BakeStats;
use lightvol_scene::stats::RayCounts;

const MAGIC: &[u8; 6] = b"LVREF\0";
const VERSION: u16 = 1;
/// Values per node a level file may declare (3 · the largest coefficient count).
const MAX_VALUES_PER_NODE: usize = 3 * 64;

/// The exact sums one shard baked of one refinement level.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LevelSums {
    /// The level (≥ 1).
    pub level: u32,
    /// Hash of the level's whole sorted unit list ([`plan_hash`]); 0 with no units.
    pub plan: u64,
    /// Units of the whole level (0: the builder had nothing to refine at this level).
    pub units: u64,
    /// Values per node (`3 · coeffs`).
    pub k: usize,
    /// The sums.
    pub sums: FixedSubsetSums,
    /// Rays the shard traced.
    pub rays: RayCounts,
}

impl LevelSums {
    /// A level the builder never reaches (no cell split below it): no units.
    #[must_use]
    pub fn nothing_to_refine(level: u32, k: usize) -> Self {
        Self { level, plan: 0, units: 0, k, sums: FixedSubsetSums::default(), rays: RayCounts::default() }
    }

    /// Adds another shard's sums of the same level and plan.
    ///
    /// # Errors
    /// [`BakeError::Settings`] when the level, plan or values per node differ.
    pub fn merge(&mut self, other: &Self) -> Result<(), BakeError> {
        if (self.level, self.plan, self.units, self.k) != (other.level, other.plan, other.units, other.k) {
            return Err(BakeError::Settings(format!(
                "level {} shards of different plans ({:016x}, {} units vs level {} {:016x}, {} units)",
                self.level, self.plan, self.units, other.level, other.plan, other.units
            )));
        }
        self.sums.merge(&other.sums)?;
        self.rays.add(&other.rays);
        Ok(())
    }
}

/// FNV-1a over the units' little-endian u64s: identifies a level's plan.
#[must_use]
pub fn plan_hash(units: &[usize]) -> u64 {
    let bytes: Vec<u8> = units.iter().flat_map(|&u| (u as u64).to_le_bytes()).collect();
    fnv1a(&bytes)
}

/// What a level file says about its bake.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LevelShardHeader {
    /// The level.
    pub level: u32,
    /// This shard's index within the level.
    pub shard_index: u32,
    /// Shards of the level.
    pub shard_count: u32,
    /// [`LevelSums::plan`].
    pub plan: u64,
    /// [`LevelSums::units`].
    pub units: u64,
    /// Values per node.
    pub k: usize,
    /// Touched nodes in the file.
    pub nodes: u64,
    /// Rays traced: sampling, query, bounce, shadow.
    pub rays: [u64; 4],
    /// Identifies the scene, lighting and settings (every file of one bake shares it).
    pub scene_hash: String,
}

fn err(m: String) -> BakeError {
    BakeError::Settings(m)
}

/// Serialises one shard of a level.
#[must_use]
pub fn level_to_bytes(l: &LevelSums, shard: (u32, u32), scene_hash: &str) -> Vec<u8> {
    let s = &l.sums;
    let header = LevelShardHeader {
        level: l.level,
        shard_index: shard.0,
        shard_count: shard.1,
        plan: l.plan,
        units: l.units,
        k: l.k,
        nodes: s.nodes.len() as u64,
        rays: [l.rays.sampling, l.rays.query, l.rays.bounce, l.rays.shadow],
        scene_hash: scene_hash.to_owned(),
    };
    let mut out = Vec::new();
    for &n in &s.nodes {
        out.extend_from_slice(&(n as u64).to_le_bytes());
    }
    let mut poisoned = Vec::new();
    let mut at = 0u64;
    for f in [&s.numerator, &s.denominator, &s.outside] {
        for (i, v) in f.raw().iter().enumerate() {
            out.extend_from_slice(&v.to_le_bytes());
            if f.get(i).is_nan() {
                poisoned.push(at + i as u64);
            }
        }
        at += f.len() as u64;
    }
    out.extend_from_slice(&(poisoned.len() as u64).to_le_bytes());
    for p in poisoned {
        out.extend_from_slice(&p.to_le_bytes());
    }
    lightvol_core::shard::frame_shard_file(MAGIC, VERSION, &header, &out)
}

/// Parses one shard of a level.
///
/// # Errors
/// [`BakeError::Settings`] naming what is damaged; every length is checked against the
/// file before anything is allocated.
pub fn level_from_bytes(bytes: &[u8]) -> Result<(LevelSums, LevelShardHeader), BakeError> {
    let (header, data): (LevelShardHeader, &[u8]) =
        lightvol_core::shard::unframe_shard_file(bytes, MAGIC, VERSION, "level shard").map_err(err)?;
    if header.shard_count == 0
        || header.shard_index >= header.shard_count
        || header.level == 0
        || header.k > MAX_VALUES_PER_NODE
    {
        return Err(err(format!(
            "level shard {} of {} of level {} with {} values per node",
            header.shard_index, header.shard_count, header.level, header.k
        )));
    }
    // Bytes per node: its index, k numerators, a denominator and an outside sum.
    let per_node = 8 + 16 * (header.k as u64 + 2);
    if header.nodes > data.len() as u64 / per_node {
        return Err(err(format!("level shard claims {} nodes", header.nodes)));
    }
    let n = header.nodes as usize;
    let k = header.k;
    let (nodes_b, rest) = data.split_at(8 * n);
    let sums_len = n * (k + 2);
    let (sums_b, rest) = rest.split_at(16 * sums_len);
    let u64_at = |b: &[u8]| u64::from_le_bytes(b.try_into().expect("8 bytes"));
    let nodes: Vec<usize> = nodes_b.chunks_exact(8).map(|c| u64_at(c) as usize).collect();
    if nodes.windows(2).any(|w| w[0] >= w[1]) {
        return Err(err("level shard nodes are not ascending".into()));
    }
    let raw: Vec<i128> =
        sums_b.chunks_exact(16).map(|c| i128::from_le_bytes(c.try_into().expect("16 bytes"))).collect();
    if rest.len() < 8 {
        return Err(err("level shard ends before its poison list".into()));
    }
    let p = u64_at(&rest[..8]);
    if p > sums_len as u64 || rest.len() as u64 != 8 + 8 * p {
        return Err(err(format!("level shard poison list of {p} entries does not fit the file")));
    }
    let mut numerator = FixedSums::from_raw(raw[..n * k].to_vec());
    let mut denominator = FixedSums::from_raw(raw[n * k..n * (k + 1)].to_vec());
    let mut outside = FixedSums::from_raw(raw[n * (k + 1)..].to_vec());
    for c in rest[8..].chunks_exact(8) {
        let i = u64_at(c) as usize;
        if i >= sums_len {
            return Err(err(format!("level shard poisons sum {i} of {sums_len}")));
        }
        let (f, j) = if i < n * k {
            (&mut numerator, i)
        } else if i < n * (k + 1) {
            (&mut denominator, i - n * k)
        } else {
            (&mut outside, i - n * (k + 1))
        };
        f.add(j, f64::NAN);
    }
    let r = header.rays;
    let sums = LevelSums {
        level: header.level,
        plan: header.plan,
        units: header.units,
        k,
        sums: FixedSubsetSums { nodes, numerator, denominator, outside },
        rays: RayCounts { sampling: r[0], query: r[1], bounce: r[2], shadow: r[3] },
    };
    Ok((sums, header))
}

/// The extension of a refinement level's shard file (`.lvref`).
pub const LEVEL_EXTENSION: &str = "lvref";

/// The shard file of `level` that a shard of an octree bake to the volume file `output`
/// writes beside it: level 0's exact sums as an accumulator (`output` with the extension
/// [`ACC_EXTENSION`]), a refinement level's as a level file ([`LEVEL_EXTENSION`]).
#[must_use]
pub fn level_shard_path(output: &Path, level: u32) -> PathBuf {
    output.with_extension(if level == 0 { ACC_EXTENSION } else { LEVEL_EXTENSION })
}

/// Writes one shard of a level atomically.
///
/// # Errors
/// The I/O error, as [`BakeError::Settings`] naming the file.
pub fn write_level(path: &Path, l: &LevelSums, shard: (u32, u32), scene_hash: &str) -> Result<(), BakeError> {
    write_atomic(path, &level_to_bytes(l, shard, scene_hash)).map_err(|e| err(e.to_string()))
}

/// Reads one shard of a level.
///
/// # Errors
/// As [`level_from_bytes`], or the I/O error.
pub fn read_level(path: &Path) -> Result<(LevelSums, LevelShardHeader), BakeError> {
    let bytes = read_bounded(path).map_err(|e| err(e.to_string()))?;
    level_from_bytes(&bytes).map_err(|e| err(format!("{}: {e}", path.display())))
}

/// The suffix of a level-0 shard's method label in its `.lvacc` metadata: a plain merge
/// refuses such a shard (its volume needs the refinement levels), and assembly checks it.
pub const BASE_SUFFIX: &str = " adaptive-level-0";

/// The method label of a level-0 shard of a bake labelled `method` ([`BASE_SUFFIX`]).
#[must_use]
pub fn base_label(method: &str) -> String {
    format!("{method}{BASE_SUFFIX}")
}

/// The shard files of a level-by-level adaptive bake, read, checked and merged: the level-0
/// sums with their sampling rays, and the refinement levels 1, 2, … in order.
pub struct ShardSet {
    /// The merged level-0 sums.
    pub base: lightvol_volume::Accumulator,
    /// Sampling rays of the level-0 shards.
    pub base_samples: u64,
    /// The merged refinement levels, level 1 first.
    pub levels: Vec<LevelSums>,
}

impl ShardSet {
    /// What the level-0 shards report to the assembly
    /// ([`crate::adaptive::assemble_adaptive`]): their sampling rays (the shard files keep no
    /// other counter).
    #[must_use]
    pub fn base_stats(&self) -> BakeStats {
        BakeStats {
            rays: RayCounts { sampling: self.base_samples, ..RayCounts::default() },
            ..BakeStats::default()
        }
    }
}

/// Why a set of adaptive shard files was refused (nothing is baked or written before).
#[derive(Debug, thiserror::Error)]
pub enum ShardSetError {
    /// A file appears twice.
    #[error("{} is given twice (its samples would count twice)", .0.display())]
    Twice(PathBuf),
    /// A `.lvacc` of another bake, or not a level-0 shard.
    #[error("{} is not a level-0 shard of this adaptive bake (method '{method}', scene and settings {hash}; this bake: '{want_method}', {want_hash})", path.display())]
    NotBase {
        /// The file.
        path: PathBuf,
        /// Its method label.
        method: String,
        /// Its scene hash.
        hash: String,
        /// The label this bake's level-0 shards carry.
        want_method: String,
        /// This bake's scene hash.
        want_hash: String,
    },
    /// A `.lvref` of another bake.
    #[error("{} belongs to another bake (scene and settings {hash}; this bake: {want})", path.display())]
    OtherBake {
        /// The file.
        path: PathBuf,
        /// Its scene hash.
        hash: String,
        /// This bake's.
        want: String,
    },
    /// Neither a `.lvacc` nor a `.lvref`.
    #[error("{}: the shard files of an adaptive bake are level-0 .lvacc and level .lvref files", .0.display())]
    Extension(PathBuf),
    /// A file could not be read or merged.
    #[error("{what} {}", path.display())]
    File {
        /// `reading` or `merging`.
        what: &'static str,
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// No level-0 shard.
    #[error("no level-0 .lvacc shard among the files (bake them as level-0 shards of the adaptive bake)")]
    NoBase,
    /// Shards of one level disagree on their count.
    #[error("{}: {what}shard of {got} where the others are of {want}", path.display())]
    MixedCount {
        /// The file.
        path: PathBuf,
        /// `""` for level 0, `"level-L "` above.
        what: String,
        /// Its count.
        got: u32,
        /// The others'.
        want: u32,
    },
    /// A shard index appears twice.
    #[error("{what}: shard {index} of {count} given twice")]
    DuplicateShard {
        /// `level-L`.
        what: String,
        /// The index.
        index: u32,
        /// The count.
        count: u32,
    },
    /// Shards are missing.
    #[error("incomplete set: {what} shards {missing} of {count} are missing; nothing written")]
    Incomplete {
        /// `level-L`.
        what: String,
        /// The missing indices, `0, 3`.
        missing: String,
        /// The count.
        count: u32,
    },
    /// A level between 1 and the top one has no shards.
    #[error("the files have level-{top} shards but none of level {level}")]
    LevelGap {
        /// The top level given.
        top: u32,
        /// The missing level.
        level: u32,
    },
}

impl ShardSetError {
    /// [`Self::File`]: reading or merging `path` failed with `e`.
    fn file(what: &'static str, path: &Path, e: impl std::error::Error + Send + Sync + 'static) -> Self {
        Self::File { what, path: path.to_owned(), source: Box::new(e) }
    }
}

impl ShardSet {
    /// Reads, checks and merges `files` of the adaptive bake whose scene and settings hash
    /// to `hash` and whose method label is `method` (level-0 shards carry
    /// [`base_label`]`(method)`): every level complete, each shard once, all of one bake.
    ///
    /// # Errors
    /// [`ShardSetError`], one for the first problem found.
    pub fn load(files: &[PathBuf], hash: &str, method: &str) -> Result<Self, ShardSetError> {
        use lightvol_volume::BakeMetadata;
        use lightvol_volume::io::accumulator::{merge_accumulator_file, read_accumulator_metadata};
        let mut seen = Vec::new();
        let mut base_files: Vec<(BakeMetadata, PathBuf)> = Vec::new();
        let mut level_files: Vec<(LevelShardHeader, LevelSums, PathBuf)> = Vec::new();
        let want_method = base_label(method);
        for p in files {
            let canon = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
            if seen.contains(&canon) {
                return Err(ShardSetError::Twice(p.clone()));
            }
            seen.push(canon);
            match p.extension().and_then(|e| e.to_str()) {
                Some(ACC_EXTENSION) => {
                    let m = read_accumulator_metadata(p).map_err(|e| ShardSetError::file("reading", p, e))?;
                    if m.method != want_method || m.scene_hash != hash {
                        return Err(ShardSetError::NotBase {
                            path: p.clone(),
                            method: m.method,
                            hash: m.scene_hash,
                            want_method,
                            want_hash: hash.to_owned(),
                        });
                    }
                    base_files.push((m, p.clone()));
                }
                Some(LEVEL_EXTENSION) => {
                    let (l, h) = read_level(p).map_err(|e| ShardSetError::file("reading", p, e))?;
                    if h.scene_hash != hash {
                        return Err(ShardSetError::OtherBake {
                            path: p.clone(),
                            hash: h.scene_hash,
                            want: hash.to_owned(),
                        });
                    }
                    level_files.push((h, l, p.clone()));
                }
                _ => return Err(ShardSetError::Extension(p.clone())),
            }
        }
        let indices = |what: &str, count: u32, have: &mut Vec<u32>| -> Result<(), ShardSetError> {
            have.sort_unstable();
            if let Some(w) = have.windows(2).find(|w| w[0] == w[1]) {
                return Err(ShardSetError::DuplicateShard { what: what.to_owned(), index: w[0], count });
            }
            let missing: Vec<String> =
                (0..count).filter(|k| !have.contains(k)).map(|k| k.to_string()).collect();
            if !missing.is_empty() {
                return Err(ShardSetError::Incomplete {
                    what: what.to_owned(),
                    missing: missing.join(", "),
                    count,
                });
            }
            Ok(())
        };
        let Some(first) = base_files.first() else { return Err(ShardSetError::NoBase) };
        let count = first.0.shard_count;
        if let Some((m, p)) = base_files.iter().find(|(m, _)| m.shard_count != count) {
            return Err(ShardSetError::MixedCount {
                path: p.clone(),
                what: String::new(),
                got: m.shard_count,
                want: count,
            });
        }
        indices("level-0", count, &mut base_files.iter().map(|(m, _)| m.shard_index).collect())?;
        let mut base = None;
        let mut base_samples = 0;
        for (m, p) in &base_files {
            let (a, _) =
                merge_accumulator_file(base.take(), p).map_err(|e| ShardSetError::file("merging", p, e))?;
            base = Some(a);
            base_samples += m.sampling_rays;
        }
        let mut levels: Vec<LevelSums> = Vec::new();
        level_files.sort_by_key(|(h, _, _)| (h.level, h.shard_index));
        let top = level_files.last().map_or(0, |(h, _, _)| h.level);
        for level in 1..=top {
            let set: Vec<&(LevelShardHeader, LevelSums, PathBuf)> =
                level_files.iter().filter(|(h, _, _)| h.level == level).collect();
            let Some(f) = set.first() else { return Err(ShardSetError::LevelGap { top, level }) };
            let count = f.0.shard_count;
            if let Some((h, _, p)) = set.iter().find(|(h, _, _)| h.shard_count != count) {
                return Err(ShardSetError::MixedCount {
                    path: p.clone(),
                    what: format!("level-{level} "),
                    got: h.shard_count,
                    want: count,
                });
            }
            indices(
                &format!("level-{level}"),
                count,
                &mut set.iter().map(|(h, _, _)| h.shard_index).collect(),
            )?;
            let mut merged = set[0].1.clone();
            for (_, l, p) in &set[1..] {
                merged.merge(l).map_err(|e| ShardSetError::file("merging", p, e))?;
            }
            levels.push(merged);
        }
        Ok(Self { base: base.ok_or(ShardSetError::NoBase)?, base_samples, levels })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> LevelSums {
        let mut numerator = FixedSums::zeros(6);
        let mut denominator = FixedSums::zeros(2);
        let outside = FixedSums::zeros(2);
        for i in 0..6 {
            numerator.add(i, 0.125 * i as f64 - 0.3);
        }
        numerator.add(4, f64::NAN);
        denominator.add(0, 1.5);
        denominator.add(1, 2.25);
        LevelSums {
            level: 2,
            plan: plan_hash(&[3, 5, 9]),
            units: 3,
            k: 3,
            sums: FixedSubsetSums { nodes: vec![4, 11], numerator, denominator, outside },
            rays: RayCounts { sampling: 10, query: 2, bounce: 3, shadow: 4 },
        }
    }

    #[test]
    fn the_base_reports_its_sampling_rays() {
        let grid = lightvol_volume::GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let base = lightvol_volume::Accumulator::new(grid, 9).unwrap();
        let set = ShardSet { base, base_samples: 1234, levels: Vec::new() };
        let s = set.base_stats();
        assert_eq!(s.rays, RayCounts { sampling: 1234, query: 0, bounce: 0, shadow: 0 });
        assert_eq!((s.units, s.candidates, s.wall_time), (0, 0, std::time::Duration::ZERO));
    }

    #[test]
    fn shard_files_sit_beside_the_output() {
        let out = Path::new("shards/level2-7.exr");
        assert_eq!(level_shard_path(out, 0), PathBuf::from("shards/level2-7.lvacc"));
        assert_eq!(level_shard_path(out, 2), PathBuf::from("shards/level2-7.lvref"));
        assert_eq!(level_shard_path(Path::new("v"), 1), PathBuf::from("v.lvref"));
    }

    #[test]
    fn level_files_round_trip_with_poison() {
        let l = sample();
        let bytes = level_to_bytes(&l, (1, 3), "abc");
        let (back, h) = level_from_bytes(&bytes).unwrap();
        assert_eq!(back, l);
        assert_eq!((h.shard_index, h.shard_count, h.scene_hash.as_str()), (1, 3, "abc"));
        assert!(back.sums.numerator.get(4).is_nan());
        // Equal inputs give equal bytes.
        assert_eq!(bytes, level_to_bytes(&l, (1, 3), "abc"));
    }

    /// Every truncation and every single-byte flip is an error, never a panic.
    #[test]
    fn damaged_level_files_are_refused() {
        let bytes = level_to_bytes(&sample(), (0, 1), "x");
        for cut in 0..bytes.len() {
            assert!(level_from_bytes(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x41;
            assert!(level_from_bytes(&b).is_err(), "flip at {i}");
        }
    }

    /// Merging splits of a node set in either order gives the whole set's sums.
    #[test]
    fn merges_are_exact_unions() {
        let k = 2;
        let whole_nodes = [1usize, 4, 6, 9];
        let value = |n: usize, c: usize| (n * 7 + c) as f64 * 0.1 + 1e-9;
        let build = |nodes: &[usize], part: usize| {
            let mut s = FixedSubsetSums {
                nodes: nodes.to_vec(),
                numerator: FixedSums::zeros(nodes.len() * k),
                denominator: FixedSums::zeros(nodes.len()),
                outside: FixedSums::zeros(nodes.len()),
            };
            for (i, &n) in nodes.iter().enumerate() {
                for c in 0..k {
                    s.numerator.add(i * k + c, value(n, c) * (part as f64 + 1.0));
                }
                s.denominator.add(i, (part + 1) as f64);
            }
            s
        };
        let a = build(&[1, 6], 0);
        let b = build(&[4, 6, 9], 1);
        let mut ab = a.clone();
        ab.merge(&b).unwrap();
        let mut ba = b.clone();
        ba.merge(&a).unwrap();
        assert_eq!(ab, ba);
        assert_eq!(ab.nodes, whole_nodes);
        // Node 6 got both parts: 1× + 2× its value, denominators 1 + 2.
        assert_eq!(ab.denominator.get(2), 3.0);
        let mut want = FixedSums::zeros(1);
        want.add(0, value(6, 1));
        want.add(0, value(6, 1) * 2.0);
        assert_eq!(ab.numerator.raw()[2 * k + 1], want.raw()[0]);
        let mut wrong = build(&[2], 0);
        wrong.numerator.extend_zeros(1);
        assert!(ab.clone().merge(&wrong).is_err());
    }
}
