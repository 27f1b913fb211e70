//! # Reports: a comparison as `report.json`, pictures and an HTML page, in memory
//!
//! [`compare_files`] turns a [`Comparison`] into the files a person and a script read: per
//! entry the \[KL06\] Fig. 6-style panel (entry | reference, points outside the domain of
//! interest bright green) and its signed error map, per camera the views of every entry
//! beside the path-traced one, all at the reference view's exposure, the memory study's
//! record and plot, `plate.exr` (luminance channels `truth`, `valid`, `near` and one per
//! entry) and `report.json` ([`CompareReport`]). [`index_html`] lays several reports out on
//! one page. Nothing here touches the file system: the caller writes the returned bytes.

use lightvol_core::samples::Samples;
use std::fmt::Write as _;
use std::path::PathBuf;

use serde::Serialize;
use serde_json::{Map, Value, json};

use super::entries::lookup_name;
use super::{CompareConfig, ComparedView, Comparison, MethodRun, Metrics, Plate, RunDetail, SweepReport};
use lightvol_scene::UpAxis;
use lightvol_scene::envmap::luminance;
use lightvol_view::picture::{PictureError, Plot, Rgb32, auto_exposure, diverging, png_linear};
use lightvol_volume::frame::FileGrid;

/// `report.json` of `compare`.
#[derive(Debug, Serialize, Clone)]
pub struct CompareReport {
    /// Scene label.
    pub scene: String,
    /// Up axis of the source scene.
    pub up: String,
    /// The plate.
    pub plate: PlateSummary,
    /// The grid.
    pub grid: FileGrid,
    /// How the methods' plate and views were read: `lightvol`'s lookups, an engine's or
    /// `native` (`compare --lookup`; left out for lightvol's own), the first way when there
    /// are several.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lookup: Option<String>,
    /// Every way the methods were read, when more than one (the runs of each further way
    /// are named `METHOD@WAY`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lookups: Option<Vec<String>>,
    /// The reference.
    pub reference: ReferenceSummary,
    /// Per method, in the order run.
    pub methods: Map<String, Value>,
    /// Per camera, in the order given (only with cameras).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub views: Option<Vec<ViewReport>>,
}

/// Plate description.
#[derive(Debug, Serialize, Clone)]
pub struct PlateSummary {
    /// Height (z).
    pub height: f64,
    /// Points per side.
    pub res: [u32; 2],
    /// Points that see no back faces.
    pub valid_points: usize,
    /// Valid points near a surface.
    pub near_points: usize,
}

/// One method's entry (its other fields come from [`extra`]).
#[derive(Debug, Serialize, Clone)]
struct MethodSummary {
    /// Samples per cell (per node for point).
    samples: u32,
    /// Rays by kind.
    rays: lightvol_scene::RayCounts,
    /// Bake wall time.
    seconds: f64,
    /// The leakage metrics.
    #[serde(flatten)]
    metrics: Metrics,
}

/// A path-traced reference: of the plate, or of one camera's view.
#[derive(Debug, Serialize, Clone)]
pub struct ReferenceSummary {
    /// Samples per point.
    pub samples: u32,
    /// Mean luminance over valid points.
    pub mean: f64,
    /// Wall time of the reference.
    pub seconds: f64,
    /// The reference's own noise in relative-RMSE units
    /// ([`crate::plate::Plate::reference_noise`], [`crate::views::ComparedView::reference_noise`]):
    /// the part of every method's `rel_rmse` that is the reference's, not the method's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<f64>,
}

/// One camera's views in `report.json`.
#[derive(Debug, Serialize, Clone)]
pub struct ViewReport {
    /// The camera's label (in the image file names).
    pub camera: String,
    /// The `--camera` specification.
    pub spec: String,
    /// Width and height in pixels.
    pub resolution: [u32; 2],
    /// Pixels that see a surface.
    pub surface_pixels: usize,
    /// Pixels that see a surface inside the grid: the pixels measured.
    pub measured_pixels: usize,
    /// The path-traced view: samples per pixel, mean luminance over the measured pixels,
    /// wall time.
    pub reference: ReferenceSummary,
    /// Per method, by name: its view's metrics against the reference view.
    pub methods: Map<String, Value>,
}

/// One method's view metrics in `report.json`.
#[derive(Debug, Serialize, Clone)]
pub struct ViewMetricsSummary {
    /// `sqrt(mean((E - T)²)) / mean(T)` over the measured pixels, `E` and `T` the
    /// luminances of the method's and the reference's pixel.
    pub rel_rmse: f64,
    /// `mean(E - T) / mean(T)`.
    pub bias: f64,
    /// Share of pixels with `E < 0.8 T`.
    pub too_dark: f64,
    /// Share of pixels with `E > 1.25 T`.
    pub too_bright: f64,
}

/// Report fields of one run beyond [`MethodSummary`].
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
        RunDetail::Bricks { probe_budget, report, octree_bytes } => {
            m.insert("probe_budget".into(), json!(probe_budget));
            m.insert("bricks_per_level".into(), json!(report.bricks_per_level));
            m.insert("dropped_bricks".into(), json!(report.dropped_bricks));
            m.insert("largest_dropped_error".into(), json!(report.largest_dropped_error));
            m.insert("probe_bytes".into(), json!(report.probe_bytes));
            m.insert("octree_bytes".into(), json!(octree_bytes));
        }
        RunDetail::Relit { order, sky_band_limit } => {
            m.insert("sky_order".into(), json!(order));
            m.insert("sky_band_limit".into(), json!(sky_band_limit));
        }
        RunDetail::Baseline { invalid_nodes, moved_nodes } => {
            m.insert("invalid_nodes".into(), json!(invalid_nodes));
            m.insert("moved_nodes".into(), json!(moved_nodes));
        }
    }
    m
}

/// The fresh bake a relit entry is measured against (`report.json`'s `vs_fresh`): for
/// `BASE+relit`, `BASE+relitN` and `BASE+skyocc` (read any way, `@WAY`) the entry `BASE`
/// read the same way, the bake of the comparison's own lighting.
fn fresh_of(name: &str) -> Option<String> {
    let (entry, way) = name.split_once('@').map_or((name, None), |(e, w)| (e, Some(w)));
    let (base, kind) = entry.rsplit_once('+')?;
    let relit = kind == "skyocc"
        || kind.strip_prefix("relit").is_some_and(|o| o.is_empty() || o.chars().all(|c| c.is_ascii_digit()));
    relit.then(|| way.map_or_else(|| base.to_owned(), |w| format!("{base}@{w}")))
}

/// A file's path, relative to the output directory, and its bytes.
pub type FileBytes = (PathBuf, Vec<u8>);

/// Every file of a comparison, in memory.
#[derive(Debug, Clone)]
pub struct CompareFiles {
    /// What `report.json` holds.
    pub report: CompareReport,
    /// Paths relative to the output directory, and their bytes: `panel_M.png`,
    /// `error_M.png`, `view_CAMERA_reference.png`, `view_CAMERA_M.png`, `memory_sweep.json`,
    /// `.svg` and `.png` (with the memory study), `plate.exr` and `report.json`.
    pub files: Vec<FileBytes>,
}

/// The report and files of `result`, compared on the scene labelled `scene` whose file
/// frame is `frame`, with `config`; `specs` are the camera specifications of the views, as
/// the user gave them.
///
/// # Errors
/// [`PictureError`] when an image cannot be encoded.
pub fn compare_files(
    scene: &str,
    frame: UpAxis,
    config: &CompareConfig,
    result: &Comparison,
    specs: &[String],
) -> Result<CompareFiles, PictureError> {
    let plate = &result.plate;
    let mut files = Vec::new();
    for run in &result.methods {
        files.extend(panels(&run.name, plate, &run.estimate, result.mean_truth)?);
    }
    let mut views = Vec::with_capacity(result.views.len());
    for (view, spec) in result.views.iter().zip(specs) {
        let (report, images) = view_files(view, spec, config.views.reference_samples)?;
        files.extend(images);
        views.push(report);
    }
    if let Some(sweep) = &result.memory_sweep {
        files.extend(sweep_files(scene, sweep)?);
    }
    let named: Vec<(String, Vec<[f64; 3]>)> =
        result.methods.iter().map(|r| (r.name.clone(), r.estimate.clone())).collect();
    files.push((PathBuf::from("plate.exr"), plate_exr(plate, &named)?));
    let mut methods = Map::new();
    for r in &result.methods {
        let summary =
            MethodSummary { samples: r.samples.get(), rays: r.rays, seconds: r.seconds, metrics: r.metrics };
        let mut v = serde_json::to_value(&summary).unwrap_or_default();
        if let Value::Object(m) = &mut v {
            m.extend(extra(r));
        }
        methods.insert(r.name.clone(), v);
    }
    for r in &result.methods {
        let Some(fresh) = fresh_of(&r.name) else { continue };
        let Some(f) = result.methods.iter().find(|m| m.name == fresh) else { continue };
        let points: Vec<super::PlatePoint> = (0..plate.truth.len())
            .map(|k| super::PlatePoint {
                estimate: luminance(r.estimate[k]),
                truth: luminance(f.estimate[k]),
                valid: plate.valid[k],
                near: plate.near[k],
            })
            .collect();
        let m = crate::metrics::compute(&points);
        if let Some(Value::Object(o)) = methods.get_mut(&r.name) {
            o.insert("vs_fresh".into(), json!({ "method": fresh, "rel_rmse": m.rel_rmse, "bias": m.bias }));
        }
    }
    let report = CompareReport {
        scene: scene.to_owned(),
        up: frame.name().to_owned(),
        lookup: config
            .lookups
            .first()
            .filter(|&&w| w != crate::ReadAs::default())
            .map(|w| w.name().to_owned()),
        lookups: (config.lookups.len() > 1)
            .then(|| config.lookups.iter().map(|w| w.name().to_owned()).collect()),
        plate: PlateSummary {
            height: plate.height,
            res: [plate.res[0] as u32, plate.res[1] as u32],
            valid_points: plate.valid_points(),
            near_points: plate.near_points(),
        },
        grid: FileGrid::of(&config.grid, frame),
        reference: ReferenceSummary {
            samples: config.plate.reference_samples.get(),
            mean: result.mean_truth,
            seconds: plate.reference_seconds,
            noise: plate.reference_noise(),
        },
        methods,
        views: (!views.is_empty()).then_some(views),
    };
    files.push((PathBuf::from("report.json"), report.to_json().into_bytes()));
    Ok(CompareFiles { report, files })
}

impl CompareReport {
    /// The report as `report.json` holds it (pretty-printed JSON).
    #[must_use]
    pub fn to_json(&self) -> String {
        // Serialising plain data with string keys cannot fail.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}

/// One camera's images, `view_LABEL_reference.png` and `view_LABEL_METHOD.png`, all at the
/// reference view's automatic exposure (so that they compare by eye, and the reference is
/// the image a reference render writes), and its report entry.
///
/// # Errors
/// [`PictureError::Png`].
pub fn view_files(
    view: &ComparedView,
    spec: &str,
    samples: Samples,
) -> Result<(ViewReport, Vec<FileBytes>), PictureError> {
    let reference = Rgb32::from(view.reference.clone());
    let exposure = auto_exposure(&reference);
    let label = &view.label;
    let mut files =
        vec![(PathBuf::from(format!("view_{label}_reference.png")), png_linear(&reference, exposure)?)];
    let mut methods = Map::new();
    for m in &view.methods {
        files.push((
            PathBuf::from(format!("view_{label}_{}.png", m.name)),
            png_linear(&Rgb32::from(m.image.clone()), exposure)?,
        ));
        let metrics = ViewMetricsSummary {
            rel_rmse: m.metrics.rel_rmse,
            bias: m.metrics.bias,
            too_dark: m.metrics.too_dark,
            too_bright: m.metrics.too_bright,
        };
        methods.insert(m.name.clone(), serde_json::to_value(metrics).unwrap_or_default());
    }
    let report = ViewReport {
        camera: label.clone(),
        spec: spec.to_owned(),
        resolution: [view.reference.width, view.reference.height],
        surface_pixels: view.reference.surface_pixels(),
        measured_pixels: view.measured.iter().filter(|&&m| m).count(),
        reference: ReferenceSummary {
            samples: samples.get(),
            mean: view.mean_reference,
            seconds: view.reference_seconds,
            noise: view.reference_noise,
        },
        methods,
    };
    Ok((report, files))
}

#[derive(Serialize)]
struct SweepJson<'a> {
    /// Scene label.
    scene: &'a str,
    /// The study.
    #[serde(flatten)]
    report: &'a SweepReport,
}

/// rel_rmse against log2 of the memory in KiB, one line per series.
#[must_use]
pub fn sweep_plot(scene: &str, report: &SweepReport) -> Plot {
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
        title: format!("{}: relative RMSE vs run-time memory", scene.trim_start_matches("builtin:")),
        x_label: "log2 of memory in KiB (each series' own run-time bytes)".into(),
        y_label: "relative RMSE".into(),
        series,
    }
}

/// The memory study's files: `memory_sweep.json` (the study's report with the scene's
/// label) and its [`sweep_plot`] as `memory_sweep.svg` and `.png`.
///
/// # Errors
/// [`PictureError::Png`].
pub fn sweep_files(scene: &str, report: &SweepReport) -> Result<Vec<FileBytes>, PictureError> {
    let json = SweepJson { scene, report };
    let mut files = vec![(
        PathBuf::from("memory_sweep.json"),
        serde_json::to_string_pretty(&json).unwrap_or_default().into_bytes(),
    )];
    files.extend(sweep_plot(scene, report).files(std::path::Path::new("memory_sweep"))?);
    Ok(files)
}

/// Bright green for points outside the domain of interest (\[KL06\] Fig. 6).
const INVALID_GREEN: [f32; 3] = [0.0, 4.0, 0.0];

/// The Fig. 6-style panel of entry `name` (entry | reference), `panel_NAME.png`, and its
/// signed error heat map, `error_NAME.png` (blue too dark, red too bright, ±50% of the
/// mean reference), both enlarged for small plates.
///
/// # Errors
/// [`PictureError::Png`].
pub fn panels(
    name: &str,
    plate: &Plate,
    estimate: &[[f64; 3]],
    mean_truth: f64,
) -> Result<[FileBytes; 2], PictureError> {
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
    let panel = (PathBuf::from(format!("panel_{name}.png")), png_linear(&panel.upscale(k), exposure)?);
    // The error map is already in display units.
    let err = Rgb32 {
        pixels: err.pixels.iter().map(|p| p.map(lightvol_core::color::srgb_decode_f32)).collect(),
        ..err
    };
    Ok([panel, (PathBuf::from(format!("error_{name}.png")), png_linear(&err.upscale(k * 2), 1.0)?)])
}

/// `plate.exr`: luminance channels `truth`, `valid`, `near` and one per entry, rows from
/// the plate's max y down.
///
/// # Errors
/// [`PictureError::Exr`].
pub fn plate_exr(plate: &Plate, methods: &[(String, Vec<[f64; 3]>)]) -> Result<Vec<u8>, PictureError> {
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
    lightvol_volume::io::exr::encode_image(ia, vec![layer]).map_err(|e| PictureError::Exr(e.to_string()))
}

/// The error-vs-memory section: plot and numbers per scene (from `memory_sweep.json`).
fn memory_html(s: &mut String, sweeps: &[(String, Value)]) {
    s.push_str("<h2>Error vs memory (uniform, uniform with SH gradients, adaptive octree; Oat 2005)</h2>\n<p>One doi-paper bake per resolution (same samples per cell), read by trilinear interpolation (uniform) or through the gradient lookups; memory is the run-time f32 data (27 floats per node, 108 with gradients). The adaptive octree is baked to each uniform grid's memory (its own count includes weights, keys and split bitmaps).</p>\n");
    for (scene, r) in sweeps {
        let _ = writeln!(
            s,
            "<h3>{scene}</h3>\n<img src=\"{scene}/memory_sweep.svg\" alt=\"{scene}: relative RMSE vs memory\"><p>Also as <a href=\"{scene}/memory_sweep.png\">PNG</a>; numbers in <a href=\"{scene}/memory_sweep.json\">memory_sweep.json</a>.</p>"
        );
        s.push_str("<table><tr><th>series</th><th>grid</th><th>memory (bytes)</th><th>rel_rmse</th><th>bias</th><th>too_dark_near</th></tr>\n");
        for p in r["points"].as_array().into_iter().flatten() {
            let g = |k: &str| p[k].as_f64().unwrap_or(f64::NAN);
            let res = &p["res"];
            let _ = writeln!(
                s,
                "<tr><th>{}</th><td>{}x{}x{}</td><td>{}</td><td>{:.4}</td><td>{:+.4}</td><td>{:.4}</td></tr>",
                p["series"].as_str().unwrap_or("?"),
                res[0],
                res[1],
                res[2],
                p["memory_bytes"],
                g("rel_rmse"),
                g("bias"),
                g("too_dark_near")
            );
        }
        s.push_str("</table>\n");
    }
}

/// The views a person compares first, large and side by side: the path-traced view,
/// lightvol's (`doi`), what three.js and Bevy draw of the same volume (the `doi@ENGINE`
/// views, lightvol's emulation of their lookups), point sampling and the engine baseline
/// with the lowest relative RMSE over the view's pixels.
fn views_html(s: &mut String, scene: &str, r: &CompareReport) {
    for v in r.views.iter().flatten() {
        let rel = |m: &str| v.methods.get(m).and_then(|x| x["rel_rmse"].as_f64());
        let best = best_baseline(v);
        let mut shown: Vec<(String, String)> = vec![("reference".into(), "path-traced".into())];
        let engines = [
            ("doi", "lightvol (doi)"),
            ("doi@three", "three.js, same volume"),
            ("doi@bevy", "Bevy, same volume"),
            ("doi+relit", "doi baked under a white sky, relit by its sky transfer"),
            ("doi+skyocc", "doi with Unity APV's sky occlusion, relit"),
        ];
        for (m, label) in engines.into_iter().chain([("point", "point sampling")]) {
            if let Some(e) = rel(m) {
                shown.push((m.to_owned(), format!("{label}: {e:.3}")));
            }
        }
        if let Some((m, e)) = best {
            shown.push((m.clone(), format!("best engine fix, {m}: {e:.3}")));
        }
        let _ = writeln!(s, "<div class=\"views\">");
        for (m, caption) in shown {
            let _ = writeln!(
                s,
                "<figure><img src=\"{scene}/view_{}_{m}.png\" alt=\"{caption}\"><figcaption>{caption}</figcaption></figure>",
                v.camera
            );
        }
        let _ = writeln!(
            s,
            "</div>\n<p class=\"note\">Camera <i>{}</i>, {}×{} pixels; numbers are the relative RMSE of each view against the path-traced one ({} samples per pixel) over the pixels that see a surface inside the grid.</p>",
            v.camera, v.resolution[0], v.resolution[1], v.reference.samples
        );
    }
}

/// The engine baseline with the lowest relative RMSE in view `v`.
fn best_baseline(v: &ViewReport) -> Option<(String, f64)> {
    v.methods
        .iter()
        .filter(|(m, _)| super::table::is_engine_baseline(m))
        .filter_map(|(m, x)| x["rel_rmse"].as_f64().map(|e| (m.clone(), e)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// The short table: point sampling, the engines' leak fixes and `doi`, by the plate's and
/// the view's relative RMSE, and the engines' views of `doi`'s volume.
fn short_table_html(s: &mut String, r: &CompareReport) {
    let view = r.views.iter().flatten().next();
    let view_rel = |m: &str| view.and_then(|v| v.methods.get(m)).and_then(|x| x["rel_rmse"].as_f64());
    let cell = |x: Option<f64>| x.map_or_else(|| "–".to_owned(), |e| format!("{e:.3}"));
    s.push_str("<table><tr><th>method</th><th>plate rel. RMSE</th><th>view rel. RMSE</th></tr>\n");
    let names =
        r.methods.keys().filter(|m| *m == "point" || *m == "doi" || super::table::is_engine_baseline(m));
    for m in names.map(String::as_str).chain(["doi@three", "doi@bevy"]) {
        let plate = r.methods.get(m).and_then(|v| v.get("rel_rmse")).and_then(Value::as_f64);
        if plate.is_none() && view_rel(m).is_none() {
            continue;
        }
        let _ = writeln!(s, "<tr><th>{m}</th><td>{}</td><td>{}</td></tr>", cell(plate), cell(view_rel(m)));
    }
    s.push_str("</table>\n");
}

/// One page of several scenes' comparisons (`reports`, each with its folder name, whose
/// files [`compare_files`] made), a resolution study's plot (`sweep.svg`, `sweep.png`) and
/// the memory studies of `sweeps` (each scene's `memory_sweep.json`); `quick` names the
/// settings level. Per scene, first the views side by side and a short
/// table of point sampling, the engines' fixes and `doi`, then folded: the plate and grid, every entry's metrics and
/// every panel; the studies folded at the end.
#[must_use]
pub fn index_html(reports: &[(String, CompareReport)], sweeps: &[(String, Value)], quick: bool) -> String {
    let mut s = String::from(
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>lightvol demo</title>\n<style>body{font-family:sans-serif;max-width:1500px;margin:1.5em auto;padding:0 1em;}table{border-collapse:collapse;margin:0.5em 0;}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right;}.views{display:flex;flex-wrap:wrap;gap:8px;}.views figure{margin:0;flex:1 1 30%;min-width:300px;}.views img{width:100%;image-rendering:pixelated;border:1px solid #ddd;}figcaption{font-size:0.9em;}.note{color:#555;font-size:0.9em;}details{margin:0.8em 0;}summary{cursor:pointer;font-weight:bold;}details img{image-rendering:pixelated;margin:4px;border:1px solid #ddd;}</style></head><body>\n<h1>lightvol: what a volume looks like in the frame</h1>\n",
    );
    let _ = writeln!(
        s,
        "<p>Each scene is baked with every method at the same sample budget and drawn from one camera: first the path-traced view, then lightvol's (<code>doi</code>, Kontkanen &amp; Laine 2006), the same volume as three.js and Bevy read it, point sampling and the best of the engines' leak fixes. The table gives each method's relative RMSE on a horizontal plate (Kontkanen &amp; Laine 2006, Fig. 6) and in the view; everything else is folded below each scene. Settings: {}.</p>",
        if quick { "quick" } else { "full" }
    );
    for (scene, r) in reports {
        let _ = writeln!(s, "<h2>{scene}</h2>");
        if scene == crate::demo::RELIGHT_SCENE {
            s.push_str("<p>A change of sky: the real interior under a photographed sunset. The fresh bake sees the sunset; the relit volume was baked once under the white sky above and relit with the sunset's SH coefficients by its sky transfer, bounces included (Sloan, Kautz &amp; Snyder 2002); Unity APV's sky occlusion, baked and relit the same way, multiplies an L1 visibility by the sky's colour in one direction per probe.</p>\n");
        }
        views_html(&mut s, scene, r);
        short_table_html(&mut s, r);
        let _ = writeln!(
            s,
            "<details><summary>All methods: metrics, plate panels and error maps</summary>\n<p>Plate at height {} m, {}×{} points, {} valid, {} near a surface; grid {}×{}×{}; reference {} samples per point. Panels show method | reference; points outside the domain of interest (inside solids) are bright green. Error maps: blue too dark, red too bright (±50% of the mean).</p>",
            r.plate.height,
            r.plate.res[0],
            r.plate.res[1],
            r.plate.valid_points,
            r.plate.near_points,
            r.grid.res[0],
            r.grid.res[1],
            r.grid.res[2],
            r.reference.samples
        );
        s.push_str("<table><tr><th>method</th><th>rel_rmse</th><th>bias</th><th>too_dark</th><th>too_dark_near</th><th>too_bright</th><th>rays</th><th>seconds</th></tr>\n");
        for (name, v) in &r.methods {
            let g = |k: &str| v.get(k).and_then(Value::as_f64).unwrap_or(f64::NAN);
            let rays = v.get("rays").and_then(|r| r.get("total")).and_then(Value::as_u64).unwrap_or(0);
            let _ = writeln!(
                s,
                "<tr><th>{name}</th><td>{:.4}</td><td>{:+.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{rays}</td><td>{:.2}</td></tr>",
                g("rel_rmse"),
                g("bias"),
                g("too_dark"),
                g("too_dark_near"),
                g("too_bright"),
                g("seconds")
            );
        }
        s.push_str("</table>\n");
        for (name, _) in &r.methods {
            let _ = writeln!(
                s,
                "<div><b>{name}</b><br><img src=\"{scene}/panel_{name}.png\" alt=\"{name} | reference\"><img src=\"{scene}/error_{name}.png\" alt=\"{name} error\"></div>"
            );
        }
        s.push_str("</details>\n");
    }
    s.push_str("<h2>Studies</h2>\n<details><summary>Grid resolution sweep (city)</summary>\n<img src=\"sweep.svg\" alt=\"relative RMSE vs resolution\"><p>Also as <a href=\"sweep.png\">PNG</a>.</p>\n</details>\n<details><summary>Error vs memory</summary>\n");
    memory_html(&mut s, sweeps);
    s.push_str("</details>\n</body></html>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::fresh_of;

    /// Relit entries name their fresh bake, read the same way; others have none.
    #[test]
    fn relit_entries_name_their_fresh_bake() {
        assert_eq!(fresh_of("doi+relit").as_deref(), Some("doi"));
        assert_eq!(fresh_of("point+relit4").as_deref(), Some("point"));
        assert_eq!(fresh_of("doi+skyocc@three").as_deref(), Some("doi@three"));
        assert_eq!(fresh_of("doi"), None);
        assert_eq!(fresh_of("point+apv"), None);
        assert_eq!(fresh_of("doi+relitx"), None);
    }
}
