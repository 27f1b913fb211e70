//! `lightvol bake`: bake an irradiance volume.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use lightvol_sampler::baselines::bake_baseline;
use lightvol_sampler::gradient_estimator::GradientEstimator;
use lightvol_sampler::method::BakeMethod;
use lightvol_sampler::method::Baseline;
use lightvol_sampler::request::{BakeRequest, Provenance, accumulator_path, bake_uniform};
use lightvol_scene::{Tracer, Transport};
use lightvol_volume::GridSpec;
use lightvol_volume::frame::FileGrid;
use lightvol_volume::io::accumulator::write_accumulator;
use lightvol_volume::io::exr::{ExrOptions, write_exr, write_exr_with_gradients};
use serde::Serialize;

use crate::bake_args::{BakeArgs, request};
use crate::progress::with_bar;
use crate::setup::{LoadedScene, with_threads};

/// Bake statistics as printed by `bake --json`.
#[derive(Debug, Serialize)]
pub(crate) struct BakeReport {
    /// Scene label.
    pub(crate) scene: String,
    /// Method name.
    pub(crate) method: String,
    /// The grid.
    pub(crate) grid: FileGrid,
    /// Samples per cell or node.
    pub(crate) samples: u32,
    /// Seed.
    pub(crate) seed: u64,
    /// Rays by kind.
    pub(crate) rays: lightvol_scene::RayCounts,
    /// Cells where Algorithm 2 found back faces.
    pub(crate) cells_with_back_faces: u64,
    /// Candidate samples.
    pub(crate) candidates: u64,
    /// Samples kept.
    pub(crate) samples_kept: u64,
    /// Samples rejected as outside the domain.
    pub(crate) samples_rejected: u64,
    /// Nodes with zero weight.
    pub(crate) zero_weight_nodes: usize,
    /// Zero-weight nodes filled from neighbours.
    pub(crate) filled_nodes: usize,
    /// Sampling wall time.
    pub(crate) seconds: f64,
    /// BVH build time.
    pub(crate) bvh_seconds: f64,
    /// Throughput.
    pub(crate) mrays_per_second: f64,
    /// The scene's size, the memory estimate against the peak, and the whole command's time.
    #[serde(flatten)]
    pub(crate) scale: ScaleJson,
    /// Output file.
    pub(crate) output: String,
    /// The gradients, when baked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) gradients: Option<GradientsJson>,
    /// What an engine baseline did, when the method is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) baseline: Option<BaselineJson>,
}

/// An engine baseline's probes in `bake --json`.
#[derive(Debug, Serialize)]
pub(crate) struct BaselineJson {
    /// Nodes its validity test rejected.
    pub(crate) invalid_nodes: usize,
    /// Nodes sampled elsewhere than at the node (virtual offset, relocation).
    pub(crate) moved_nodes: usize,
    /// Whether the volume file carries the validity mask (`point+apv`).
    pub(crate) validity_mask: bool,
}

/// Size and cost figures of a bake, in `bake --json` (flattened into [`BakeReport`]).
#[derive(Debug, Serialize)]
pub(crate) struct ScaleJson {
    /// Triangles the scene places (every instance counted).
    pub(crate) triangles: u64,
    /// Triangles stored (each instanced mesh once).
    pub(crate) unique_triangles: u64,
    /// Mesh instances.
    pub(crate) instances: u64,
    /// The memory estimate checked against `--max-memory-mib`: scene, ray tracer and grid.
    pub(crate) estimated_memory_bytes: u64,
    /// This process's peak resident memory (Linux), measured after writing the volume.
    pub(crate) peak_memory_bytes: Option<u64>,
    /// Wall time of the whole command: load, BVH, bake and write.
    pub(crate) total_seconds: f64,
}

impl ScaleJson {
    /// The figures of a bake of `loaded` on `grid` with `coeffs` coefficients per channel,
    /// recording the node reach or not (`node_reach`), begun at `started` (call it once the
    /// volume is written).
    #[must_use]
    pub(crate) fn now(
        loaded: &LoadedScene,
        grid: &GridSpec,
        coeffs: usize,
        node_reach: bool,
        started: Instant,
    ) -> Self {
        Self {
            triangles: loaded.scene.triangle_count() as u64,
            unique_triangles: loaded.scene.unique_triangle_count() as u64,
            instances: loaded.scene.instances.len() as u64,
            estimated_memory_bytes: u64::try_from(
                lightvol_sampler::scene_setup::bake_memory_bytes(
                    grid.res().map(u64::from),
                    coeffs,
                    node_reach,
                ) + u128::from(loaded.memory.total()),
            )
            .unwrap_or(u64::MAX),
            peak_memory_bytes: lightvol_scene::estimate::peak_resident_bytes(),
            total_seconds: started.elapsed().as_secs_f64(),
        }
    }
}

/// The gradient step in `bake --json`.
#[derive(Debug, Serialize)]
pub(crate) struct GradientsJson {
    /// Estimator name.
    pub(crate) estimator: GradientEstimator,
    /// Nodes with a singular basis-gradient system (zero gradient).
    pub(crate) singular_nodes: usize,
    /// Directions traced beyond the bake.
    pub(crate) extra_directions: u64,
    /// Wall time beyond the bake.
    pub(crate) seconds: f64,
    /// Bytes of gradient data (f32).
    pub(crate) memory_bytes: usize,
}

/// Runs `lightvol bake`.
pub(crate) fn run(args: &BakeArgs) -> anyhow::Result<ExitCode> {
    if args.adaptive.adaptive {
        return crate::adaptive_bake::run(args);
    }
    let request = request(args, None)?;
    if let Some(first) = args.adaptive.stray_options().first() {
        bail!("{first} needs --adaptive");
    }
    if let BakeMethod::Baseline(b) = request.method {
        return run_baseline(args, &request, b);
    }
    let started = Instant::now();
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    let grid = args.grid.grid(&loaded, request.records_node_reach())?;
    let label = request.label();
    let key = request.key(&loaded.scene, &grid);
    let provenance = Provenance { frame: loaded.frame, key: &key };
    let (bake, bvh_seconds) = with_threads(args.sampling.threads, || -> anyhow::Result<_> {
        let t0 = Instant::now();
        let tracer = Tracer::new(&loaded.scene);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let transport = Transport::new(&loaded.scene, &tracer, request.transport);
        let bake = with_bar(args.quiet, &args.method, |c| {
            bake_uniform(&transport, &loaded.scene, &grid, &request, provenance, c)
        })?;
        Ok((bake, bvh_seconds))
    })??;
    if request.writes_accumulator() {
        let acc_path = accumulator_path(&args.output);
        write_accumulator(&acc_path, &bake.output.accumulator, bake.volume.metadata())
            .with_context(|| format!("writing {}", acc_path.display()))?;
        if !args.json {
            eprintln!("wrote {}", acc_path.display());
        }
    }
    if let (Some((lambda, solve)), false) = (&bake.least_squares, args.json) {
        eprintln!(
            "least-squares fit (λ = {lambda}): {} nodes, {} CG iterations, residual {:.1e}",
            solve.active_nodes, solve.max_iterations, solve.max_relative_residual
        );
    }
    let vol = &bake.volume;
    match &bake.gradients {
        None => write_exr(&args.output, vol, &ExrOptions::default()),
        Some(g) => write_exr_with_gradients(&args.output, vol, &g.gradients, &ExrOptions::default()),
    }
    .with_context(|| format!("writing {}", args.output.display()))?;
    let s = &bake.output.stats;
    let report = BakeReport {
        scene: loaded.label.clone(),
        method: label,
        grid: FileGrid::of(&grid, loaded.frame),
        samples: args.sampling.samples.get(),
        seed: args.sampling.seed,
        rays: s.rays,
        cells_with_back_faces: s.cells_with_back_faces,
        candidates: s.candidates,
        samples_kept: s.samples_kept,
        samples_rejected: s.samples_rejected,
        zero_weight_nodes: vol.weights().iter().filter(|&&w| w == 0.0).count(),
        filled_nodes: bake.fill.filled,
        seconds: s.wall_time.as_secs_f64(),
        bvh_seconds,
        mrays_per_second: s.mrays_per_second(),
        scale: ScaleJson::now(&loaded, &grid, args.grid.coeffs(), request.records_node_reach(), started),
        output: args.output.display().to_string(),
        gradients: bake.gradients.as_ref().map(|g| GradientsJson {
            estimator: g.estimator,
            singular_nodes: g.singular_nodes,
            extra_directions: g.extra_directions,
            seconds: g.seconds,
            memory_bytes: g.gradients.memory_bytes(),
        }),
        baseline: None,
    };
    print_report(args, &report)?;
    Ok(ExitCode::SUCCESS)
}

/// `lightvol bake --method point+…`: an engine baseline ([`lightvol_sampler::baselines`]),
/// whole (no shards, gradients or octree), written as the native EXR (`point+apv` with its
/// validity mask).
fn run_baseline(args: &BakeArgs, request: &BakeRequest, baseline: Baseline) -> anyhow::Result<ExitCode> {
    let name = baseline.name();
    let started = Instant::now();
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    let grid = args.grid.grid(&loaded, false)?;
    let settings = request.settings();
    let (bake, bvh_seconds, seconds) = with_threads(args.sampling.threads, || -> anyhow::Result<_> {
        let t0 = Instant::now();
        let tracer = Tracer::new(&loaded.scene);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let transport = Transport::new(&loaded.scene, &tracer, request.transport);
        let t1 = Instant::now();
        let bake = bake_baseline(&transport, &grid, &settings, baseline).context("baking")?;
        Ok((bake, bvh_seconds, t1.elapsed().as_secs_f64()))
    })??;
    let key = request.key(&loaded.scene, &grid);
    let meta = request.metadata(&loaded.scene, loaded.frame, &key, bake.rays.sampling);
    let vol = bake.volume.clone().with_metadata(meta);
    write_exr(&args.output, &vol, &ExrOptions::default())
        .with_context(|| format!("writing {}", args.output.display()))?;
    let report = BakeReport {
        scene: loaded.label.clone(),
        method: name.to_owned(),
        grid: FileGrid::of(&grid, loaded.frame),
        samples: args.sampling.samples.get(),
        seed: args.sampling.seed,
        rays: bake.rays,
        cells_with_back_faces: 0,
        candidates: 0,
        samples_kept: 0,
        samples_rejected: 0,
        zero_weight_nodes: bake.invalid_nodes(),
        filled_nodes: bake.filled,
        seconds,
        bvh_seconds,
        mrays_per_second: if seconds > 0.0 { bake.rays.total() as f64 / seconds / 1e6 } else { 0.0 },
        scale: ScaleJson::now(&loaded, &grid, args.grid.coeffs(), request.records_node_reach(), started),
        output: args.output.display().to_string(),
        gradients: None,
        baseline: Some(BaselineJson {
            invalid_nodes: bake.invalid_nodes(),
            moved_nodes: bake.moved_nodes(&grid),
            validity_mask: vol.validity().is_some(),
        }),
    };
    print_report(args, &report)?;
    Ok(ExitCode::SUCCESS)
}

/// Prints `report`: JSON on stdout with `--json`, else lines on stderr.
fn print_report(args: &BakeArgs, report: &BakeReport) -> anyhow::Result<()> {
    if args.json {
        println!("{}", serde_json::to_string_pretty(report)?);
    } else {
        eprintln!(
            "baked {} ({}) on {}x{}x{} nodes: {} rays ({} sampling, {} query, {} bounce, {} shadow) in {:.2} s = {:.2} Mrays/s",
            report.scene,
            report.method,
            report.grid.res[0],
            report.grid.res[1],
            report.grid.res[2],
            report.rays.total(),
            report.rays.sampling,
            report.rays.query,
            report.rays.bounce,
            report.rays.shadow,
            report.seconds,
            report.mrays_per_second
        );
        if let Some(b) = &report.baseline {
            eprintln!(
                "invalid nodes {} (filled {}), moved nodes {}, validity mask {}",
                b.invalid_nodes,
                report.filled_nodes,
                b.moved_nodes,
                if b.validity_mask { "written (validity-weighted lookups)" } else { "none" }
            );
        } else {
            eprintln!(
                "cells with back faces {}, samples kept {} / rejected {}, zero-weight nodes {} (filled {})",
                report.cells_with_back_faces,
                report.samples_kept,
                report.samples_rejected,
                report.zero_weight_nodes,
                report.filled_nodes
            );
        }
        if let Some(g) = &report.gradients {
            eprintln!(
                "gradients ({}) in {:.2} s: {} extra directions, {} singular nodes (zero gradient), {} bytes",
                g.estimator.name(),
                g.seconds,
                g.extra_directions,
                g.singular_nodes,
                g.memory_bytes
            );
        }
        eprintln!("wrote {}", args.output.display());
    }
    Ok(())
}
