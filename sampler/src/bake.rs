//! The bake methods, accumulating into [`lightvol_volume::Accumulator`]: the three of
//! Kontkanen & Laine 2006 and two that keep their domain of interest with a narrower support:
//!
//! - [`Method::Point`]: Eq. 4 at every node, `samples` uniform directions per node;
//! - [`Method::Prefilter`]: Eq. 5-6 with origins uniform in each cell and no domain test (an
//!   ablation: it blurs, but darkness inside solids still leaks);
//! - [`Method::DoiPaper`]: Eq. 5-6 restricted to the domain of interest by Algorithm 2;
//! - [`Method::DoiNode`]: Algorithm 2 over the node's own cell;
//! - [`Method::Doi`] (the default): Eq. 4 at the node where the node is in the domain of
//!   interest, at a relocated point where it is not, and from its neighbours where neither
//!   is ([`ProbeCapture`]).
//!
//! Origins and directions come from one 5-D Owen-scrambled Halton sequence per cell
//! (dimensions 0-2 the position in the cell, 3-4 the direction), scrambled and rotated per
//! cell so cells are decorrelated ([`Qmc`]). Each sample's radiance is one path ([`Transport`]); when
//! `light_sampling` is on, each sample also carries one light sample at its origin,
//! MIS-weighted against the uniform sphere density 1/4π, so suns and punctual lights reach
//! the probes (uniform directions alone would almost never hit a small sun, and never a
//! delta light).
//!
//! **Determinism.** Work is split in units (cells, or nodes for point sampling), processed in
//! parallel in chunks; each unit's samples use only per-(unit, sample) random streams; the
//! results are fed into the accumulator strictly in unit order. Any thread count therefore
//! gives bit-identical sums. Shard `k` of `n` takes a contiguous range of units
//! ([`lightvol_core::shard::shard_range`]); the accumulator's sums are exact fixed-point integers
//! (lightvol-volume's `fixed`), so merging shards in any order gives the whole bake's bits.

use std::f64::consts::PI;
use std::sync::atomic::Ordering;
use std::time::Instant;

use glam::DVec3;
use lightvol_sh::eval::eval_into;
use lightvol_sh::index::bands_of;
use lightvol_sh::lowdisc::hash2;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::accumulator::add_terms;
use lightvol_volume::fixed::FixedSums;
use lightvol_volume::{Accumulator, GridSpec, IrradianceVolume};
use rayon::prelude::*;

use crate::domain::{Retest, classify_cell};
use crate::error::BakeError;
use crate::method::Method;
use crate::stats::BakeStats;
use lightvol_core::progress::{BakeControl, Progress};
use lightvol_scene::qmc::Qmc;
use lightvol_scene::transport::{PathRng, Transport};

/// Bake settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeSettings {
    /// Estimator.
    pub method: Method,
    /// Candidates per cell (prefilter, doi-paper), per node (doi-node, and doi's support),
    /// or directions per node (point, doi).
    pub samples: u32,
    /// SH coefficients per channel (4, 9 or 16).
    pub coeffs: usize,
    /// Seed of every random stream.
    pub seed: u64,
    /// One light sample per probe sample (next-event estimation at the probe, MIS).
    pub light_sampling: bool,
    /// Shard `(k, n)`: this bake covers units `k·U/n .. (k+1)·U/n`.
    pub shard: (u32, u32),
    /// Units per parallel chunk (progress and cancellation granularity).
    pub chunk: usize,
}

impl Default for BakeSettings {
    fn default() -> Self {
        Self {
            method: Method::Doi,
            samples: 256,
            coeffs: 9,
            seed: 0,
            light_sampling: true,
            shard: (0, 1),
            chunk: 256,
        }
    }
}

/// A finished (shard of a) bake.
#[derive(Clone, Debug)]
pub struct BakeOutput {
    /// The Eq. 6 sums; merge shards with [`Accumulator::merge`], then `finalize`.
    pub accumulator: Accumulator,
    /// Counters and timing.
    pub stats: BakeStats,
}

impl BakeOutput {
    /// Finalizes the volume (Eq. 6 division and lightvol-volume's zero-weight fill) and
    /// records the fill in the statistics.
    #[must_use]
    pub fn finish(mut self) -> (IrradianceVolume, BakeStats) {
        let zero = self.accumulator.denominator().iter().filter(|&&d| !(d > 0.0)).count();
        let (volume, report) = self.accumulator.finalize();
        self.stats.zero_weight_nodes = zero as u64;
        self.stats.fill_report = format!("{report:?}");
        (volume, self.stats)
    }
}

/// One sample's contribution: trilinear weights of its origin for the unit's 8 nodes, and
/// up to two directional terms `(direction, radiance / pdf)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SampleOut {
    pub(crate) weights: [f64; 8],
    pub(crate) terms: [(DVec3, [f64; 3]); 2],
    pub(crate) n_terms: u8,
}

/// One unit's (cell's or node's) samples and counters.
#[derive(Debug, Default)]
pub(crate) struct UnitOut {
    pub(crate) nodes: [usize; 8],
    pub(crate) samples: Vec<SampleOut>,
    rejected: Vec<[f64; 8]>,
    stats: BakeStats,
    /// [`Method::Doi`]: the point a node outside the domain was relocated to.
    pub(crate) relocated: Option<DVec3>,
}

/// Density of uniform sphere directions.
const UNIFORM_SPHERE_PDF: f64 = 1.0 / (4.0 * PI);

/// Runs a bake (or one shard of it).
///
/// # Errors
/// [`BakeError::Settings`] for zero samples, a bad shard or coefficient count,
/// [`BakeError::Volume`] if the accumulator rejects the grid, [`BakeError::Cancelled`].
pub fn bake(
    transport: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    control: &BakeControl<'_>,
) -> Result<BakeOutput, BakeError> {
    bake_with_sink(transport, grid, settings, control, |_| {})
}

/// [`bake`], also handing every unit's kept samples to `sink`, on the calling thread, in
/// unit order (so whatever `sink` accumulates is as deterministic as the bake; the
/// gradient estimator of [`crate::gradient_bake`] uses it).
pub(crate) fn bake_with_sink(
    transport: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    control: &BakeControl<'_>,
    mut sink: impl FnMut(&UnitOut),
) -> Result<BakeOutput, BakeError> {
    let (k, n) = settings.shard;
    if n == 0 || k >= n {
        return Err(BakeError::Settings(format!("shard {k} of {n}")));
    }
    if settings.samples == 0 {
        return Err(BakeError::Settings("samples must be positive".into()));
    }
    let mut acc =
        Accumulator::new(grid.clone(), settings.coeffs).map_err(|e| BakeError::Volume(e.to_string()))?;
    let units = match settings.method {
        Method::Point | Method::DoiNode | Method::Doi => grid.node_count(),
        Method::Prefilter | Method::DoiPaper => grid.cell_count(),
    };
    let range = lightvol_core::shard::shard_range(units, (k, n));
    let lo = range.start;
    let mut relocated = vec![None; if settings.method == Method::Doi { range.len() } else { 0 }];
    let mut record = |out: &UnitOut| {
        if let Some(y) = out.relocated {
            relocated[out.nodes[0] - lo] = Some(y);
        }
        sink(out);
    };
    let mut stats =
        run_units(transport, grid, settings, control, range.len(), |i| lo + i, &mut acc, &mut record)?;
    if settings.method == Method::Doi {
        // The node reach of the shard's nodes (its units), recorded in node order.
        let t0 = Instant::now();
        let reach: Vec<([f32; 6], u64)> = range
            .clone()
            .into_par_iter()
            .map(|node| crate::reach::node_reach(transport.tracer(), grid, node, relocated[node - lo]))
            .collect();
        for (node, (r, rays)) in range.zip(reach) {
            acc.set_reach(node, r);
            stats.rays.query += rays;
        }
        stats.wall_time += t0.elapsed();
    }
    Ok(BakeOutput { accumulator: acc, stats })
}

/// Where a bake's contributions go: the dense [`Accumulator`], or the sparse sums of a
/// unit-subset bake ([`SubsetSums`]). Both perform exactly the additions of
/// [`Accumulator::add`] / [`Accumulator::add_outside`].
trait NodeSums {
    fn add(&mut self, node: usize, b: f64, radiance_over_pdf: [f64; 3], basis: &[f64]);
    fn add_outside(&mut self, node: usize, b: f64);
}

impl NodeSums for Accumulator {
    fn add(&mut self, node: usize, b: f64, radiance_over_pdf: [f64; 3], basis: &[f64]) {
        Accumulator::add(self, node, b, radiance_over_pdf, basis);
    }
    fn add_outside(&mut self, node: usize, b: f64) {
        Accumulator::add_outside(self, node, b);
    }
}

/// The per-node sums of a bake restricted to a subset of its units ([`bake_units`]): the
/// touched nodes (flat indices of the grid, ascending) with their Eq. 6 numerators
/// `[node][coeff][rgb]`, denominators and outside sums.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SubsetSums {
    /// Touched nodes, ascending.
    pub nodes: Vec<usize>,
    /// Numerators, `[i][coeff][rgb]` for `nodes[i]`.
    pub numerator: Vec<f64>,
    /// Denominators `Σ b`.
    pub denominator: Vec<f64>,
    /// Sums `Σ b` of rejected candidates.
    pub outside: Vec<f64>,
}

impl SubsetSums {
    /// Position of `node` in [`Self::nodes`].
    #[must_use]
    pub fn find(&self, node: usize) -> Option<usize> {
        self.nodes.binary_search(&node).ok()
    }
}

/// [`SubsetSums`] before conversion to f64: exact fixed-point sums (lightvol-volume's
/// `fixed`), so that the sums of disjoint unit subsets baked on different machines add up
/// ([`Self::merge`]) to the sums of their union bit for bit.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FixedSubsetSums {
    /// Touched nodes, ascending.
    pub nodes: Vec<usize>,
    /// Numerators, `[i][coeff][rgb]` for `nodes[i]`.
    pub numerator: FixedSums,
    /// Denominators `Σ b`.
    pub denominator: FixedSums,
    /// Sums `Σ b` of rejected candidates.
    pub outside: FixedSums,
}

impl FixedSubsetSums {
    /// Values per node in [`Self::numerator`] (`3 · coeffs`), 0 when there are no nodes.
    #[must_use]
    pub fn values_per_node(&self) -> usize {
        if self.nodes.is_empty() { 0 } else { self.numerator.len() / self.nodes.len() }
    }

    /// The sums as f64 (correctly rounded; NaN where a sum is poisoned).
    #[must_use]
    pub fn to_subset(&self) -> SubsetSums {
        SubsetSums {
            nodes: self.nodes.clone(),
            numerator: self.numerator.to_f64(),
            denominator: self.denominator.to_f64(),
            outside: self.outside.to_f64(),
        }
    }

    /// Adds `other`'s sums (the union of the node sets, ascending); exact, so any order of
    /// merging gives the same sums.
    ///
    /// # Errors
    /// [`BakeError::Settings`] when both have nodes and their values per node differ.
    pub fn merge(&mut self, other: &Self) -> Result<(), BakeError> {
        let (ka, kb) = (self.values_per_node(), other.values_per_node());
        if ka != 0 && kb != 0 && ka != kb {
            return Err(BakeError::Settings(format!(
                "subset sums of {ka} and {kb} values per node cannot be merged"
            )));
        }
        let k = ka.max(kb);
        let mut out = Self::default();
        let (mut i, mut j) = (0, 0);
        let take = |out: &mut Self, src: &Self, at: usize| {
            let d = out.nodes.len() - 1;
            out.denominator.add_sum(d, &src.denominator, at);
            out.outside.add_sum(d, &src.outside, at);
            for c in 0..k {
                out.numerator.add_sum(d * k + c, &src.numerator, at * k + c);
            }
        };
        while i < self.nodes.len() || j < other.nodes.len() {
            let a = self.nodes.get(i).copied().unwrap_or(usize::MAX);
            let b = other.nodes.get(j).copied().unwrap_or(usize::MAX);
            let node = a.min(b);
            out.nodes.push(node);
            out.numerator.extend_zeros(k);
            out.denominator.extend_zeros(1);
            out.outside.extend_zeros(1);
            if a == node {
                take(&mut out, self, i);
                i += 1;
            }
            if b == node {
                take(&mut out, other, j);
                j += 1;
            }
        }
        *self = out;
        Ok(())
    }
}

/// Sparse sums in insertion order (sorted by [`SparseSums::finish`]).
struct SparseSums {
    k: usize,
    slot: std::collections::HashMap<usize, usize>,
    nodes: Vec<usize>,
    numerator: FixedSums,
    denominator: FixedSums,
    outside: FixedSums,
}

impl SparseSums {
    fn slot(&mut self, node: usize) -> usize {
        let next = self.nodes.len();
        let s = *self.slot.entry(node).or_insert(next);
        if s == next {
            self.nodes.push(node);
            self.numerator.extend_zeros(self.k);
            self.denominator.extend_zeros(1);
            self.outside.extend_zeros(1);
        }
        s
    }

    fn finish(self) -> FixedSubsetSums {
        let mut order: Vec<usize> = (0..self.nodes.len()).collect();
        order.sort_unstable_by_key(|&i| self.nodes[i]);
        let k = self.k;
        FixedSubsetSums {
            nodes: order.iter().map(|&i| self.nodes[i]).collect(),
            numerator: self.numerator.gather(order.iter().flat_map(|&i| i * k..(i + 1) * k)),
            denominator: self.denominator.gather(order.iter().copied()),
            outside: self.outside.gather(order.iter().copied()),
        }
    }
}

impl NodeSums for SparseSums {
    fn add(&mut self, node: usize, b: f64, radiance_over_pdf: [f64; 3], basis: &[f64]) {
        let s = self.slot(node);
        // The arithmetic of Accumulator::add, term for term.
        add_terms(&mut self.numerator, s * self.k, b, radiance_over_pdf, basis);
        self.denominator.add(s, b);
    }
    fn add_outside(&mut self, node: usize, b: f64) {
        let s = self.slot(node);
        self.outside.add(s, b);
    }
}

/// A bake restricted to the listed units (cells for prefilter and doi-paper, nodes for the
/// others; flat indices of `grid`, strictly increasing). Each unit is sampled exactly as
/// in [`bake`] and the contributions are added in unit order, so every node whose units
/// all lie in the subset gets sums bit-identical to the full bake's, for any thread count.
/// `settings.shard` must be `(0, 1)`. Progress reports count the listed units. The sums
/// are exact ([`FixedSubsetSums`]): bakes of disjoint subsets merge into the union's.
///
/// # Errors
/// As [`bake`], plus [`BakeError::Settings`] for units out of range or not increasing.
pub fn bake_units_fixed(
    transport: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    units: &[usize],
    control: &BakeControl<'_>,
) -> Result<(FixedSubsetSums, BakeStats), BakeError> {
    if settings.shard != (0, 1) {
        return Err(BakeError::Settings("a unit-subset bake cannot be sharded".into()));
    }
    if settings.samples == 0 {
        return Err(BakeError::Settings("samples must be positive".into()));
    }
    lightvol_volume::volume::check_coeffs(settings.coeffs).map_err(|e| BakeError::Settings(e.to_string()))?;
    let count = match settings.method {
        Method::Point | Method::DoiNode | Method::Doi => grid.node_count(),
        Method::Prefilter | Method::DoiPaper => grid.cell_count(),
    };
    if units.windows(2).any(|w| w[0] >= w[1]) || units.last().is_some_and(|&u| u >= count) {
        return Err(BakeError::Settings(format!("units must be increasing and below {count}")));
    }
    let mut sums = SparseSums {
        k: settings.coeffs * 3,
        slot: std::collections::HashMap::new(),
        nodes: Vec::new(),
        numerator: FixedSums::default(),
        denominator: FixedSums::default(),
        outside: FixedSums::default(),
    };
    let stats =
        run_units(transport, grid, settings, control, units.len(), |i| units[i], &mut sums, &mut |_| {})?;
    Ok((sums.finish(), stats))
}

/// [`bake_units_fixed`] with the sums converted to f64.
///
/// # Errors
/// As [`bake_units_fixed`].
pub fn bake_units(
    transport: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    units: &[usize],
    control: &BakeControl<'_>,
) -> Result<(SubsetSums, BakeStats), BakeError> {
    let (sums, stats) = bake_units_fixed(transport, grid, settings, units, control)?;
    Ok((sums.to_subset(), stats))
}

/// Samples units `unit_of(0..count)` in parallel chunks and feeds them in order.
#[allow(
    clippy::too_many_arguments,
    reason = "the bake loop's inputs are independent; a struct would only rename them"
)]
fn run_units(
    transport: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    control: &BakeControl<'_>,
    count: usize,
    unit_of: impl Fn(usize) -> usize + Sync,
    acc: &mut impl NodeSums,
    sink: &mut impl FnMut(&UnitOut),
) -> Result<BakeStats, BakeError> {
    let bands = bands_of(settings.coeffs)
        .ok_or_else(|| BakeError::Settings(format!("{} coefficients", settings.coeffs)))?;
    let start = Instant::now();
    let mut stats = BakeStats::default();
    let chunk = settings.chunk.max(1);
    let mut basis = [vec![0.0; settings.coeffs], vec![0.0; settings.coeffs]];
    let mut done = 0;
    for c0 in (0..count).step_by(chunk) {
        let c1 = (c0 + chunk).min(count);
        let outs: Vec<Option<UnitOut>> = (c0..c1)
            .into_par_iter()
            .map(|i| {
                let u = unit_of(i);
                if control.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return None;
                }
                Some(match settings.method {
                    Method::Point => point_unit(transport, grid, settings, u),
                    Method::DoiNode => node_box_unit(transport, grid, settings, u),
                    Method::Doi => probe_unit(transport, grid, settings, u).0,
                    Method::Prefilter | Method::DoiPaper => cell_unit(transport, grid, settings, u),
                })
            })
            .collect();
        if control.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) || outs.iter().any(Option::is_none) {
            return Err(BakeError::Cancelled);
        }
        for out in outs.into_iter().flatten() {
            feed(acc, &out, bands, &mut basis);
            sink(&out);
            stats.add_counts(&out.stats);
        }
        done += c1 - c0;
        if let Some(p) = control.progress {
            p(Progress { done, total: count });
        }
    }
    stats.wall_time = start.elapsed();
    Ok(stats)
}

/// Adds a unit's samples in order. A sample with two terms is added as two half-weight
/// contributions with doubled radiance: `(b/2)·(2 r)` equals `b·r` exactly (powers of two),
/// so the numerator receives `b (r₁ Y(ω₁) + r₂ Y(ω₂))` and the denominator exactly `b`.
fn feed(acc: &mut impl NodeSums, out: &UnitOut, bands: usize, basis: &mut [Vec<f64>; 2]) {
    for s in &out.samples {
        let n_terms = usize::from(s.n_terms);
        // One basis evaluation per term, shared by the (up to 8) corners.
        for (t, b) in s.terms[..n_terms].iter().zip(basis.iter_mut()) {
            eval_into(bands, t.0.to_array(), b);
        }
        for (c, &w) in s.weights.iter().enumerate() {
            if w <= 0.0 {
                continue;
            }
            let node = out.nodes[c];
            if n_terms == 1 {
                acc.add(node, w, s.terms[0].1, &basis[0]);
            } else {
                for (t, b) in s.terms[..n_terms].iter().zip(basis.iter()) {
                    acc.add(node, 0.5 * w, t.1.map(|v| 2.0 * v), b);
                }
            }
        }
    }
    for r in &out.rejected {
        for (c, &w) in r.iter().enumerate() {
            if w > 0.0 {
                acc.add_outside(out.nodes[c], w);
            }
        }
    }
}

/// The light terms of one probe sample at `x` along `dir` with first hit `hit`.
pub(crate) fn sample_terms(
    t: &Transport<'_>,
    settings: &BakeSettings,
    x: DVec3,
    dir: DVec3,
    hit: Option<lightvol_scene::bvh::Hit>,
    rng: &mut PathRng,
    stats: &mut BakeStats,
) -> ([(DVec3, [f64; 3]); 2], u8) {
    let pdf = settings.light_sampling.then_some(UNIFORM_SPHERE_PDF);
    let l = t.radiance_from_hit(dir, hit, pdf, rng, &mut stats.rays);
    let first = (dir, l.map(|v| v / UNIFORM_SPHERE_PDF));
    if settings.light_sampling {
        let u = rng.next3();
        if let Some(second) = t.light_sample(x, UNIFORM_SPHERE_PDF, u, &mut stats.rays) {
            return ([first, second], 2);
        }
    }
    ([first, (DVec3::Z, [0.0; 3])], 1)
}

fn point_unit(t: &Transport<'_>, grid: &GridSpec, settings: &BakeSettings, node: usize) -> UnitOut {
    let [i, j, k] = grid.node_coords(node);
    let x = DVec3::from_array(grid.node_position_world(i, j, k));
    let h = Qmc::<2>::new(settings.seed, hash2(node as u64, 0x0070_6f69_6e74));
    let mut out = UnitOut { nodes: [node; 8], ..Default::default() };
    let mut weights = [0.0; 8];
    weights[0] = 1.0;
    for s in 0..u64::from(settings.samples) {
        let p = h.point(s);
        let dir = DVec3::from_array(sample_uniform_sphere(p));
        let mut rng = PathRng::new(settings.seed, hash2(node as u64, 0x0070_6f69_6e74), s);
        out.stats.rays.sampling += 1;
        let hit = t.tracer().closest_hit(x, dir, 0.0, f64::INFINITY);
        let (terms, n_terms) = sample_terms(t, settings, x, dir, hit, &mut rng, &mut out.stats);
        out.samples.push(SampleOut { weights, terms, n_terms });
    }
    out.stats.units = 1;
    out.stats.candidates = u64::from(settings.samples);
    out.stats.samples_kept = u64::from(settings.samples);
    out
}

/// [`Method::DoiNode`]: `samples` candidates uniform in the node-centred box of one cell
/// (clamped to the grid), classified by Algorithm 2, the kept ones averaged with weight 1.
fn node_box_unit(t: &Transport<'_>, grid: &GridSpec, settings: &BakeSettings, node: usize) -> UnitOut {
    let [i, j, k] = grid.node_coords(node);
    let at = |a: usize, d: i64| neighbour_coordinate(grid, [i, j, k], a, d);
    // Half a cell each way, within the grid's box.
    let centre = DVec3::from_array(grid.node_position(i, j, k));
    let lo =
        DVec3::new(0.5 * (at(0, -1) + centre.x), 0.5 * (at(1, -1) + centre.y), 0.5 * (at(2, -1) + centre.z));
    let hi =
        DVec3::new(0.5 * (at(0, 1) + centre.x), 0.5 * (at(1, 1) + centre.y), 0.5 * (at(2, 1) + centre.z));
    let stream = hash2(node as u64, 0x6e6f_6465);
    let h = Qmc::<5>::new(settings.seed, stream);
    let mut out = UnitOut { nodes: [node; 8], ..Default::default() };
    let n = u64::from(settings.samples);
    let points: Vec<(DVec3, DVec3)> = (0..n)
        .map(|s| {
            let p = h.point(s);
            let g = lo + (hi - lo) * DVec3::new(p[0], p[1], p[2]);
            (
                DVec3::from_array(grid.to_world(g.to_array())),
                DVec3::from_array(sample_uniform_sphere([p[3], p[4]])),
            )
        })
        .collect();
    let back_face_points = kept_node_samples(t, settings, stream, &points, &mut out);
    out.stats.back_face_points = back_face_points;
    out.stats.cells_with_back_faces = u64::from(back_face_points > 0);
    out.stats.units = 1;
    out.stats.candidates = n;
    out
}

/// [`Method::Doi`]: rays from the node before it counts as outside the domain of
/// interest, also the rays among which the closest back face is looked for.
pub const PROBE_SEARCH_RAYS: u64 = 16;

/// [`Method::Doi`]: each axis of a relocation's offset is clamped to this share of the grid
/// spacing. DDGI's [`crate::baselines::DDGI_MAX_OFFSET`] (0.45) leaves a node at the middle
/// of a wall one cell thick inside it (half a cell from either face), so it would be filled
/// from the nodes on both sides of the wall; half a cell plus a tenth moves the middle node
/// out of any wall thinner than 1.1 cells, and the node's reach
/// ([`crate::reach::node_reach`]) then cuts it off from the side it was not moved to.
pub const PROBE_MAX_OFFSET: f64 = 0.55;

/// [`Method::Doi`]: a back face farther than one grid spacing along some axis (outside the
/// node's trilinear support) takes the node out of the domain of interest only when more
/// than this share of its directions meet one: the back-face share above which DDGI
/// relocates a probe and Unity APV invalidates one ([`crate::baselines`]). A node deep
/// inside a solid wider than two cells meets back faces in nearly every direction and is
/// still outside; a node in a room that sees the back of a single-sided panel, a window
/// frame or a blind across the room is not, and keeps its point sample (measured on the
/// Breakfast Room at 1024 samples: relative RMSE 0.151 to 0.119, see the crate README).
pub const PROBE_FAR_BACK_SHARE: f64 = crate::baselines::DDGI_BACKFACE_THRESHOLD;

/// [`Method::Doi`]: a node outside the domain of interest spends at most this share of
/// `samples` on its relocated point.
pub const PROBE_OUTSIDE_SHARE: f64 = 0.5;

/// Where [`Method::Doi`] took a node's value from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ProbeCapture {
    /// The node is in the domain of interest: it sees no back face inside its trilinear
    /// support, and far ones in at most [`PROBE_FAR_BACK_SHARE`] of its directions;
    /// point-sampled there (Eq. 4).
    AtNode,
    /// The node is outside the domain of interest; this point, reached through the closest
    /// back face among the first [`PROBE_SEARCH_RAYS`] directions whose move keeps it in the
    /// grid's box (the closest of all when no move does: moved out of the box, the node
    /// would carry the light of a place that no lookup asks about, so a node in the middle
    /// of a wall on the grid's boundary moves to the side the lookups read), each axis of
    /// the move clamped to [`PROBE_MAX_OFFSET`] × spacing
    /// ([`crate::baselines::relocate_within`]), is in the domain by the same test and was
    /// point-sampled.
    Relocated(DVec3),
    /// Neither the node nor its relocated point is in the domain: the node keeps no
    /// samples, its domain weight is 0, and the accumulator's fill
    /// ([`lightvol_volume::fill`]) gives it the inverse-square-distance mean of its 26
    /// neighbours' estimates, the way a node deep inside a solid is filled under Eq. 6.
    /// (Eq. 6's own average over the node's support was measured worse: with a wall
    /// inside the support it mixes the light of both sides, and at half the samples it is
    /// noisy; see the crate README.)
    Filled,
}

/// Where [`clean_point_samples`] stopped: the directions it traced, the last one meeting a
/// back face at this direction and distance.
struct Stopped {
    traced: u64,
    back_face: (DVec3, f64),
}

/// [`Method::Doi`]'s distance-limited back-face test of a point: a back face inside the
/// box of one grid spacing around the point (a node's trilinear support, \[KL06\] Eq. 6)
/// takes it out of the domain of interest; back faces beyond that box do only when more
/// than [`PROBE_FAR_BACK_SHARE`] of the directions meet one.
struct BackFaceTest {
    /// Grid spacing per axis: the half-widths of the box.
    spacing: DVec3,
    /// Far back faces tolerated among the directions traced.
    far_allowed: u64,
}

impl BackFaceTest {
    /// The test on a grid of `spacing` for a point traced along `count` directions.
    fn new(spacing: [f64; 3], count: u64) -> Self {
        Self {
            spacing: DVec3::from_array(spacing),
            far_allowed: (count as f64 * PROBE_FAR_BACK_SHARE).floor() as u64,
        }
    }

    /// The back face met at distance `t` along the unit direction `dir` lies inside the box.
    fn near(&self, dir: DVec3, t: f64) -> bool {
        (dir * t).abs().cmple(self.spacing).all()
    }
}

/// Point samples at `x` along directions `first..first + count` of `h` (stream `stream`),
/// stopping at the first back face that takes `x` out of the domain under `test`: the
/// samples, or where it stopped. Directions meeting a tolerated far back face are kept,
/// as `point` keeps them.
#[allow(clippy::too_many_arguments, reason = "one sampling loop, two callers")]
fn clean_point_samples(
    t: &Transport<'_>,
    settings: &BakeSettings,
    h: &Qmc<2>,
    stream: u64,
    x: DVec3,
    first: u64,
    count: u64,
    test: &BackFaceTest,
    out: &mut UnitOut,
) -> Result<Vec<SampleOut>, Stopped> {
    let mut one = [0.0; 8];
    one[0] = 1.0;
    let mut hits = Vec::with_capacity(count as usize);
    let mut far = 0u64;
    for s in first..first + count {
        let dir = DVec3::from_array(sample_uniform_sphere(h.point(s)));
        out.stats.rays.sampling += 1;
        let hit = t.tracer().closest_hit(x, dir, 0.0, f64::INFINITY);
        if let Some(b) = hit.filter(|h| h.back_face) {
            if test.near(dir, b.t) || far >= test.far_allowed {
                return Err(Stopped { traced: s + 1 - first, back_face: (dir, b.t) });
            }
            far += 1;
        }
        hits.push((s, dir, hit));
    }
    Ok(hits
        .into_iter()
        .map(|(s, dir, hit)| {
            let mut rng = PathRng::new(settings.seed, stream, s);
            let (terms, n_terms) = sample_terms(t, settings, x, dir, hit, &mut rng, &mut out.stats);
            SampleOut { weights: one, terms, n_terms }
        })
        .collect())
}

/// [`Method::Doi`] for one node: the samples and where they were taken.
pub(crate) fn probe_unit(
    t: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    node: usize,
) -> (UnitOut, ProbeCapture) {
    let [i, j, k] = grid.node_coords(node);
    let x = DVec3::from_array(grid.node_position_world(i, j, k));
    // `point`'s stream and directions, so that a node in the domain is `point`'s bit for bit.
    let stream = hash2(node as u64, 0x0070_6f69_6e74);
    let h = Qmc::<2>::new(settings.seed, stream);
    let n = u64::from(settings.samples);
    let mut out = UnitOut { nodes: [node; 8], ..Default::default() };
    out.stats.units = 1;
    out.stats.candidates = n;
    let spacing = crate::baselines::spacing(grid);
    let at_node = BackFaceTest::new(spacing, n);
    let (mut used, first_back) =
        match clean_point_samples(t, settings, &h, stream, x, 0, n, &at_node, &mut out) {
            Ok(samples) => {
                out.stats.samples_kept = samples.len() as u64;
                out.samples = samples;
                return (out, ProbeCapture::AtNode);
            }
            Err(e) => (e.traced, e.back_face),
        };
    out.stats.back_face_points = 1;
    out.stats.cells_with_back_faces = 1;
    let (lo, hi) = grid.bounds();
    // A back face met at `dist` along `dir`: where the node moves through it, and whether
    // that point stays in the grid's box.
    let candidate = |(dir, dist): (DVec3, f64)| {
        let y = crate::baselines::relocate_within(x, dir, dist, spacing, PROBE_MAX_OFFSET);
        let g = grid.to_grid(y.to_array());
        (dist, y, (0..3).all(|a| (lo[a]..=hi[a]).contains(&g[a])))
    };
    // The best back face among the first PROBE_SEARCH_RAYS directions: one whose move stays
    // in the box beats one whose move leaves it; otherwise the closer one wins.
    let rank = |(dist, _, in_box): (f64, DVec3, bool)| (!in_box, dist);
    let mut best = candidate(first_back);
    let search = PROBE_SEARCH_RAYS.min(n);
    while used < search {
        let dir = DVec3::from_array(sample_uniform_sphere(h.point(used)));
        out.stats.rays.sampling += 1;
        used += 1;
        if let Some(b) = t.tracer().closest_hit(x, dir, 0.0, f64::INFINITY).filter(|h| h.back_face) {
            let c = candidate((dir, b.t));
            if rank(c) < rank(best) {
                best = c;
            }
        }
    }
    let left = n.saturating_sub(used).min((n as f64 * PROBE_OUTSIDE_SHARE).ceil() as u64);
    if left > 0 {
        let y = best.1;
        let at_y = BackFaceTest::new(spacing, left);
        if let Ok(samples) = clean_point_samples(t, settings, &h, stream, y, n, left, &at_y, &mut out) {
            out.stats.samples_kept = samples.len() as u64;
            out.samples = samples;
            out.relocated = Some(y);
            return (out, ProbeCapture::Relocated(y));
        }
    }
    (out, ProbeCapture::Filled)
}

/// Algorithm 2 over one node's candidates `(origin, direction)` (stream `stream`): the kept
/// ones become samples of weight 1 for the node, the rejected ones its outside weight.
/// Returns the back-face points found.
fn kept_node_samples(
    t: &Transport<'_>,
    settings: &BakeSettings,
    stream: u64,
    points: &[(DVec3, DVec3)],
    out: &mut UnitOut,
) -> u64 {
    let c = classify_cell(t.tracer(), points.len() as u64, |s| points[s as usize], Retest::QueryDirection);
    out.stats.rays.add(&c.rays);
    out.stats.samples_rejected = c.rejected.len() as u64;
    let mut one = [0.0; 8];
    one[0] = 1.0;
    out.rejected = vec![one; c.rejected.len()];
    for cand in &c.kept {
        let mut rng = PathRng::new(settings.seed, stream, cand.index);
        let (terms, n_terms) =
            sample_terms(t, settings, cand.origin, cand.dir, cand.hit, &mut rng, &mut out.stats);
        out.samples.push(SampleOut { weights: one, terms, n_terms });
    }
    out.stats.samples_kept = c.kept.len() as u64;
    c.back_face_points.len() as u64
}

/// Grid coordinate along axis `a` of the node `d` steps from `node` on that axis, clamped to
/// the grid (a boundary node's neighbour outside is itself).
fn neighbour_coordinate(grid: &GridSpec, node: [u32; 3], a: usize, d: i64) -> f64 {
    let m = i64::from(grid.res()[a]) - 1;
    let mut c = node;
    c[a] = (i64::from(c[a]) + d).clamp(0, m) as u32;
    grid.node_position(c[0], c[1], c[2])[a]
}

fn cell_unit(t: &Transport<'_>, grid: &GridSpec, settings: &BakeSettings, cell: usize) -> UnitOut {
    let (lo, hi) = grid.cell_bounds(cell);
    let (lo, hi) = (DVec3::from_array(lo), DVec3::from_array(hi));
    let h = Qmc::<5>::new(settings.seed, cell as u64);
    let mut out = UnitOut { nodes: grid.cell_corners(cell), ..Default::default() };
    let n = u64::from(settings.samples);
    // Grid-space origin (for the weights) and world-space ray, computed once per candidate.
    let points: Vec<(DVec3, DVec3, DVec3)> = (0..n)
        .map(|i| {
            let p = h.point(i);
            let g = lo + (hi - lo) * DVec3::new(p[0], p[1], p[2]);
            let w = DVec3::from_array(grid.to_world(g.to_array()));
            (g, w, DVec3::from_array(sample_uniform_sphere([p[3], p[4]])))
        })
        .collect();
    let candidate_at = |i: u64| points[i as usize];
    let weights_of = |g: DVec3| -> [f64; 8] {
        let f = (g - lo) / (hi - lo);
        lightvol_volume::grid::corner_weights([f.x, f.y, f.z].map(|v| v.clamp(0.0, 1.0)))
    };
    let candidates: Vec<crate::domain::Candidate> = match settings.method {
        Method::DoiPaper => {
            let c = classify_cell(
                t.tracer(),
                n,
                |i| {
                    let (_, w, d) = candidate_at(i);
                    (w, d)
                },
                Retest::QueryDirection,
            );
            out.stats.rays.add(&c.rays);
            out.stats.back_face_points = c.back_face_points.len() as u64;
            out.stats.cells_with_back_faces = u64::from(!c.back_face_points.is_empty());
            out.stats.samples_rejected = c.rejected.len() as u64;
            out.rejected = c.rejected.iter().map(|&(i, _)| weights_of(candidate_at(i).0)).collect();
            c.kept
        }
        _ => (0..n)
            .map(|i| {
                let (_, w, d) = candidate_at(i);
                out.stats.rays.sampling += 1;
                let hit = t.tracer().closest_hit(w, d, 0.0, f64::INFINITY);
                crate::domain::Candidate { index: i, origin: w, dir: d, hit }
            })
            .collect(),
    };
    for c in &candidates {
        let mut rng = PathRng::new(settings.seed, cell as u64, c.index);
        let (terms, n_terms) = sample_terms(t, settings, c.origin, c.dir, c.hit, &mut rng, &mut out.stats);
        out.samples.push(SampleOut { weights: weights_of(candidate_at(c.index).0), terms, n_terms });
    }
    out.stats.units = 1;
    out.stats.candidates = n;
    out.stats.samples_kept = candidates.len() as u64;
    out
}

#[cfg(test)]
#[path = "bake_tests.rs"]
mod tests;
