//! Two studies on one plate and one path-traced reference.
//!
//! **Error against memory** ([`memory_sweep`]): the relative RMSE of
//!
//! - `uniform`: a `doi-paper` bake (\[KL06\] §5-6) read by trilinear interpolation (Eq. 2),
//! - `uniform+taylor`, `uniform+gtrilinear`, `uniform+hermite`: the same bake with per-node
//!   SH gradients (\[Oat05\]; the `basis` estimator from the bake's own samples, or the one
//!   the caller names) read by the gradient lookups,
//! - `doi`: a uniform bake with the default method, `doi` (relocation, fill and node reach),
//!   its memory counting the reach,
//! - `adaptive`, `adaptive1`: \[Oat05\]'s octree baked to the memory of each uniform grid,
//!   finest level 2 or 1 (the `adaptive[L]` entries, module `entries`; `res` is its finest
//!   level's, `nodes` its stored nodes),
//!
//! at several grid resolutions (the grid's cell counts scaled by [`SweepConfig::scales`],
//! same bounds), against the run-time memory of each (\[Oat05\]'s accounting: `3 n²` f32 per
//! node, `4 · 3 n²` with gradients; the octree's own count with its weights and index).
//! Every bake takes the same samples per cell; every uniform volume is the \[KL06\] Eq. 6
//! average (no least-squares fit), so the uniform series differ only in resolution and
//! lookup.
//!
//! **Error against resolution** ([`resolution_sweep`]): uniform bakes of several methods
//! on grids of the base grid's bounds and cell aspect with more or fewer nodes along x.

use lightvol_volume::bricks::{BrickParams, bricks_from_octree};
use lightvol_volume::{GridSpec, VolumeField};
use serde::Serialize;

use crate::entries::{LOOKUPS, lookup_name, uniform_memory_bytes};
use crate::error::EvalError;
use crate::metrics::{Metrics, SweepPoint};
use crate::plate::Plate;
use crate::runs::{
    BakeContext, adaptive_volume, evaluate_adaptive, evaluate_bricks, gradient_volume, run_uniform,
    scaled_grid,
};
use lightvol_sampler::gradient_estimator::GradientEstimator;
use lightvol_sampler::method::Method;
use lightvol_sampler::node_fit::Fit;

/// Largest accepted scale of the cell counts (a 16-cell axis becomes 64).
pub const MAX_SWEEP_SCALE: f64 = 4.0;

/// The octree series: name and finest level.
const ADAPTIVE_SERIES: [(&str, u32); 2] = [("adaptive", 2), ("adaptive1", 1)];

/// Settings of the error-against-memory study.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepConfig {
    /// Scale factors of the grid's cell counts, each in `(0, MAX_SWEEP_SCALE]`.
    pub scales: Vec<f64>,
    /// Gradient estimator of the uniform bakes (`None`: `basis`, the default for `doi`).
    pub gradient_estimator: Option<GradientEstimator>,
}

impl SweepConfig {
    /// The scales that the command line uses by default.
    pub const DEFAULT_SCALES: [f64; 4] = [0.5, 0.7, 1.0, 1.4];
}

impl Default for SweepConfig {
    fn default() -> Self {
        Self { scales: Self::DEFAULT_SCALES.to_vec(), gradient_estimator: None }
    }
}

/// Checks sweep scales: at least one, each in `(0, MAX_SWEEP_SCALE]`.
///
/// # Errors
/// [`EvalError::NoSweepScales`], [`EvalError::SweepScale`].
pub fn check_scales(scales: &[f64]) -> Result<(), EvalError> {
    if scales.is_empty() {
        return Err(EvalError::NoSweepScales);
    }
    if let Some(s) = scales.iter().find(|s| !(**s > 0.0 && **s <= MAX_SWEEP_SCALE)) {
        return Err(EvalError::SweepScale { scale: *s, max: MAX_SWEEP_SCALE });
    }
    Ok(())
}

/// The error-against-memory study's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepReport {
    /// Plate height.
    pub plate_height: f64,
    /// Valid plate points.
    pub valid_points: usize,
    /// Samples per cell of every bake.
    pub samples: u32,
    /// The base grid's resolution (scale 1).
    pub base_res: [u32; 3],
    /// Scales of the cell counts.
    pub scales: Vec<f64>,
    /// Every point, series by series, each series by memory.
    pub points: Vec<SweepPoint>,
}

/// Runs the error-against-memory study on `plate` over grids scaled from `base` (module
/// docs); stages `sweep xS` (the uniform bake at scale `S`), `adaptive xS`, `adaptive1 xS`.
///
/// # Errors
/// Invalid scales, and the bakes' errors.
pub fn memory_sweep(
    ctx: &BakeContext<'_>,
    base: &GridSpec,
    plate: &Plate,
    config: &SweepConfig,
) -> Result<SweepReport, EvalError> {
    check_scales(&config.scales)?;
    let mut points = Vec::new();
    for &scale in &config.scales {
        let grid = scaled_grid(base, scale)?;
        let label = format!("sweep x{scale}");
        let gv = gradient_volume(ctx, &grid, Method::DoiPaper, config.gradient_estimator, &label)?;
        let bake_rays = gv.stats.rays.total();
        let bake_seconds = gv.stats.wall_time.as_secs_f64();
        let bands = gv.volume.bands();
        let mut push = |series: String, memory_bytes: usize, estimate: &[[f64; 3]], seconds: f64| {
            let m = plate.metrics(estimate);
            let p = point(series, grid.res(), grid.node_count(), memory_bytes, &m, bake_rays, seconds);
            ctx.observer.sweep_point(&p, None);
            points.push(p);
        };
        push(
            "uniform".into(),
            uniform_memory_bytes(gv.volume.spec(), bands, false),
            &plate.evaluate(&gv.volume),
            bake_seconds,
        );
        for lookup in LOOKUPS {
            let est = gv.evaluate(lookup, plate)?;
            push(
                format!("uniform+{}", lookup_name(lookup)),
                uniform_memory_bytes(gv.volume.spec(), bands, true),
                &est,
                bake_seconds + gv.gradient_seconds,
            );
        }
        // Uniform doi, the default method (with its node reach, which its memory counts).
        let doi = run_uniform(ctx, &grid, &format!("doi x{scale}"), Method::Doi, Fit::Average, plate)?;
        let p = point(
            "doi".into(),
            grid.res(),
            grid.node_count(),
            doi.memory_bytes,
            &doi.metrics,
            doi.rays.total(),
            doi.seconds,
        );
        ctx.observer.sweep_point(&p, None);
        points.push(p);
        for (series, levels) in ADAPTIVE_SERIES {
            // At the uniform series' memory (doi-paper's coefficients, no node reach).
            let budget = uniform_memory_bytes(&grid, bands, false);
            let (av, stats, _) = adaptive_volume(ctx, &grid, levels, &format!("{series} x{scale}"), budget)?;
            let (rays, seconds) = (stats.rays.total(), stats.wall_time.as_secs_f64());
            let base_res = Some(av.base().spec().res());
            let m = plate.metrics(&evaluate_adaptive(&av, plate));
            let p = point(
                series.into(),
                av.finest_res(),
                av.stored_nodes(),
                av.memory_bytes(),
                &m,
                rays,
                seconds,
            );
            ctx.observer.sweep_point(&p, base_res);
            points.push(p);
            if levels == crate::entries::ADAPTIVE_MAX_LEVEL {
                // The same octree as the engines' brick export (no extra rays).
                let (bricks, _) = bricks_from_octree(&av, &BrickParams::default())?;
                let m = plate.metrics(&evaluate_bricks(&bricks, plate));
                let memory = VolumeField::memory_bytes(&bricks);
                let p =
                    point("bricks".into(), av.finest_res(), bricks.probe_count(), memory, &m, rays, seconds);
                ctx.observer.sweep_point(&p, base_res);
                points.push(p);
            }
        }
    }
    // Series by series, each by memory.
    points.sort_by(|a, b| a.series.cmp(&b.series).then(a.memory_bytes.cmp(&b.memory_bytes)));
    Ok(SweepReport {
        plate_height: plate.height,
        valid_points: plate.valid_points(),
        samples: ctx.samples.get(),
        base_res: base.res(),
        scales: config.scales.clone(),
        points,
    })
}

/// A study point of `series` from its plate metrics `m`.
fn point(
    series: String,
    res: [u32; 3],
    nodes: usize,
    memory_bytes: usize,
    m: &Metrics,
    rays: u64,
    seconds: f64,
) -> SweepPoint {
    SweepPoint {
        series,
        res,
        nodes,
        memory_bytes,
        rel_rmse: m.rel_rmse,
        bias: m.bias,
        too_dark_near: m.too_dark_near,
        rays,
        seconds,
    }
}

/// One method's errors against grid resolution.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolutionSeries {
    /// The method's name.
    pub name: String,
    /// `(nodes along x, metrics)`, in the order of the requested node counts.
    pub points: Vec<(u32, Metrics)>,
}

/// Runs the error-against-resolution study on `plate`: every `(name, method)` of `methods`,
/// finalized with `fit`, on grids of `base`'s bounds with `n` nodes along x for every `n` of
/// `nodes_x` (counts below 2 give 2; the other axes keep the base grid's cell aspect,
/// [`scaled_grid`]); stages named after the methods.
///
/// # Errors
/// The bakes'.
pub fn resolution_sweep(
    ctx: &BakeContext<'_>,
    base: &GridSpec,
    plate: &Plate,
    methods: &[(String, Method)],
    fit: Fit,
    nodes_x: &[u32],
) -> Result<Vec<ResolutionSeries>, EvalError> {
    let mut series = Vec::with_capacity(methods.len());
    for (name, method) in methods {
        let mut points = Vec::with_capacity(nodes_x.len());
        for &nx in nodes_x {
            // Same cell aspect as the base grid, nx nodes along x.
            let scale = f64::from(nx.saturating_sub(1)) / f64::from(base.res()[0] - 1);
            let grid = scaled_grid(base, scale)?;
            let run = run_uniform(ctx, &grid, name, *method, fit, plate)?;
            ctx.observer.resolution_point(name, nx, &run.metrics);
            points.push((nx, run.metrics));
        }
        series.push(ResolutionSeries { name: name.clone(), points });
    }
    Ok(series)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_are_checked() {
        assert!(check_scales(&[0.5, 1.0]).is_ok());
        assert!(matches!(check_scales(&[]), Err(EvalError::NoSweepScales)));
        assert!(check_scales(&[0.0]).is_err());
        assert!(check_scales(&[f64::NAN]).is_err());
        assert!(matches!(check_scales(&[5.0]), Err(EvalError::SweepScale { scale, .. }) if scale == 5.0));
        assert!(check_scales(&[MAX_SWEEP_SCALE]).is_ok());
    }
}
