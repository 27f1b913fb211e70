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
//!   is ([`ProbeCapture`](crate::probe::ProbeCapture)).
//!
//! Origins and directions come from one 5-D Owen-scrambled Halton sequence per cell
//! (dimensions 0-2 the position in the cell, 3-4 the direction), scrambled and rotated per
//! cell so cells are decorrelated ([`Qmc`](lightvol_scene::qmc::Qmc)). Each sample's radiance is one path ([`Transport`]); when
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

use std::time::Instant;

use lightvol_sh::eval::eval_into;
use lightvol_sh::index::bands_of;
use lightvol_volume::accumulator::add_terms;
use lightvol_volume::fixed::FixedSums;
use lightvol_volume::{Accumulator, GridSpec, IrradianceVolume};
use rayon::prelude::*;

use crate::error::BakeError;
use crate::method::Method;
use crate::noise::NoiseTarget;
use crate::probe::{classify_node, probe_samples, probe_unit};
use crate::settings::BakeSettings;
use crate::stats::BakeStats;
use crate::unit::{UnitOut, cell_unit, node_box_unit, point_unit};
use lightvol_core::progress::{BakeControl, Progress};
use lightvol_scene::stats::RayCounts;
use lightvol_scene::transport::Transport;

/// A finished (shard of a) bake.
#[derive(Clone, Debug)]
pub struct BakeOutput {
    /// The Eq. 6 sums; merge shards with [`Accumulator::merge`], then `finalize`.
    pub accumulator: Accumulator,
    /// Counters and timing.
    pub stats: BakeStats,
    /// `doi` only: each of the shard's nodes' estimated relative error of its estimate
    /// (in unit order from the shard's first node; [`crate::noise`]'s prefix estimate over
    /// its kept samples), NaN where the estimate cannot judge it (fewer than
    /// [`crate::noise::MIN_VALUES`] kept samples, or no positive mean). Empty for the other
    /// methods. Shards, kept accumulators and checkpoints of a targeted bake carry it in
    /// their sums ([`crate::noise::attach_node_errors`]) for the merged set's smoothing.
    pub node_error: Vec<f32>,
}

impl BakeOutput {
    /// Stores [`Self::node_error`] in the accumulator's auxiliary sums
    /// ([`crate::noise::attach_node_errors`]), for the merged set's smoothing; the output of
    /// shard `shard` of a bake on `grid` (`(0, 1)`: the whole). Nothing for methods without
    /// per-node errors.
    pub fn keep_node_errors(&mut self, grid: &GridSpec, shard: (u32, u32)) {
        if !self.node_error.is_empty() {
            let first = lightvol_core::shard::shard_range(grid.node_count(), shard).start;
            crate::noise::attach_node_errors(&mut self.accumulator, first, &self.node_error);
        }
    }

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

/// Runs a bake (or one shard of it).
///
/// # Errors
/// [`BakeError::Settings`] for a bad shard or coefficient count,
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
    let mut acc =
        Accumulator::new(grid.clone(), settings.coeffs).map_err(|e| BakeError::Volume(e.to_string()))?;
    if let Some(g) = transport.groups() {
        let sky = g
            .sky_transfer()
            .map(|(_, n)| lightvol_scene::light_groups::sky_coefficients(&transport.scene().environment, n));
        acc.enable_groups(lightvol_volume::accumulator::GroupLabels { names: g.names().to_vec(), sky });
    }
    let units = match settings.method {
        Method::Point | Method::DoiNode | Method::Doi => grid.node_count(),
        Method::Prefilter | Method::DoiPaper => grid.cell_count(),
    };
    let range = lightvol_core::shard::shard_range(units, (k, n));
    let lo = range.start;
    let doi_nodes = if settings.method == Method::Doi { range.len() } else { 0 };
    let mut relocated = vec![None; doi_nodes];
    let mut node_error = vec![f32::NAN; doi_nodes];
    let mut record = |out: &UnitOut| {
        if settings.method == Method::Doi {
            if let Some(y) = out.relocated {
                relocated[out.nodes[0] - lo] = Some(y);
            }
            let e = crate::noise::relative_error_of(&out.sample_values()).filter(|e| e.is_finite());
            node_error[out.nodes[0] - lo] = e.map_or(f32::NAN, |e| e as f32);
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
            stats.reach_rays += rays;
        }
        stats.wall_time += t0.elapsed();
    }
    Ok(BakeOutput { accumulator: acc, stats, node_error })
}

/// Where a bake's contributions go: the dense [`Accumulator`], or the sparse sums of a
/// unit-subset bake ([`SubsetSums`]). Both perform exactly the additions of
/// [`Accumulator::add`] / [`Accumulator::add_outside`].
trait NodeSums {
    fn add(&mut self, node: usize, b: f64, radiance_over_pdf: [f64; 3], basis: &[f64]);
    fn add_outside(&mut self, node: usize, b: f64);
    /// Light-group numerators kept (0: none; [`Accumulator::add_group`]).
    fn groups(&self) -> usize {
        0
    }
    fn add_group(&mut self, _g: usize, _node: usize, _b: f64, _radiance_over_pdf: [f64; 3], _basis: &[f64]) {}
}

impl NodeSums for Accumulator {
    fn add(&mut self, node: usize, b: f64, radiance_over_pdf: [f64; 3], basis: &[f64]) {
        Accumulator::add(self, node, b, radiance_over_pdf, basis);
    }
    fn groups(&self) -> usize {
        self.group_count()
    }
    fn add_group(&mut self, g: usize, node: usize, b: f64, radiance_over_pdf: [f64; 3], basis: &[f64]) {
        Accumulator::add_group(self, g, node, b, radiance_over_pdf, basis);
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
    if transport.groups().is_some() {
        return Err(BakeError::Settings("a unit-subset bake is not split by light group".into()));
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
                if control.cancelled() {
                    return None;
                }
                Some(sample_unit(transport, grid, settings, u))
            })
            .collect();
        if control.cancelled() || outs.iter().any(Option::is_none) {
            return Err(BakeError::Cancelled);
        }
        for out in outs.into_iter().flatten() {
            feed(acc, &out, bands, &mut basis);
            sink(&out);
            stats.add_counts(&out.stats);
        }
        done += c1 - c0;
        control.report(Progress { done, total: count });
    }
    stats.wall_time = start.elapsed();
    Ok(stats)
}

/// One unit's samples at `settings.samples`, or with a noise target in growing rounds
/// until its estimate converges ([`until_converged`]). `doi` classifies a node once, with
/// the cap's directions, so it is kept, relocated or filled as a bake at the cap would
/// have it whatever count it stops at (a classification at each round's count moves near
/// its thresholds as the count grows, [`crate::probe`]); each of its rounds takes the
/// first kept directions a bake of its count would take
/// ([`NodeClass::take`](crate::probe::NodeClass::take)) and reuses the samples of the round
/// before. The other methods' rounds bake afresh.
fn sample_unit(transport: &Transport<'_>, grid: &GridSpec, settings: &BakeSettings, u: usize) -> UnitOut {
    let once = |s: &BakeSettings| {
        let mut out = match s.method {
            Method::Point => point_unit(transport, grid, s, u),
            Method::DoiNode => node_box_unit(transport, grid, s, u),
            Method::Doi => probe_unit(transport, grid, s, u).0,
            Method::Prefilter | Method::DoiPaper => cell_unit(transport, grid, s, u),
        };
        out.stats.final_samples = u64::from(s.samples.get());
        out
    };
    let with = |n: u32| BakeSettings { samples: lightvol_core::samples::samples(n), ..*settings };
    let Some(target) = settings.noise else { return once(settings) };
    if settings.method != Method::Doi {
        return until_converged(settings.samples.get(), &target, RayCounts::default(), |n, _| once(&with(n)));
    }
    let cap = target.max_samples.get();
    let class = classify_node(transport.tracer(), grid, settings.seed, u64::from(cap), u);
    let spent = RayCounts { sampling: class.rays, ..Default::default() };
    until_converged(settings.samples.get().min(cap), &target, spent, |n, earlier| {
        let mut out =
            probe_samples(transport, &with(n), u, &class, class.take(u64::from(n)), earlier.as_ref());
        out.stats.final_samples = u64::from(n);
        out
    })
}

/// A unit's rounds under a noise target ([`crate::noise`]), from `start` samples: `round`
/// gives the round of `n` samples, given the previous round (none at first).
/// Returns the last round, with the rays of every round and `spent` (those traced before
/// the first) added to its own.
fn until_converged(
    start: u32,
    target: &NoiseTarget,
    mut spent: RayCounts,
    mut round: impl FnMut(u32, Option<UnitOut>) -> UnitOut,
) -> UnitOut {
    let mut n = start;
    let mut earlier = None;
    loop {
        let mut out = round(n, earlier);
        let unmet = crate::noise::unmet_error(&out.sample_values(), target);
        if unmet.is_none() || n >= target.max_samples.get() {
            out.stats.rays.add(&spent);
            out.stats.capped_units = u64::from(unmet.is_some());
            return out;
        }
        spent.add(&out.stats.rays);
        n = crate::noise::next_samples(n, unmet.unwrap_or(f64::INFINITY), target);
        earlier = Some(out);
    }
}

/// Adds a unit's samples in order. A sample with two terms is added as two half-weight
/// contributions with doubled radiance: `(b/2)·(2 r)` equals `b·r` exactly (powers of two),
/// so the numerator receives `b (r₁ Y(ω₁) + r₂ Y(ω₂))` and the denominator exactly `b`.
///
/// With light groups, each group's terms are added the same way to its numerator (a zero
/// term adds nothing, so it is skipped).
fn feed(acc: &mut impl NodeSums, out: &UnitOut, bands: usize, basis: &mut [Vec<f64>; 2]) {
    let groups = acc.groups();
    for (i, s) in out.samples.iter().enumerate() {
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
            for g in 0..groups {
                let term = |t: usize| out.grouped[(2 * i + t) * groups + g];
                if n_terms == 1 {
                    if term(0) != [0.0; 3] {
                        acc.add_group(g, node, w, term(0), &basis[0]);
                    }
                } else {
                    for (t, b) in basis.iter().enumerate() {
                        if term(t) != [0.0; 3] {
                            acc.add_group(g, node, 0.5 * w, term(t).map(|v| 2.0 * v), b);
                        }
                    }
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

#[cfg(test)]
#[path = "bake_tests.rs"]
mod tests;
