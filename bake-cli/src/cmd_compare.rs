//! `lightvol compare`: bake every method at equal sample budget and evaluate each on a
//! horizontal plate against a path-traced reference (Kontkanen & Laine 2006, Fig. 6).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_sampler::domain::classify_point;
use lightvol_sampler::envmap::luminance;
use lightvol_sampler::fit::Fit;
use lightvol_sampler::{BakeSettings, DVec3, Method, Tracer, Transport, reference_irradiance_many};
use lightvol_sh::lowdisc::hash2;
use lightvol_volume::{GridSpec, IrradianceVolume};
use rayon::prelude::*;
use serde::Serialize;

use crate::cmd_bake::{GridJson, RaysJson, progress_bar, run_bake_fitted};
use crate::compare_entries::{Entry, GradientCache, adaptive_run, gradient_run, parse_entry, uniform_extra};
use crate::imaging::{Rgb32, diverging, write_atomic, write_png_linear};
use crate::metrics::{Metrics, PlatePoint, compute};
use crate::setup::{GridArgs, LoadedScene, SampleArgs, SceneArgs, with_threads};

/// `lightvol compare`.
#[derive(Debug, Args, Clone)]
pub struct CompareArgs {
    /// Scene and lights.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Grid.
    #[command(flatten)]
    pub grid: GridArgs,
    /// Sampling (the same budget for every method).
    #[command(flatten)]
    pub sampling: SampleArgs,
    /// Height of the horizontal evaluation plate along the scene file's up axis (normal =
    /// up; the same number in either frame, since the internal +Z is the file's up). Default: the built-in
    /// scene's first recommended height, or 10% of the scene's height above its floor.
    #[arg(long)]
    pub plate_height: Option<f64>,
    /// Plate resolution along its longer side.
    #[arg(long, default_value_t = 128)]
    pub plate_res: u32,
    /// Methods to compare: `point`, `prefilter`, `doi` (trilinear lookup), or
    /// `BASE+LOOKUP` for a bake with SH gradients (Oat 2005) read by `taylor` (nearest node,
    /// first-order Taylor), `gtrilinear` (gradient-extrapolated corners, trilinear) or
    /// `hermite` (tricubic Hermite), e.g. `doi+taylor,doi+hermite`; `adaptive` for Oat's
    /// octree baked to the uniform grid's memory (finest level 2 below half the grid's
    /// resolution; `adaptive1` stops one level earlier); `BASE+lsq[:λ]` or `BASE+average` for
    /// a bake finalized with that node fit instead of `--fit`'s.
    #[arg(long, default_value = "point,prefilter,doi", value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Gradient estimator of the `BASE+LOOKUP` entries (default: `basis` for prefilter/doi,
    /// no extra rays; `central` for point).
    #[arg(long, value_enum)]
    pub gradient_estimator: Option<crate::gradients::GradientEstimator>,
    /// Also run the error-vs-memory study on this plate: uniform doi at several
    /// resolutions, the same bakes read through the Taylor and Hermite gradient lookups,
    /// writing `memory_sweep.json`, `.png` and `.svg`.
    #[arg(long)]
    pub memory_sweep: bool,
    /// Scale factors of the grid's cell counts for `--memory-sweep`.
    #[arg(long, value_delimiter = ',', default_value = "0.5,0.7,1,1.4")]
    pub sweep_scales: Vec<f64>,
    /// Path-traced samples per plate point for the reference.
    #[arg(long, default_value_t = 512)]
    pub reference_samples: u32,
    /// Directions traced per plate point to decide whether it sees back faces.
    #[arg(long, default_value_t = 256)]
    pub classify_dirs: u32,
    /// Output directory (created if missing).
    #[arg(short, long, default_value = "compare-out")]
    pub output: PathBuf,
    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// `report.json` of `compare`.
#[derive(Debug, Serialize, Clone)]
pub struct CompareReport {
    /// Scene label.
    pub scene: String,
    /// Up axis of the source scene.
    pub up: String,
    /// The plate.
    pub plate: PlateJson,
    /// The grid.
    pub grid: GridJson,
    /// The reference.
    pub reference: ReferenceJson,
    /// Per method, in the order run.
    pub methods: serde_json::Map<String, serde_json::Value>,
}

/// Plate description.
#[derive(Debug, Serialize, Clone)]
pub struct PlateJson {
    /// Height (z).
    pub height: f64,
    /// Points per side.
    pub res: [u32; 2],
    /// Points that see no back faces.
    pub valid_points: usize,
    /// Valid points near a surface.
    pub near_points: usize,
}

/// Reference description.
#[derive(Debug, Serialize, Clone)]
pub struct ReferenceJson {
    /// Samples per point.
    pub samples: u32,
    /// Mean luminance over valid points.
    pub mean: f64,
    /// Wall time of the reference.
    pub seconds: f64,
}

/// One method's entry.
#[derive(Debug, Serialize, Clone)]
pub struct MethodJson {
    /// Samples per cell (per node for point).
    pub samples: u32,
    /// Rays by kind.
    pub rays: RaysJson,
    /// Bake wall time.
    pub seconds: f64,
    /// The leakage metrics.
    #[serde(flatten)]
    pub metrics: Metrics,
}

/// Everything computed on the plate (also used by `demo`).
pub struct PlateData {
    /// Points per side.
    pub res: [usize; 2],
    /// Plate height.
    pub height: f64,
    /// World positions, row-major (row 0 at min y).
    pub points: Vec<DVec3>,
    /// Sees no back faces.
    pub valid: Vec<bool>,
    /// Nearest surface closer than half the largest cell edge.
    pub near: Vec<bool>,
    /// Reference irradiance (RGB).
    pub truth: Vec<[f64; 3]>,
}

/// Rays traced per point to find the nearest surface (spherical Fibonacci set).
const NEAREST_DIRS: u32 = 128;

fn default_plate_height(loaded: &LoadedScene) -> f64 {
    if let Some(&h) = loaded.plate_heights.first() {
        return h;
    }
    let (lo, hi) = loaded.scene.bounds();
    lo.z + 0.1 * (hi.z - lo.z)
}

/// Builds the plate over the grid's horizontal extent, classifies its points, finds their
/// nearest surfaces and path-traces the reference.
pub fn plate(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    args: &CompareArgs,
    height: f64,
) -> anyhow::Result<(PlateData, f64)> {
    let (min, max) = grid.bounds();
    if !(min[2]..=max[2]).contains(&height) {
        bail!("--plate-height {height} is outside the grid's z range [{}, {}]", min[2], max[2]);
    }
    if args.plate_res < 2 {
        bail!("--plate-res must be at least 2");
    }
    let (ex, ey) = (max[0] - min[0], max[1] - min[1]);
    let long = f64::from(args.plate_res);
    let res = if ex >= ey {
        [args.plate_res as usize, ((long * ey / ex).round() as usize).max(2)]
    } else {
        [((long * ex / ey).round() as usize).max(2), args.plate_res as usize]
    };
    // Texel centres: no point lies exactly on the grid boundary.
    let points: Vec<DVec3> = (0..res[1])
        .flat_map(|j| (0..res[0]).map(move |i| (i, j)))
        .map(|(i, j)| {
            DVec3::new(
                min[0] + ex * (i as f64 + 0.5) / res[0] as f64,
                min[1] + ey * (j as f64 + 0.5) / res[1] as f64,
                height,
            )
        })
        .collect();
    let half_cell = 0.5 * grid.cell_size().iter().fold(0.0f64, |a, &b| a.max(b));
    let seed = args.sampling.seed;
    let classes: Vec<(bool, bool)> = points
        .par_iter()
        .enumerate()
        .map(|(i, &x)| {
            let valid = classify_point(tracer, x, args.classify_dirs, hash2(seed ^ 0xc1a5, i as u64)).inside;
            let n = f64::from(NEAREST_DIRS);
            let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let nearest = (0..NEAREST_DIRS)
                .filter_map(|k| {
                    let z = 1.0 - (2.0 * f64::from(k) + 1.0) / n;
                    let r = (1.0 - z * z).sqrt();
                    let phi = golden * f64::from(k);
                    tracer
                        .closest_hit(x, DVec3::new(r * phi.cos(), r * phi.sin(), z), 0.0, f64::INFINITY)
                        .map(|h| h.t)
                })
                .fold(f64::INFINITY, f64::min);
            (valid, nearest < half_cell)
        })
        .collect();
    let transport = Transport::new(&loaded.scene, tracer, args.sampling.transport());
    let t0 = Instant::now();
    let pb = progress_bar(args.quiet, 1, "reference");
    let pts: Vec<(DVec3, DVec3)> = points.iter().map(|&p| (p, DVec3::Z)).collect();
    let truth = reference_irradiance_many(&transport, &pts, args.reference_samples, seed ^ 0x7e7e);
    pb.finish_and_clear();
    let seconds = t0.elapsed().as_secs_f64();
    Ok((
        PlateData {
            res,
            height,
            points,
            valid: classes.iter().map(|c| c.0).collect(),
            near: classes.iter().map(|c| c.1).collect(),
            truth,
        },
        seconds,
    ))
}

/// Irradiance (normal up) of a volume at every plate point.
#[must_use]
pub fn evaluate(vol: &IrradianceVolume, plate: &PlateData) -> Vec<[f64; 3]> {
    plate
        .points
        .par_iter()
        .map(|p| vol.irradiance(p.as_vec3().to_array(), [0.0, 0.0, 1.0]).map(f64::from))
        .collect()
}

/// Metrics of one estimate against the plate's reference.
#[must_use]
pub fn plate_metrics(plate: &PlateData, estimate: &[[f64; 3]]) -> Metrics {
    let pts: Vec<PlatePoint> = (0..plate.points.len())
        .map(|i| PlatePoint {
            estimate: luminance(estimate[i]),
            truth: luminance(plate.truth[i]),
            valid: plate.valid[i],
            near: plate.near[i],
        })
        .collect();
    compute(&pts)
}

/// Bright green for points outside the domain of interest (\[KL06\] Fig. 6).
const INVALID_GREEN: [f32; 3] = [0.0, 4.0, 0.0];

/// Writes the Fig. 6-style panel (method | reference) and the signed error heat map.
pub fn write_panels(
    dir: &Path,
    name: &str,
    plate: &PlateData,
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
    let err = Rgb32 { pixels: err.pixels.iter().map(|p| p.map(srgb_to_linear)).collect(), ..err };
    write_png_linear(&dir.join(format!("error_{name}.png")), &err.upscale(k * 2), 1.0)
}

fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

/// Writes `plate.exr`: luminance channels `truth`, `valid`, `near` and one per method.
pub fn write_plate_exr(
    path: &Path,
    plate: &PlateData,
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
    let image = Image::from_layer(layer);
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write()
        .non_parallel()
        .to_buffered(&mut bytes)
        .map_err(|e| anyhow::anyhow!("encoding plate.exr: {e}"))?;
    let mut bytes = bytes.into_inner();
    lightvol_volume::exr_io::canonical_attribute_order(&mut bytes)?;
    write_atomic(path, &bytes)
}

/// One method's bake and evaluation.
pub struct MethodRun {
    /// Name.
    pub name: String,
    /// Report entry.
    pub json: MethodJson,
    /// Plate estimate.
    pub estimate: Vec<[f64; 3]>,
}

/// Bakes `method`, finalized with `fit`, and evaluates it on the plate.
#[allow(clippy::too_many_arguments, reason = "the bake's inputs and its evaluation plate")]
pub fn run_method(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    args: &CompareArgs,
    name: &str,
    method: Method,
    fit: Fit,
    plate: &PlateData,
) -> anyhow::Result<MethodRun> {
    let settings = BakeSettings {
        method,
        samples: args.sampling.samples,
        coeffs: args.grid.coeffs(),
        seed: args.sampling.seed,
        ..BakeSettings::default()
    };
    let ts = args.sampling.transport();
    let (vol, stats) = run_bake_fitted(loaded, tracer, grid, &settings, ts, args.quiet, name, fit)?;
    let estimate = evaluate(&vol, plate);
    let metrics = plate_metrics(plate, &estimate);
    Ok(MethodRun {
        name: name.to_owned(),
        json: MethodJson {
            samples: args.sampling.samples,
            rays: RaysJson::of(&stats.rays),
            seconds: stats.wall_time.as_secs_f64(),
            metrics,
        },
        estimate,
    })
}

/// Runs the whole comparison and writes its outputs; returns the report.
pub fn compare(args: &CompareArgs) -> anyhow::Result<CompareReport> {
    let methods: Vec<(String, Entry)> = args
        .methods
        .iter()
        .map(|m| Ok((m.trim().to_owned(), parse_entry(m.trim())?)))
        .collect::<anyhow::Result<_>>()?;
    if args.memory_sweep {
        crate::memory_sweep::check_scales(&args.sweep_scales)?;
    }
    if methods.is_empty() {
        bail!("--methods needs at least one method");
    }
    if args.reference_samples == 0 || args.sampling.samples == 0 {
        bail!("--samples and --reference-samples must be at least 1");
    }
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    let grid = args.grid.grid(&loaded)?;
    if grid.placement().is_some() {
        bail!("compare needs an axis-aligned grid (no placement transform)");
    }
    let height = args.plate_height.unwrap_or_else(|| default_plate_height(&loaded));
    if !height.is_finite() {
        bail!("--plate-height must be finite");
    }
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    with_threads(args.sampling.threads, || -> anyhow::Result<CompareReport> {
        let tracer = Tracer::new(&loaded.scene);
        let (plate, ref_seconds) = plate(&loaded, &tracer, &grid, args, height)?;
        let valid_truth: Vec<f64> =
            (0..plate.points.len()).filter(|&i| plate.valid[i]).map(|i| luminance(plate.truth[i])).collect();
        if valid_truth.is_empty() {
            bail!("no plate point at height {height} sees the scene from inside the domain of interest");
        }
        let mean_truth = valid_truth.iter().sum::<f64>() / valid_truth.len() as f64;
        let mut runs = Vec::new();
        let mut extras = Vec::new();
        let mut gradient_bakes = GradientCache::default();
        for (name, entry) in &methods {
            let (run, extra) = match *entry {
                Entry::Uniform(method) => (
                    run_method(&loaded, &tracer, &grid, args, name, method, args.sampling.fit, &plate)?,
                    uniform_extra(&grid, args.grid.coeffs()),
                ),
                Entry::Fitted(method, fit) => (
                    run_method(&loaded, &tracer, &grid, args, name, method, fit, &plate)?,
                    uniform_extra(&grid, args.grid.coeffs()),
                ),
                Entry::Gradient(base, lookup) => {
                    let gv = gradient_bakes.get(
                        &loaded,
                        &tracer,
                        &grid,
                        args,
                        base,
                        args.gradient_estimator,
                        name,
                    )?;
                    gradient_run(gv, name, lookup, args.sampling.samples, &plate)?
                }
                Entry::Adaptive(levels) => adaptive_run(&loaded, &tracer, &grid, args, name, levels, &plate)?,
                Entry::Baseline(b) => {
                    crate::compare_entries::baseline_run(&loaded, &tracer, &grid, args, name, b, &plate)?
                }
            };
            write_panels(&args.output, name, &plate, &run.estimate, mean_truth)?;
            runs.push(run);
            extras.push(extra);
        }
        if args.memory_sweep {
            crate::memory_sweep::run(&loaded, &tracer, &grid, args, &plate, &args.output)?;
        }
        let named: Vec<(String, Vec<[f64; 3]>)> =
            runs.iter().map(|r| (r.name.clone(), r.estimate.clone())).collect();
        write_plate_exr(&args.output.join("plate.exr"), &plate, &named)?;
        let mut methods_json = serde_json::Map::new();
        for (r, extra) in runs.iter().zip(extras) {
            let mut v = serde_json::to_value(&r.json)?;
            if let serde_json::Value::Object(m) = &mut v {
                m.extend(extra);
            }
            methods_json.insert(r.name.clone(), v);
        }
        let report = CompareReport {
            scene: loaded.label.clone(),
            up: loaded.frame.name().to_owned(),
            plate: PlateJson {
                height,
                res: [plate.res[0] as u32, plate.res[1] as u32],
                valid_points: plate.valid.iter().filter(|&&v| v).count(),
                near_points: (0..plate.points.len()).filter(|&i| plate.valid[i] && plate.near[i]).count(),
            },
            grid: GridJson::of(&grid, loaded.frame),
            reference: ReferenceJson {
                samples: args.reference_samples,
                mean: mean_truth,
                seconds: ref_seconds,
            },
            methods: methods_json,
        };
        write_atomic(&args.output.join("report.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
        Ok(report)
    })?
}

/// Runs `lightvol compare`.
pub fn run(args: &CompareArgs) -> anyhow::Result<ExitCode> {
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
