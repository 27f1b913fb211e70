//! `lightvol compare`: bake every method at equal sample budget and evaluate each on a
//! horizontal plate against a path-traced reference (Kontkanen & Laine 2006, Fig. 6).
//!
//! The comparison itself is lightvol-eval's `compare`; this verb turns the options
//! into its `CompareConfig`, draws its progress, and writes the files `eval::report` makes
//! of what it returns: `report.json`,
//! `plate.exr`, the panels, with `--camera` the views (`view_CAMERA_METHOD.png`,
//! `view_CAMERA_reference.png`) and, with `--memory-sweep`, the sweep's files.

use lightvol_core::samples::{Samples, parse_samples};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::{Mutex, PoisonError};

use anyhow::Context;
use clap::Args;
use indicatif::ProgressBar;
use lightvol_core::progress::Progress;
use lightvol_eval::report::{CompareReport, compare_files};
use lightvol_eval::sweep::{SweepConfig, check_scales};
use lightvol_eval::{
    CompareConfig, Comparison, EvalError, Metrics, NamedEntry, Observer, PlateConfig, SweepPoint, ViewCamera,
    default_plate_height,
};
use lightvol_view::ViewError;
use lightvol_volume::GridSpec;

use crate::compare_views::{ViewArgs, cameras};
use crate::imaging::write_atomic;
use crate::progress::{progress_bar, show};
use crate::setup::{GridArgs, LoadedScene, SampleArgs, SceneArgs, resolve_threads};

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
    /// resolution; `adaptive1` stops one level earlier); `bricks` for the engines' sparse
    /// brick export of an octree (level 0 at a quarter of the grid's cell counts, finest at
    /// the grid's), `bricksN` with its probes capped at 1/N of the uniform grid's in the same
    /// texel format; `BASE+lsq[:λ]` or `BASE+average` for
    /// a bake finalized with that node fit instead of `--fit`'s; the engines' leak fixes
    /// `point+validity` (invalid probes dilated), `point+apv` (Unity APV, validity-weighted
    /// lookups), `point+vlm` (Unreal), `point+ddgi` (DDGI relocation); `BASE+ENGINE`
    /// (`three`, `bevy`, `trilinear`, `apv`) for a bake whose node values are fitted for that
    /// engine's lookup (`bake --target`), read through it with `--lookup native` or that
    /// engine's name; `bound+LOOKUP` (`three`, `bevy`, `trilinear`, `apv`, `lightvol`) for
    /// the node values that fit the plate's reference best through that lookup: not a
    /// bake but the lowest plate error any bake reaches on this grid read that way, always
    /// read through its own lookup.
    #[arg(long, default_value = "point,prefilter,doi-paper,doi", value_delimiter = ',')]
    pub(crate) methods: Vec<String>,
    /// Gradient estimator of the `BASE+LOOKUP` entries (default: `basis` for
    /// prefilter/doi-paper, no extra rays; `central` for point, doi and doi-node).
    #[arg(long, value_enum)]
    pub(crate) gradient_estimator: Option<crate::gradient_args::GradientEstimatorArg>,
    /// Also run the error-vs-memory study on this plate: uniform doi-paper at several
    /// resolutions, the same bakes read through the Taylor and Hermite gradient lookups,
    /// uniform doi, the adaptive octrees at their memory and the brick export of the finer one,
    /// writing `memory_sweep.json`, `.png` and `.svg`.
    #[arg(long)]
    pub(crate) memory_sweep: bool,
    /// Scale factors of the grid's cell counts for `--memory-sweep`.
    #[arg(long, value_delimiter = ',', default_value = "0.5,0.7,1,1.4")]
    pub(crate) sweep_scales: Vec<f64>,
    /// Path-traced samples per plate point for the reference.
    #[arg(long, value_parser = parse_samples, default_value_t = PlateConfig::DEFAULT_REFERENCE_SAMPLES)]
    pub(crate) reference_samples: Samples,
    /// Directions traced per plate point to decide whether it sees back faces.
    #[arg(long, default_value_t = PlateConfig::DEFAULT_CLASSIFY_DIRS)]
    pub(crate) classify_dirs: u32,
    /// Views through cameras.
    #[command(flatten)]
    pub(crate) views: ViewArgs,
    /// Read every entry's plate and views as this engine does: `lightvol` (its own
    /// lookups), `trilinear`, `three`, `bevy` or `apv` (as for `render --lookup`; uniform-grid
    /// entries only), or `native`: each entry as its own engine reads it (`point+apv`
    /// through APV's lookup, the other engines' fixes through plain trilinear, `BASE+ENGINE`
    /// through that engine's, lightvol's methods through lightvol's). Repeatable (or
    /// comma-separated): the first way keeps the methods' names, each further way adds
    /// `METHOD@WAY`, read from the same bakes.
    #[arg(long, value_delimiter = ',', default_value = "lightvol")]
    pub(crate) lookup: Vec<lightvol_eval::ReadAs>,
    /// The sky `BASE+relit` entries (a sky transfer) and `BASE+skyocc` entries (Unity APV's
    /// sky occlusion, the baseline) are baked under before they are relit to the
    /// comparison's own lighting: `sky:R,G,B[:R,G,B]` or `env:FILE.exr`. The other methods
    /// and the reference see the comparison's lighting (--sky, --env).
    #[arg(long, value_name = "sky:R,G,B[:R,G,B]|env:FILE")]
    pub(crate) relight_from: Option<String>,
    /// Output directory (created if missing).
    #[arg(short, long, default_value = "compare-out")]
    pub(crate) output: PathBuf,
    /// No progress bars.
    #[arg(long)]
    pub(crate) quiet: bool,
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
            show(pb, p);
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
        EvalError::NoSweepScales => anyhow::anyhow!("--sweep-scales needs at least one scale"),
        EvalError::SweepScale { scale, max } => {
            anyhow::anyhow!("--sweep-scales: {scale} is not in (0, {max}]")
        }
        EvalError::PlateHeightNotFinite(_) => anyhow::anyhow!("--plate-height must be finite"),
        EvalError::PlateOutsideGrid { height, min, max } => {
            anyhow::anyhow!("--plate-height {height} is outside the grid's z range [{min}, {max}]")
        }
        EvalError::PlateResolution { max, .. } => anyhow::anyhow!("--plate-res must be between 2 and {max}"),
        EvalError::BasisNeedsCells { .. } => anyhow::anyhow!(
            "--gradients basis needs cell samples (prefilter, doi-paper); use --gradient-estimator central with point, doi or doi-node"
        ),
        EvalError::ZeroThreads => anyhow::anyhow!("--threads must be at least 1"),
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

/// The sky of `--relight-from`: `sky:R,G,B[:R,G,B]` or `env:FILE.exr`.
fn relight_from(spec: &str) -> anyhow::Result<lightvol_scene::Environment> {
    let s = crate::setup::parse_scenario(&format!("from={spec}")).context("--relight-from")?;
    match (s.lights.sky, s.lights.environment_map, s.lights.sun.is_some() || s.lights.no_sun) {
        (_, Some(path), false) => Ok(lightvol_scene::Environment::Map(
            lightvol_scene::envmap::EnvMap::from_exr(&path)
                .with_context(|| format!("reading {}", path.display()))?,
        )),
        (Some((sky, ground)), None, false) => Ok(lightvol_scene::Environment::UniformSky { sky, ground }),
        _ => anyhow::bail!("--relight-from: give one sky: sky:R,G,B[:R,G,B] or env:FILE.exr"),
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
        // Checked by `compare` before the scene is read; the demo sets none.
        noise: args.sampling.noise_target().ok().flatten(),
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
        views: args.views.config(views),
        lookups: args.lookup.clone(),
        threads,
        relight_from: None,
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
    args.sampling.noise_target()?;
    args.sampling.check_memory(args.grid.memory_limit())?;
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    let grid = args.grid.grid(&loaded, methods.iter().any(|m| m.entry.records_node_reach()))?;
    if grid.placement().is_some() {
        return Err(flag_error(EvalError::PlacedGrid));
    }
    let height = plate_height(args, &loaded);
    // The plate is checked before the output folder is made: a refused request leaves
    // nothing behind.
    PlateConfig { res: args.plate_res, ..PlateConfig::at_height(height) }
        .validate(&grid)
        .map_err(flag_error)?;
    let views = cameras(&args.views, &loaded, &grid)?;
    args.views.config(views.clone()).validate().map_err(flag_error)?;
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    let threads = resolve_threads(args.sampling.threads)?;
    let mut config = config(args, methods, grid, height, views, threads);
    config.relight_from = args.relight_from.as_deref().map(relight_from).transpose()?;
    let result =
        lightvol_eval::compare(&loaded.scene, &config, &ProgressBars::new(args.quiet)).map_err(flag_error)?;
    write_outputs(&args.output, &loaded, &config, &result, &args.views.cameras)
}

/// Writes the panels, the views, the sweep's files, `plate.exr` and `report.json` of
/// `result` into `dir` (lightvol-eval's `report::compare_files`; `specs`: the
/// `--camera` options of the views); returns the report.
fn write_outputs(
    dir: &Path,
    loaded: &LoadedScene,
    config: &CompareConfig,
    result: &Comparison,
    specs: &[String],
) -> anyhow::Result<CompareReport> {
    let out = compare_files(&loaded.label, loaded.frame, config, result, specs)
        .with_context(|| format!("encoding the files of {}", dir.display()))?;
    for (rel, bytes) in &out.files {
        write_atomic(&dir.join(rel), bytes)?;
    }
    Ok(out.report)
}

/// Runs `lightvol compare`.
pub(crate) fn run(args: &CompareArgs) -> anyhow::Result<ExitCode> {
    let report = compare(args)?;
    if let Some(noise) = report.reference.noise {
        eprintln!(
            "plate reference: {} samples a point, noise {noise:.4} (relative RMSE; part of every method's)",
            report.reference.samples
        );
    }
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
        let noise = v.reference.noise.map_or(String::new(), |n| format!(", noise {n:.4}"));
        eprintln!(
            "view {} ({w}x{h}, {} reference samples{noise}): relative RMSE over pixels",
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
