//! The entries of `lightvol compare` beyond seed 000's three bakes: a uniform bake read
//! through one of seed 002's gradient lookups (`doi+taylor`, `doi+gtrilinear`,
//! `doi+hermite`, any base method), and, with lightvol's adaptive octree, `adaptive`.
//!
//! Every entry reports `memory_bytes`, the run-time bytes of what a renderer would keep:
//! for a uniform grid seed 002's accounting (RGB SH floats per node, ×4 with gradients,
//! f32; bake weights not counted, see [`uniform_memory_bytes`]).

use std::collections::BTreeMap;

use anyhow::bail;
use lightvol_sampler::{BakeSettings, BakeStats, Method, Tracer, TransportSettings};
use lightvol_volume::gradient::{GradientLookup, irradiance as gradient_irradiance};
use lightvol_volume::{GridSpec, IrradianceVolume, VolumeGradients};
use rayon::prelude::*;
use serde_json::{Map, Value, json};

use crate::cmd_bake::RaysJson;
use crate::cmd_compare::{CompareArgs, MethodJson, MethodRun, PlateData, plate_metrics};
use crate::gradients::{GradientEstimator, bake_with, lookup_name, parse_lookup, uniform_memory_bytes};
use crate::setup::{LoadedScene, parse_method};

/// One `--methods` entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entry {
    /// A uniform bake read by trilinear interpolation (seed 000 Fig. 6).
    Uniform(Method),
    /// A uniform bake with per-node gradients, read by a gradient lookup (seed 002).
    Gradient(Method, GradientLookup),
}

/// Parses `point|prefilter|doi` or `BASE+LOOKUP` with LOOKUP one of `taylor`,
/// `gtrilinear`, `hermite`.
pub fn parse_entry(s: &str) -> anyhow::Result<Entry> {
    match s.split_once('+') {
        None => Ok(Entry::Uniform(parse_method(s)?)),
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
    let ts = TransportSettings { bounces: args.sampling.bounces, ..TransportSettings::default() };
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

/// Report fields a plain uniform entry adds to [`MethodJson`].
#[must_use]
pub fn uniform_extra(grid: &GridSpec, coeffs: usize) -> Map<String, Value> {
    let bands = (coeffs as f64).sqrt().round() as usize;
    let mut m = Map::new();
    m.insert(
        "memory_bytes".into(),
        json!(grid.node_count() * lightvol_volume::gradient::floats_per_sample(bands, false) * 4),
    );
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
        let key = method_key(base);
        if !self.bakes.contains_key(&key) {
            let gv = gradient_volume(loaded, tracer, grid, args, base, estimator, label)?;
            self.bakes.insert(key, gv);
        }
        match self.bakes.get(&key) {
            Some(gv) => Ok(gv),
            None => bail!("gradient bake missing"),
        }
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
        assert!(parse_entry("doi+cubic").is_err());
        assert!(parse_entry("bogus+taylor").is_err());
    }

    /// Seed 002's accounting for a 16×16×7 order-3 grid: 27 floats × 4 bytes per node.
    #[test]
    fn uniform_memory_is_seed_002_floats() {
        let g = GridSpec::new([0.0; 3], [1.0; 3], [16, 16, 7]).unwrap();
        assert_eq!(uniform_extra(&g, 9)["memory_bytes"], json!(16 * 16 * 7 * 27 * 4));
    }
}
