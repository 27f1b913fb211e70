//! The error-vs-memory study (`compare --memory-sweep`, and `demo` on `city` and
//! `interior`): on one plate and one path-traced reference, the relative RMSE of
//!
//! - `uniform`: a `doi` bake (\[KL06\] §5-6) read by trilinear interpolation (Eq. 2),
//! - `uniform+taylor`, `uniform+gtrilinear`, `uniform+hermite`: the same bake with per-node
//!   SH gradients (\[Oat05\]; the `basis` estimator from the bake's own samples, or the one
//!   `--gradient-estimator` names) read by the gradient lookups,
//!
//! - `adaptive`, `adaptive1`: \[Oat05\]'s octree baked to the memory of each uniform grid,
//!   finest level 2 or 1 (the `adaptive[L]` entries of `compare`, see
//!   [`crate::compare_entries`]; `res` is its finest level's, `nodes` its stored nodes),
//!
//! at several grid resolutions (the grid's cell counts scaled by `--sweep-scales`, same
//! bounds), against the run-time memory of each (\[Oat05\]'s accounting: `3 n²` f32 per
//! node, `4 · 3 n²` with gradients; the octree's own count with its weights and index).
//! Every bake takes `--samples` per cell; every uniform volume is the \[KL06\] Eq. 6
//! average (no `--fit`), so the uniform series differ only in resolution and lookup.

use std::path::Path;

use anyhow::bail;
use lightvol_sampler::{Method, Tracer};
use lightvol_volume::GridSpec;
use lightvol_volume::gradient::GradientLookup;
use serde::Serialize;

use crate::cmd_compare::{CompareArgs, PlateData, evaluate, plate_metrics};
use crate::compare_entries::{adaptive_volume, evaluate_adaptive, evaluate_gradient, gradient_volume};
use crate::gradients::{lookup_name, uniform_memory_bytes};
use crate::imaging::{Plot, write_atomic};
use crate::setup::LoadedScene;

/// Largest accepted scale of the cell counts (a 16-cell axis becomes 64).
const MAX_SCALE: f64 = 4.0;

/// One (series, resolution) point of the study.
#[derive(Debug, Clone, Serialize)]
pub struct SweepPoint {
    /// `uniform`, `uniform+taylor`, `uniform+gtrilinear`, `uniform+hermite`, `adaptive`,
    /// `adaptive1`.
    pub series: String,
    /// Grid nodes per axis.
    pub res: [u32; 3],
    /// Stored nodes.
    pub nodes: usize,
    /// Run-time bytes (\[Oat05\]'s accounting).
    pub memory_bytes: usize,
    /// Relative RMSE on the plate's valid points.
    pub rel_rmse: f64,
    /// Relative bias.
    pub bias: f64,
    /// Share of valid near-surface points with `E < 0.8 T`.
    pub too_dark_near: f64,
    /// Rays of the bake (and gradient step).
    pub rays: u64,
    /// Bake seconds (and gradient step).
    pub seconds: f64,
}

/// `memory_sweep.json`.
#[derive(Debug, Clone, Serialize)]
pub struct SweepReport {
    /// Scene label.
    pub scene: String,
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
    /// Every point, series by series.
    pub points: Vec<SweepPoint>,
}

/// Checks `--sweep-scales`.
pub fn check_scales(scales: &[f64]) -> anyhow::Result<()> {
    if scales.is_empty() {
        bail!("--sweep-scales needs at least one scale");
    }
    if let Some(s) = scales.iter().find(|s| !(**s > 0.0 && **s <= MAX_SCALE)) {
        bail!("--sweep-scales: {s} is not in (0, {MAX_SCALE}]");
    }
    Ok(())
}

/// `base` with its cell counts scaled by `scale` (at least one cell per axis), same bounds.
pub fn scaled_grid(base: &GridSpec, scale: f64) -> anyhow::Result<GridSpec> {
    let (min, max) = base.bounds();
    let res = base.res().map(|r| ((f64::from(r - 1) * scale).round() as u32).max(1) + 1);
    Ok(GridSpec::new(min, max, res)?)
}

/// The octree series: name and finest level (see [`crate::compare_entries`]).
const ADAPTIVE_SERIES: [(&str, u32); 2] = [("adaptive", 2), ("adaptive1", 1)];

const LOOKUPS: [GradientLookup; 3] =
    [GradientLookup::Taylor, GradientLookup::GradientTrilinear, GradientLookup::Hermite];

/// Runs the study on `plate` (module docs).
pub fn sweep(
    loaded: &LoadedScene,
    tracer: &Tracer,
    base: &GridSpec,
    args: &CompareArgs,
    plate: &PlateData,
) -> anyhow::Result<SweepReport> {
    check_scales(&args.sweep_scales)?;
    let mut points = Vec::new();
    for &scale in &args.sweep_scales {
        let grid = scaled_grid(base, scale)?;
        let label = format!("sweep x{scale}");
        let gv = gradient_volume(loaded, tracer, &grid, args, Method::Doi, args.gradient_estimator, &label)?;
        let bake_rays = gv.stats.rays.total();
        let bake_seconds = gv.stats.wall_time.as_secs_f64();
        let mut push = |series: String, memory_bytes: usize, estimate: &[[f64; 3]], seconds: f64| {
            let m = plate_metrics(plate, estimate);
            if !args.quiet {
                eprintln!(
                    "memory sweep {series:<18} {:>3}x{:>3}x{:>3} {:>9} bytes: rel RMSE {:.4}",
                    grid.res()[0],
                    grid.res()[1],
                    grid.res()[2],
                    memory_bytes,
                    m.rel_rmse
                );
            }
            points.push(SweepPoint {
                series,
                res: grid.res(),
                nodes: grid.node_count(),
                memory_bytes,
                rel_rmse: m.rel_rmse,
                bias: m.bias,
                too_dark_near: m.too_dark_near,
                rays: bake_rays,
                seconds,
            });
        };
        push(
            "uniform".into(),
            uniform_memory_bytes(&gv.volume, false),
            &evaluate(&gv.volume, plate),
            bake_seconds,
        );
        for lookup in LOOKUPS {
            let est = evaluate_gradient(&gv, lookup, plate)?;
            push(
                format!("uniform+{}", lookup_name(lookup)),
                uniform_memory_bytes(&gv.volume, true),
                &est,
                bake_seconds + gv.gradient_seconds,
            );
        }
        for (series, levels) in ADAPTIVE_SERIES {
            let (av, stats, _) =
                adaptive_volume(loaded, tracer, &grid, args, levels, &format!("{series} x{scale}"))?;
            let m = plate_metrics(plate, &evaluate_adaptive(&av, plate));
            if !args.quiet {
                eprintln!(
                    "memory sweep {:<18} base {:?} {:>9} bytes: rel RMSE {:.4}",
                    series,
                    av.base().spec().res(),
                    av.memory_bytes(),
                    m.rel_rmse
                );
            }
            points.push(SweepPoint {
                series: series.into(),
                res: av.finest_res(),
                nodes: av.stored_nodes(),
                memory_bytes: av.memory_bytes(),
                rel_rmse: m.rel_rmse,
                bias: m.bias,
                too_dark_near: m.too_dark_near,
                rays: stats.rays.total(),
                seconds: stats.wall_time.as_secs_f64(),
            });
        }
    }
    // Series by series, each by memory.
    points.sort_by(|a, b| a.series.cmp(&b.series).then(a.memory_bytes.cmp(&b.memory_bytes)));
    Ok(SweepReport {
        scene: loaded.label.clone(),
        plate_height: plate.height,
        valid_points: plate.valid.iter().filter(|&&v| v).count(),
        samples: args.sampling.samples,
        base_res: base.res(),
        scales: args.sweep_scales.clone(),
        points,
    })
}

/// rel_rmse against log2 of the memory in KiB, one line per series.
#[must_use]
pub fn plot(report: &SweepReport) -> Plot {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for p in &report.points {
        // Memories span two orders of magnitude: a log axis (the plot's axis is linear).
        let xy = ((p.memory_bytes as f64 / 1024.0).log2(), p.rel_rmse);
        match series.iter_mut().find(|s| s.0 == p.series) {
            Some(s) => s.1.push(xy),
            None => series.push((p.series.clone(), vec![xy])),
        }
    }
    Plot {
        title: format!("{}: relative RMSE vs run-time memory", report.scene.trim_start_matches("builtin:")),
        x_label: "log2 of memory in KiB (f32 SH [+ gradients] per node)".into(),
        y_label: "relative RMSE".into(),
        series,
    }
}

/// Runs the study and writes `memory_sweep.json`, `memory_sweep.svg` and `memory_sweep.png`
/// into `dir`.
pub fn run(
    loaded: &LoadedScene,
    tracer: &Tracer,
    base: &GridSpec,
    args: &CompareArgs,
    plate: &PlateData,
    dir: &Path,
) -> anyhow::Result<SweepReport> {
    let report = sweep(loaded, tracer, base, args, plate)?;
    write_atomic(&dir.join("memory_sweep.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    plot(&report).write(&dir.join("memory_sweep"))?;
    Ok(report)
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
        assert!(check_scales(&[0.5, 1.0]).is_ok());
        assert!(check_scales(&[]).is_err());
        assert!(check_scales(&[0.0]).is_err());
        assert!(check_scales(&[f64::NAN]).is_err());
        assert!(check_scales(&[5.0]).is_err());
    }
}
