//! Building an [`AdaptiveVolume`] level by level (\[Oat05\], "Adaptive Subdivision": min and
//! max levels, a threshold per heuristic, culling of redundant children).
//!
//! [`build_adaptive`] is tracer-agnostic: it takes the finished base volume and two
//! callbacks.
//!
//! - `score(&Candidates)`: for each leaf cell of the current level, a score; a cell with
//!   score `≥ 1` asks to be split, and a score of `+∞` forces the split and keeps the nodes
//!   it creates from culling, as `min_level` does (a density volume). The caller evaluates its heuristics there (lightvol-
//!   sampler: gradient, geometry inside the cell, harmonic mean depth); the built-in
//!   [`Candidates::corner_change`] measures the change of the field across the cell.
//! - `bake(level, nodes)`: the baked values of the listed nodes of `level` (sorted packed-key
//!   order), each with a weight (0 = no estimate: such a node keeps the coarser levels'
//!   interpolation, surplus 0).
//!
//! For each level `l < max_level`: score the leaves; split every cell with score `≥ 1` (all
//! cells below `min_level`); bake the level-`l+1` nodes the splits create; store each node's
//! surplus unless it is culled (see [`crate::adaptive`]).
//!
//! **Memory budget.** \[Oat05\]'s brute-force scheme ("Adaptive Subdivision"): "super-sample,
//! then discard redundant voxels using some error tolerance". When the tree the heuristics
//! grew exceeds `memory_budget` (as [`AdaptiveVolume::memory_bytes`] counts it), a second,
//! L2-weighted cull threshold is raised by bisection until it fits: a node is kept only if
//! `max |s| · 2^(-3l/2)` (its surplus times the L2 norm of its tent relative to level 0)
//! exceeds it. The surpluses are recomputed level by level from the baked values for each
//! trial, so the nodes kept are, across all levels, those whose removal would change the
//! field most. The threshold used is stored in [`OctreeParams::budget_tolerance`]. Everything is deterministic given
//! deterministic callbacks.

use std::collections::BTreeSet;

use crate::adaptive::{
    AdaptiveVolume, LevelStats, LevelTable, OctreeParams, level_grid, memory_model, pack_key,
};
use crate::error::VolumeError;
use crate::grid::GridSpec;
use crate::volume::IrradianceVolume;

/// The baked values of a list of nodes: `values` `[node][coeff][rgb]`, `weights` one per
/// node (the domain-of-interest weight; 0 = no estimate).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LevelSamples {
    /// `[node][coeff][rgb]`.
    pub values: Vec<f64>,
    /// One weight per node; `≤ 0` (or NaN) means the node has no estimate.
    pub weights: Vec<f64>,
}

/// Field values at the nodes of one level, sorted by key.
#[derive(Debug, Default)]
struct NodeValues {
    keys: Vec<u64>,
    vals: Vec<f64>,
    k: usize,
}

impl NodeValues {
    fn get(&self, c: [u32; 3]) -> Option<&[f64]> {
        let i = self.keys.binary_search(&pack_key(c)).ok()?;
        Some(&self.vals[i * self.k..(i + 1) * self.k])
    }
}

/// The leaf cells of one level offered for splitting, with the current field at their
/// corners.
#[derive(Debug)]
pub struct Candidates<'a> {
    level: u32,
    grid: &'a GridSpec,
    cells: &'a [[u32; 3]],
    values: &'a NodeValues,
    value_scale: f64,
}

impl Candidates<'_> {
    /// The level of the cells.
    #[must_use]
    pub fn level(&self) -> u32 {
        self.level
    }

    /// The level's grid ([`crate::adaptive::level_grid`]).
    #[must_use]
    pub fn grid(&self) -> &GridSpec {
        self.grid
    }

    /// The cells (level-grid coordinates, sorted in `(k, j, i)` order).
    #[must_use]
    pub fn cells(&self) -> &[[u32; 3]] {
        self.cells
    }

    /// The field (all levels so far, as stored) at the 8 corners of cell `i`, corner
    /// `c = dx + 2dy + 4dz`, each `[coeff][rgb]`.
    ///
    /// # Panics
    /// If `i` is out of range.
    #[must_use]
    pub fn corner_values(&self, i: usize) -> [&[f64]; 8] {
        let c = self.cells[i];
        std::array::from_fn(|q| {
            let node = [c[0] + (q as u32 & 1), c[1] + ((q as u32 >> 1) & 1), c[2] + ((q as u32 >> 2) & 1)];
            self.values.get(node).expect("corners of a leaf cell are nodes of its level")
        })
    }

    /// The change of the field across cell `i`: the largest `|c_a − c_b|` over the cell's 12
    /// edges, all coefficients and RGB, divided by [`Self::value_scale`]. This is \[Oat05\]'s
    /// "large gradient" heuristic as `|∇c| · h` (the gradient times the cell size, i.e. what
    /// linear interpolation across the cell has to bridge), estimated by corner differences.
    #[must_use]
    pub fn corner_change(&self, i: usize) -> f64 {
        let v = self.corner_values(i);
        let mut worst = 0.0f64;
        for c in 0..8 {
            for bit in [1, 2, 4] {
                if c & bit == 0 {
                    for (a, b) in v[c].iter().zip(v[c | bit]) {
                        worst = worst.max((a - b).abs());
                    }
                }
            }
        }
        worst / self.value_scale
    }

    /// The scale of the relative measures ([`AdaptiveVolume::value_scale`]).
    #[must_use]
    pub fn value_scale(&self) -> f64 {
        self.value_scale
    }
}

/// An error of [`build_adaptive`]: from the volume crate, or from a callback.
#[derive(Debug)]
pub enum BuildError<E> {
    /// Invalid parameters, budget, or callback output.
    Volume(VolumeError),
    /// A callback failed.
    Callback(E),
}

impl<E: std::fmt::Display> std::fmt::Display for BuildError<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Volume(e) => write!(f, "{e}"),
            Self::Callback(e) => write!(f, "{e}"),
        }
    }
}

impl<E: std::error::Error + 'static> std::error::Error for BuildError<E> {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Volume(e) => Some(e),
            Self::Callback(e) => Some(e),
        }
    }
}

impl<E> From<VolumeError> for BuildError<E> {
    fn from(e: VolumeError) -> Self {
        Self::Volume(e)
    }
}

/// Mean over nodes with weight > 0 of `max_rgb |c_00|` (floored at the smallest positive
/// f64 so that relative measures stay finite for an all-black volume).
fn value_scale(base: &IrradianceVolume) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (node, &w) in base.weights().iter().enumerate() {
        if w > 0.0 {
            let c = base.node(node);
            sum += f64::from(c[0].abs().max(c[1].abs()).max(c[2].abs()));
            n += 1;
        }
    }
    if n == 0 { f64::MIN_POSITIVE } else { (sum / n as f64).max(f64::MIN_POSITIVE) }
}

/// The 27 level-`l+1` nodes of the children of level-`l` cell `c`.
fn child_nodes(c: [u32; 3]) -> impl Iterator<Item = [u32; 3]> {
    (0..27u32).map(move |q| [2 * c[0] + q % 3, 2 * c[1] + (q / 3) % 3, 2 * c[2] + q / 9])
}

/// Baked values of the nodes of one level `≥ 1`, sorted by key (`None`: no estimate).
type Baked = Vec<(u64, Option<Vec<f64>>)>;

/// Builds an adaptive volume over `base` (module docs). Errors on invalid parameters, a
/// memory budget below the base level plus the nodes `min_level` keeps, callback output of
/// the wrong length or with non-finite values, and callback errors.
pub fn build_adaptive<E>(
    base: IrradianceVolume,
    params: &OctreeParams,
    mut score: impl FnMut(&Candidates<'_>) -> Result<Vec<f64>, E>,
    mut bake: impl FnMut(u32, &[[u32; 3]]) -> Result<LevelSamples, E>,
) -> Result<AdaptiveVolume, BuildError<E>> {
    params.validate()?;
    let ml = params.max_level;
    let coeffs = base.coeffs();
    let k = coeffs * 3;
    let spec0 = base.spec().clone();
    let scale = value_scale(&base);
    if let Some(b) = params.memory_budget {
        let need = memory_model(&spec0, coeffs, ml, 0, 0);
        if b < need {
            return Err(VolumeError::InvalidData(format!(
                "memory budget of {b} bytes is below the base level's {need} bytes"
            ))
            .into());
        }
    }
    let mut field = NodeValues {
        keys: (0..spec0.node_count()).map(|n| pack_key(spec0.node_coords(n))).collect(),
        vals: base.data().iter().map(|&v| f64::from(v)).collect(),
        k,
    };
    let mut stats: Vec<LevelStats> =
        (0..=ml).map(|level| LevelStats { level, ..LevelStats::default() }).collect();
    stats[0].cells = spec0.cell_count();
    stats[0].created_nodes = spec0.node_count();
    stats[0].stored_nodes = spec0.node_count();
    let empty_tables = vec![LevelTable::default(); ml as usize];
    let mut vol = AdaptiveVolume::from_parts(
        base,
        *params,
        scale,
        empty_tables,
        vec![Vec::new(); ml as usize],
        stats.clone(),
    )?;
    let mut baked: Vec<Baked> = vec![Vec::new(); ml as usize];
    // Per level `l + 1`: the nodes created by forced splits of level `l`.
    let mut forced: Vec<BTreeSet<u64>> = vec![BTreeSet::new(); ml as usize];

    for l in 0..ml {
        let grid = level_grid(&spec0, l)?;
        let cand: Vec<[u32; 3]> = if l == 0 {
            (0..spec0.cell_count()).map(|c| spec0.cell_coords(c)).collect()
        } else {
            let mut v: Vec<[u32; 3]> = vol.split[l as usize - 1]
                .iter()
                .flat_map(|&key| {
                    let c = crate::adaptive::unpack_key(key);
                    (0..8u32)
                        .map(move |q| [2 * c[0] + (q & 1), 2 * c[1] + ((q >> 1) & 1), 2 * c[2] + (q >> 2)])
                })
                .collect();
            v.sort_unstable_by_key(|&c| pack_key(c));
            v
        };
        if cand.is_empty() {
            break;
        }
        let scores = if l < params.min_level {
            vec![f64::INFINITY; cand.len()]
        } else {
            let c = Candidates { level: l, grid: &grid, cells: &cand, values: &field, value_scale: scale };
            score(&c).map_err(BuildError::Callback)?
        };
        if scores.len() != cand.len() || scores.iter().any(|s| s.is_nan()) {
            return Err(VolumeError::InvalidData(format!(
                "level {l}: {} scores for {} cells (or a NaN score)",
                scores.len(),
                cand.len()
            ))
            .into());
        }
        let split_l: Vec<u64> =
            (0..cand.len()).filter(|&i| scores[i] >= 1.0).map(|i| pack_key(cand[i])).collect();
        let new: BTreeSet<u64> = split_l
            .iter()
            .flat_map(|&key| child_nodes(crate::adaptive::unpack_key(key)).map(pack_key))
            .collect();
        // Nodes of forced splits (score +∞) are kept whatever their surplus.
        forced[l as usize] = (0..cand.len())
            .filter(|&i| scores[i] == f64::INFINITY)
            .flat_map(|i| child_nodes(cand[i]).map(pack_key))
            .collect();
        let nodes: Vec<[u32; 3]> = new.iter().map(|&key| crate::adaptive::unpack_key(key)).collect();
        let level_baked: Baked = if nodes.is_empty() {
            Vec::new()
        } else {
            let s = bake(l + 1, &nodes).map_err(BuildError::Callback)?;
            if s.values.len() != nodes.len() * k || s.weights.len() != nodes.len() {
                return Err(VolumeError::InvalidData(format!(
                    "level {}: bake returned {} values and {} weights for {} nodes",
                    l + 1,
                    s.values.len(),
                    s.weights.len(),
                    nodes.len()
                ))
                .into());
            }
            let mut out = Vec::with_capacity(nodes.len());
            for (idx, &key) in new.iter().enumerate() {
                let v = &s.values[idx * k..(idx + 1) * k];
                let has = s.weights[idx] > 0.0;
                if has && v.iter().any(|x| !x.is_finite()) {
                    return Err(
                        VolumeError::InvalidData(format!("level {}: non-finite node value", l + 1)).into()
                    );
                }
                out.push((key, has.then(|| v.to_vec())));
            }
            out
        };
        let st = &mut stats[l as usize];
        st.cells = cand.len();
        st.split = split_l.len();
        st.leaves = cand.len() - split_l.len();
        stats[l as usize + 1].cells = 8 * split_l.len();
        vol.split[l as usize] = split_l;
        // Surpluses of the new level at the requested tolerance; the field they give
        // feeds the next level's candidates.
        let (table, values) = level_surpluses(
            &vol,
            l + 1,
            &level_baked,
            &forced[l as usize],
            params.cull_tolerance * scale,
            0.0,
        );
        vol.tables[l as usize] = table;
        field = values;
        baked[l as usize] = level_baked;
    }
    // Leaves of the finest level present.
    if let Some(last) = stats.iter_mut().rev().find(|s| s.cells > 0)
        && last.level == ml
    {
        last.leaves = last.cells;
    }
    let mut params = *params;
    if let Some(b) = params.memory_budget {
        params.budget_tolerance =
            fit_budget(&mut vol, &baked, &forced, b, params.cull_tolerance * scale)? / scale;
    }
    for l in 1..=ml as usize {
        let st = &mut stats[l];
        st.created_nodes = baked[l - 1].len();
        st.stored_nodes = vol.tables[l - 1].keys.len();
        st.culled_nodes = st.created_nodes - st.stored_nodes;
        st.empty_nodes = baked[l - 1].iter().filter(|(_, v)| v.is_none()).count();
    }
    let AdaptiveVolume { base, tables, split, .. } = vol;
    Ok(AdaptiveVolume::from_parts(base, params, scale, tables, split, stats)?)
}

/// `2^(-3l/2)`: the L2 norm of a level-`l` tent function relative to a level-0 one (its
/// support has `2^(-3l)` of the volume).
fn l2_weight(level: u32) -> f64 {
    2f64.powf(-1.5 * f64::from(level))
}

/// The surplus table of `level` from its baked values, against the tables of the coarser
/// levels already in `vol`, and the field values at the level's nodes. A node is culled
/// (never at or below `min_level`, nor one of the `forced` nodes) when `max |s| ≤ cull_abs`
/// or `max |s| · 2^(-3l/2) ≤ l2_abs`.
fn level_surpluses(
    vol: &AdaptiveVolume,
    level: u32,
    baked: &Baked,
    forced: &BTreeSet<u64>,
    cull_abs: f64,
    l2_abs: f64,
) -> (LevelTable, NodeValues) {
    let w = l2_weight(level);
    let k = vol.coeffs() * 3;
    let inv = 1.0 / f64::from(1u32 << level);
    let mut interp = vec![0.0f64; k];
    let mut table = LevelTable::default();
    let mut values =
        NodeValues { keys: Vec::with_capacity(baked.len()), vals: Vec::with_capacity(baked.len() * k), k };
    for (key, v) in baked {
        // Exact: node coordinates over a power of two.
        let u0 = crate::adaptive::unpack_key(*key).map(|c| f64::from(c) * inv);
        vol.sum_levels_f64(u0, level, &mut interp);
        let sur: Vec<f32> = match v {
            Some(v) => v.iter().zip(&interp).map(|(a, b)| (a - b) as f32).collect(),
            None => vec![0.0; k],
        };
        let m = crate::adaptive::surplus_measure(&sur);
        let keep = level <= vol.params.min_level
            || forced.contains(key)
            || (v.is_some() && m > cull_abs && m * w > l2_abs);
        values.keys.push(*key);
        if keep {
            values.vals.extend(interp.iter().zip(&sur).map(|(a, &b)| a + f64::from(b)));
            table.keys.push(*key);
            table.data.extend(sur);
        } else {
            values.vals.extend_from_slice(&interp);
        }
    }
    (table, values)
}

/// Rebuilds every level's surpluses with the absolute tolerances of [`level_surpluses`];
/// returns the resulting memory.
fn rebuild(
    vol: &mut AdaptiveVolume,
    baked: &[Baked],
    forced: &[BTreeSet<u64>],
    cull_abs: f64,
    l2_abs: f64,
) -> usize {
    for l in 1..=vol.params.max_level {
        let i = l as usize - 1;
        let (table, _) = level_surpluses(vol, l, &baked[i], &forced[i], cull_abs, l2_abs);
        vol.tables[l as usize - 1] = table;
    }
    vol.memory_bytes()
}

/// Bisection steps of [`fit_budget`] (on a log scale over up to 12 decades: the found
/// tolerance is within a factor 1.000002 of the smallest feasible one).
const BUDGET_STEPS: u32 = 48;

/// Finds, by bisection, the smallest L2 tolerance `l2_abs` (see [`level_surpluses`]) with
/// which `memory_bytes() ≤ budget`, and leaves `vol` rebuilt with it: \[Oat05\]'s
/// "super-sample, then discard redundant samples", keeping across all levels the nodes whose
/// removal would change the field most in the L2 sense (`|s|` times the L2 norm of the
/// node's tent, the standard thresholding of hierarchical bases). Returns the tolerance
/// (0 when the tree already fits).
fn fit_budget(
    vol: &mut AdaptiveVolume,
    baked: &[Baked],
    forced: &[BTreeSet<u64>],
    budget: usize,
    cull_abs: f64,
) -> Result<f64, VolumeError> {
    if vol.memory_bytes() <= budget {
        return Ok(0.0);
    }
    // Above every weighted surplus magnitude: culls every node above min_level.
    let big = baked
        .iter()
        .flatten()
        .filter_map(|(_, v)| v.as_ref())
        .flatten()
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(vol.base.data().iter().fold(0.0f64, |m, x| m.max(f64::from(x.abs()))));
    let mut hi = 4.0 * big + f64::MIN_POSITIVE;
    if rebuild(vol, baked, forced, cull_abs, hi) > budget {
        return Err(VolumeError::InvalidData(format!(
            "memory budget of {budget} bytes is below the {} bytes that the base level, min_level {} and the density volumes require",
            vol.memory_bytes(),
            vol.params.min_level
        )));
    }
    let mut lo = hi * 1e-12;
    for _ in 0..BUDGET_STEPS {
        let mid = (lo * hi).sqrt();
        if rebuild(vol, baked, forced, cull_abs, mid) <= budget {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    rebuild(vol, baked, forced, cull_abs, hi);
    Ok(hi)
}
