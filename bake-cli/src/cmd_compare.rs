//! `lightvol compare`: bake every method at equal sample budget and evaluate each on a
//! horizontal plate against a path-traced reference (Kontkanen & Laine 2006, Fig. 6).
//!
//! The comparison itself is lightvol-sampler's `eval::compare`; this verb turns the options
//! into its `CompareConfig`, draws its progress, and writes what it returns: `report.json`,
//! `plate.exr`, the panels, with `--camera` the views (`view_CAMERA_METHOD.png`,
//! `view_CAMERA_reference.png`) and, with `--memory-sweep`, the sweep's files.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::{Mutex, PoisonError};

use anyhow::Context;
use clap::Args;
use indicatif::ProgressBar;
use lightvol_sampler::envmap::luminance;
use lightvol_sampler::eval::entries::lookup_name;
use lightvol_sampler::eval::sweep::{MAX_SWEEP_SCALE, SweepConfig, check_scales};
use lightvol_sampler::eval::{
    CompareConfig, Comparison, EvalError, MethodRun, Metrics, NamedEntry, Observer, Plate, PlateConfig,
    RunDetail, SweepPoint, ViewCamera, ViewsConfig, default_plate_height,
};
use lightvol_sampler::view::ViewError;
use lightvol_sampler::{GridSpec, Progress};
use serde::Serialize;
use serde_json::{Map, Value, json};

use crate::compare_views::{ViewArgs, ViewJson, cameras, write_view};
use crate::imaging::{Rgb32, diverging, write_atomic, write_png_linear};
use crate::progress::progress_bar;
use crate::report_parts::{RaysJson, ReferenceJson};
use crate::setup::{GridArgs, LoadedScene, SampleArgs, SceneArgs, resolve_threads};
use lightvol_volume::frame::FileGrid;

/// `lightvol compare`.
#[derive(Debug, Args, Clone)]
pub(crate) struct CompareArgs {
    /// Scene and lights.
    #[command(flatten)]
    pub(crate) scene: SceneArgs,
    /// Grid.
    #[command(flatten)]
    pub(crate) grid: GridArgs,
    /// Sampling (the same budget for every method).
    #[command(flatten)]
    pub(crate) sampling: SampleArgs,
    /// Height of the horizontal evaluation plate along the scene file's up axis (normal =
    /// up; the same number in either frame, since the internal +Z is the file's up). Default: the built-in
    /// scene's first recommended height, or 10% of the scene's height above its floor.
    #[arg(long)]
    pub(crate) plate_height: Option<f64>,
    /// Plate resolution along its longer side.
    #[arg(long, default_value_t = PlateConfig::DEFAULT_RES)]
    pub(crate) plate_res: u32,
    /// Methods to compare: `point`, `prefilter`, `doi`, `doi-paper`, `doi-node` (trilinear
    /// lookup; see `bake --method`), or
    /// `BASE+LOOKUP` for a bake with SH gradients (Oat 2005) read by `taylor` (nearest node,
    /// first-order Taylor), `gtrilinear` (gradient-extrapolated corners, trilinear) or
    /// `hermite` (tricubic Hermite), e.g. `doi-paper+taylor,doi-paper+hermite`; `adaptive` for Oat's
    /// octree baked to the uniform grid's memory (finest level 2 below half the grid's
    /// resolution; `adaptive1` stops one level earlier); `BASE+lsq[:λ]` or `BASE+average` for
    /// a bake finalized with that node fit instead of `--fit`'s; the engines' leak fixes
    /// `point+validity` (invalid probes dilated), `point+apv` (Unity APV, validity-weighted
    /// lookups), `point+vlm` (Unreal), `point+ddgi` (DDGI relocation).
    #[arg(long, default_value = "point,prefilter,doi-paper,doi", value_delimiter = ',')]
    pub(crate) methods: Vec<String>,
    /// Gradient estimator of the `BASE+LOOKUP` entries (default: `basis` for
    /// prefilter/doi-paper, no extra rays; `central` for point, doi and doi-node).
    #[arg(long, value_enum)]
    pub(crate) gradient_estimator: Option<crate::gradient_args::GradientEstimatorArg>,
    /// Also run the error-vs-memory study on this plate: uniform doi-paper at several
    /// resolutions, the same bakes read through the Taylor and Hermite gradient lookups,
    /// writing `memory_sweep.json`, `.png` and `.svg`.
    #[arg(long)]
    pub(crate) memory_sweep: bool,
    /// Scale factors of the grid's cell counts for `--memory-sweep`.
    #[arg(long, value_delimiter = ',', default_value = "0.5,0.7,1,1.4")]
    pub(crate) sweep_scales: Vec<f64>,
    /// Path-traced samples per plate point for the reference.
    #[arg(long, default_value_t = PlateConfig::DEFAULT_REFERENCE_SAMPLES)]
    pub(crate) reference_samples: u32,
    /// Directions traced per plate point to decide whether it sees back faces.
    #[arg(long, default_value_t = PlateConfig::DEFAULT_CLASSIFY_DIRS)]
    pub(crate) classify_dirs: u32,
    /// Views through cameras.
    #[command(flatten)]
    pub(crate) views: ViewArgs,
    /// Output directory (created if missing).
    #[arg(short, long, default_value = "compare-out")]
    pub(crate) output: PathBuf,
    /// No progress bars.
    #[arg(long)]
    pub(crate) quiet: bool,
}

/// `report.json` of `compare`.
#[derive(Debug, Serialize, Clone)]
pub(crate) struct CompareReport {
    /// Scene label.
    pub(crate) scene: String,
    /// Up axis of the source scene.
    pub(crate) up: String,
    /// The plate.
    pub(crate) plate: PlateJson,
    /// The grid.
    pub(crate) grid: FileGrid,
    /// The reference.
    pub(crate) reference: ReferenceJson,
    /// Per method, in the order run.
    pub(crate) methods: Map<String, Value>,
    /// Per camera, in the order given (only with `--camera`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) views: Option<Vec<ViewJson>>,
}

/// Plate description.
#[derive(Debug, Serialize, Clone)]
pub(crate) struct PlateJson {
    /// Height (z).
    pub(crate) height: f64,
    /// Points per side.
    pub(crate) res: [u32; 2],
    /// Points that see no back faces.
    pub(crate) valid_points: usize,
    /// Valid points near a surface.
    pub(crate) near_points: usize,
}

/// One method's entry.
#[derive(Debug, Serialize, Clone)]
pub(crate) struct MethodJson {
    /// Samples per cell (per node for point).
    pub(crate) samples: u32,
    /// Rays by kind.
    pub(crate) rays: RaysJson,
    /// Bake wall time.
    pub(crate) seconds: f64,
    /// The leakage metrics.
    #[serde(flatten)]
    pub(crate) metrics: Metrics,
}

/// Progress bars on stderr for the stages of an evaluation, and the sweeps' lines (nothing
/// when quiet).
pub(crate) struct ProgressBars {
    quiet: bool,
    bar: Mutex<Option<ProgressBar>>,
}

impl ProgressBars {
    /// ProgressBars drawn unless `quiet`.
    #[must_use]
    pub(crate) fn new(quiet: bool) -> Self {
        Self { quiet, bar: Mutex::new(None) }
    }

    fn bar(&self) -> std::sync::MutexGuard<'_, Option<ProgressBar>> {
        self.bar.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl Observer for ProgressBars {
    fn stage_started(&self, label: &str) {
        *self.bar() = Some(progress_bar(self.quiet, 0, label));
    }

    fn progress(&self, p: Progress) {
        if let Some(pb) = &*self.bar() {
            pb.set_length(p.total as u64);
            pb.set_position(p.done as u64);
        }
    }

    fn stage_finished(&self) {
        if let Some(pb) = self.bar().take() {
            pb.finish_and_clear();
        }
    }

    fn sweep_point(&self, p: &SweepPoint, octree_base: Option<[u32; 3]>) {
        if self.quiet {
            return;
        }
        match octree_base {
            None => eprintln!(
                "memory sweep {:<18} {:>3}x{:>3}x{:>3} {:>9} bytes: rel RMSE {:.4}",
                p.series, p.res[0], p.res[1], p.res[2], p.memory_bytes, p.rel_rmse
            ),
            Some(base) => eprintln!(
                "memory sweep {:<18} base {:?} {:>9} bytes: rel RMSE {:.4}",
                p.series, base, p.memory_bytes, p.rel_rmse
            ),
        }
    }

    fn resolution_point(&self, method: &str, nodes_x: u32, metrics: &Metrics) {
        if !self.quiet {
            eprintln!("sweep {method:>9} {nodes_x:>3} nodes along x: rel RMSE {:.4}", metrics.rel_rmse);
        }
    }
}

/// The evaluation's errors in the words of this verb's options.
#[must_use]
pub(crate) fn flag_error(e: EvalError) -> anyhow::Error {
    match e {
        EvalError::NoMethods => anyhow::anyhow!("--methods needs at least one method"),
        EvalError::ZeroSamples => anyhow::anyhow!("--samples and --reference-samples must be at least 1"),
        EvalError::NoSweepScales => anyhow::anyhow!("--sweep-scales needs at least one scale"),
        EvalError::SweepScale(s) => anyhow::anyhow!("--sweep-scales: {s} is not in (0, {MAX_SWEEP_SCALE}]"),
        EvalError::PlateHeightNotFinite(_) => anyhow::anyhow!("--plate-height must be finite"),
        EvalError::PlateOutsideGrid { height, min, max } => {
            anyhow::anyhow!("--plate-height {height} is outside the grid's z range [{min}, {max}]")
        }
        EvalError::PlateResolution(_) => anyhow::anyhow!("--plate-res must be at least 2"),
        EvalError::BasisNeedsCells { .. } => anyhow::anyhow!(
            "--gradients basis needs cell samples (prefilter, doi-paper); use --gradient-estimator central with point, doi or doi-node"
        ),
        EvalError::ZeroThreads => anyhow::anyhow!("--threads must be at least 1"),
        EvalError::View(ViewError::ZeroSamples) => anyhow::anyhow!("--view-samples must be at least 1"),
        EvalError::View(e @ ViewError::ImageSize { .. }) => {
            anyhow::Error::new(e).context("--view-width/--view-height")
        }
        EvalError::DuplicateView(label) => {
            anyhow::anyhow!("two --camera options give the view '{label}'; give each camera once")
        }
        EvalError::ViewSeesNothing(label) => {
            anyhow::anyhow!("--camera: view '{label}' sees no surface inside the grid")
        }
        e => e.into(),
    }
}

/// The evaluation's configuration from the options, for `grid`, the plate at `height` and
/// the cameras `views`.
#[must_use]
pub(crate) fn config(
    args: &CompareArgs,
    methods: Vec<NamedEntry>,
    grid: GridSpec,
    height: f64,
    views: Vec<ViewCamera>,
    threads: Option<usize>,
) -> CompareConfig {
    let gradient_estimator = args.gradient_estimator.map(Into::into);
    CompareConfig {
        grid,
        coeffs: args.grid.coeffs(),
        methods,
        samples: args.sampling.samples,
        seed: args.sampling.seed,
        transport: args.sampling.transport(),
        fit: args.sampling.fit,
        gradient_estimator,
        plate: PlateConfig {
            height,
            res: args.plate_res,
            reference_samples: args.reference_samples,
            classify_dirs: args.classify_dirs,
        },
        memory_sweep: args
            .memory_sweep
            .then(|| SweepConfig { scales: args.sweep_scales.clone(), gradient_estimator }),
        views: ViewsConfig { cameras: views, reference_samples: args.views.view_samples },
        threads,
    }
}

/// The plate height of the options: `--plate-height`, else the scene's default.
#[must_use]
pub(crate) fn plate_height(args: &CompareArgs, loaded: &LoadedScene) -> f64 {
    args.plate_height.unwrap_or_else(|| default_plate_height(&loaded.scene, &loaded.plate_heights))
}

/// Runs the whole comparison and writes its outputs; returns the report.
pub(crate) fn compare(args: &CompareArgs) -> anyhow::Result<CompareReport> {
    // Checks in the order the verb has always made them: the options alone, then with the
    // scene and grid, then (after the output folder exists) the rest, in the evaluation.
    let methods: Vec<NamedEntry> =
        args.methods.iter().map(|m| NamedEntry::parse(m)).collect::<Result<_, _>>()?;
    if args.memory_sweep {
        check_scales(&args.sweep_scales).map_err(flag_error)?;
    }
    if methods.is_empty() {
        return Err(flag_error(EvalError::NoMethods));
    }
    if args.reference_samples == 0 || args.sampling.samples == 0 {
        return Err(flag_error(EvalError::ZeroSamples));
    }
    if !args.views.cameras.is_empty() && args.views.view_samples == 0 {
        return Err(flag_error(EvalError::View(ViewError::ZeroSamples)));
    }
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    let grid = args.grid.grid(&loaded)?;
    if grid.placement().is_some() {
        return Err(flag_error(EvalError::PlacedGrid));
    }
    let height = plate_height(args, &loaded);
    if !height.is_finite() {
        return Err(flag_error(EvalError::PlateHeightNotFinite(height)));
    }
    let views = cameras(&args.views, &loaded, &grid)?;
    ViewsConfig { cameras: views.clone(), reference_samples: args.views.view_samples }
        .validate()
        .map_err(flag_error)?;
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    let threads = resolve_threads(args.sampling.threads)?;
    let config = config(args, methods, grid, height, views, threads);
    let result = lightvol_sampler::eval::compare(&loaded.scene, &config, &ProgressBars::new(args.quiet))
        .map_err(flag_error)?;
    write_outputs(&args.output, &loaded, &config, &result, &args.views.cameras)
}

/// Report fields of one run beyond [`MethodJson`].
fn extra(run: &MethodRun) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("memory_bytes".into(), json!(run.memory_bytes));
    m.insert("nodes".into(), json!(run.nodes));
    match &run.detail {
        RunDetail::Uniform => {}
        RunDetail::Gradient { lookup, estimator, extra_directions, singular_nodes } => {
            m.insert("lookup".into(), json!(lookup_name(*lookup)));
            m.insert("gradient_estimator".into(), json!(estimator.name()));
            m.insert("gradient_extra_directions".into(), json!(extra_directions));
            m.insert("gradient_singular_nodes".into(), json!(singular_nodes));
        }
        RunDetail::Adaptive { memory_budget, base_res, finest_res, levels, depth_rays } => {
            m.insert("memory_budget".into(), json!(memory_budget));
            m.insert("base_res".into(), json!(base_res));
            m.insert("finest_res".into(), json!(finest_res));
            m.insert("levels".into(), json!(levels));
            m.insert("depth_rays".into(), json!(depth_rays));
        }
        RunDetail::Baseline { invalid_nodes, moved_nodes } => {
            m.insert("invalid_nodes".into(), json!(invalid_nodes));
            m.insert("moved_nodes".into(), json!(moved_nodes));
        }
    }
    m
}

/// Writes the panels, the views, the sweep's files, `plate.exr` and `report.json` of
/// `result` into `dir` (`specs`: the `--camera` options of the views); returns the report.
fn write_outputs(
    dir: &Path,
    loaded: &LoadedScene,
    config: &CompareConfig,
    result: &Comparison,
    specs: &[String],
) -> anyhow::Result<CompareReport> {
    let plate = &result.plate;
    for run in &result.methods {
        write_panels(dir, &run.name, plate, &run.estimate, result.mean_truth)?;
    }
    let mut views_json = Vec::with_capacity(result.views.len());
    for (view, spec) in result.views.iter().zip(specs) {
        views_json.push(write_view(dir, view, spec, config.views.reference_samples)?);
    }
    if let Some(sweep) = &result.memory_sweep {
        crate::memory_sweep::write(dir, &loaded.label, sweep)?;
    }
    let named: Vec<(String, Vec<[f64; 3]>)> =
        result.methods.iter().map(|r| (r.name.clone(), r.estimate.clone())).collect();
    write_plate_exr(&dir.join("plate.exr"), plate, &named)?;
    let mut methods_json = Map::new();
    for r in &result.methods {
        let json = MethodJson {
            samples: r.samples,
            rays: RaysJson::of(&r.rays),
            seconds: r.seconds,
            metrics: r.metrics,
        };
        let mut v = serde_json::to_value(&json)?;
        if let Value::Object(m) = &mut v {
            m.extend(extra(r));
        }
        methods_json.insert(r.name.clone(), v);
    }
    let report = CompareReport {
        scene: loaded.label.clone(),
        up: loaded.frame.name().to_owned(),
        plate: PlateJson {
            height: plate.height,
            res: [plate.res[0] as u32, plate.res[1] as u32],
            valid_points: plate.valid_points(),
            near_points: plate.near_points(),
        },
        grid: FileGrid::of(&config.grid, loaded.frame),
        reference: ReferenceJson {
            samples: config.plate.reference_samples,
            mean: result.mean_truth,
            seconds: plate.reference_seconds,
        },
        methods: methods_json,
        views: (!views_json.is_empty()).then_some(views_json),
    };
    write_atomic(&dir.join("report.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    Ok(report)
}

/// Bright green for points outside the domain of interest (\[KL06\] Fig. 6).
const INVALID_GREEN: [f32; 3] = [0.0, 4.0, 0.0];

/// Writes the Fig. 6-style panel (method | reference) and the signed error heat map.
pub(crate) fn write_panels(
    dir: &Path,
    name: &str,
    plate: &Plate,
    estimate: &[[f64; 3]],
    mean_truth: f64,
) -> anyhow::Result<()> {
    let [w, h] = plate.res;
    let exposure = if mean_truth > 0.0 { (0.45 / mean_truth) as f32 } else { 1.0 };
    let mut panel = Rgb32::new(2 * w + 4, h);
    let mut err = Rgb32::new(w, h);
    for j in 0..h {
        // Image row 0 is the plate's max y (north up).
        let y = h - 1 - j;
        for i in 0..w {
            let k = j * w + i;
            let (e, t) = (estimate[k], plate.truth[k]);
            if plate.valid[k] {
                panel.set(i, y, e.map(|v| v as f32));
                panel.set(w + 4 + i, y, t.map(|v| v as f32));
                let rel = ((luminance(e) - luminance(t)) / mean_truth.max(1e-12)) as f32;
                err.set(i, y, diverging(rel * 2.0));
            } else {
                panel.set(i, y, INVALID_GREEN.map(|v| v / exposure));
                panel.set(w + 4 + i, y, INVALID_GREEN.map(|v| v / exposure));
                err.set(i, y, [0.0, 1.0, 0.0]);
            }
        }
        for g in 0..4 {
            panel.set(w + g, y, [1.0 / exposure; 3]);
        }
    }
    // Small plates are enlarged so that a person can see them (at least ~384 px wide).
    let k = (384 / (2 * w + 4)).max(1);
    write_png_linear(&dir.join(format!("panel_{name}.png")), &panel.upscale(k), exposure)?;
    // The error map is already in display units.
    let err = Rgb32 {
        pixels: err.pixels.iter().map(|p| p.map(lightvol_core::color::srgb_decode_f32)).collect(),
        ..err
    };
    write_png_linear(&dir.join(format!("error_{name}.png")), &err.upscale(k * 2), 1.0)
}

/// Writes `plate.exr`: luminance channels `truth`, `valid`, `near` and one per method.
pub(crate) fn write_plate_exr(
    path: &Path,
    plate: &Plate,
    methods: &[(String, Vec<[f64; 3]>)],
) -> anyhow::Result<()> {
    use exr::prelude::*;
    let [w, h] = plate.res;
    // EXR rows run top-down: row 0 = max y.
    let flip = |v: &dyn Fn(usize) -> f32| -> Vec<f32> {
        (0..h).rev().flat_map(|j| (0..w).map(move |i| j * w + i)).map(v).collect()
    };
    let mut channels = vec![
        AnyChannel::new("truth", FlatSamples::F32(flip(&|k| luminance(plate.truth[k]) as f32))),
        AnyChannel::new("valid", FlatSamples::F32(flip(&|k| f32::from(u8::from(plate.valid[k]))))),
        AnyChannel::new("near", FlatSamples::F32(flip(&|k| f32::from(u8::from(plate.near[k]))))),
    ];
    for (name, est) in methods {
        channels.push(AnyChannel::new(name.as_str(), FlatSamples::F32(flip(&|k| luminance(est[k]) as f32))));
    }
    let layer = Layer::new(
        (w, h),
        LayerAttributes::named("plate"),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let ia = ImageAttributes::new(layer.absolute_bounds());
    let bytes = lightvol_volume::io::exr::encode_image(ia, vec![layer]).context("encoding plate.exr")?;
    write_atomic(path, &bytes)
}

/// Runs `lightvol compare`.
pub(crate) fn run(args: &CompareArgs) -> anyhow::Result<ExitCode> {
    let report = compare(args)?;
    eprintln!(
        "{:<14} {:>9} {:>8} {:>9} {:>13} {:>10} {:>10} {:>8} {:>10}",
        "method", "rel_rmse", "bias", "too_dark", "too_dark_near", "too_bright", "rays", "seconds", "memory"
    );
    for (name, v) in &report.methods {
        let m: MethodJsonView = serde_json::from_value(v.clone())?;
        eprintln!(
            "{name:<14} {:>9.4} {:>8.4} {:>9.4} {:>13.4} {:>10.4} {:>10} {:>8.2} {:>10}",
            m.rel_rmse,
            m.bias,
            m.too_dark,
            m.too_dark_near,
            m.too_bright,
            m.rays.total,
            m.seconds,
            m.memory_bytes
        );
    }
    for v in report.views.iter().flatten() {
        let [w, h] = v.resolution;
        eprintln!(
            "view {} ({w}x{h}, {} reference samples): relative RMSE over pixels",
            v.camera, v.reference.samples
        );
        for (name, m) in &v.methods {
            eprintln!("  {name:<14} {:>9.4}", m["rel_rmse"].as_f64().unwrap_or(f64::NAN));
        }
    }
    eprintln!("wrote {}", args.output.join("report.json").display());
    Ok(ExitCode::SUCCESS)
}

#[derive(serde::Deserialize)]
struct MethodJsonView {
    rays: RaysView,
    seconds: f64,
    rel_rmse: f64,
    bias: f64,
    too_dark: f64,
    too_dark_near: f64,
    too_bright: f64,
    #[serde(default)]
    memory_bytes: u64,
}

#[derive(serde::Deserialize)]
struct RaysView {
    total: u64,
}
