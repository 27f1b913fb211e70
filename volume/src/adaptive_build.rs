//! Building an [`AdaptiveVolume`] level by level (seed 002, "Adaptive Subdivision": min and
//! max levels, a threshold per heuristic, culling of redundant children).
//!
//! [`build_adaptive`] is tracer-agnostic: it takes the finished base volume and two
//! callbacks.
//!
//! - `score(&Candidates)`: for each leaf cell of the current level, a score; a cell with
//!   score `≥ 1` asks to be split. The caller evaluates its heuristics there (lightvol-
//!   sampler: gradient, geometry inside the cell, harmonic mean depth); the built-in
//!   [`Candidates::corner_change`] measures the change of the field across the cell.
//! - `bake(level, nodes)`: the baked values of the listed nodes of `level` (sorted packed-key
//!   order), each with a weight (0 = no estimate: such a node keeps the coarser levels'
//!   interpolation, surplus 0).
//!
//! For each level `l < max_level`: score the leaves; split, in order of decreasing score
//! (ties by cell key), every cell with score `≥ 1` (all cells below `min_level`); bake the
//! level-`l+1` nodes the splits create; store each node's surplus unless it is culled (see
//! [`crate::adaptive`]). With a memory budget a split is taken only while the memory model of
//! [`AdaptiveVolume::memory_bytes`] (counting the new nodes before culling) stays within it;
//! cells that did not fit are retried after culling has freed memory, for at most
//! [`MAX_ROUNDS`] rounds per level. Everything is deterministic given deterministic callbacks.

use std::collections::{BTreeMap, BTreeSet};

use crate::adaptive::{
    AdaptiveVolume, LevelStats, LevelTable, OctreeParams, level_grid, memory_model, pack_key,
};
use crate::error::VolumeError;
use crate::grid::GridSpec;
use crate::volume::IrradianceVolume;

/// Refinement rounds per level under a memory budget.
pub const MAX_ROUNDS: usize = 8;

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
    /// edges, all coefficients and RGB, divided by [`Self::value_scale`]. This is seed 002's
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

/// Builds an adaptive volume over `base` (module docs). Errors on invalid parameters, a
/// memory budget below the base level (plus the splits `min_level` forces), callback output
/// of the wrong length or with non-finite values, and callback errors.
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
    let cull_at = params.cull_tolerance * scale;
    let node_bytes = k * 4 + 8;
    let mut mem = memory_model(&spec0, coeffs, ml, 0, 0);
    if let Some(b) = params.memory_budget
        && b < mem
    {
        return Err(VolumeError::InvalidData(format!(
            "memory budget of {b} bytes is below the base level's {mem} bytes"
        ))
        .into());
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
    let mut interp = vec![0.0f64; k];

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
        let forced = l < params.min_level;
        let scores = if forced {
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
        let mut remaining: Vec<usize> = (0..cand.len()).filter(|&i| scores[i] >= 1.0).collect();
        // Largest score first; ties in key order (cand is sorted by key).
        remaining.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]).then(a.cmp(&b)));

        let bitmap_cost = usize::from(l + 1 < ml);
        let mut new_field: BTreeMap<u64, Vec<f64>> = BTreeMap::new();
        let mut stored: BTreeMap<u64, Vec<f32>> = BTreeMap::new();
        let mut split_l: Vec<u64> = Vec::new();
        let (mut created, mut empty) = (0usize, 0usize);
        for _round in 0..MAX_ROUNDS {
            let mut pending: BTreeSet<u64> = BTreeSet::new();
            let mut taken = Vec::new();
            let mut left = Vec::new();
            for &ci in &remaining {
                let new: Vec<u64> = child_nodes(cand[ci])
                    .map(pack_key)
                    .filter(|key| !new_field.contains_key(key) && !pending.contains(key))
                    .collect();
                let cost = new.len() * node_bytes + bitmap_cost;
                if !forced && params.memory_budget.is_some_and(|b| mem + cost > b) {
                    left.push(ci);
                    continue;
                }
                mem += cost;
                pending.extend(new);
                taken.push(ci);
            }
            if taken.is_empty() {
                break;
            }
            let nodes: Vec<[u32; 3]> = pending.iter().map(|&key| crate::adaptive::unpack_key(key)).collect();
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
            let inv = 1.0 / f64::from(1u32 << (l + 1));
            for (idx, (&key, node)) in pending.iter().zip(&nodes).enumerate() {
                // Exact: node coordinates over a power of two.
                let u0 = node.map(|c| f64::from(c) * inv);
                vol.sum_levels_f64(u0, l + 1, &mut interp);
                created += 1;
                let v = &s.values[idx * k..(idx + 1) * k];
                let has = s.weights[idx] > 0.0;
                if has && v.iter().any(|x| !x.is_finite()) {
                    return Err(
                        VolumeError::InvalidData(format!("level {}: non-finite node value", l + 1)).into()
                    );
                }
                let sur: Vec<f32> = if has {
                    v.iter().zip(&interp).map(|(a, b)| (a - b) as f32).collect()
                } else {
                    vec![0.0; k]
                };
                empty += usize::from(!has);
                let keep =
                    l + 1 <= params.min_level || (has && sur.iter().any(|x| f64::from(x.abs()) > cull_at));
                let value: Vec<f64> = if keep {
                    interp.iter().zip(&sur).map(|(a, &b)| a + f64::from(b)).collect()
                } else {
                    mem -= node_bytes;
                    interp.clone()
                };
                if keep {
                    stored.insert(key, sur);
                }
                new_field.insert(key, value);
            }
            split_l.extend(taken.iter().map(|&ci| pack_key(cand[ci])));
            remaining = left;
            if remaining.is_empty() || params.memory_budget.is_none() {
                break;
            }
        }
        if forced
            && let Some(b) = params.memory_budget
            && mem > b
        {
            return Err(VolumeError::InvalidData(format!(
                "memory budget of {b} bytes is below the {mem} bytes that min_level {} requires",
                params.min_level
            ))
            .into());
        }
        split_l.sort_unstable();
        let st = &mut stats[l as usize];
        st.cells = cand.len();
        st.split = split_l.len();
        st.leaves = cand.len() - split_l.len();
        let next = &mut stats[l as usize + 1];
        next.cells = 8 * split_l.len();
        next.created_nodes = created;
        next.stored_nodes = stored.len();
        next.culled_nodes = created - stored.len();
        next.empty_nodes = empty;
        vol.split[l as usize] = split_l;
        let mut table = LevelTable::default();
        for (key, s) in stored {
            table.keys.push(key);
            table.data.extend(s);
        }
        vol.tables[l as usize] = table;
        field = NodeValues {
            keys: new_field.keys().copied().collect(),
            vals: new_field.into_values().flatten().collect(),
            k,
        };
    }
    // Leaves of the finest level present.
    if let Some(last) = stats.iter_mut().rev().find(|s| s.cells > 0)
        && last.level == ml
    {
        last.leaves = last.cells;
    }
    let AdaptiveVolume { base, tables, split, .. } = vol;
    Ok(AdaptiveVolume::from_parts(base, *params, scale, tables, split, stats)?)
}
