//! `lightvol bake`: bake an irradiance volume.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lightvol_sampler::baselines::{Baseline, bake_baseline};
use lightvol_sampler::eval::entries::{BakeMethod, parse_bake_method};
use lightvol_sampler::gradient_estimator::GradientEstimator;
use lightvol_sampler::provenance;
use lightvol_sampler::request::{
    AdaptiveRequest, BakeRequest, Conflict, GradientChoice, Provenance, RequestError, bake_uniform,
};
use lightvol_sampler::{
    BakeControl, BakeOutput, BakeSettings, Progress, Tracer, Transport, TransportSettings,
};
use lightvol_volume::GridSpec;
use lightvol_volume::frame::FileGrid;
use lightvol_volume::io::accumulator::write_accumulator;
use lightvol_volume::io::exr::{ExrOptions, write_exr, write_exr_with_gradients};
use serde::Serialize;

use crate::gradient_args::GradientEstimatorArg;
use crate::setup::{GridArgs, LoadedScene, SampleArgs, SceneArgs, with_threads};

/// `lightvol bake`.
#[derive(Debug, Args)]
pub struct BakeArgs {
    /// Scene and lights.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Grid.
    #[command(flatten)]
    pub grid: GridArgs,
    /// Sampling.
    #[command(flatten)]
    pub sampling: SampleArgs,
    /// Sampling method: `doi` (default: each node point-sampled where it is in the domain of
    /// interest, at a point relocated through its closest back face or over Eq. 6's support
    /// where it is not), `doi-paper` (Kontkanen & Laine 2006: Eq. 5-6 restricted to the
    /// domain of interest, Algorithm 2), `doi-node` (Algorithm 2 over each node's own cell),
    /// `point` (Eq. 4 at each node), `prefilter` (Eq. 5-6, no domain test); or point
    /// sampling with an engine's leak fix: `point+validity` (invalid probes dilated),
    /// `point+apv` (Unity APV: virtual offset, dilation, and a validity mask in the file for
    /// validity-weighted lookups), `point+vlm` (Unreal) or `point+ddgi` (DDGI relocation).
    #[arg(long, default_value = "doi")]
    /// Method name.
    pub method: String,
    /// Bake only shard K of N (by cells, or nodes for point sampling), or `auto`: the shard
    /// from the job scheduler (Slurm array variables, Kubernetes `JOB_COMPLETION_INDEX` or
    /// AWS Batch `AWS_BATCH_JOB_ARRAY_INDEX` with --shards, or `LIGHTVOL_SHARD=K/N`). The
    /// shard's exact sums are written beside the output as `<stem>.lvacc`; `lightvol merge`
    /// combines shards into the volume the whole bake gives, bit for bit.
    #[arg(long, value_name = "K/N|auto")]
    pub shard: Option<String>,
    /// Number of shards, for `--shard auto` with Kubernetes or AWS Batch indices (checked
    /// against the Slurm array or `LIGHTVOL_SHARD` where those give it).
    #[arg(long, value_name = "N")]
    pub shards: Option<u32>,
    /// Also write the exact accumulator (`<stem>.lvacc`) of an unsharded bake: its Eq. 6
    /// sums as `merge` reads them (for example to finalize it again with `merge`).
    #[arg(long)]
    pub keep_accumulator: bool,
    /// Also bake per-node SH irradiance gradients (Oat 2005) and store them in the EXR:
    /// `basis` (from the bake's own samples, no extra rays; prefilter/doi-paper) or
    /// `central` (six extra point projections per node at 1/16 cell). Without a value, the
    /// method's own: `basis` for prefilter and doi-paper, `central` for the others.
    #[arg(long, value_enum, value_name = "ESTIMATOR", num_args = 0..=1)]
    pub gradients: Option<Option<GradientEstimatorArg>>,
    /// Adaptive octree (Oat 2005, "Adaptive Octree Subdivision").
    #[command(flatten)]
    pub adaptive: crate::adaptive_bake::AdaptiveArgs,
    /// Output volume (native multi-part EXR).
    #[arg(short, long, default_value = "volume.exr")]
    pub output: PathBuf,
    /// Print the bake statistics as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Bake statistics as printed by `bake --json`.
#[derive(Debug, Serialize)]
pub struct BakeReport {
    /// Scene label.
    pub scene: String,
    /// Method name.
    pub method: String,
    /// The grid.
    pub grid: FileGrid,
    /// Samples per cell or node.
    pub samples: u32,
    /// Seed.
    pub seed: u64,
    /// Rays by kind.
    pub rays: RaysJson,
    /// Cells where Algorithm 2 found back faces.
    pub cells_with_back_faces: u64,
    /// Candidate samples.
    pub candidates: u64,
    /// Samples kept.
    pub samples_kept: u64,
    /// Samples rejected as outside the domain.
    pub samples_rejected: u64,
    /// Nodes with zero weight.
    pub zero_weight_nodes: usize,
    /// Zero-weight nodes filled from neighbours.
    pub filled_nodes: usize,
    /// Sampling wall time.
    pub seconds: f64,
    /// BVH build time.
    pub bvh_seconds: f64,
    /// Throughput.
    pub mrays_per_second: f64,
    /// The scene's size, the memory estimate against the peak, and the whole command's time.
    #[serde(flatten)]
    pub scale: ScaleJson,
    /// Output file.
    pub output: String,
    /// The gradients, when baked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gradients: Option<GradientsJson>,
    /// What an engine baseline did, when the method is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baseline: Option<BaselineJson>,
}

/// An engine baseline's probes in `bake --json`.
#[derive(Debug, Serialize)]
pub struct BaselineJson {
    /// Nodes its validity test rejected.
    pub invalid_nodes: usize,
    /// Nodes sampled elsewhere than at the node (virtual offset, relocation).
    pub moved_nodes: usize,
    /// Whether the volume file carries the validity mask (`point+apv`).
    pub validity_mask: bool,
}

/// Size and cost figures of a bake, in `bake --json` (flattened into [`BakeReport`]).
#[derive(Debug, Serialize)]
pub struct ScaleJson {
    /// Triangles the scene places (every instance counted).
    pub triangles: u64,
    /// Triangles stored (each instanced mesh once).
    pub unique_triangles: u64,
    /// Mesh instances.
    pub instances: u64,
    /// The memory estimate checked against `--max-memory-mib`: scene, ray tracer and grid.
    pub estimated_memory_bytes: u64,
    /// This process's peak resident memory (Linux), measured after writing the volume.
    pub peak_memory_bytes: Option<u64>,
    /// Wall time of the whole command: load, BVH, bake and write.
    pub total_seconds: f64,
}

impl ScaleJson {
    /// The figures of a bake of `loaded` on `grid` with `coeffs` coefficients per channel,
    /// begun at `started` (call it once the volume is written).
    #[must_use]
    pub fn now(loaded: &LoadedScene, grid: &GridSpec, coeffs: usize, started: Instant) -> Self {
        Self {
            triangles: loaded.scene.triangle_count() as u64,
            unique_triangles: loaded.scene.unique_triangle_count() as u64,
            instances: loaded.scene.instances.len() as u64,
            estimated_memory_bytes: u64::try_from(
                lightvol_sampler::scene_setup::bake_memory_bytes(grid.res().map(u64::from), coeffs)
                    + u128::from(loaded.memory.total()),
            )
            .unwrap_or(u64::MAX),
            peak_memory_bytes: lightvol_sampler::estimate::peak_resident_bytes(),
            total_seconds: started.elapsed().as_secs_f64(),
        }
    }
}

/// The gradient step in `bake --json`.
#[derive(Debug, Serialize)]
pub struct GradientsJson {
    /// Estimator name.
    pub estimator: GradientEstimator,
    /// Nodes with a singular basis-gradient system (zero gradient).
    pub singular_nodes: usize,
    /// Directions traced beyond the bake.
    pub extra_directions: u64,
    /// Wall time beyond the bake.
    pub seconds: f64,
    /// Bytes of gradient data (f32).
    pub memory_bytes: usize,
}

/// Rays by kind in reports.
#[derive(Debug, Serialize, Clone, Copy)]
pub struct RaysJson {
    /// Sampling rays.
    pub sampling: u64,
    /// Query rays (Algorithm 2).
    pub query: u64,
    /// Bounce rays.
    pub bounce: u64,
    /// Shadow rays.
    pub shadow: u64,
    /// All rays.
    pub total: u64,
}

impl RaysJson {
    /// Converts counts.
    pub fn of(r: &lightvol_sampler::RayCounts) -> Self {
        Self { sampling: r.sampling, query: r.query, bounce: r.bounce, shadow: r.shadow, total: r.total() }
    }
}

/// A progress bar on stderr (hidden when quiet or not a terminal).
pub fn progress_bar(quiet: bool, len: u64, what: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_owned());
    pb
}

/// Runs `f` with a [`BakeControl`] whose progress drives a bar labelled `label` (hidden when
/// `quiet`), cleared when `f` returns.
pub fn with_bar<T>(quiet: bool, label: &str, f: impl FnOnce(&BakeControl<'_>) -> T) -> T {
    let pb = progress_bar(quiet, 0, label);
    let report = |p: Progress| {
        pb.set_length(p.total as u64);
        pb.set_position(p.done as u64);
    };
    let out = f(&BakeControl { progress: Some(&report), cancel: None });
    pb.finish_and_clear();
    out
}

/// Runs `bake` with a transport over `loaded` and a progress bar labelled `label` (hidden
/// when `quiet`), cleared when the bake ends.
pub(crate) fn with_progress<T>(
    loaded: &LoadedScene,
    tracer: &Tracer,
    transport_settings: TransportSettings,
    quiet: bool,
    label: &str,
    bake: impl FnOnce(&Transport<'_>, &BakeControl<'_>) -> Result<T, lightvol_sampler::BakeError>,
) -> anyhow::Result<T> {
    let transport = Transport::new(&loaded.scene, tracer, transport_settings);
    with_bar(quiet, label, |c| bake(&transport, c)).context("baking")
}

/// Bakes `loaded` on `grid` with `settings`, showing progress.
pub fn run_bake(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    settings: &BakeSettings,
    transport_settings: TransportSettings,
    quiet: bool,
    label: &str,
) -> anyhow::Result<BakeOutput> {
    with_progress(loaded, tracer, transport_settings, quiet, label, |t, c| {
        lightvol_sampler::bake(t, grid, settings, c)
    })
}

/// The bake request of the options (the shard resolved from `--shard`, `--shards` and the
/// scheduler's environment), validated.
pub(crate) fn request(args: &BakeArgs, adaptive: Option<AdaptiveRequest>) -> anyhow::Result<BakeRequest> {
    let shard = lightvol_sampler::shard::resolve_shard(args.shard.as_deref(), args.shards, |k| {
        std::env::var(k).ok()
    })?;
    let request = BakeRequest {
        method: parse_bake_method(&args.method)?,
        samples: args.sampling.samples,
        coeffs: args.grid.coeffs(),
        seed: args.sampling.seed,
        transport: args.sampling.transport(),
        fit: args.sampling.fit,
        gradients: args
            .gradients
            .map(|g| g.map_or(GradientChoice::MethodDefault, |e| GradientChoice::Estimator(e.into()))),
        shard: args.shard.is_some().then_some(shard),
        keep_accumulator: args.keep_accumulator,
        adaptive,
    };
    request.validate().map_err(request_error)?;
    Ok(request)
}

/// A refused request, in the options' words.
pub(crate) fn request_error(e: RequestError) -> anyhow::Error {
    let option = |c: Conflict| match c {
        Conflict::Adaptive => "--adaptive".to_owned(),
        Conflict::Shard => "--shard".to_owned(),
        Conflict::KeepAccumulator => "--keep-accumulator".to_owned(),
        Conflict::Gradients => "--gradients".to_owned(),
        Conflict::Fit(fit) => format!("--fit {fit}"),
    };
    match e {
        RequestError::ZeroSamples => anyhow::anyhow!("--samples must be at least 1"),
        RequestError::Baseline { baseline, with } => anyhow::anyhow!(
            "{} cannot be combined with --method {} (the engine baselines bake a whole uniform grid)",
            option(with),
            baseline.name()
        ),
        RequestError::Adaptive(c @ Conflict::KeepAccumulator) => anyhow::anyhow!(
            "--adaptive cannot be combined with {} (shard an octree bake with --shard and --level)",
            option(c)
        ),
        RequestError::Adaptive(c @ Conflict::Gradients) => {
            anyhow::anyhow!(
                "--adaptive cannot be combined with {} (the octree stores no gradients)",
                option(c)
            )
        }
        RequestError::Adaptive(c) => {
            anyhow::anyhow!(
                "--adaptive cannot be combined with {} (the octree levels use Eq. 6's average)",
                option(c)
            )
        }
        RequestError::LevelNeedsShard => anyhow::anyhow!("--level needs --shard K/N (or --shard auto)"),
        RequestError::BaseLevelFromShards => anyhow::anyhow!(
            "level 0 is baked from the scene alone: drop --from-shards, or bake a level >= 1 with --level L"
        ),
        RequestError::LevelNeedsShards(l) => {
            anyhow::anyhow!("--level {l} needs the shard files of levels 0..{l} (--from-shards)")
        }
        RequestError::FitNeedsCells { fit, method } => anyhow::anyhow!(
            "--fit {fit} needs cell samples (--method prefilter or doi-paper); {} samples per node",
            lightvol_sampler::eval::entries::method_name(method)
        ),
        RequestError::FitWithGradients(fit) => anyhow::anyhow!(
            "--fit {fit} cannot be combined with --gradients (the gradient estimators assume --fit average)"
        ),
        RequestError::BasisNeedsCells(_) => anyhow::anyhow!(
            "--gradients basis needs cell samples (--method prefilter or doi-paper); use --gradients central with point, doi or doi-node"
        ),
    }
}

/// The settings key of a bake of `request` on `grid` ([`lightvol_sampler::provenance`]).
pub(crate) fn bake_key(loaded: &LoadedScene, grid: &GridSpec, request: &BakeRequest, label: &str) -> String {
    let adaptive = request.adaptive.map(|a| a.settings);
    provenance::bake_key(
        &loaded.scene,
        grid,
        label,
        request.samples,
        request.coeffs,
        &request.transport,
        adaptive.as_ref(),
    )
}

/// Runs `lightvol bake`.
pub fn run(args: &BakeArgs) -> anyhow::Result<ExitCode> {
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
    let grid = args.grid.grid(&loaded)?;
    let label = request.label();
    let key = bake_key(&loaded, &grid, &request, &label);
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
        let acc_path = args.output.with_extension("lvacc");
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
        samples: args.sampling.samples,
        seed: args.sampling.seed,
        rays: RaysJson::of(&s.rays),
        cells_with_back_faces: s.cells_with_back_faces,
        candidates: s.candidates,
        samples_kept: s.samples_kept,
        samples_rejected: s.samples_rejected,
        zero_weight_nodes: vol.weights().iter().filter(|&&w| w == 0.0).count(),
        filled_nodes: bake.fill.filled,
        seconds: s.wall_time.as_secs_f64(),
        bvh_seconds,
        mrays_per_second: s.mrays_per_second(),
        scale: ScaleJson::now(&loaded, &grid, args.grid.coeffs(), started),
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
    let grid = args.grid.grid(&loaded)?;
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
    let key = bake_key(&loaded, &grid, request, name);
    let meta = provenance::bake_metadata(
        &loaded.scene,
        loaded.frame,
        &key,
        name,
        bake.rays.sampling,
        request.seed,
        (0, 1),
    );
    let vol = bake.volume.clone().with_metadata(meta);
    write_exr(&args.output, &vol, &ExrOptions::default())
        .with_context(|| format!("writing {}", args.output.display()))?;
    let report = BakeReport {
        scene: loaded.label.clone(),
        method: name.to_owned(),
        grid: FileGrid::of(&grid, loaded.frame),
        samples: args.sampling.samples,
        seed: args.sampling.seed,
        rays: RaysJson::of(&bake.rays),
        cells_with_back_faces: 0,
        candidates: 0,
        samples_kept: 0,
        samples_rejected: 0,
        zero_weight_nodes: bake.invalid_nodes(),
        filled_nodes: bake.filled,
        seconds,
        bvh_seconds,
        mrays_per_second: if seconds > 0.0 { bake.rays.total() as f64 / seconds / 1e6 } else { 0.0 },
        scale: ScaleJson::now(&loaded, &grid, args.grid.coeffs(), started),
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
            report.rays.total,
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
