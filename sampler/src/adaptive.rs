//! Adaptive bakes (Oat, *Irradiance Volumes for Games*, \[Oat05\], "Adaptive Octree
//! Subdivision" to "Adaptive Subdivision"): the three subdivision heuristics and the
//! domain-of-interest bake of each level, driving lightvol-volume's
//! [`lightvol_volume::build_adaptive`].
//!
//! ## Levels
//! Level 0 is the ordinary [`bake`] of the base grid (with lightvol-volume's zero-weight
//! fill). The nodes a split creates at level `l` are baked by the same estimator on the
//! level-`l` grid (cell size `base / 2^l`, so each node keeps the prefilter support of its
//! level), restricted to the cells around those nodes
//! ([`bake_units`](crate::bake::bake_units)): every node gets the sums a full bake of that
//! grid would give it, bit for bit. A node with no sample in the domain of interest keeps
//! the coarser levels' interpolation.
//!
//! ## Heuristics (\[Oat05\], "Subdivision Heuristics"), each with a threshold
//! A leaf cell of level `l` is split when any enabled heuristic fires:
//! 1. **Gradient**: the change of the field across the cell, `corner_change` (the largest
//!    coefficient difference along the cell's 12 edges relative to the volume's value
//!    scale, i.e. `|∇c|·h`), is at least `gradient_threshold`.
//! 2. **Geometry inside the voxel** (\[Oat05\] citing \[GSHG98\]): a scene triangle overlaps the
//!    closed cell box, decided exactly by the separating-axis test ([`triangle_box_overlap`];
//!    13 axes).
//! 3. **Harmonic mean of scene depth** (\[Oat05\] citing \[PH04\]): from each corner,
//!    `depth_rays` seeded uniform rays; `H = N / Σ 1/d_i` (misses contribute 0); the cell
//!    splits when its edge exceeds `depth_ratio_threshold · H` at some corner ("if the
//!    neighboring irradiance samples are further away than this upper-bound, their voxels
//!    should be subdivided").
//!    Corners inside solids (more than half of their rays meet back faces, Kontkanen &
//!    Laine 2006 §5) do not vote: they are outside the domain of interest.
//!
//! ## Placement boxes
//! The user's boxes ([`AdaptiveSettings::regions`]) then override the heuristics, as the
//! engines' density and exclusion volumes do: with walkable boxes, cells that overlap none
//! of them are not split ("probes only where the player can go"); cells inside an exclusion
//! box are not split; cells that overlap a density box of a finer level are split whatever
//! the heuristics say, and the nodes those splits create are never culled.
//!
//! The split score handed to the builder is `1 + gradient_ratio` for a cell that splits and
//! 0 otherwise (`+∞` for a density box's split). A memory budget is met afterwards by lightvol-volume, which raises the cull
//! tolerance until the tree fits (\[Oat05\]'s "discard redundant samples"; see
//! `lightvol_volume::adaptive::build`).
//!
//! **Determinism**: every ray is seeded per (level, node, ray), every bake per cell, and all
//! reductions run in a fixed order: results are bit-identical for any thread count.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;
use lightvol_sh::lowdisc::hash2;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::adaptive::{level_grid, pack_key};
use lightvol_volume::{
    Accumulator, AdaptiveVolume, BuildError, Candidates, GridSpec, LevelSamples, build_adaptive,
};
use rayon::prelude::*;

use crate::adaptive_regions::GridRegions;
use crate::adaptive_shard::{LevelSums, plan_hash};
use crate::bake::{BakeOutput, bake, bake_units_fixed};
use crate::error::BakeError;
use crate::method::Method;
use crate::settings::BakeSettings;
use crate::stats::BakeStats;
use lightvol_core::progress::{BakeControl, Progress};
use lightvol_scene::bvh::Tracer;
use lightvol_scene::qmc::Qmc;
use lightvol_scene::stats::RayCounts;
use lightvol_scene::transport::Transport;

/// Settings of an adaptive bake: lightvol-volume's [`OctreeSettings`](lightvol_volume::adaptive::OctreeSettings),
/// the one definition (every octree file records them).
pub use lightvol_volume::adaptive::OctreeSettings as AdaptiveSettings;

/// What an adaptive bake reports besides the volume.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AdaptiveStats {
    /// The level-0 bake.
    pub base: BakeStats,
    /// The bakes of levels `1..=max_level` (index `l - 1`; a level with several rounds
    /// sums them).
    pub levels: Vec<BakeStats>,
    /// Rays of the depth heuristic.
    pub depth_rays: u64,
    /// All rays (bakes and heuristics).
    pub rays: RayCounts,
    /// Cells each heuristic asked to split: `[gradient, geometry, depth]` (a cell may count
    /// under several).
    pub split_votes: [usize; 3],
    /// Wall time of the whole bake.
    pub wall_time: Duration,
}

/// Bytes of `nodes` uniform nodes of `coeffs` RGB coefficients with their f32 weights (what
/// a uniform volume of them stores): an octree's memory budget stated as a node count.
#[must_use]
pub fn node_budget_bytes(nodes: u64, coeffs: usize) -> u128 {
    u128::from(nodes) * (3 * coeffs as u128 + 1) * 4
}

/// Harmonic mean of the hit distances of `rays` seeded uniform rays from `x` (stream
/// `stream`), `H = N / Σ 1/d_i` with misses contributing 0 (`INFINITY` when nothing is
/// hit), and whether more than half of the rays met back faces (`x` inside a solid).
#[must_use]
pub fn harmonic_mean_depth(tracer: &Tracer, x: DVec3, rays: u32, seed: u64, stream: u64) -> (f64, bool) {
    let h = Qmc::<2>::new(seed, stream);
    let (mut inv, mut back) = (0.0f64, 0u32);
    for i in 0..u64::from(rays) {
        let d = DVec3::from_array(sample_uniform_sphere(h.point(i)));
        if let Some(hit) = tracer.closest_hit(x, d, 0.0, f64::INFINITY) {
            back += u32::from(hit.back_face);
            inv += 1.0 / hit.t.max(f64::MIN_POSITIVE);
        }
    }
    let hm = if inv > 0.0 { f64::from(rays) / inv } else { f64::INFINITY };
    (hm, 2 * back > rays)
}

/// Whether the triangle `t` overlaps the closed box `[lo, hi]`: the separating-axis test of
/// Akenine-Möller (2001), axes = the 3 box normals, the triangle normal and the 9 cross
/// products of box and triangle edges, in f64.
#[must_use]
pub fn triangle_box_overlap(t: &[DVec3; 3], lo: DVec3, hi: DVec3) -> bool {
    let c = (lo + hi) * 0.5;
    let e = (hi - lo) * 0.5;
    let v = [t[0] - c, t[1] - c, t[2] - c];
    let separated = |axis: DVec3| -> bool {
        if axis.length_squared() == 0.0 {
            return false;
        }
        let p = [v[0].dot(axis), v[1].dot(axis), v[2].dot(axis)];
        let r = e.x * axis.x.abs() + e.y * axis.y.abs() + e.z * axis.z.abs();
        p[0].min(p[1]).min(p[2]) > r || p[0].max(p[1]).max(p[2]) < -r
    };
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let box_axes = [DVec3::X, DVec3::Y, DVec3::Z];
    if box_axes.iter().any(|&a| separated(a)) || separated(edges[0].cross(edges[1])) {
        return false;
    }
    !box_axes.iter().any(|&a| edges.iter().any(|&ed| separated(a.cross(ed))))
}

/// For each candidate cell (level-grid coordinates, sorted by key), whether a triangle
/// (grid space) overlaps it.
fn cells_with_geometry(tris: &[[DVec3; 3]], grid: &GridSpec, cells: &[[u32; 3]]) -> Vec<bool> {
    let keys: Vec<u64> = cells.iter().map(|&c| pack_key(c)).collect();
    let (min, _) = grid.bounds();
    let cs = grid.cell_size();
    let res = grid.res();
    let mut hits: Vec<usize> = tris
        .par_iter()
        .flat_map_iter(|t| {
            let tlo = t[0].min(t[1]).min(t[2]).to_array();
            let thi = t[0].max(t[1]).max(t[2]).to_array();
            // Cell range whose closed boxes can touch the triangle's bounding box.
            let mut r = [[0u32; 2]; 3];
            let mut empty = false;
            for a in 0..3 {
                let top = f64::from(res[a] - 2);
                let l = ((tlo[a] - min[a]) / cs[a]).ceil() - 1.0;
                let h = ((thi[a] - min[a]) / cs[a]).floor();
                if h < 0.0 || l > top {
                    empty = true;
                }
                r[a] = [l.clamp(0.0, top) as u32, h.clamp(0.0, top) as u32];
            }
            let span: u64 = (0..3).map(|a| u64::from(r[a][1] - r[a][0] + 1)).product();
            let test = |i: usize| {
                let c = cells[i];
                let lo = DVec3::from_array(grid.node_position(c[0], c[1], c[2]));
                let hi = DVec3::from_array(grid.node_position(c[0] + 1, c[1] + 1, c[2] + 1));
                triangle_box_overlap(t, lo, hi)
            };
            let found: Vec<usize> = if empty {
                Vec::new()
            } else if span <= keys.len() as u64 {
                let mut v = Vec::new();
                for k in r[2][0]..=r[2][1] {
                    for j in r[1][0]..=r[1][1] {
                        for i in r[0][0]..=r[0][1] {
                            if let Ok(idx) = keys.binary_search(&pack_key([i, j, k]))
                                && test(idx)
                            {
                                v.push(idx);
                            }
                        }
                    }
                }
                v
            } else {
                (0..cells.len())
                    .filter(|&idx| {
                        (0..3).all(|a| cells[idx][a] >= r[a][0] && cells[idx][a] <= r[a][1]) && test(idx)
                    })
                    .collect()
            };
            found
        })
        .collect();
    hits.sort_unstable();
    hits.dedup();
    let mut out = vec![false; cells.len()];
    for i in hits {
        out[i] = true;
    }
    out
}

/// The units (cells, or nodes for point sampling) of the level grid a bake of `nodes`
/// needs: every cell that has one of the nodes as a corner.
fn units_for(grid: &GridSpec, method: Method, nodes: &[[u32; 3]]) -> Vec<usize> {
    let res = grid.res();
    let mut units: Vec<usize> = match method {
        Method::Point | Method::DoiNode | Method::Doi => {
            nodes.iter().map(|n| grid.node_index(n[0], n[1], n[2])).collect()
        }
        Method::Prefilter | Method::DoiPaper => nodes
            .iter()
            .flat_map(|n| {
                (0..8u32).filter_map(move |q| {
                    let d = [q & 1, (q >> 1) & 1, q >> 2];
                    let c: [i64; 3] = std::array::from_fn(|a| i64::from(n[a]) - i64::from(d[a]));
                    (0..3)
                        .all(|a| c[a] >= 0 && c[a] < i64::from(res[a]) - 1)
                        .then(|| grid.cell_index(c[0] as u32, c[1] as u32, c[2] as u32))
                })
            })
            .collect(),
    };
    units.sort_unstable();
    units.dedup();
    units
}

/// Bakes an adaptive volume (module docs): the base grid with [`bake`], then level by level
/// the nodes that the heuristics' splits create. `settings.shard` must be `(0, 1)` (shard an
/// adaptive bake level by level: [`crate::adaptive_shard`]).
/// Progress counts units (cells) baked so far against units planned so far (the total
/// grows as levels are planned).
///
/// # Errors
/// [`BakeError::Settings`] for invalid settings or a memory budget below the base level,
/// [`BakeError::Volume`] for grids the volume crate rejects, [`BakeError::Cancelled`].
pub fn bake_adaptive(
    transport: &Transport<'_>,
    base_grid: &GridSpec,
    settings: &BakeSettings,
    adaptive: &AdaptiveSettings,
    control: &BakeControl<'_>,
) -> Result<(AdaptiveVolume, AdaptiveStats), BakeError> {
    match drive(transport, base_grid, settings, adaptive, &Source::Whole, control)? {
        Driven::Volume(b) => Ok(*b),
        Driven::Level(_) => unreachable!("a whole bake never stops at a level"),
    }
}

/// One shard of refinement level `level` (≥ 1) of a sharded adaptive bake
/// ([`crate::adaptive_shard`]): replays the builder on `base` (the merged level-0 sums, from
/// a sharded [`bake`] of `base_grid` with `settings`) and `levels` (the merged sums of levels
/// `1..level`, in order), then bakes shard `shard` of level `level`'s units. A level the
/// builder does not reach (nothing split below it) gives [`LevelSums::nothing_to_refine`].
///
/// # Errors
/// As [`bake_adaptive`], and [`BakeError::Settings`] when `levels` are not levels
/// `1..level`, when `base` is not on `base_grid`, or when a level's plan differs from the
/// replay's (its shards were baked from other inputs).
#[allow(clippy::too_many_arguments, reason = "the bake's inputs, plus what the level replays")]
pub fn bake_adaptive_level_shard(
    transport: &Transport<'_>,
    base_grid: &GridSpec,
    settings: &BakeSettings,
    adaptive: &AdaptiveSettings,
    base: &Accumulator,
    levels: &[LevelSums],
    level: u32,
    shard: (u32, u32),
    control: &BakeControl<'_>,
) -> Result<LevelSums, BakeError> {
    if level == 0 || level > adaptive.max_level {
        return Err(BakeError::Settings(format!(
            "refinement level {level} is not in 1..={}",
            adaptive.max_level
        )));
    }
    if levels.len() != level as usize - 1 {
        return Err(BakeError::Settings(format!(
            "level {level} needs the merged sums of levels 1..{level}, got {} level(s)",
            levels.len()
        )));
    }
    if shard.1 == 0 || shard.0 >= shard.1 {
        return Err(BakeError::Settings(format!("shard {} of {}", shard.0, shard.1)));
    }
    let source =
        Source::Replay { base, base_stats: BakeStats::default(), levels, target: Some((level, shard)) };
    match drive(transport, base_grid, settings, adaptive, &source, control)? {
        Driven::Level(l) => Ok(*l),
        Driven::Volume(_) => Ok(LevelSums::nothing_to_refine(level, settings.coeffs * 3)),
    }
}

/// Assembles a sharded adaptive bake: replays the builder on `base` (merged level-0 sums,
/// whose bake statistics were `base_stats`) and `levels` (the merged sums of levels `1..`,
/// in order, as far as the builder refines). The volume equals [`bake_adaptive`]'s bit for
/// bit.
///
/// # Errors
/// As [`bake_adaptive_level_shard`], and [`BakeError::Settings`] naming the first level the
/// builder needs that `levels` lacks, or a level with units the builder never reaches.
#[allow(clippy::too_many_arguments, reason = "the bake's inputs, plus what the assembly replays")]
pub fn assemble_adaptive(
    transport: &Transport<'_>,
    base_grid: &GridSpec,
    settings: &BakeSettings,
    adaptive: &AdaptiveSettings,
    base: &Accumulator,
    base_stats: BakeStats,
    levels: &[LevelSums],
    control: &BakeControl<'_>,
) -> Result<(AdaptiveVolume, AdaptiveStats), BakeError> {
    if levels.len() > adaptive.max_level as usize {
        return Err(BakeError::Settings(format!(
            "{} refinement levels given for --max-level {}",
            levels.len(),
            adaptive.max_level
        )));
    }
    let source = Source::Replay { base, base_stats, levels, target: None };
    match drive(transport, base_grid, settings, adaptive, &source, control)? {
        Driven::Volume(b) => Ok(*b),
        Driven::Level(_) => unreachable!("an assembly never stops at a level"),
    }
}

/// Where the levels of [`drive`] come from.
#[allow(clippy::large_enum_variant, reason = "one value per adaptive bake, made once")]
enum Source<'a> {
    /// Bake every level.
    Whole,
    /// Replay merged sums; with a target, bake that shard of that level and stop.
    Replay {
        base: &'a Accumulator,
        base_stats: BakeStats,
        levels: &'a [LevelSums],
        target: Option<(u32, (u32, u32))>,
    },
}

/// What [`drive`] ends with.
enum Driven {
    Volume(Box<(AdaptiveVolume, AdaptiveStats)>),
    Level(Box<LevelSums>),
}

/// Why the builder's callbacks stopped it.
enum Halt {
    Bake(BakeError),
    Stop(Box<LevelSums>),
}

impl From<BakeError> for Halt {
    fn from(e: BakeError) -> Self {
        Self::Bake(e)
    }
}

/// The adaptive bake of [`bake_adaptive`], its level shards and its assembly.
fn drive(
    transport: &Transport<'_>,
    base_grid: &GridSpec,
    settings: &BakeSettings,
    adaptive: &AdaptiveSettings,
    source: &Source<'_>,
    control: &BakeControl<'_>,
) -> Result<Driven, BakeError> {
    adaptive.validate().map_err(|e| BakeError::Settings(e.to_string()))?;
    if settings.shard != (0, 1) {
        return Err(BakeError::Settings(
            "an adaptive bake is sharded level by level (adaptive_shard), not by settings.shard".into(),
        ));
    }
    let k = settings.coeffs * 3;
    let start = Instant::now();
    let done = AtomicUsize::new(0);
    let planned = AtomicUsize::new(match settings.method {
        Method::Point | Method::DoiNode | Method::Doi => base_grid.node_count(),
        Method::Prefilter | Method::DoiPaper => base_grid.cell_count(),
    });
    let offset_progress = |p: Progress| {
        let d = done.load(Ordering::Relaxed);
        control.report(Progress { done: d + p.done, total: planned.load(Ordering::Relaxed) });
    };
    let inner = BakeControl { progress: Some(&offset_progress), cancel: control.cancel };
    let (base, base_stats) = match source {
        Source::Whole => bake(transport, base_grid, settings, &inner)?.finish(),
        Source::Replay { base, base_stats, levels, .. } => {
            if !base.spec().same_nodes(base_grid) || base.coeffs() != settings.coeffs {
                return Err(BakeError::Settings(
                    "the level-0 sums are not on the bake's grid and coefficient count".into(),
                ));
            }
            if let Some((i, l)) = levels.iter().enumerate().find(|(i, l)| l.level != *i as u32 + 1) {
                return Err(BakeError::Settings(format!(
                    "refinement sums out of order: level {} given as the {}. level",
                    l.level,
                    i + 1
                )));
            }
            BakeOutput { accumulator: (*base).clone(), stats: base_stats.clone(), node_error: Vec::new() }
                .finish()
        }
    };
    done.fetch_add(planned.load(Ordering::Relaxed), Ordering::Relaxed);
    let mut used_levels = 0usize;

    let tracer = transport.tracer();
    let tris: Vec<[DVec3; 3]> = if adaptive.geometry {
        transport
            .scene()
            .world_triangles()
            .map(|t| t.v.map(|p| DVec3::from_array(base_grid.to_grid(p.to_array()))))
            .collect()
    } else {
        Vec::new()
    };
    let mut stats = AdaptiveStats {
        base: base_stats,
        levels: vec![BakeStats::default(); adaptive.max_level as usize],
        ..AdaptiveStats::default()
    };
    let mut regions = GridRegions::new(base_grid, &adaptive.regions);
    let mut votes = [0usize; 3];
    let mut depth_rays = 0u64;

    let score = |c: &Candidates<'_>| -> Result<Vec<f64>, Halt> {
        let cells = c.cells();
        let grid = c.grid();
        let grad: Vec<f64> = match adaptive.gradient_threshold {
            Some(t) => (0..cells.len()).map(|i| c.corner_change(i) / t).collect(),
            None => vec![0.0; cells.len()],
        };
        let geom = if adaptive.geometry {
            cells_with_geometry(&tris, grid, cells)
        } else {
            vec![false; cells.len()]
        };
        let depth_fires: Vec<bool> = match adaptive.depth_ratio_threshold {
            Some(ratio) => {
                let mut nodes: Vec<[u32; 3]> = cells
                    .iter()
                    .flat_map(|&cl| {
                        (0..8u32).map(move |q| [cl[0] + (q & 1), cl[1] + ((q >> 1) & 1), cl[2] + (q >> 2)])
                    })
                    .collect();
                nodes.sort_unstable_by_key(|&n| pack_key(n));
                nodes.dedup();
                let level = u64::from(c.level());
                let hm: Vec<(f64, bool)> = nodes
                    .par_iter()
                    .map(|n| {
                        let x = DVec3::from_array(grid.node_position_world(n[0], n[1], n[2]));
                        harmonic_mean_depth(
                            tracer,
                            x,
                            adaptive.depth_rays,
                            settings.seed,
                            hash2(level, pack_key(*n)),
                        )
                    })
                    .collect();
                depth_rays += nodes.len() as u64 * u64::from(adaptive.depth_rays);
                // World edge lengths of a cell (placement applied).
                let o = DVec3::from_array(grid.node_position_world(0, 0, 0));
                let edge = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
                    .iter()
                    .map(|d| (DVec3::from_array(grid.node_position_world(d[0], d[1], d[2])) - o).length())
                    .fold(0.0f64, f64::max);
                cells
                    .iter()
                    .map(|&cl| {
                        (0..8u32).any(|q| {
                            let n = [cl[0] + (q & 1), cl[1] + ((q >> 1) & 1), cl[2] + (q >> 2)];
                            let i = nodes
                                .binary_search_by_key(&pack_key(n), |&m| pack_key(m))
                                .expect("corner listed");
                            let (h, inside_solid) = hm[i];
                            !inside_solid && edge > ratio * h
                        })
                    })
                    .collect()
            }
            None => vec![false; cells.len()],
        };
        if control.cancelled() {
            return Err(BakeError::Cancelled.into());
        }
        Ok((0..cells.len())
            .map(|i| {
                let fires = [grad[i] >= 1.0, geom[i], depth_fires[i]];
                for (v, &f) in votes.iter_mut().zip(&fires) {
                    *v += usize::from(f);
                }
                let score = if fires.iter().any(|&f| f) { 1.0 + grad[i] } else { 0.0 };
                regions.score(c.level(), grid, cells[i], score)
            })
            .collect())
    };

    let mut level_stats = vec![BakeStats::default(); adaptive.max_level as usize];
    let bake_nodes = |level: u32, nodes: &[[u32; 3]]| -> Result<LevelSamples, Halt> {
        let grid = level_grid(base_grid, level).map_err(|e| BakeError::Volume(e.to_string()))?;
        let units = units_for(&grid, settings.method, nodes);
        let plan = plan_hash(&units);
        let (fixed, st) = match source {
            Source::Whole => {
                planned.fetch_add(units.len(), Ordering::Relaxed);
                bake_units_fixed(transport, &grid, settings, &units, &inner)?
            }
            Source::Replay { levels, target, .. } => match levels.get(level as usize - 1) {
                Some(l) => {
                    if (l.plan, l.units) != (plan, units.len() as u64) || l.k != k {
                        return Err(BakeError::Settings(format!(
                            "the level-{level} sums were baked for another plan ({} units, plan {:016x}; this replay plans {} units, plan {plan:016x}): bake them from the same lower levels",
                            l.units,
                            l.plan,
                            units.len()
                        ))
                        .into());
                    }
                    used_levels = used_levels.max(level as usize);
                    (l.sums.clone(), BakeStats { rays: l.rays, ..BakeStats::default() })
                }
                None => match target {
                    Some((t, shard)) if *t == level => {
                        let r = lightvol_core::shard::shard_range(units.len(), *shard);
                        planned.fetch_add(r.len(), Ordering::Relaxed);
                        let (sums, st) = bake_units_fixed(transport, &grid, settings, &units[r], &inner)?;
                        return Err(Halt::Stop(Box::new(LevelSums {
                            level,
                            plan,
                            units: units.len() as u64,
                            k,
                            sums,
                            rays: st.rays,
                        })));
                    }
                    _ => {
                        return Err(BakeError::Settings(format!(
                            "no sums of refinement level {level} among the inputs (the builder refines {} units there)",
                            units.len()
                        ))
                        .into());
                    }
                },
            },
        };
        let sums = fixed.to_subset();
        done.fetch_add(units.len(), Ordering::Relaxed);
        let ls = &mut level_stats[level as usize - 1];
        ls.add_counts(&st);
        ls.wall_time += st.wall_time;
        let mut out = LevelSamples {
            values: Vec::with_capacity(nodes.len() * k),
            weights: Vec::with_capacity(nodes.len()),
        };
        for n in nodes {
            let flat = grid.node_index(n[0], n[1], n[2]);
            match sums.find(flat) {
                Some(i) if sums.denominator[i] > 0.0 && sums.denominator[i].is_finite() => {
                    let d = sums.denominator[i];
                    let vals = sums.numerator[i * k..(i + 1) * k].iter().map(|v| v / d);
                    let w = d / (d + sums.outside[i]);
                    let before = out.values.len();
                    out.values.extend(vals);
                    if out.values[before..].iter().all(|v| v.is_finite()) {
                        out.weights.push(w);
                    } else {
                        out.values[before..].fill(0.0);
                        out.weights.push(0.0);
                    }
                }
                _ => {
                    out.values.extend(std::iter::repeat_n(0.0, k));
                    out.weights.push(0.0);
                }
            }
        }
        Ok(out)
    };

    let vol = match build_adaptive(base, &adaptive.params(), score, bake_nodes) {
        Ok(v) => v,
        Err(BuildError::Callback(Halt::Stop(l))) => return Ok(Driven::Level(l)),
        Err(BuildError::Callback(Halt::Bake(b))) => return Err(b),
        Err(BuildError::Volume(v)) => return Err(BakeError::Settings(v.to_string())),
    };
    if let Source::Replay { levels, target: None, .. } = source {
        let used = used_levels;
        if let Some(l) = levels[used..].iter().find(|l| l.units > 0) {
            return Err(BakeError::Settings(format!(
                "the level-{} sums refine {} units, but this replay stops at level {used}: they were baked from other inputs",
                l.level, l.units
            )));
        }
    }
    stats.split_votes = votes;
    stats.depth_rays = depth_rays;
    stats.levels = level_stats;
    stats.rays = stats.base.rays;
    for l in &stats.levels {
        stats.rays.add(&l.rays);
    }
    stats.rays.query += depth_rays;
    stats.wall_time = start.elapsed();
    Ok(Driven::Volume(Box::new((vol, stats))))
}

#[cfg(test)]
#[path = "adaptive_tests.rs"]
mod tests;
