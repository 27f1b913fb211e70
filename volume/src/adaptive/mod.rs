//! The adaptive octree volume of Oat, *Irradiance Volumes for Games* (\[Oat05\], "Adaptive
//! Octree Subdivision" to "Trilinear Interpolation"), stored as hierarchical surpluses on
//! nested grids.
//!
//! ## Representation
//! Level 0 is a complete uniform [`IrradianceVolume`] over a base [`GridSpec`]. Level `l`
//! is the *virtual* uniform grid over the same box with `(n - 1)·2^l + 1` nodes per axis
//! ([`AdaptiveVolume::level_grid`]): its cells are the octree cells of depth `l`, its nodes
//! their corners, and node `(i, j, k)` of level `l - 1` is node `(2i, 2j, 2k)` of level `l`.
//! A cell is *split* when its 8 children exist; the children's 27 corners are the nodes of
//! level `l + 1` it creates. Each node of level `l ≥ 1` that is kept stores its *surplus*
//!
//! `s_l(x_i) = v_l(x_i) − Σ_{m<l} I_m(x_i)`,
//!
//! the value baked at the node (level-`l` prefilter support) minus what the coarser levels
//! already interpolate there; `I_m` is the trilinear interpolation of level `m`'s
//! surpluses, with absent nodes counting as 0. A lookup at `x` is
//!
//! `L(x) = Σ_l I_l(x)`: for each level, the 8 corners of the level-`l` cell containing `x`,
//! weighted by their trilinear weights (\[KL06\] Eq. 2), summed.
//!
//! Every term is a sum of continuous tent functions, so `L` is continuous (C0) everywhere,
//! in particular where a coarse leaf meets subdivided neighbours. This is the "continue
//! using samples from subdivided neighbors for interpolation" rule of \[Oat05\] ("Trilinear
//! Interpolation"): the fine nodes on the face between a coarse leaf and its split
//! neighbour (the T-junction samples) keep contributing inside the coarse leaf, over half a
//! fine cell, so an object moving from the fine to the coarse side sees no sample "suddenly
//! ignored". \[Oat05\] suggests pointers from each octree node to the samples on its faces;
//! the surplus sum reaches the same samples through the fine level's node table instead,
//! with no per-face bookkeeping. Where a region is fully refined to level `L` the sum
//! equals the uniform level-`L` trilinear interpolant of the baked values (the coarse tents
//! are trilinear inside each fine cell and the surpluses make the sum hit the baked value
//! at every fine node).
//!
//! ## Culling
//! \[Oat05\], "Adaptive Subdivision": "if a voxel has been subdivided and its children don't
//! differ enough from the parent, these samples may be culled". Here a node is dropped when
//! its surplus (its difference from the parent levels' interpolation) is small in
//! irradiance:
//! [`surplus_measure`]`(s) ≤ cull_tolerance · value_scale`, with
//! [`AdaptiveVolume::value_scale`] the mean over weighted base nodes of `max_rgb |c_00|`.
//! Dropping a node changes the irradiance near it by at most that (L2 norm over normals,
//! divided by π) and keeps the field continuous. Nodes of levels `≤ min_level` are never
//! culled.
//!
//! ## Lookups ([`crate::adaptive::lookup`])
//! [`AdaptiveVolume::coeffs_at_reference`] / [`AdaptiveVolume::irradiance_reference`]: f64,
//! binary search in each level's sorted key table. [`AdaptiveVolume::coeffs_at`] /
//! [`AdaptiveVolume::irradiance`]: f32, hash-map index (a fixed hasher: deterministic). A
//! test bounds their difference. Points outside the box clamp to it, as in [`crate::grid`].

pub mod build;
pub mod lookup;

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use lightvol_sh::index::sh_lm;

use crate::error::VolumeError;
use crate::grid::GridSpec;
use crate::metadata::BakeMetadata;
use crate::volume::{IrradianceVolume, sample_bytes};

pub use crate::metadata::OctreeSettings;

/// The finest level accepted: node coordinates of every level must fit the 21 bits per
/// axis of a packed key, and `(n - 1)·2^8` keeps that for any base grid of up to 8192
/// cells per axis.
pub const MAX_LEVEL: u32 = 8;

/// Largest node count [`AdaptiveVolume::to_uniform`] produces (2^24 nodes: 1.7 GiB at 9
/// RGB f32 coefficients); a guard against a typo in an export resolution.
pub const TO_UNIFORM_MAX_NODES: usize = 1 << 24;

/// Bits per axis in a packed node or cell key.
const KEY_BITS: u32 = 21;
const KEY_MASK: u64 = (1 << KEY_BITS) - 1;

/// Packs level coordinates `(i, j, k)` into a key whose order is `(k, j, i)` lexicographic
/// (the flat x-fastest order of [`GridSpec`]).
#[must_use]
#[inline]
pub fn pack_key(c: [u32; 3]) -> u64 {
    u64::from(c[0]) | (u64::from(c[1]) << KEY_BITS) | (u64::from(c[2]) << (2 * KEY_BITS))
}

/// Inverse of [`pack_key`].
#[must_use]
#[inline]
pub fn unpack_key(key: u64) -> [u32; 3] {
    [
        (key & KEY_MASK) as u32,
        ((key >> KEY_BITS) & KEY_MASK) as u32,
        ((key >> (2 * KEY_BITS)) & KEY_MASK) as u32,
    ]
}

/// The octree's reading of the settings record ([`OctreeSettings`] is plain data in
/// [`crate::metadata`], below the volume whose bake record holds it).
impl OctreeSettings {
    /// Errors on non-finite or non-positive thresholds, zero depth rays with the depth
    /// heuristic on, or bad levels.
    ///
    /// # Errors
    /// [`VolumeError::InvalidData`] naming the setting.
    pub fn validate(&self) -> Result<(), VolumeError> {
        for (name, t) in [("gradient", self.gradient_threshold), ("depth ratio", self.depth_ratio_threshold)]
        {
            if let Some(t) = t
                && !(t.is_finite() && t > 0.0)
            {
                return Err(VolumeError::InvalidData(format!(
                    "{name} threshold {t} must be finite and positive"
                )));
            }
        }
        if self.depth_ratio_threshold.is_some() && self.depth_rays == 0 {
            return Err(VolumeError::InvalidData("depth_rays must be positive".into()));
        }
        self.params().validate()
    }

    /// The volume crate's parameters.
    #[must_use]
    pub fn params(&self) -> OctreeParams {
        OctreeParams {
            min_level: self.min_level,
            max_level: self.max_level,
            cull_tolerance: self.cull_tolerance,
            memory_budget: self.memory_budget,
            budget_tolerance: 0.0,
        }
    }
}

/// Refinement and culling parameters of an adaptive volume (\[Oat05\], "Adaptive
/// Subdivision": "Specify a Min and Max level of subdivision", culling of redundant samples,
/// plus a memory budget).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OctreeParams {
    /// Every cell of the levels below `min_level` is split; nodes of levels `≤ min_level`
    /// are never culled.
    pub min_level: u32,
    /// The finest level (`min_level ≤ max_level ≤` [`MAX_LEVEL`]).
    pub max_level: u32,
    /// A node is culled when `max |surplus| ≤ cull_tolerance · value_scale` (module docs).
    pub cull_tolerance: f64,
    /// Upper bound on [`AdaptiveVolume::memory_bytes`], met by raising `budget_tolerance`
    /// ([`crate::adaptive::build`]).
    pub memory_budget: Option<usize>,
    /// The L2-weighted cull threshold (relative to the value scale) that the memory budget
    /// required: a node of level `l` is also culled when `max |s| · 2^(-3l/2) ≤
    /// budget_tolerance · value_scale`. An output of the builder (0 without a budget or when
    /// the tree fits); ignored on input.
    pub budget_tolerance: f64,
}

impl Default for OctreeParams {
    fn default() -> Self {
        Self { min_level: 0, max_level: 2, cull_tolerance: 0.01, memory_budget: None, budget_tolerance: 0.0 }
    }
}

impl OctreeParams {
    /// Errors unless `min_level ≤ max_level ≤ MAX_LEVEL` and the tolerance is finite and
    /// non-negative.
    pub fn validate(&self) -> Result<(), VolumeError> {
        if self.max_level > MAX_LEVEL || self.min_level > self.max_level {
            return Err(VolumeError::InvalidData(format!(
                "octree levels: need min_level ({}) <= max_level ({}) <= {MAX_LEVEL}",
                self.min_level, self.max_level
            )));
        }
        if !(self.cull_tolerance.is_finite()
            && self.cull_tolerance >= 0.0
            && self.budget_tolerance.is_finite()
            && self.budget_tolerance >= 0.0)
        {
            return Err(VolumeError::InvalidData(format!(
                "cull tolerances {} and {} must be finite and >= 0",
                self.cull_tolerance, self.budget_tolerance
            )));
        }
        Ok(())
    }
}

/// Per-level counts of an adaptive volume (what `lightvol info` prints).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct LevelStats {
    /// The level.
    pub level: u32,
    /// Cells of this level present in the tree (level 0: all base cells).
    pub cells: usize,
    /// Cells of this level that are leaves (not split).
    pub leaves: usize,
    /// Cells of this level split into 8 children.
    pub split: usize,
    /// Nodes baked at this level (level 0: all base nodes).
    pub created_nodes: usize,
    /// Nodes kept after culling (level 0: all base nodes).
    pub stored_nodes: usize,
    /// `created_nodes - stored_nodes` (includes `empty_nodes`).
    pub culled_nodes: usize,
    /// Nodes whose bake found no sample in the domain of interest (surplus 0, culled).
    pub empty_nodes: usize,
}

/// A fixed multiplicative hasher for packed keys (deterministic across runs, unlike the
/// std default; the keys are already well spread in their low bits).
#[derive(Default, Clone, Copy)]
pub(crate) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    fn write_u64(&mut self, x: u64) {
        // splitmix64 finaliser.
        let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        self.0 = z ^ (z >> 31);
    }
}

pub(crate) type KeyMap = HashMap<u64, u32, BuildHasherDefault<KeyHasher>>;

/// The stored nodes of one level `≥ 1`: sorted keys and their surpluses `[node][coeff][rgb]`.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct LevelTable {
    pub(crate) keys: Vec<u64>,
    pub(crate) data: Vec<f32>,
}

/// An adaptive irradiance volume (module docs): a base [`IrradianceVolume`] plus sparse
/// surplus tables of levels `1..=max_level` and the split structure.
#[derive(Clone)]
pub struct AdaptiveVolume {
    pub(crate) base: IrradianceVolume,
    pub(crate) params: OctreeParams,
    pub(crate) value_scale: f64,
    /// Levels `1..=params.max_level` (index `l - 1`).
    pub(crate) tables: Vec<LevelTable>,
    /// Split cells of levels `0..params.max_level` (index `l`), sorted keys.
    pub(crate) split: Vec<Vec<u64>>,
    pub(crate) stats: Vec<LevelStats>,
    /// Hash index of `tables` (derived).
    pub(crate) index: Vec<KeyMap>,
}

/// Equality of the stored content (the derived hash index is not compared).
impl PartialEq for AdaptiveVolume {
    fn eq(&self, o: &Self) -> bool {
        self.base == o.base
            && self.params == o.params
            && self.value_scale.to_bits() == o.value_scale.to_bits()
            && self.tables == o.tables
            && self.split == o.split
            && self.stats == o.stats
    }
}

/// A summary.
impl std::fmt::Debug for AdaptiveVolume {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AdaptiveVolume")
            .field("base", &self.base)
            .field("params", &self.params)
            .field("value_scale", &self.value_scale)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

/// The level-`level` grid over `base`'s box: `(n - 1)·2^level + 1` nodes per axis, same
/// placement.
pub fn level_grid(base: &GridSpec, level: u32) -> Result<GridSpec, VolumeError> {
    if level > MAX_LEVEL {
        return Err(VolumeError::InvalidGrid(format!("level {level} above {MAX_LEVEL}")));
    }
    let (min, max) = base.bounds();
    let res = base.res().map(|n| (n - 1) * (1 << level) + 1);
    let g = GridSpec::new(min, max, res)?;
    Ok(match base.placement() {
        Some(p) => g.with_placement(*p),
        None => g,
    })
}

impl AdaptiveVolume {
    /// Assembles a volume from checked parts (builder and reader).
    pub(crate) fn from_parts(
        base: IrradianceVolume,
        params: OctreeParams,
        value_scale: f64,
        tables: Vec<LevelTable>,
        split: Vec<Vec<u64>>,
        stats: Vec<LevelStats>,
    ) -> Result<Self, VolumeError> {
        params.validate()?;
        let ml = params.max_level as usize;
        if tables.len() != ml || split.len() != ml || stats.len() != ml + 1 {
            return Err(VolumeError::Mismatch(format!(
                "octree of {ml} levels with {} tables, {} split lists, {} stats",
                tables.len(),
                split.len(),
                stats.len()
            )));
        }
        let k = base.coeffs() * 3;
        let res0 = base.spec().res();
        for (l, t) in tables.iter().enumerate() {
            let n = res0.map(|r| (r - 1) * (1 << (l + 1)) + 1);
            if t.data.len() != t.keys.len() * k {
                return Err(VolumeError::Mismatch(format!("level {} table lengths", l + 1)));
            }
            check_keys(&t.keys, n, &format!("level {} nodes", l + 1))?;
            crate::error::check_finite("octree surpluses", &t.data)?;
        }
        for (l, s) in split.iter().enumerate() {
            let n = res0.map(|r| (r - 1) * (1 << l));
            check_keys(s, n, &format!("level {l} split cells"))?;
        }
        if !(value_scale.is_finite() && value_scale > 0.0) {
            return Err(VolumeError::InvalidData(format!("value scale {value_scale}")));
        }
        let index = tables
            .iter()
            .map(|t| t.keys.iter().enumerate().map(|(i, &key)| (key, i as u32)).collect())
            .collect();
        Ok(Self { base, params, value_scale, tables, split, stats, index })
    }

    /// The level-0 volume (a complete uniform bake of the base grid).
    #[must_use]
    pub fn base(&self) -> &IrradianceVolume {
        &self.base
    }

    /// SH coefficients per colour channel.
    #[must_use]
    pub fn coeffs(&self) -> usize {
        self.base.coeffs()
    }

    /// The parameters the volume was built with.
    #[must_use]
    pub fn params(&self) -> &OctreeParams {
        &self.params
    }

    /// The finest level with cells in the tree (`≤ params().max_level`).
    #[must_use]
    pub fn max_level(&self) -> u32 {
        self.stats.iter().rev().find(|s| s.cells > 0).map_or(0, |s| s.level)
    }

    /// Mean over base nodes with weight > 0 of `max_rgb |c_00|`: the scale of the culling
    /// tolerance and the gradient heuristic.
    #[must_use]
    pub fn value_scale(&self) -> f64 {
        self.value_scale
    }

    /// The virtual uniform grid of `level` (see the module docs).
    pub fn level_grid(&self, level: u32) -> Result<GridSpec, VolumeError> {
        level_grid(self.base.spec(), level)
    }

    /// Nodes per axis of the finest level present.
    #[must_use]
    pub fn finest_res(&self) -> [u32; 3] {
        self.base.spec().res().map(|n| (n - 1) * (1 << self.max_level()) + 1)
    }

    /// Per-level counts, index = level, `0..=params().max_level`.
    #[must_use]
    pub fn level_stats(&self) -> &[LevelStats] {
        &self.stats
    }

    /// Stored nodes of one level `≥ 1` as `(coordinates, surpluses [coeff][rgb])`.
    pub fn level_nodes(&self, level: u32) -> impl Iterator<Item = ([u32; 3], &[f32])> {
        let k = self.coeffs() * 3;
        let t = (level >= 1).then(|| self.tables.get(level as usize - 1)).flatten();
        t.into_iter().flat_map(move |t| {
            t.keys.iter().zip(t.data.chunks_exact(k)).map(|(&key, d)| (unpack_key(key), d))
        })
    }

    /// Split cells of `level` (coordinates in the level grid), sorted.
    pub fn split_cells(&self, level: u32) -> impl Iterator<Item = [u32; 3]> + '_ {
        self.split.get(level as usize).into_iter().flatten().map(|&k| unpack_key(k))
    }

    /// Whether cell `c` of `level` is split.
    #[must_use]
    pub fn is_split(&self, level: u32, c: [u32; 3]) -> bool {
        self.split.get(level as usize).is_some_and(|s| s.binary_search(&pack_key(c)).is_ok())
    }

    /// Base nodes plus stored nodes of levels `≥ 1`.
    #[must_use]
    pub fn stored_nodes(&self) -> usize {
        self.base.spec().node_count() + self.tables.iter().map(|t| t.keys.len()).sum::<usize>()
    }

    /// Bytes of the representation: coefficient floats of every stored node, the base
    /// weights, one 8-byte key per stored node of level `≥ 1`, and the split bitmaps (one
    /// bit per cell of levels `0..max_level`: `ceil(base_cells / 8)` plus one byte per
    /// split cell of levels `0..max_level-1`). The hash index of the fast lookup is an
    /// acceleration structure, reported by [`Self::index_bytes`], not here.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        let fine: usize = self.tables.iter().map(|t| t.keys.len()).sum();
        let split_below: usize =
            self.split.iter().take((self.params.max_level as usize).saturating_sub(1)).map(Vec::len).sum();
        memory_model(self.base.spec(), self.coeffs(), self.params.max_level, fine, split_below)
    }

    /// Approximate bytes of the run-time hash index: per slot of capacity, one
    /// `(u64, u32)` entry (16 bytes with padding) and one control byte.
    #[must_use]
    pub fn index_bytes(&self) -> usize {
        self.index.iter().map(|m| m.capacity() * (16 + 1)).sum()
    }

    /// The bake metadata (of the base volume).
    #[must_use]
    pub fn metadata(&self) -> &BakeMetadata {
        self.base.metadata()
    }

    /// Replaces the bake metadata.
    pub fn set_metadata(&mut self, meta: BakeMetadata) {
        self.base.set_metadata(meta);
    }

    /// The same volume with `meta` attached.
    #[must_use]
    pub fn with_metadata(mut self, meta: BakeMetadata) -> Self {
        self.base.set_metadata(meta);
        self
    }
}

/// The memory model of [`AdaptiveVolume::memory_bytes`] from counts: `fine_nodes` stored
/// nodes of levels `≥ 1`, `split_below` split cells of levels `0..max_level-1`.
#[must_use]
pub fn memory_model(
    base: &GridSpec,
    coeffs: usize,
    max_level: u32,
    fine_nodes: usize,
    split_below: usize,
) -> usize {
    let node_bytes = sample_bytes(1, coeffs.isqrt(), false);
    let base_bytes = base.node_count() * (node_bytes + 4);
    let bitmaps = if max_level > 0 { base.cell_count().div_ceil(8) + split_below } else { 0 };
    base_bytes + fine_nodes * (node_bytes + 8) + bitmaps
}

/// The culling measure of a surplus `[coeff][rgb]`: the L2 norm over the sphere of the
/// irradiance it adds, divided by π, largest over RGB:
/// `max_rgb sqrt(∫ E_s(n)² dn) / π = max_rgb sqrt(Σ_j (Â_l(j) s_j)²)`, with
/// `Â_l = A_l / π` the normalised clamped-cosine factors (1, 2/3, 1/4, 0, −1/24, …;
/// Ramamoorthi & Hanrahan 2001) and the SH basis orthonormal. For a surplus in the DC
/// term alone it is `|s_0|`. Coefficients of odd bands above 1 do not change irradiance
/// and do not count.
#[must_use]
pub fn surplus_measure(s: &[f32]) -> f64 {
    let coeffs = s.len() / 3;
    (0..3)
        .map(|ch| {
            (0..coeffs)
                .map(|j| {
                    let a = lightvol_sh::irradiance::normalized_cosine_lobe_factor(sh_lm(j).0);
                    (a * f64::from(s[3 * j + ch])).powi(2)
                })
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// Checks that keys are strictly increasing and within `n` per axis.
fn check_keys(keys: &[u64], n: [u32; 3], what: &str) -> Result<(), VolumeError> {
    if keys.windows(2).any(|w| w[0] >= w[1]) {
        return Err(VolumeError::InvalidData(format!("{what}: keys not strictly increasing")));
    }
    if let Some(&bad) = keys.iter().find(|&&k| {
        let c = unpack_key(k);
        k >> (3 * KEY_BITS) != 0 || (0..3).any(|a| c[a] >= n[a])
    }) {
        return Err(VolumeError::InvalidData(format!("{what}: key {:?} outside {n:?}", unpack_key(bad))));
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests;
