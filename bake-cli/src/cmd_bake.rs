//! `lightvol bake`: bake an irradiance volume.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lightvol_sampler::baselines::{Baseline, bake_baseline};
use lightvol_sampler::eval::entries::{BakeMethod, parse_bake_method};
use lightvol_sampler::gradient_estimator::{GradientEstimator, bake_with_estimator};
use lightvol_sampler::node_fit::{
    Fit, MassMatrix, bake_with_mass, finalize_least_squares, solve_least_squares,
};
use lightvol_sampler::{
    BakeControl, BakeOutput, BakeSettings, Method, Progress, Tracer, Transport, TransportSettings,
};
use lightvol_volume::io::accumulator::write_accumulator;
use lightvol_volume::io::exr::{ExrOptions, write_exr, write_exr_with_gradients};
use lightvol_volume::{BakeMetadata, GridSpec, IrradianceVolume};
use serde::Serialize;

use crate::gradient_args::GradientEstimatorArg;
use crate::setup::{GridArgs, LoadedScene, SampleArgs, SceneArgs, parse_method, with_threads};

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
    pub grid: GridJson,
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
                crate::setup::bake_memory_bytes(grid.res().map(u64::from), coeffs)
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

/// Grid description in reports.
#[derive(Debug, Serialize, Clone)]
pub struct GridJson {
    /// Nodes per axis, along the scene file's axes.
    pub res: [u32; 3],
    /// Min and max corners in the scene file's frame.
    pub bounds: [[f64; 3]; 2],
    /// The frame of `res` and `bounds` (the scene file's: `y-up` or `z-up`).
    pub frame: lightvol_sampler::UpAxis,
}

impl GridJson {
    /// Describes an (unplaced) internal grid in the scene file's frame `frame`, so that
    /// `--bounds` and `--res` with these values give the same grid back.
    pub fn of(spec: &GridSpec, frame: lightvol_sampler::UpAxis) -> Self {
        let f = lightvol_volume::frame::grid_in_file_frame(spec, frame).unwrap_or_else(|_| spec.clone());
        let (a, b) = f.bounds();
        Self { res: f.res(), bounds: [a, b], frame }
    }
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

/// What a bake carries besides its accumulator.
enum Grads {
    /// Per-node SH gradients, their report, and what a shard file carries of them (boxed:
    /// the variant is much larger than the others).
    Gradients(
        lightvol_volume::VolumeGradients,
        GradientsJson,
        Box<lightvol_sampler::gradient_bake::ShardGradients>,
    ),
    /// The mass matrix of a least-squares fit.
    Mass(MassMatrix),
}

/// [`run_bake`] that also accumulates the least-squares mass matrix.
fn run_bake_with_mass(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    settings: &BakeSettings,
    transport_settings: TransportSettings,
    quiet: bool,
    label: &str,
) -> anyhow::Result<(BakeOutput, MassMatrix)> {
    with_progress(loaded, tracer, transport_settings, quiet, label, |t, c| {
        bake_with_mass(t, grid, settings, c)
    })
}

/// A short stable hash of the scene geometry and bake settings (FNV-1a over the triangle
/// vertices and the settings' text), for the file metadata.
pub fn scene_hash(loaded: &LoadedScene, extra: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    let scene = &loaded.scene;
    for t in scene.triangles.iter().chain(scene.prototypes.iter().flat_map(|p| &p.triangles)) {
        for v in t.v {
            for c in v.to_array() {
                eat(&c.to_le_bytes());
            }
        }
    }
    for i in &scene.instances {
        eat(&i.prototype.to_le_bytes());
        for c in i.to_world.to_cols_array() {
            eat(&c.to_le_bytes());
        }
    }
    eat(extra.as_bytes());
    format!("{h:016x}")
}

/// Finalizes an accumulator into a volume with metadata.
pub fn finish_volume(
    out: &BakeOutput,
    meta: BakeMetadata,
) -> (IrradianceVolume, lightvol_volume::FillReport) {
    let (vol, fill) = out.accumulator.finalize();
    (vol.with_metadata(meta), fill)
}

/// Runs `lightvol bake`.
pub fn run(args: &BakeArgs) -> anyhow::Result<ExitCode> {
    if let BakeMethod::Baseline(b) = parse_bake_method(&args.method)? {
        return run_baseline(args, b);
    }
    if args.adaptive.adaptive {
        return crate::adaptive_bake::run(args);
    }
    if let Some(first) = args.adaptive.stray_options().first() {
        bail!("{first} needs --adaptive");
    }
    let method = parse_method(&args.method)?;
    let started = Instant::now();
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    let grid = args.grid.grid(&loaded)?;
    if args.sampling.samples == 0 {
        anyhow::bail!("--samples must be at least 1");
    }
    let shard = lightvol_sampler::shard::resolve_shard(args.shard.as_deref(), args.shards, |k| {
        std::env::var(k).ok()
    })?;
    let settings = BakeSettings {
        method,
        samples: args.sampling.samples,
        coeffs: args.grid.coeffs(),
        seed: args.sampling.seed,
        shard,
        ..BakeSettings::default()
    };
    let fit = if method == Method::Point { Fit::Average } else { args.sampling.fit };
    if matches!(method, Method::DoiNode | Method::Doi) && fit != Fit::Average {
        bail!(
            "--fit {fit} needs cell samples (--method prefilter or doi-paper); {} samples per node",
            lightvol_sampler::eval::entries::method_name(method)
        );
    }
    if fit != Fit::Average && args.gradients.is_some() {
        bail!(
            "--fit {fit} cannot be combined with --gradients (the gradient estimators assume --fit average)"
        );
    }
    let estimator =
        args.gradients.map(|g| g.map_or(GradientEstimator::default_for(method), GradientEstimator::from));
    if estimator.is_some_and(|e| !e.supports(method)) {
        bail!(
            "--gradients basis needs cell samples (--method prefilter or doi-paper); use --gradients central with point, doi or doi-node"
        );
    }
    let ts = args.sampling.transport();
    let (mut out, grads, bvh_seconds) = with_threads(args.sampling.threads, || -> anyhow::Result<_> {
        let t0 = Instant::now();
        let tracer = Tracer::new(&loaded.scene);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        Ok(match estimator {
            None if fit != Fit::Average => {
                let (out, mass) =
                    run_bake_with_mass(&loaded, &tracer, &grid, &settings, ts, args.quiet, &args.method)?;
                (out, Some(Grads::Mass(mass)), bvh_seconds)
            }
            None => (
                run_bake(&loaded, &tracer, &grid, &settings, ts, args.quiet, &args.method)?,
                None,
                bvh_seconds,
            ),
            Some(est) => {
                let transport = Transport::new(&loaded.scene, &tracer, ts);
                let g = with_bar(args.quiet, &args.method, |c| {
                    bake_with_estimator(&transport, &grid, &settings, est, c)
                })?;
                let json = GradientsJson {
                    estimator: g.estimator,
                    singular_nodes: g.singular_nodes,
                    extra_directions: g.extra_directions,
                    seconds: g.seconds,
                    memory_bytes: g.gradients.memory_bytes(),
                };
                (g.output, Some(Grads::Gradients(g.gradients, json, Box::new(g.sums))), bvh_seconds)
            }
        })
    })??;
    let method_label =
        if fit == Fit::Average { args.method.clone() } else { format!("{} fit={fit}", args.method) };
    let meta = bake_metadata(args, &loaded, &grid, &settings, &method_label, out.stats.rays.sampling, shard);
    if args.shard.is_some() || args.keep_accumulator {
        let acc_path = args.output.with_extension("lvacc");
        // A least-squares bake's mass matrix travels in the shard file (exact sums too), so
        // `merge` solves the fit over the whole set.
        // (Auxiliary sums do not change what the accumulator finalizes to.)
        match &grads {
            Some(Grads::Mass(mass)) => mass.attach_to(&mut out.accumulator),
            Some(Grads::Gradients(_, _, sums)) => sums.attach_to(&mut out.accumulator),
            _ => {}
        }
        write_accumulator(&acc_path, &out.accumulator, &meta)
            .with_context(|| format!("writing {}", acc_path.display()))?;
        if !args.json {
            eprintln!("wrote {}", acc_path.display());
        }
    }
    let (vol, fill, grads, grads_json) = match grads {
        None => {
            let (vol, fill) = finish_volume(&out, meta);
            (vol, fill, None, None)
        }
        Some(Grads::Gradients(g, j, _)) => {
            let (vol, fill) = finish_volume(&out, meta);
            (vol, fill, Some(g), Some(j))
        }
        Some(Grads::Mass(mass)) => {
            let Fit::LeastSquares { lambda } = fit else {
                unreachable!("mass matrices are only baked for lsq")
            };
            let (values, solve) =
                solve_least_squares(&mass, &out.accumulator, lambda).context("least-squares node fit")?;
            if !args.json {
                eprintln!(
                    "least-squares fit (λ = {lambda}): {} nodes, {} CG iterations, residual {:.1e}",
                    solve.active_nodes, solve.max_iterations, solve.max_relative_residual
                );
            }
            let (vol, fill) = finalize_least_squares(&out.accumulator, values);
            (vol.with_metadata(meta), fill, None, None)
        }
    };
    match &grads {
        None => write_exr(&args.output, &vol, &ExrOptions::default()),
        Some(g) => write_exr_with_gradients(&args.output, &vol, g, &ExrOptions::default()),
    }
    .with_context(|| format!("writing {}", args.output.display()))?;
    let s = &out.stats;
    let report = BakeReport {
        scene: loaded.label.clone(),
        method: method_label,
        grid: GridJson::of(&grid, loaded.frame),
        samples: args.sampling.samples,
        seed: args.sampling.seed,
        rays: RaysJson::of(&s.rays),
        cells_with_back_faces: s.cells_with_back_faces,
        candidates: s.candidates,
        samples_kept: s.samples_kept,
        samples_rejected: s.samples_rejected,
        zero_weight_nodes: vol.weights().iter().filter(|&&w| w == 0.0).count(),
        filled_nodes: fill.filled,
        seconds: s.wall_time.as_secs_f64(),
        bvh_seconds,
        mrays_per_second: s.mrays_per_second(),
        scale: ScaleJson::now(&loaded, &grid, args.grid.coeffs(), started),
        output: args.output.display().to_string(),
        gradients: grads_json,
        baseline: None,
    };
    print_report(args, &report)?;
    Ok(ExitCode::SUCCESS)
}

/// The file metadata of a bake of `grid` with `settings`, under the method name `label`,
/// which used `samples` sampling rays.
fn bake_metadata(
    args: &BakeArgs,
    loaded: &LoadedScene,
    grid: &GridSpec,
    settings: &BakeSettings,
    label: &str,
    samples: u64,
    shard: (u32, u32),
) -> BakeMetadata {
    BakeMetadata {
        method: label.to_owned(),
        samples,
        seed: args.sampling.seed,
        shard_index: shard.0,
        shard_count: shard.1,
        scene_hash: scene_hash(
            loaded,
            &format!(
                "{:?} {:?} {} {} coeffs={} bounces={} {} lightvol={}",
                grid.bounds(),
                grid.res(),
                label,
                settings.samples,
                settings.coeffs,
                args.sampling.transport().label(),
                lightvol_sampler::surface::lighting_fingerprint(&loaded.scene, &args.sampling.transport()),
                env!("CARGO_PKG_VERSION")
            ),
        ),
        units: "relative".into(),
        frame: loaded.frame,
    }
}

/// `lightvol bake --method point+…`: an engine baseline ([`lightvol_sampler::baselines`]),
/// whole (no shards, gradients or octree), written as the native EXR (`point+apv` with its
/// validity mask).
fn run_baseline(args: &BakeArgs, baseline: Baseline) -> anyhow::Result<ExitCode> {
    let name = baseline.name();
    let refused = [
        (args.adaptive.adaptive, "--adaptive"),
        (args.shard.is_some() || args.shards.is_some(), "--shard"),
        (args.keep_accumulator, "--keep-accumulator"),
        (args.gradients.is_some(), "--gradients"),
    ];
    if let Some((_, option)) = refused.iter().find(|(set, _)| *set) {
        bail!(
            "{option} cannot be combined with --method {name} (the engine baselines bake a whole uniform grid)"
        );
    }
    if let Some(first) = args.adaptive.stray_options().first() {
        bail!("{first} needs --adaptive");
    }
    let started = Instant::now();
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    let grid = args.grid.grid(&loaded)?;
    if args.sampling.samples == 0 {
        bail!("--samples must be at least 1");
    }
    let settings = BakeSettings {
        method: Method::Point,
        samples: args.sampling.samples,
        coeffs: args.grid.coeffs(),
        seed: args.sampling.seed,
        ..BakeSettings::default()
    };
    let ts = args.sampling.transport();
    let (bake, bvh_seconds, seconds) = with_threads(args.sampling.threads, || -> anyhow::Result<_> {
        let t0 = Instant::now();
        let tracer = Tracer::new(&loaded.scene);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let transport = Transport::new(&loaded.scene, &tracer, ts);
        let t1 = Instant::now();
        let bake = bake_baseline(&transport, &grid, &settings, baseline).context("baking")?;
        Ok((bake, bvh_seconds, t1.elapsed().as_secs_f64()))
    })??;
    let meta = bake_metadata(args, &loaded, &grid, &settings, name, bake.rays.sampling, (0, 1));
    let vol = bake.volume.clone().with_metadata(meta);
    write_exr(&args.output, &vol, &ExrOptions::default())
        .with_context(|| format!("writing {}", args.output.display()))?;
    let report = BakeReport {
        scene: loaded.label.clone(),
        method: name.to_owned(),
        grid: GridJson::of(&grid, loaded.frame),
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
