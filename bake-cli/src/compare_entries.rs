//! The entries of `lightvol compare` beyond the three bakes of \[KL06\] §4-6: a uniform bake
//! read through one of \[Oat05\]'s gradient lookups (`doi+taylor`, `doi+gtrilinear`,
//! `doi+hermite`, any base method), and `adaptive`, \[Oat05\]'s octree.
//!
//! Every entry reports `memory_bytes`, the run-time bytes of what a renderer would keep:
//! for a uniform grid \[Oat05\]'s accounting (RGB SH floats per node, ×4 with gradients,
//! f32; bake weights not counted, see [`uniform_memory_bytes`]); for the octree
//! `AdaptiveVolume::memory_bytes` (coefficients, base weights, an 8-byte key per fine
//! node, split bitmaps).
//!
//! **Equal memory.** The `adaptive[L]` entry is baked (doi, `--samples` per cell at every
//! level) with level 0 on the compare grid with its cell counts scaled by
//! [`ADAPTIVE_BASE_SCALE`], down to level `L` (`adaptive` is [`ADAPTIVE_MAX_LEVEL`] = 2;
//! level 1 has the compare grid's cell size, level 2 half of it), the sampler's default
//! heuristics and
//! culling, under a memory budget equal
//! to the uniform entry's `memory_bytes`. The octree's own count includes its weights and
//! index, which the uniform count leaves out, so the octree never gets more memory than the
//! uniform grid it is compared with.

use std::collections::BTreeMap;

use anyhow::bail;
use lightvol_sampler::adaptive::{AdaptiveSettings, AdaptiveStats};
use lightvol_sampler::baselines::{Baseline, bake_baseline, validity_weighted_irradiance};
use lightvol_sampler::fit::Fit;
use lightvol_sampler::{BakeSettings, BakeStats, Method, Tracer};
use lightvol_volume::gradient::{GradientLookup, floats_per_sample, irradiance as gradient_irradiance};
use lightvol_volume::{AdaptiveVolume, GridSpec, IrradianceVolume, VolumeGradients};
use rayon::prelude::*;
use serde_json::{Map, Value, json};

use crate::adaptive_bake::run_adaptive_bake;
use crate::cmd_bake::RaysJson;
use crate::cmd_compare::{CompareArgs, MethodJson, MethodRun, PlateData, plate_metrics};
use crate::gradients::{GradientEstimator, bake_with, lookup_name, parse_lookup, uniform_memory_bytes};
use crate::setup::{LoadedScene, parse_method};

/// One `--methods` entry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Entry {
    /// A uniform bake read by trilinear interpolation (\[KL06\] Fig. 6).
    Uniform(Method),
    /// A uniform bake with per-node gradients, read by a gradient lookup (\[Oat05\]).
    Gradient(Method, GradientLookup),
    /// A uniform bake finalized with another node fit than `--fit`: `BASE+average` or
    /// `BASE+lsq[:λ]` (lightvol-sampler's `fit` module).
    Fitted(Method, Fit),
    /// \[Oat05\]'s adaptive octree at the uniform grid's memory, with this finest level
    /// (module docs). Named `adaptive` (level 2) or `adaptiveL`.
    Adaptive(u32),
    /// Point sampling with an engine's leak fix (lightvol-sampler's `baselines`):
    /// `point+validity` (Unity APV), `point+vlm` (Unreal), `point+ddgi` (DDGI/RTXGI).
    Baseline(Baseline),
}

/// Level 0 of the `adaptive` entry: the compare grid's cell counts times this.
pub const ADAPTIVE_BASE_SCALE: f64 = 0.5;
/// Finest level of the `adaptive` entry: level 1 has the compare grid's cell size, level 2
/// half of it. Measured with `compare --memory-sweep` (128 samples per cell, 64-point plate):
/// at every memory from 35 kB to 1.5 MB the level-2 octree has the lowest error on both
/// `city` (e.g. rel_rmse 0.1826 against the uniform grid's 0.1862 at 193.5 kB) and
/// `interior` (0.5884 against 0.8273 at 587 kB), while `adaptive1` ties with the uniform
/// grid on `city` (0.1864) and is barely better on `interior` (0.8248).
pub const ADAPTIVE_MAX_LEVEL: u32 = 2;

/// Largest `L` accepted in `adaptiveL`.
pub const ADAPTIVE_LEVELS_MAX: u32 = 3;

/// Parses `point|prefilter|doi`, `adaptive[L]`, `point+validity|vlm|ddgi`, or `BASE+LOOKUP`
/// with LOOKUP one of `taylor`, `gtrilinear`, `hermite`.
pub fn parse_entry(s: &str) -> anyhow::Result<Entry> {
    if s == "adaptive" {
        return Ok(Entry::Adaptive(ADAPTIVE_MAX_LEVEL));
    }
    if let Some(l) = s.strip_prefix("adaptive") {
        return match l.parse::<u32>() {
            Ok(l) if (1..=ADAPTIVE_LEVELS_MAX).contains(&l) => Ok(Entry::Adaptive(l)),
            _ => bail!("'{s}': adaptiveL needs a finest level L from 1 to {ADAPTIVE_LEVELS_MAX}"),
        };
    }
    for b in [Baseline::Apv, Baseline::Vlm, Baseline::Ddgi] {
        if s == b.name() {
            return Ok(Entry::Baseline(b));
        }
    }
    match s.split_once('+') {
        None => Ok(Entry::Uniform(parse_method(s)?)),
        Some((base, fit)) if fit == "average" || fit.starts_with("lsq") => Ok(Entry::Fitted(
            parse_method(base)?,
            fit.parse::<Fit>().map_err(|e| anyhow::anyhow!("'{s}': {e}"))?,
        )),
        Some((base, lookup)) => Ok(Entry::Gradient(parse_method(base)?, parse_lookup(lookup)?)),
    }
}

/// A bake with gradients, shared by every lookup on the same base method.
pub struct GradientVolume {
    /// The Eq. 6 volume.
    pub volume: IrradianceVolume,
    /// Its gradients.
    pub gradients: VolumeGradients,
    /// The bake's statistics.
    pub stats: BakeStats,
    /// Estimator used.
    pub estimator: GradientEstimator,
    /// Singular nodes (basis estimator).
    pub singular_nodes: usize,
    /// Directions traced beyond the bake (central estimator).
    pub extra_directions: u64,
    /// Seconds beyond the bake.
    pub gradient_seconds: f64,
}

/// Bakes with gradients on `grid`, the estimator `estimator` or the one that fits the method.
#[allow(clippy::too_many_arguments, reason = "the bake's inputs plus its presentation")]
pub fn gradient_volume(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    args: &CompareArgs,
    base: Method,
    estimator: Option<GradientEstimator>,
    label: &str,
) -> anyhow::Result<GradientVolume> {
    let settings = BakeSettings {
        method: base,
        samples: args.sampling.samples,
        coeffs: args.grid.coeffs(),
        seed: args.sampling.seed,
        ..BakeSettings::default()
    };
    let ts = args.sampling.transport();
    let estimator = estimator.unwrap_or_else(|| GradientEstimator::default_for(base));
    let g = bake_with(&loaded.scene, tracer, grid, &settings, ts, estimator, args.quiet, label)?;
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

/// Irradiance (normal up) at every plate point through a gradient lookup.
pub fn evaluate_gradient(
    gv: &GradientVolume,
    lookup: GradientLookup,
    plate: &PlateData,
) -> anyhow::Result<Vec<[f64; 3]>> {
    plate
        .points
        .par_iter()
        .map(|p| Ok(gradient_irradiance(&gv.volume, &gv.gradients, lookup, p.to_array(), [0.0, 0.0, 1.0])?))
        .collect()
}

/// The method entry of a gradient lookup on `gv` (report fields beyond [`MethodJson`]: the
/// lookup, the estimator, its cost, `memory_bytes`).
pub fn gradient_run(
    gv: &GradientVolume,
    name: &str,
    lookup: GradientLookup,
    samples: u32,
    plate: &PlateData,
) -> anyhow::Result<(MethodRun, Map<String, Value>)> {
    let estimate = evaluate_gradient(gv, lookup, plate)?;
    let metrics = plate_metrics(plate, &estimate);
    let extra = json!({
        "memory_bytes": uniform_memory_bytes(&gv.volume, true),
        "lookup": lookup_name(lookup),
        "gradient_estimator": gv.estimator.name(),
        "gradient_extra_directions": gv.extra_directions,
        "gradient_singular_nodes": gv.singular_nodes,
        "nodes": gv.volume.spec().node_count(),
    });
    let Value::Object(extra) = extra else { unreachable!("json! of an object literal") };
    Ok((
        MethodRun {
            name: name.to_owned(),
            json: MethodJson {
                samples,
                rays: RaysJson::of(&gv.stats.rays),
                seconds: gv.stats.wall_time.as_secs_f64() + gv.gradient_seconds,
                metrics,
            },
            estimate,
        },
        extra,
    ))
}

/// An adaptive bake with finest level `max_level` at the memory of the uniform grid `grid`
/// (module docs); returns the volume, its statistics and the budget in bytes.
pub fn adaptive_volume(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    args: &CompareArgs,
    max_level: u32,
    label: &str,
) -> anyhow::Result<(AdaptiveVolume, AdaptiveStats, usize)> {
    let coeffs = args.grid.coeffs();
    let bands = (coeffs as f64).sqrt().round() as usize;
    let budget = grid.node_count() * floats_per_sample(bands, false) * 4;
    let base = crate::memory_sweep::scaled_grid(grid, ADAPTIVE_BASE_SCALE)?;
    let settings = BakeSettings {
        method: Method::Doi,
        samples: args.sampling.samples,
        coeffs,
        seed: args.sampling.seed,
        ..BakeSettings::default()
    };
    let adaptive = AdaptiveSettings { max_level, memory_budget: Some(budget), ..AdaptiveSettings::default() };
    let ts = args.sampling.transport();
    let (vol, stats) = run_adaptive_bake(loaded, tracer, &base, &settings, &adaptive, ts, args.quiet, label)?;
    Ok((vol, stats, budget))
}

/// Irradiance (normal up) of an adaptive volume at every plate point (f32 lookup, like the
/// uniform entries').
#[must_use]
pub fn evaluate_adaptive(vol: &AdaptiveVolume, plate: &PlateData) -> Vec<[f64; 3]> {
    plate
        .points
        .par_iter()
        .map(|p| vol.irradiance(p.as_vec3().to_array(), [0.0, 0.0, 1.0]).map(f64::from))
        .collect()
}

/// The `adaptive` entry on the uniform grid `grid`'s memory.
pub fn adaptive_run(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    args: &CompareArgs,
    name: &str,
    max_level: u32,
    plate: &PlateData,
) -> anyhow::Result<(MethodRun, Map<String, Value>)> {
    let (vol, stats, budget) = adaptive_volume(loaded, tracer, grid, args, max_level, name)?;
    let estimate = evaluate_adaptive(&vol, plate);
    let metrics = plate_metrics(plate, &estimate);
    let extra = json!({
        "memory_bytes": vol.memory_bytes(),
        "memory_budget": budget,
        "nodes": vol.stored_nodes(),
        "base_res": vol.base().spec().res(),
        "finest_res": vol.finest_res(),
        "levels": vol.level_stats(),
        "depth_rays": stats.depth_rays,
    });
    let Value::Object(extra) = extra else { unreachable!("json! of an object literal") };
    Ok((
        MethodRun {
            name: name.to_owned(),
            json: MethodJson {
                samples: args.sampling.samples,
                rays: RaysJson::of(&stats.rays),
                seconds: stats.wall_time.as_secs_f64(),
                metrics,
            },
            estimate,
        },
        extra,
    ))
}

/// Runs an engine baseline on the compare grid (point samples, `--samples` per node, plus
/// the validity rays, which its ray count includes).
pub fn baseline_run(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    args: &CompareArgs,
    name: &str,
    baseline: Baseline,
    plate: &PlateData,
) -> anyhow::Result<(MethodRun, Map<String, Value>)> {
    let settings = BakeSettings {
        method: Method::Point,
        samples: args.sampling.samples,
        coeffs: args.grid.coeffs(),
        seed: args.sampling.seed,
        ..BakeSettings::default()
    };
    let ts = args.sampling.transport();
    let transport = lightvol_sampler::Transport::new(&loaded.scene, tracer, ts);
    let t0 = std::time::Instant::now();
    let b = bake_baseline(&transport, grid, &settings, baseline)?;
    let seconds = t0.elapsed().as_secs_f64();
    let estimate: Vec<[f64; 3]> = match baseline {
        Baseline::Apv => plate
            .points
            .par_iter()
            .map(|p| validity_weighted_irradiance(&b.volume, &b.valid, p.to_array(), [0.0, 0.0, 1.0]))
            .collect(),
        Baseline::Vlm | Baseline::Ddgi => crate::cmd_compare::evaluate(&b.volume, plate),
    };
    let metrics = plate_metrics(plate, &estimate);
    let mut extra = uniform_extra(grid, args.grid.coeffs());
    extra.insert("invalid_nodes".into(), json!(b.valid.iter().filter(|v| !**v).count()));
    let moved = b
        .capture
        .iter()
        .enumerate()
        .filter(|(i, c)| {
            let [x, y, z] = grid.node_coords(*i);
            lightvol_sampler::DVec3::from_array(grid.node_position_world(x, y, z)) != **c
        })
        .count();
    extra.insert("moved_nodes".into(), json!(moved));
    Ok((
        MethodRun {
            name: name.to_owned(),
            json: MethodJson {
                samples: args.sampling.samples,
                rays: RaysJson::of(&b.rays),
                seconds,
                metrics,
            },
            estimate,
        },
        extra,
    ))
}

/// Report fields a plain uniform entry adds to [`MethodJson`].
#[must_use]
pub fn uniform_extra(grid: &GridSpec, coeffs: usize) -> Map<String, Value> {
    let bands = (coeffs as f64).sqrt().round() as usize;
    let mut m = Map::new();
    m.insert("memory_bytes".into(), json!(grid.node_count() * floats_per_sample(bands, false) * 4));
    m.insert("nodes".into(), json!(grid.node_count()));
    m
}

/// Gradient bakes keyed by base method, so that `doi+taylor,doi+hermite` bake once.
#[derive(Default)]
pub struct GradientCache {
    bakes: BTreeMap<u8, GradientVolume>,
}

fn method_key(m: Method) -> u8 {
    match m {
        Method::Point => 0,
        Method::Prefilter => 1,
        Method::Doi => 2,
    }
}

impl GradientCache {
    /// The gradient bake for `base`, baked on first use.
    #[allow(clippy::too_many_arguments, reason = "the bake's inputs plus its presentation")]
    pub fn get(
        &mut self,
        loaded: &LoadedScene,
        tracer: &Tracer,
        grid: &GridSpec,
        args: &CompareArgs,
        base: Method,
        estimator: Option<GradientEstimator>,
        label: &str,
    ) -> anyhow::Result<&GradientVolume> {
        Ok(match self.bakes.entry(method_key(base)) {
            std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::btree_map::Entry::Vacant(e) => {
                e.insert(gradient_volume(loaded, tracer, grid, args, base, estimator, label)?)
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_parse() {
        assert_eq!(parse_entry("doi").unwrap(), Entry::Uniform(Method::Doi));
        assert_eq!(parse_entry("doi+taylor").unwrap(), Entry::Gradient(Method::Doi, GradientLookup::Taylor));
        assert_eq!(
            parse_entry("point+hermite").unwrap(),
            Entry::Gradient(Method::Point, GradientLookup::Hermite)
        );
        assert_eq!(parse_entry("adaptive").unwrap(), Entry::Adaptive(2));
        assert_eq!(parse_entry("doi+lsq").unwrap(), Entry::Fitted(Method::Doi, Fit::default()));
        assert_eq!(
            parse_entry("prefilter+lsq:0.5").unwrap(),
            Entry::Fitted(Method::Prefilter, Fit::LeastSquares { lambda: 0.5 })
        );
        assert_eq!(parse_entry("doi+average").unwrap(), Entry::Fitted(Method::Doi, Fit::Average));
        assert!(parse_entry("doi+lsq:-2").is_err());
        assert_eq!(parse_entry("adaptive1").unwrap(), Entry::Adaptive(1));
        assert_eq!(parse_entry("adaptive2").unwrap(), Entry::Adaptive(2));
        assert!(parse_entry("adaptive0").is_err());
        assert!(parse_entry("adaptive9").is_err());
        assert!(parse_entry("doi+cubic").is_err());
        assert!(parse_entry("bogus+taylor").is_err());
    }

    /// \[Oat05\]'s accounting for a 16×16×7 order-3 grid: 27 floats × 4 bytes per node.
    #[test]
    fn uniform_memory_is_27_floats_per_node() {
        let g = GridSpec::new([0.0; 3], [1.0; 3], [16, 16, 7]).unwrap();
        assert_eq!(uniform_extra(&g, 9)["memory_bytes"], json!(16 * 16 * 7 * 27 * 4));
    }
}
