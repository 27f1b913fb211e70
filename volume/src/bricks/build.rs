//! Resampling an [`AdaptiveVolume`] into bricks ([`bricks_from_octree`]): refinement where
//! the octree stores finer nodes, the memory budget (sibling bricks merged into their parent,
//! least useful first), the probe values and the stitching to coarser neighbours (module
//! docs of [`crate::bricks`]).

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashSet};

use rayon::prelude::*;

use crate::adaptive::{AdaptiveVolume, pack_key, surplus_measure, unpack_key};
use crate::bricks::{Brick, BrickParams, BrickVolume, bricks_per_axis, probe_bytes, texel_index};
use crate::error::VolumeError;
use crate::grid::corner_weights;

/// What [`bricks_from_octree`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BrickReport {
    /// Bricks per level, index = level.
    pub bricks_per_level: Vec<usize>,
    /// Bricks where the octree stores finer nodes, before any merge.
    pub refined_bricks: usize,
    /// Merges of sibling bricks that lose no more than [`BrickParams::merge_tolerance`].
    pub smooth_merges: usize,
    /// Bricks after those merges: what the export holds without a budget.
    pub bricks_wanted: usize,
    /// Merges the budget made (each replaces up to 8 sibling bricks by their parent).
    pub merges: usize,
    /// Bricks the budget removed (`bricks_wanted − bricks`).
    pub dropped_bricks: usize,
    /// Largest irradiance a merge lost, relative to the octree's value scale (0 when
    /// nothing was merged).
    pub largest_dropped_error: f64,
    /// Probe bytes of `bricks_wanted`.
    pub wanted_probe_bytes: usize,
    /// Probe bytes kept.
    pub probe_bytes: usize,
    /// Probes whose values were replaced by a coarser neighbour's to keep the field
    /// continuous.
    pub stitched_probes: usize,
}

impl BrickReport {
    /// One line for a person: bricks per level, memory, and what the budget dropped.
    #[must_use]
    pub fn summary(&self) -> String {
        let levels: Vec<String> =
            self.bricks_per_level.iter().enumerate().map(|(l, n)| format!("{n} at level {l}")).collect();
        let mib = |b: usize| b as f64 / (1024.0 * 1024.0);
        let mut s = format!(
            "{} bricks ({}), {:.3} MiB of probes; {} sibling groups merged within the tolerance",
            self.bricks(),
            levels.join(", "),
            mib(self.probe_bytes),
            self.smooth_merges
        );
        if self.dropped_bricks > 0 {
            s += &format!(
                "; the budget dropped {} of {} bricks ({:.3} of {:.3} MiB) in {} merges into coarser bricks, losing at most {:.4} of the mean irradiance",
                self.dropped_bricks,
                self.bricks_wanted,
                mib(self.wanted_probe_bytes - self.probe_bytes),
                mib(self.wanted_probe_bytes),
                self.merges,
                self.largest_dropped_error
            );
        }
        s
    }

    /// Bricks kept.
    #[must_use]
    pub fn bricks(&self) -> usize {
        self.bricks_per_level.iter().sum()
    }
}

/// A brick as a key: level in the top bits, packed coordinates below.
fn brick_key(level: u32, c: [u32; 3]) -> (u32, u64) {
    (level, pack_key(c))
}

/// The bricks of `oct` (module docs of [`crate::bricks`]), with a report.
///
/// # Errors
/// [`VolumeError::InvalidData`] for a brick size outside [`crate::bricks::BRICK_CELLS`], a
/// budget below the level-0 bricks' bytes (in one line, with both sizes), or a probe value
/// beyond half-float range.
pub fn bricks_from_octree(
    oct: &AdaptiveVolume,
    params: &BrickParams,
) -> Result<(BrickVolume, BrickReport), VolumeError> {
    build(oct, params, true)
}

/// [`bricks_from_octree`], with the stitching optional (tests show what it mends).
pub(crate) fn build(
    oct: &AdaptiveVolume,
    params: &BrickParams,
    stitch_bricks: bool,
) -> Result<(BrickVolume, BrickReport), VolumeError> {
    let cells = params.cells;
    if !crate::bricks::BRICK_CELLS.contains(&cells) {
        return Err(VolumeError::InvalidData(format!(
            "{cells} cells per brick (accepted: {:?})",
            crate::bricks::BRICK_CELLS
        )));
    }
    let spec = oct.base().spec().clone();
    // The finest level with a stored node: no brick needs to be finer.
    let finest =
        (1..=oct.params().max_level).rev().find(|&l| oct.level_nodes(l).next().is_some()).unwrap_or(0);
    let per_level: Vec<[u32; 3]> = (0..=finest).map(|l| bricks_per_axis(&spec, cells, finest, l)).collect();

    // Bricks that hold a finer stored node in their closed box.
    let mut marked: HashSet<(u32, u64)> = HashSet::new();
    for m in 1..=finest {
        for (c, _) in oct.level_nodes(m) {
            for l in 0..m {
                let size = cells << (m - l);
                let range = |a: usize| {
                    let x = c[a];
                    let hi = (x / size).min(per_level[l as usize][a] - 1);
                    let lo = if x % size == 0 && x > 0 { (x / size - 1).min(hi) } else { hi };
                    lo..=hi
                };
                for z in range(2) {
                    for y in range(1) {
                        for x in range(0) {
                            marked.insert(brick_key(l, [x, y, z]));
                        }
                    }
                }
            }
        }
    }
    // Internal (refined) bricks: marked bricks above the finest level.
    let mut internal: HashSet<(u32, u64)> = marked.into_iter().filter(|&(l, _)| l < finest).collect();
    let refined = leaves(&internal, &per_level, finest);
    let floor = probe_bytes(per_level[0].iter().map(|&n| n as usize).product(), cells, oct.coeffs());
    if let Some(max) = params.max_probe_bytes
        && floor > max
    {
        return Err(VolumeError::InvalidData(format!(
            "a probe memory budget of {:.3} MiB is below the {:.3} MiB of the coarsest bricks; raise it or bake a coarser base grid",
            max as f64 / 1048576.0,
            floor as f64 / 1048576.0
        )));
    }
    let merged = merge_bricks(oct, cells, &per_level, finest, &mut internal, &refined, params);
    let bricks = leaves(&internal, &per_level, finest);
    // Probe values: the octree summed over the brick's levels, in half floats.
    let k = oct.coeffs() * 3;
    let p = cells + 1;
    let per = (p as usize).pow(3) * k;
    let mut data = vec![0.0f32; bricks.len() * per];
    data.par_chunks_mut(per).zip(&bricks).try_for_each(|(d, b)| -> Result<(), VolumeError> {
        let v = brick_values(oct, cells, *b);
        for (o, x) in d.iter_mut().zip(v) {
            *o = to_half(x)?;
        }
        Ok(())
    })?;
    let mut vol =
        BrickVolume::from_parts(spec, oct.coeffs(), cells, finest, bricks, data, oct.metadata().clone())?;
    let stitched_probes = if stitch_bricks { stitch(&mut vol)? } else { 0 };
    let report = BrickReport {
        bricks_per_level: vol.bricks_per_level(),
        refined_bricks: refined.len(),
        smooth_merges: merged.smooth,
        bricks_wanted: merged.wanted,
        merges: merged.budget,
        dropped_bricks: merged.wanted - vol.bricks.len(),
        largest_dropped_error: merged.largest,
        wanted_probe_bytes: probe_bytes(merged.wanted, cells, oct.coeffs()),
        probe_bytes: vol.probe_bytes(),
        stitched_probes,
    };
    Ok((vol, report))
}

/// `x` rounded to the nearest half float, as f32.
fn to_half(x: f64) -> Result<f32, VolumeError> {
    let h = half::f16::from_f64(x);
    if h.is_finite() {
        Ok(h.to_f32())
    } else {
        Err(VolumeError::InvalidData(format!(
            "a probe coefficient of {x:e} is beyond the half-float range of the brick atlas; scale the lighting down"
        )))
    }
}

/// The leaves under the level-0 bricks, in stream order: level-0 bricks in `(z, y, x)` order,
/// each followed depth-first by its subtree (children in order `dx + 2dy + 4dz`).
fn leaves(internal: &HashSet<(u32, u64)>, per_level: &[[u32; 3]], finest: u32) -> Vec<Brick> {
    fn visit(
        l: u32,
        c: [u32; 3],
        internal: &HashSet<(u32, u64)>,
        per_level: &[[u32; 3]],
        finest: u32,
        out: &mut Vec<Brick>,
    ) {
        if l < finest && internal.contains(&brick_key(l, c)) {
            let n = per_level[l as usize + 1];
            for q in 0..8u32 {
                let ch = [2 * c[0] + (q & 1), 2 * c[1] + ((q >> 1) & 1), 2 * c[2] + (q >> 2)];
                if (0..3).all(|a| ch[a] < n[a]) {
                    visit(l + 1, ch, internal, per_level, finest, out);
                }
            }
        } else {
            out.push(Brick { level: l, coords: c });
        }
    }
    let n0 = per_level[0];
    let mut out = Vec::new();
    for z in 0..n0[2] {
        for y in 0..n0[1] {
            for x in 0..n0[0] {
                visit(0, [x, y, z], internal, per_level, finest, &mut out);
            }
        }
    }
    out
}

/// The probes of brick `b` in f64: `Σ_{m ≤ level}` of the octree at its level-`level`
/// nodes (positions beyond the box clamp to it), `[probe][coeff][rgb]`.
fn brick_values(oct: &AdaptiveVolume, cells: u32, b: Brick) -> Vec<f64> {
    let k = oct.coeffs() * 3;
    let p = cells + 1;
    let res0 = oct.base().spec().res();
    let inv = 1.0 / f64::from(1u32 << b.level);
    let mut out = vec![0.0; (p as usize).pow(3) * k];
    let mut v = vec![0.0; k];
    for z in 0..p {
        for y in 0..p {
            for x in 0..p {
                let q = [x, y, z];
                // Exact: node coordinates over a power of two.
                let u0: [f64; 3] = std::array::from_fn(|a| {
                    (f64::from(b.coords[a] * cells + q[a]) * inv).min(f64::from(res0[a] - 1))
                });
                oct.sum_levels_f64(u0, b.level + 1, &mut v);
                let at = (x + p * (y + p * z)) as usize * k;
                out[at..at + k].copy_from_slice(&v);
            }
        }
    }
    out
}

/// Trilinear interpolation of brick probes `vals` (`[probe][coeff][rgb]`, `p` per axis) at
/// local coordinates `s ∈ [0, p − 1]³`.
fn interpolate<T: Copy + Into<f64>>(vals: &[T], p: usize, k: usize, s: [f64; 3]) -> Vec<f64> {
    let cell: [usize; 3] = std::array::from_fn(|a| (s[a].floor() as usize).min(p - 2));
    let w = corner_weights(std::array::from_fn(|a| s[a] - cell[a] as f64));
    let mut out = vec![0.0; k];
    for (c, &wc) in w.iter().enumerate() {
        let q = [cell[0] + (c & 1), cell[1] + ((c >> 1) & 1), cell[2] + (c >> 2)];
        let at = (q[0] + p * (q[1] + p * q[2])) * k;
        for (o, v) in out.iter_mut().zip(&vals[at..at + k]) {
            *o += wc * (*v).into();
        }
    }
    out
}

/// A merge candidate: a parent whose present children are all leaves, with the largest
/// irradiance the merge would lose. Ordered so that a max-heap pops the smallest error
/// first (ties: finer level first, then the smaller key).
struct Merge {
    error: f64,
    level: u32,
    key: u64,
}

impl PartialEq for Merge {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Merge {}
impl PartialOrd for Merge {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Merge {
    fn cmp(&self, o: &Self) -> Ordering {
        o.error.total_cmp(&self.error).then(self.level.cmp(&o.level)).then(o.key.cmp(&self.key))
    }
}

/// The present children of parent `(l, c)`.
fn children(l: u32, c: [u32; 3], per_level: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let n = per_level[l as usize + 1];
    (0..8u32)
        .map(|q| [2 * c[0] + (q & 1), 2 * c[1] + ((q >> 1) & 1), 2 * c[2] + (q >> 2)])
        .filter(|ch| (0..3).all(|a| ch[a] < n[a]))
        .collect()
}

/// The largest [`surplus_measure`] of a child probe minus the parent's interpolation there,
/// over the children of `(l, c)`, relative to the value scale.
fn merge_error(oct: &AdaptiveVolume, cells: u32, l: u32, c: [u32; 3], per_level: &[[u32; 3]]) -> f64 {
    let k = oct.coeffs() * 3;
    let p = cells as usize + 1;
    let parent = brick_values(oct, cells, Brick { level: l, coords: c });
    let mut worst = 0.0f64;
    for ch in children(l, c, per_level) {
        let vals = brick_values(oct, cells, Brick { level: l + 1, coords: ch });
        for z in 0..p {
            for y in 0..p {
                for x in 0..p {
                    let q = [x, y, z];
                    let s: [f64; 3] = std::array::from_fn(|a| {
                        f64::from(ch[a] * cells + q[a] as u32) * 0.5 - f64::from(c[a] * cells)
                    });
                    let interp = interpolate(&parent, p, k, s);
                    let at = (x + p * (y + p * z)) * k;
                    let d: Vec<f32> =
                        vals[at..at + k].iter().zip(&interp).map(|(a, b)| (a - b) as f32).collect();
                    worst = worst.max(surplus_measure(&d));
                }
            }
        }
    }
    worst / oct.value_scale()
}

/// What [`merge_bricks`] did.
struct Merged {
    /// Merges within the tolerance.
    smooth: usize,
    /// Bricks after them.
    wanted: usize,
    /// Merges the budget made after them.
    budget: usize,
    /// The largest relative error a budget merge lost.
    largest: f64,
}

/// Merges sibling leaves into their parents, least useful first: every merge that loses at
/// most `params.merge_tolerance`, then more until the leaves' probe bytes fit
/// `params.max_probe_bytes`.
fn merge_bricks(
    oct: &AdaptiveVolume,
    cells: u32,
    per_level: &[[u32; 3]],
    finest: u32,
    internal: &mut HashSet<(u32, u64)>,
    refined: &[Brick],
    params: &BrickParams,
) -> Merged {
    let coeffs = oct.coeffs();
    let leaf_parent = |l: u32, c: [u32; 3], internal: &HashSet<(u32, u64)>| {
        l < finest && children(l, c, per_level).iter().all(|ch| !internal.contains(&brick_key(l + 1, *ch)))
    };
    let mut parents: Vec<(u32, [u32; 3])> = refined
        .iter()
        .filter(|b| b.level > 0)
        .map(|b| (b.level - 1, b.coords.map(|x| x / 2)))
        .filter(|&(l, c)| leaf_parent(l, c, internal))
        .collect();
    parents.sort_unstable_by_key(|&(l, c)| brick_key(l, c));
    parents.dedup();
    let mut heap: BinaryHeap<Merge> = parents
        .par_iter()
        .map(|&(l, c)| Merge { error: merge_error(oct, cells, l, c, per_level), level: l, key: pack_key(c) })
        .collect::<Vec<_>>()
        .into();
    let mut count = refined.len();
    let mut out = Merged { smooth: 0, wanted: count, budget: 0, largest: 0.0 };
    let over =
        |count: usize| params.max_probe_bytes.is_some_and(|max| probe_bytes(count, cells, coeffs) > max);
    loop {
        let smooth = heap.peek().is_some_and(|m| m.error <= params.merge_tolerance);
        if !smooth && !over(count) {
            break;
        }
        let Some(m) = heap.pop() else { break };
        let c = unpack_key(m.key);
        internal.remove(&brick_key(m.level, c));
        count = count + 1 - children(m.level, c, per_level).len();
        if smooth {
            out.smooth += 1;
            out.wanted = count;
        } else {
            out.budget += 1;
            out.largest = out.largest.max(m.error);
        }
        if m.level > 0 {
            let (gl, gc) = (m.level - 1, c.map(|x| x / 2));
            if leaf_parent(gl, gc, internal) {
                heap.push(Merge {
                    error: merge_error(oct, cells, gl, gc, per_level),
                    level: gl,
                    key: pack_key(gc),
                });
            }
        }
    }
    out
}

/// Stitches every brick's boundary probes to its coarsest neighbour (module docs), coarse
/// levels first; returns the number of probes changed.
fn stitch(vol: &mut BrickVolume) -> Result<usize, VolumeError> {
    let cells = vol.cells;
    let p = cells + 1;
    let k = vol.coeffs * 3;
    let res = vol.indirection_res;
    let finest = vol.finest;
    let mut changed = 0usize;
    for level in 1..=finest {
        let updates: Vec<(usize, Vec<f32>)> = (0..vol.bricks.len())
            .into_par_iter()
            .filter(|&i| vol.bricks[i].level == level)
            .map(|i| -> Result<Vec<(usize, Vec<f32>)>, VolumeError> {
                let b = vol.bricks[i];
                let span = 1u32 << (finest - level);
                let mut out = Vec::new();
                for z in 0..p {
                    for y in 0..p {
                        for x in 0..p {
                            let q = [x, y, z];
                            if q.iter().all(|&v| v > 0 && v < cells) {
                                continue;
                            }
                            // Position in level-`level` node units, and in texel units ×cells.
                            let n: [u32; 3] = std::array::from_fn(|a| b.coords[a] * cells + q[a]);
                            let t_num: [u64; 3] = std::array::from_fn(|a| u64::from(n[a]) * u64::from(span));
                            let axis_texels = |a: usize| -> Vec<u32> {
                                let tc = t_num[a] / u64::from(cells);
                                let on_edge = t_num[a].is_multiple_of(u64::from(cells));
                                // Texels beyond the grid clamp to its last one.
                                let last = u64::from(res[a] - 1);
                                let mut v = Vec::with_capacity(2);
                                if on_edge && tc > 0 {
                                    v.push((tc - 1).min(last) as u32);
                                }
                                v.push(tc.min(last) as u32);
                                v.dedup();
                                v
                            };
                            let (tx, ty, tz) = (axis_texels(0), axis_texels(1), axis_texels(2));
                            let mut coarsest: Option<usize> = None;
                            for &zz in &tz {
                                for &yy in &ty {
                                    for &xx in &tx {
                                        let j = vol.indirection[texel_index(res, [xx, yy, zz])] as usize;
                                        let better = match coarsest {
                                            None => true,
                                            Some(c) => (vol.bricks[j].level, j) < (vol.bricks[c].level, c),
                                        };
                                        if better {
                                            coarsest = Some(j);
                                        }
                                    }
                                }
                            }
                            let Some(j) = coarsest else { continue };
                            let nb = vol.bricks[j];
                            if nb.level >= level {
                                continue;
                            }
                            let down = f64::from(1u32 << (level - nb.level));
                            let s: [f64; 3] = std::array::from_fn(|a| {
                                (f64::from(n[a]) / down - f64::from(nb.coords[a] * cells))
                                    .clamp(0.0, f64::from(cells))
                            });
                            let v = interpolate(vol.brick_data(j), p as usize, k, s);
                            let at = (x + p * (y + p * z)) as usize * k;
                            let own = &vol.brick_data(i)[at..at + k];
                            let new: Vec<f32> = v.into_iter().map(to_half).collect::<Result<_, _>>()?;
                            if new.iter().zip(own).any(|(a, b)| a.to_bits() != b.to_bits()) {
                                out.push((i * vol.brick_values() + at, new));
                            }
                        }
                    }
                }
                Ok(out)
            })
            .collect::<Result<Vec<_>, _>>()?
            .into_iter()
            .flatten()
            .collect();
        changed += updates.len();
        for (at, v) in updates {
            vol.data[at..at + v.len()].copy_from_slice(&v);
        }
    }
    Ok(changed)
}
