//! Baking one [`Entry`](crate::Entry) and measuring it on the plate: the bakes every
//! entry kind needs ([`lightvol_sampler::node_fit::bake_fitted`], [`bake_with_estimator`], [`bake_adaptive`],
//! [`bake_baseline`]), their reads at the plate points, and what each adds to the report.
//!
//! Everything an entry bakes shares a [`BakeContext`]: one scene and ray tracer, one light
//! transport, one sample budget and one seed, so entries differ only in how they sample
//! and read.

use lightvol_core::samples::Samples;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use lightvol_volume::bricks::{BrickParams, BrickVolume, bricks_from_octree};
use lightvol_volume::gradient::{GradientLookup, irradiance as gradient_irradiance};
use lightvol_volume::validity::ValidityMask;
use lightvol_volume::{AdaptiveVolume, EngineLookup, GridSpec, IrradianceVolume, LevelStats, VolumeField};
use rayon::prelude::*;

use crate::baked::{GradientVolume, RunVolume};
use crate::entries::{ADAPTIVE_BASE_SCALE, bands_of_coeffs, uniform_memory_bytes};
use crate::error::EvalError;
use crate::metrics::Metrics;
use crate::observer::Observer;
use crate::plate::Plate;
use lightvol_core::progress::{BakeControl, Progress};
use lightvol_sampler::adaptive::{AdaptiveSettings, AdaptiveStats, bake_adaptive};
use lightvol_sampler::baselines::bake_baseline;
use lightvol_sampler::gradient_estimator::{GradientEstimator, bake_with_estimator};
use lightvol_sampler::method::Baseline;
use lightvol_sampler::method::Method;
use lightvol_sampler::node_fit::{Fit, bake_fitted};
use lightvol_sampler::settings::BakeSettings;
use lightvol_sampler::target::{
    KnownPoint, TargetSettings, best_for_points, fit_for_lookup, own_samples_mask,
};
use lightvol_scene::stats::RayCounts;
use lightvol_scene::transport::Transport;

/// What every bake of one evaluation shares.
pub struct BakeContext<'a> {
    /// The light transport over the scene and its ray tracer.
    pub transport: Transport<'a>,
    /// Samples per cell (per node for point sampling).
    pub samples: Samples,
    /// SH coefficients per channel (4, 9 or 16).
    pub coeffs: usize,
    /// Seed of every random stream.
    pub seed: u64,
    /// The noise target of every bake, if any ([`lightvol_sampler::noise`]).
    pub noise: Option<lightvol_sampler::noise::NoiseTarget>,
    /// Where progress goes.
    pub observer: &'a dyn Observer,
}

impl BakeContext<'_> {
    /// The bake settings of `method` under this context.
    #[must_use]
    pub fn settings(&self, method: Method) -> BakeSettings {
        BakeSettings {
            method,
            samples: self.samples,
            coeffs: self.coeffs,
            seed: self.seed,
            noise: self.noise,
            ..BakeSettings::default()
        }
    }

    /// Runs `f` as the observer's stage `label`, its bake reporting progress to the
    /// observer.
    pub fn stage<T>(&self, label: &str, f: impl FnOnce(&BakeControl<'_>) -> T) -> T {
        self.observer.stage_started(label);
        let report = |p: Progress| self.observer.progress(p);
        let out = f(&BakeControl { progress: Some(&report), cancel: None });
        self.observer.stage_finished();
        out
    }
}

/// What an entry adds to its [`MethodRun`] beyond the common fields.
#[derive(Clone, Debug, PartialEq)]
pub enum RunDetail {
    /// A uniform bake (plain or fitted).
    Uniform,
    /// A uniform bake read through a gradient lookup.
    Gradient {
        /// The lookup.
        lookup: GradientLookup,
        /// The estimator of the gradients.
        estimator: GradientEstimator,
        /// Directions traced for the gradients beyond the bake.
        extra_directions: u64,
        /// Nodes whose basis-gradient system was singular.
        singular_nodes: usize,
    },
    /// The adaptive octree.
    Adaptive {
        /// The memory budget (the uniform grid's bytes).
        memory_budget: usize,
        /// Nodes per axis of level 0.
        base_res: [u32; 3],
        /// Nodes per axis of the finest level.
        finest_res: [u32; 3],
        /// Per-level counts.
        levels: Vec<LevelStats>,
        /// Rays of the depth heuristic.
        depth_rays: u64,
    },
    /// The brick export of an octree.
    Bricks {
        /// The probe budget (`None`: the merge tolerance alone).
        probe_budget: Option<usize>,
        /// What the export made and dropped.
        report: lightvol_volume::bricks::BrickReport,
        /// The octree's memory (its budget is the uniform `doi` grid's bytes).
        octree_bytes: usize,
    },
    /// A sky transfer relit to the comparison's sky.
    Relit {
        /// The transfer's SH order (`order²` coefficients of the sky's radiance).
        order: u32,
        /// The comparison's sky's open-sky irradiance band-limit error at that order
        /// ([`lightvol_scene::band_limit`]).
        sky_band_limit: f64,
    },
    /// An engine baseline.
    Baseline {
        /// Nodes its validity test rejected.
        invalid_nodes: usize,
        /// Nodes it sampled elsewhere than at the node.
        moved_nodes: usize,
    },
}

/// One entry baked and measured on the plate.
#[derive(Clone, Debug)]
pub struct MethodRun {
    /// The entry's name.
    pub name: String,
    /// Samples per cell (per node for point sampling).
    pub samples: Samples,
    /// Rays traced, by kind (the bake's, the gradient step's and the validity rays
    /// included).
    pub rays: RayCounts,
    /// Wall time of the bake (and gradient step), in seconds.
    pub seconds: f64,
    /// The leakage metrics.
    pub metrics: Metrics,
    /// Run-time bytes (module `entries`).
    pub memory_bytes: usize,
    /// Stored nodes.
    pub nodes: usize,
    /// What the entry kind adds.
    pub detail: RunDetail,
    /// Irradiance (RGB, normal up) at every plate point.
    pub estimate: Vec<[f64; 3]>,
    /// What the entry baked, read through the entry's lookup (the plate's `estimate` is it
    /// at the plate points, normal up).
    pub volume: RunVolume,
}

impl MethodRun {
    #[allow(clippy::too_many_arguments, reason = "every field of the run but its name")]
    pub(crate) fn new(
        name: &str,
        samples: Samples,
        rays: RayCounts,
        seconds: f64,
        plate: &Plate,
        estimate: Vec<[f64; 3]>,
        memory_bytes: usize,
        nodes: usize,
        detail: RunDetail,
        volume: RunVolume,
    ) -> Self {
        Self {
            name: name.to_owned(),
            samples,
            rays,
            seconds,
            metrics: plate.metrics(&estimate),
            memory_bytes,
            nodes,
            detail,
            estimate,
            volume,
        }
    }
}

/// Bakes `method` on `grid` (Eq. 6's average), fits its node values for `lookup`'s engine
/// ([`fit_for_lookup`]) and measures it on the plate read through that lookup (stage
/// `name`). The fit's rays count with the bake's.
///
/// # Errors
/// The bake's and the fit's.
pub fn run_targeted(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    method: Method,
    lookup: EngineLookup,
    plate: &Plate,
) -> Result<MethodRun, EvalError> {
    run_set_for_lookup(ctx, grid, name, method, lookup, plate, |baked, valid, errors| {
        let settings = TargetSettings::new(lookup, ctx.seed);
        let (vol, report) = fit_for_lookup(&ctx.transport, baked, &settings, Some(valid), errors)
            .map_err(EvalError::at("fitting for the target lookup"))?;
        Ok((vol, report.rays))
    })
}

/// The plate's lower bound through `lookup` (stage `name`): bakes `doi` on `grid` for a
/// starting point and APV's validity, then sets the node values that fit the plate's
/// reference best through the lookup ([`best_for_points`]; the points the reference
/// classifies as seeing back faces are left out, as the metrics leave them out). Its rays
/// are the bake's; its time includes the fit.
///
/// # Errors
/// The bake's and the fit's.
pub fn run_bound(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    lookup: EngineLookup,
    plate: &Plate,
) -> Result<MethodRun, EvalError> {
    let up = [0.0, 0.0, 1.0];
    let points: Vec<KnownPoint> = (0..plate.points.len())
        .filter(|&i| plate.valid[i])
        .map(|i| KnownPoint { p: plate.points[i].to_array(), n: up, to_eye: up, value: plate.truth[i] })
        .collect();
    run_set_for_lookup(ctx, grid, name, Method::Doi, lookup, plate, |baked, valid, _errors| {
        let vol = best_for_points(baked, lookup, Some(valid), &points)
            .map_err(EvalError::at("fitting the plate's reference"))?;
        Ok((vol, 0))
    })
}

/// Bakes `method` on `grid` (stage `name`), sets its node values with `set` (given the
/// bake and the mask of its nodes with samples of their own; it returns the volume and the
/// rays it traced, counted with the bake's), and measures the result on the plate read
/// through `lookup`.
fn run_set_for_lookup(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    method: Method,
    lookup: EngineLookup,
    plate: &Plate,
    set: impl FnOnce(
        &IrradianceVolume,
        ValidityMask,
        Option<&[f32]>,
    ) -> Result<(IrradianceVolume, u64), EvalError>,
) -> Result<MethodRun, EvalError> {
    let settings = ctx.settings(method);
    let mut out = ctx
        .stage(name, |c| lightvol_sampler::bake(&ctx.transport, grid, &settings, c))
        .map_err(EvalError::at("baking"))?;
    let valid = own_samples_mask(&out.accumulator);
    let errors = std::mem::take(&mut out.node_error);
    let errors = (errors.len() == valid.len()).then_some(errors);
    let (baked, mut stats) = out.finish();
    let t0 = Instant::now();
    let (vol, rays) = set(&baked, valid, errors.as_deref())?;
    stats.rays.query += rays;
    let seconds = stats.wall_time.as_secs_f64() + t0.elapsed().as_secs_f64();
    let estimate = plate.engine_estimate(&vol, lookup);
    let memory = uniform_memory_bytes(grid, bands_of_coeffs(ctx.coeffs), false)
        + vol.validity().map_or(0, ValidityMask::memory_bytes);
    Ok(MethodRun::new(
        name,
        ctx.samples,
        stats.rays,
        seconds,
        plate,
        estimate,
        memory,
        grid.node_count(),
        RunDetail::Uniform,
        RunVolume::Engine(Arc::new(vol), lookup),
    ))
}

/// Bakes `method` on `grid`, finalized with `fit` ([`bake_fitted`]; `point` always takes
/// the average), and measures it on the plate (stage `name`).
///
/// # Errors
/// The bake's.
pub fn run_uniform(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    method: Method,
    fit: Fit,
    plate: &Plate,
) -> Result<MethodRun, EvalError> {
    let settings = ctx.settings(method);
    let (vol, stats, _) = ctx
        .stage(name, |c| bake_fitted(&ctx.transport, grid, &settings, c, fit))
        .map_err(EvalError::at("baking"))?;
    Ok(uniform_run(ctx, grid, name, plate, vol, stats.rays, stats.wall_time.as_secs_f64()))
}

/// The run of a uniform volume `vol` on `grid` read through lightvol's lookup: its plate
/// estimate and its memory (the coefficients and, for doi, the node reach), with the rays
/// and seconds it took.
pub(crate) fn uniform_run(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    plate: &Plate,
    vol: IrradianceVolume,
    rays: RayCounts,
    seconds: f64,
) -> MethodRun {
    let estimate = plate.evaluate(&vol);
    let memory = uniform_memory_bytes(grid, bands_of_coeffs(ctx.coeffs), false)
        + vol.reach().map_or(0, lightvol_volume::NodeReach::memory_bytes);
    MethodRun::new(
        name,
        ctx.samples,
        rays,
        seconds,
        plate,
        estimate,
        memory,
        grid.node_count(),
        RunDetail::Uniform,
        RunVolume::Uniform(Arc::new(vol)),
    )
}

/// Bakes `base` with gradients on `grid` by `estimator`, or the estimator that fits the
/// method ([`GradientEstimator::default_for`]); stage `label`. The volume is the plain
/// Eq. 6 average.
///
/// # Errors
/// The bake's, and the basis estimator with `point`.
pub fn gradient_volume(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    base: Method,
    estimator: Option<GradientEstimator>,
    label: &str,
) -> Result<GradientVolume, EvalError> {
    let settings = ctx.settings(base);
    let estimator = estimator.unwrap_or_else(|| GradientEstimator::default_for(base));
    let g = ctx.stage(label, |c| bake_with_estimator(&ctx.transport, grid, &settings, estimator, c))?;
    let (volume, _) = g.output.accumulator.finalize();
    Ok(GradientVolume {
        volume,
        gradients: g.gradients,
        stats: g.output.stats,
        estimator,
        singular_nodes: g.singular_nodes,
        extra_directions: g.extra_directions,
        gradient_seconds: g.seconds,
    })
}

impl GradientVolume {
    /// Irradiance (normal up) at every plate point through `lookup`.
    ///
    /// # Errors
    /// The lookup's (a point outside the grid).
    pub fn evaluate(&self, lookup: GradientLookup, plate: &Plate) -> Result<Vec<[f64; 3]>, EvalError> {
        plate
            .points
            .par_iter()
            .map(|p| {
                Ok(gradient_irradiance(&self.volume, &self.gradients, lookup, p.to_array(), [0.0, 0.0, 1.0])?)
            })
            .collect()
    }
}

/// The run of `lookup` on the gradient bake `gv` (its rays and time include the gradient
/// step).
///
/// # Errors
/// The lookup's.
pub fn run_gradient(
    gv: &Arc<GradientVolume>,
    name: &str,
    lookup: GradientLookup,
    samples: Samples,
    plate: &Plate,
) -> Result<MethodRun, EvalError> {
    let estimate = gv.evaluate(lookup, plate)?;
    let spec = gv.volume.spec();
    Ok(MethodRun::new(
        name,
        samples,
        gv.stats.rays,
        gv.stats.wall_time.as_secs_f64() + gv.gradient_seconds,
        plate,
        estimate,
        uniform_memory_bytes(spec, gv.volume.bands(), true),
        spec.node_count(),
        RunDetail::Gradient {
            lookup,
            estimator: gv.estimator,
            extra_directions: gv.extra_directions,
            singular_nodes: gv.singular_nodes,
        },
        RunVolume::Gradient { bake: Arc::clone(gv), lookup },
    ))
}

/// Gradient bakes keyed by base method, so that `doi+taylor,doi+hermite` bake once.
#[derive(Default)]
pub struct GradientCache {
    bakes: BTreeMap<u8, Arc<GradientVolume>>,
}

fn method_key(m: Method) -> u8 {
    match m {
        Method::Point => 0,
        Method::Prefilter => 1,
        Method::DoiPaper => 2,
        Method::DoiNode => 3,
        Method::Doi => 4,
    }
}

impl GradientCache {
    /// The gradient bake of `base` on `grid`, baked on first use ([`gradient_volume`]).
    /// Every call on one cache must pass the same context, grid and estimator.
    ///
    /// # Errors
    /// As [`gradient_volume`].
    pub fn get(
        &mut self,
        ctx: &BakeContext<'_>,
        grid: &GridSpec,
        base: Method,
        estimator: Option<GradientEstimator>,
        label: &str,
    ) -> Result<&Arc<GradientVolume>, EvalError> {
        Ok(match self.bakes.entry(method_key(base)) {
            std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::btree_map::Entry::Vacant(e) => {
                e.insert(Arc::new(gradient_volume(ctx, grid, base, estimator, label)?))
            }
        })
    }
}

/// `base` with its cell counts scaled by `scale` (rounded, at least one cell per axis), same
/// bounds, no placement.
///
/// # Errors
/// A grid lightvol-volume refuses.
pub fn scaled_grid(base: &GridSpec, scale: f64) -> Result<GridSpec, EvalError> {
    let (min, max) = base.bounds();
    let res = base.res().map(|r| ((f64::from(r - 1) * scale).round() as u32).max(1) + 1);
    Ok(GridSpec::new(min, max, res)?)
}

/// An adaptive `doi` bake with finest level `max_level` over the grid `grid` (module
/// `entries`) within `budget` bytes; stage `label`. Returns the volume, its statistics and
/// the budget.
///
/// # Errors
/// The bake's.
pub fn adaptive_volume(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    max_level: u32,
    label: &str,
    budget: usize,
) -> Result<(AdaptiveVolume, AdaptiveStats, usize), EvalError> {
    octree_volume(ctx, grid, ADAPTIVE_BASE_SCALE, max_level, label, budget)
}

/// [`adaptive_volume`] with level 0 on `grid`'s cell counts times `base_scale`.
///
/// # Errors
/// The bake's.
pub fn octree_volume(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    base_scale: f64,
    max_level: u32,
    label: &str,
    budget: usize,
) -> Result<(AdaptiveVolume, AdaptiveStats, usize), EvalError> {
    let base = scaled_grid(grid, base_scale)?;
    let settings = ctx.settings(Method::Doi);
    let adaptive = AdaptiveSettings { max_level, memory_budget: Some(budget), ..AdaptiveSettings::default() };
    let (vol, stats) = ctx
        .stage(label, |c| bake_adaptive(&ctx.transport, &base, &settings, &adaptive, c))
        .map_err(EvalError::at("adaptive bake"))?;
    Ok((vol, stats, budget))
}

/// Irradiance (normal up) of an adaptive volume at every plate point (f32 lookup, like the
/// uniform entries').
#[must_use]
pub fn evaluate_adaptive(vol: &AdaptiveVolume, plate: &Plate) -> Vec<[f64; 3]> {
    plate
        .points
        .par_iter()
        .map(|p| vol.irradiance(p.as_vec3().to_array(), [0.0, 0.0, 1.0]).map(f64::from))
        .collect()
}

/// The octree of the `bricks[N]` entries, baked once per comparison: every brick entry
/// exports the same octree under its own budget (and reports its rays).
#[derive(Default)]
pub struct BrickOctree {
    baked: Option<(Arc<AdaptiveVolume>, AdaptiveStats)>,
}

impl BrickOctree {
    /// The octree on `grid` (module docs of [`run_bricks`]), baked on first use under the
    /// stage `label`. Every call on one cache must pass the same context and grid.
    ///
    /// # Errors
    /// The bake's.
    pub fn get(
        &mut self,
        ctx: &BakeContext<'_>,
        grid: &GridSpec,
        label: &str,
    ) -> Result<&(Arc<AdaptiveVolume>, AdaptiveStats), EvalError> {
        if self.baked.is_none() {
            let budget = crate::entries::uniform_doi_memory_bytes(grid, bands_of_coeffs(ctx.coeffs));
            let (oct, stats, _) = octree_volume(
                ctx,
                grid,
                crate::entries::BRICKS_BASE_SCALE,
                crate::entries::BRICKS_MAX_LEVEL,
                label,
                budget,
            )?;
            self.baked = Some((Arc::new(oct), stats));
        }
        Ok(self.baked.as_ref().expect("baked above"))
    }
}

/// Irradiance (normal up) of a brick volume at every plate point (its f32 lookup).
#[must_use]
pub fn evaluate_bricks(vol: &BrickVolume, plate: &Plate) -> Vec<[f64; 3]> {
    plate
        .points
        .par_iter()
        .map(|p| vol.irradiance(p.as_vec3().to_array(), [0.0, 0.0, 1.0]).map(f64::from))
        .collect()
}

/// The `adaptive[L]` entry at the memory of the uniform `doi` grid `grid` (coefficients and
/// node reach).
///
/// # Errors
/// The bake's.
pub fn run_adaptive(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    max_level: u32,
    plate: &Plate,
) -> Result<MethodRun, EvalError> {
    let budget = crate::entries::uniform_doi_memory_bytes(grid, bands_of_coeffs(ctx.coeffs));
    let (vol, stats, budget) = adaptive_volume(ctx, grid, max_level, name, budget)?;
    let estimate = evaluate_adaptive(&vol, plate);
    Ok(MethodRun::new(
        name,
        ctx.samples,
        stats.rays,
        stats.wall_time.as_secs_f64(),
        plate,
        estimate,
        vol.memory_bytes(),
        vol.stored_nodes(),
        RunDetail::Adaptive {
            memory_budget: budget,
            base_res: vol.base().spec().res(),
            finest_res: vol.finest_res(),
            levels: vol.level_stats().to_vec(),
            depth_rays: stats.depth_rays,
        },
        RunVolume::Adaptive(Arc::new(vol)),
    ))
}

/// The `bricks[N]` entry: an octree (level 0 at [`crate::entries::BRICKS_BASE_SCALE`] of
/// the grid's cell counts, finest level [`crate::entries::BRICKS_MAX_LEVEL`], at the uniform
/// `doi` grid's memory) resampled into bricks, with a probe budget of `1/divisor` of the uniform grid's probes in the same texel
/// format when `divisor > 0`; read by the brick lookup (f32), its memory the atlas's probes
/// and the indirection texture.
///
/// # Errors
/// The bake's, and a budget below the coarsest bricks.
pub fn run_bricks(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    divisor: u32,
    octree: &mut BrickOctree,
    plate: &Plate,
) -> Result<MethodRun, EvalError> {
    let (oct, stats) = octree.get(ctx, grid, name)?;
    let probe_budget =
        (divisor > 0).then(|| crate::entries::uniform_probe_bytes(grid, ctx.coeffs) / divisor as usize);
    let params = BrickParams { max_probe_bytes: probe_budget, ..BrickParams::default() };
    let (vol, report) = bricks_from_octree(oct, &params)?;
    let estimate = evaluate_bricks(&vol, plate);
    Ok(MethodRun::new(
        name,
        ctx.samples,
        stats.rays,
        stats.wall_time.as_secs_f64(),
        plate,
        estimate,
        VolumeField::memory_bytes(&vol),
        vol.probe_count(),
        RunDetail::Bricks { probe_budget, report, octree_bytes: oct.memory_bytes() },
        RunVolume::Bricks(Arc::new(vol)),
    ))
}

/// An engine baseline on `grid` (point samples, the context's samples per node, plus the
/// validity rays, which its ray count includes), read through its volume's lookup: Unity
/// APV's volume carries its validity mask, so its lookups are validity-weighted, the others
/// are plain trilinear. APV is read by the f64 reference lookup
/// ([`IrradianceVolume::irradiance_reference`], which applies the mask like the f32 path),
/// as the comparison has always read it; the other baselines by the f32 lookup of every
/// uniform entry ([`Plate::evaluate`]). Its memory adds the mask's bytes
/// ([`lightvol_volume::ValidityMask::memory_bytes`]) to the uniform grid's.
///
/// # Errors
/// The bake's.
pub fn run_baseline(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    baseline: Baseline,
    plate: &Plate,
) -> Result<MethodRun, EvalError> {
    let settings = ctx.settings(Method::Point);
    let t0 = Instant::now();
    let b = bake_baseline(&ctx.transport, grid, &settings, baseline).map_err(EvalError::at("baking"))?;
    let seconds = t0.elapsed().as_secs_f64();
    let estimate: Vec<[f64; 3]> = if baseline.weights_lookups() {
        plate
            .points
            .par_iter()
            .map(|p| b.volume.irradiance_reference(p.to_array(), [0.0, 0.0, 1.0]))
            .collect()
    } else {
        plate.evaluate(&b.volume)
    };
    let detail = RunDetail::Baseline { invalid_nodes: b.invalid_nodes(), moved_nodes: b.moved_nodes(grid) };
    let memory = uniform_memory_bytes(grid, bands_of_coeffs(ctx.coeffs), false)
        + b.volume.validity().map_or(0, ValidityMask::memory_bytes);
    let volume = if baseline.weights_lookups() {
        RunVolume::Reference(Arc::new(b.volume))
    } else {
        RunVolume::Uniform(Arc::new(b.volume))
    };
    Ok(MethodRun::new(
        name,
        ctx.samples,
        b.rays,
        seconds,
        plate,
        estimate,
        memory,
        grid.node_count(),
        detail,
        volume,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_grids_keep_bounds_and_scale_cells() {
        let base = GridSpec::new([-30.0, -30.0, -1.0], [30.0, 30.0, 23.0], [16, 16, 7]).unwrap();
        let g = scaled_grid(&base, 0.5).unwrap();
        // 15 cells * 0.5 = 7.5 -> 8 cells (round half away from zero), 6 * 0.5 = 3 cells.
        assert_eq!(g.res(), [9, 9, 4]);
        assert_eq!(g.bounds(), base.bounds());
        assert_eq!(scaled_grid(&base, 1.0).unwrap().res(), base.res());
        assert_eq!(scaled_grid(&base, 0.01).unwrap().res(), [2, 2, 2]);
    }
}
