//! `lightvol bake --adaptive`: an adaptive octree volume (\[Oat05\], "Adaptive Octree
//! Subdivision", "Subdivision Heuristics"), baked by lightvol-sampler's `bake_adaptive`
//! over the grid options' grid as level 0, written to the native EXR's adaptive extension.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_sampler::adaptive::{AdaptiveSettings, AdaptiveStats, bake_adaptive};
use lightvol_sampler::{BakeControl, BakeSettings, Progress, Tracer, Transport, TransportSettings};
use lightvol_volume::adaptive_io::write_adaptive_exr;
use lightvol_volume::{AdaptiveVolume, BakeMetadata, GridSpec};
use serde_json::json;

use crate::cmd_bake::{BakeArgs, RaysJson, progress_bar, scene_hash};
use crate::setup::{LoadedScene, parse_method, with_threads};

/// Options of `bake --adaptive` (each heuristic with its threshold, Oat 2005, "Subdivision
/// Heuristics"). Defaults are lightvol-sampler's `AdaptiveSettings::default()`; giving any
/// of them without `--adaptive` is an error.
#[derive(Debug, Clone, Args)]
pub struct AdaptiveArgs {
    /// Bake an adaptive octree volume: the grid options give level 0, cells split by the
    /// heuristics below down to --max-level, redundant nodes are culled.
    #[arg(long)]
    pub adaptive: bool,
    /// Every cell of the levels below this one is split (nodes of levels up to it are never
    /// culled). Default 0.
    #[arg(long, value_name = "L")]
    pub min_level: Option<u32>,
    /// The finest level (level l has cells 2^l times smaller than the grid's); at most 8.
    /// Default 2.
    #[arg(long, value_name = "L")]
    pub max_level: Option<u32>,
    /// Split a cell when the largest coefficient change along its edges, relative to the
    /// volume's mean DC value, is at least T (`off` disables the heuristic). Default 0.25.
    #[arg(long, value_name = "T|off", allow_hyphen_values = true)]
    pub gradient_threshold: Option<String>,
    /// Do not split cells because scene geometry lies inside them.
    #[arg(long)]
    pub no_geometry_split: bool,
    /// Split a cell when its edge exceeds R times the harmonic-mean scene depth at a corner
    /// (`off` disables the heuristic). Default 1.
    #[arg(long, value_name = "R|off", allow_hyphen_values = true)]
    pub depth_ratio: Option<String>,
    /// Rays per node for the harmonic-mean depth. Default 32.
    #[arg(long, value_name = "N")]
    pub depth_rays: Option<u32>,
    /// Cull a node whose difference from the coarser levels' interpolation is within this
    /// fraction of the volume's mean DC value. Default 0.01.
    #[arg(long, value_name = "TOL", allow_hyphen_values = true)]
    pub cull_tolerance: Option<f64>,
    /// Memory budget, stated as the node count of a uniform grid of the same memory: the
    /// octree's bytes (coefficients, base weights, 8-byte keys, split bitmaps) stay within
    /// N × (3·coeffs + 1) × 4 bytes, the bytes of N uniform nodes with their weights.
    #[arg(long, value_name = "N")]
    pub node_budget: Option<u64>,
}

fn threshold(name: &str, s: Option<&str>, default: Option<f64>) -> anyhow::Result<Option<f64>> {
    let Some(s) = s else { return Ok(default) };
    if s.trim() == "off" {
        return Ok(None);
    }
    let t: f64 = s.trim().parse().with_context(|| format!("{name}: '{s}' is not a number or 'off'"))?;
    if !(t.is_finite() && t > 0.0) {
        bail!("{name} must be a positive finite number or 'off', got {s}");
    }
    Ok(Some(t))
}

/// Bytes of `nodes` uniform nodes with their weights (`IrradianceVolume::memory_bytes`).
#[must_use]
pub fn node_budget_bytes(nodes: u64, coeffs: usize) -> u128 {
    u128::from(nodes) * (3 * coeffs as u128 + 1) * 4
}

impl AdaptiveArgs {
    /// The options given without `--adaptive`, if any.
    #[must_use]
    pub fn stray_options(&self) -> Vec<&'static str> {
        let given = [
            ("--min-level", self.min_level.is_some()),
            ("--max-level", self.max_level.is_some()),
            ("--gradient-threshold", self.gradient_threshold.is_some()),
            ("--no-geometry-split", self.no_geometry_split),
            ("--depth-ratio", self.depth_ratio.is_some()),
            ("--depth-rays", self.depth_rays.is_some()),
            ("--cull-tolerance", self.cull_tolerance.is_some()),
            ("--node-budget", self.node_budget.is_some()),
        ];
        if self.adaptive { Vec::new() } else { given.iter().filter(|g| g.1).map(|g| g.0).collect() }
    }

    /// The sampler's settings, validated (one clear error each).
    pub fn settings(&self, coeffs: usize) -> anyhow::Result<AdaptiveSettings> {
        let d = AdaptiveSettings::default();
        let cull_tolerance = self.cull_tolerance.unwrap_or(d.cull_tolerance);
        if !(cull_tolerance.is_finite() && cull_tolerance >= 0.0) {
            bail!("--cull-tolerance must be finite and >= 0, got {cull_tolerance}");
        }
        let max = lightvol_volume::adaptive::MAX_LEVEL;
        let (min_level, max_level) =
            (self.min_level.unwrap_or(d.min_level), self.max_level.unwrap_or(d.max_level));
        if max_level > max || min_level > max_level {
            bail!("--min-level {min_level} and --max-level {max_level} need min <= max <= {max}");
        }
        let memory_budget = match self.node_budget {
            None => None,
            Some(0) => bail!("--node-budget must be at least 1"),
            Some(n) => Some(
                usize::try_from(node_budget_bytes(n, coeffs))
                    .map_err(|_| anyhow::anyhow!("--node-budget {n} is too large"))?,
            ),
        };
        let depth_ratio_threshold =
            threshold("--depth-ratio", self.depth_ratio.as_deref(), d.depth_ratio_threshold)?;
        let depth_rays = self.depth_rays.unwrap_or(d.depth_rays);
        if depth_ratio_threshold.is_some() && depth_rays == 0 {
            bail!("--depth-rays must be at least 1 with the depth heuristic on");
        }
        let s = AdaptiveSettings {
            min_level,
            max_level,
            gradient_threshold: threshold(
                "--gradient-threshold",
                self.gradient_threshold.as_deref(),
                d.gradient_threshold,
            )?,
            geometry: !self.no_geometry_split,
            depth_ratio_threshold,
            depth_rays,
            cull_tolerance,
            memory_budget,
        };
        s.validate().map_err(|e| anyhow::anyhow!("{e}"))?;
        Ok(s)
    }
}

/// Runs `bake_adaptive` with a progress bar.
#[allow(clippy::too_many_arguments, reason = "the bake's inputs plus its presentation")]
pub fn run_adaptive_bake(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    settings: &BakeSettings,
    adaptive: &AdaptiveSettings,
    ts: TransportSettings,
    quiet: bool,
    label: &str,
) -> anyhow::Result<(AdaptiveVolume, AdaptiveStats)> {
    let transport = Transport::new(&loaded.scene, tracer, ts);
    let pb = progress_bar(quiet, 0, label);
    let report = |p: Progress| {
        pb.set_length(p.total as u64);
        pb.set_position(p.done as u64);
    };
    let control = BakeControl { progress: Some(&report), cancel: None };
    let out = bake_adaptive(&transport, grid, settings, adaptive, &control).context("adaptive bake")?;
    pb.finish_and_clear();
    Ok(out)
}

/// `lightvol bake --adaptive`.
pub fn run(args: &BakeArgs) -> anyhow::Result<ExitCode> {
    if args.shard.is_some() || args.keep_accumulator {
        bail!(
            "--adaptive cannot be combined with --shard or --keep-accumulator (an octree bake is not sharded)"
        );
    }
    if args.gradients.is_some() {
        bail!("--adaptive cannot be combined with --gradients (the octree stores no gradients)");
    }
    let method = parse_method(&args.method)?;
    let loaded = args.scene.load()?;
    let grid = args.grid.grid(&loaded)?;
    if args.sampling.samples == 0 {
        bail!("--samples must be at least 1");
    }
    let coeffs = args.grid.coeffs();
    let adaptive = args.adaptive.settings(coeffs)?;
    let settings = BakeSettings {
        method,
        samples: args.sampling.samples,
        coeffs,
        seed: args.sampling.seed,
        ..BakeSettings::default()
    };
    let ts = TransportSettings { bounces: args.sampling.bounces, ..TransportSettings::default() };
    let (vol, stats, bvh_seconds) = with_threads(args.sampling.threads, || -> anyhow::Result<_> {
        let t0 = Instant::now();
        let tracer = Tracer::new(&loaded.scene);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let (v, s) =
            run_adaptive_bake(&loaded, &tracer, &grid, &settings, &adaptive, ts, args.quiet, &args.method)?;
        Ok((v, s, bvh_seconds))
    })??;
    let meta = BakeMetadata {
        method: args.method.clone(),
        samples: stats.rays.sampling,
        seed: args.sampling.seed,
        shard_index: 0,
        shard_count: 1,
        scene_hash: scene_hash(
            &loaded,
            &format!(
                "{:?} {:?} {} {} {adaptive:?}",
                grid.bounds(),
                grid.res(),
                args.method,
                settings.samples
            ),
        ),
        units: "relative".into(),
    };
    let vol = vol.with_metadata(meta);
    write_adaptive_exr(&args.output, &vol).with_context(|| format!("writing {}", args.output.display()))?;
    let rays = RaysJson::of(&stats.rays);
    let report = json!({
        "scene": loaded.label,
        "method": args.method,
        "adaptive": true,
        "grid": crate::cmd_bake::GridJson::of(&grid),
        "samples": args.sampling.samples,
        "seed": args.sampling.seed,
        "rays": rays,
        "depth_rays": stats.depth_rays,
        "split_votes": { "gradient": stats.split_votes[0], "geometry": stats.split_votes[1], "depth": stats.split_votes[2] },
        "octree": crate::adaptive_files::octree_json(&vol),
        "seconds": stats.wall_time.as_secs_f64(),
        "bvh_seconds": bvh_seconds,
        "output": args.output.display().to_string(),
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    let [nx, ny, nz] = grid.res();
    let f = vol.finest_res();
    eprintln!(
        "baked {} ({}, adaptive) on {nx}x{ny}x{nz} base nodes, levels 0..{} (finest {}x{}x{}): {} rays in {:.2} s",
        loaded.label,
        args.method,
        vol.max_level(),
        f[0],
        f[1],
        f[2],
        rays.total,
        stats.wall_time.as_secs_f64()
    );
    eprintln!(
        "split votes: gradient {}, geometry {}, depth {}",
        stats.split_votes[0], stats.split_votes[1], stats.split_votes[2]
    );
    for l in vol.level_stats() {
        eprintln!(
            "level {}: {} cells ({} leaves, {} split), {} nodes stored of {} baked",
            l.level, l.cells, l.leaves, l.split, l.stored_nodes, l.created_nodes
        );
    }
    eprintln!("memory {} bytes ({} stored nodes)", vol.memory_bytes(), vol.stored_nodes());
    eprintln!("wrote {}", args.output.display());
    Ok(ExitCode::SUCCESS)
}
