//! `lightvol demo`: the main job on the built-in scenes. Runs `compare` on `city`,
//! `interior` and `maze` at their recommended settings, sweeps the grid resolution on
//! `city`, and writes an `index.html` that shows every panel, the metrics and the plot.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;
use lightvol_sampler::builtin::BUILTIN_NAMES;
use lightvol_sampler::eval::{NamedEntry, Plate, resolution_sweep};
use lightvol_sampler::{Tracer, Transport};

use crate::cmd_compare::{CompareArgs, CompareReport, ProgressBars, compare, config, flag_error};
use crate::imaging::{Plot, write_atomic};
use crate::setup::{GridArgs, SampleArgs, SceneArgs, parse_method};

/// `lightvol demo`.
#[derive(Debug, Args)]
pub(crate) struct DemoArgs {
    /// Output directory.
    #[arg(short, long, default_value = "lightvol-demo")]
    pub(crate) output: PathBuf,
    /// Reduced settings that finish in under two minutes on a 2-core machine.
    #[arg(long)]
    pub(crate) quick: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(crate) threads: Option<usize>,
    /// No progress bars.
    #[arg(long)]
    pub(crate) quiet: bool,
}

/// Settings of one demo level.
struct Level {
    samples: u32,
    plate_res: u32,
    reference_samples: u32,
    sweep: &'static [u32],
    /// Cell-count scales of the error-vs-memory study (`compare --memory-sweep`).
    memory_scales: &'static [f64],
    /// Width of each scene's overview views (`compare --camera overview`).
    view_width: u32,
    /// Path-traced samples per pixel of the reference views.
    view_samples: u32,
}

/// Scenes of the error-vs-memory study (`city` and `interior`).
const MEMORY_SWEEP_SCENES: [&str; 2] = ["city", "interior"];

/// Entries added to every scene's comparison besides point, prefilter, doi-paper and doi:
/// doi-paper with the least-squares node fit, the doi-paper bake read through \[Oat05\]'s
/// gradient lookups, \[Oat05\]'s octree at doi-paper's memory (finest level 2 and 1), the
/// domain test on each node's own cell, and the engines' leak fixes
/// (`lightvol_sampler::baselines`).
const EXTRA_ENTRIES: [&str; 10] = [
    "doi-paper+lsq",
    "doi-paper+taylor",
    "doi-paper+hermite",
    "adaptive",
    "adaptive1",
    "doi-node",
    "point+validity",
    "point+apv",
    "point+vlm",
    "point+ddgi",
];

/// A real interior made by other people, embedded so that the demo needs no files: the
/// occlusion-culling demo room of the Godot demo projects (MIT licence, written next to its
/// results as `LICENSE.txt`). It has no lights: a uniform white sky through its openings,
/// sky and bounce light only (`--light sky+indirect`), as engines bake their probes.
const REAL_INTERIOR: (&str, &[u8], &str) = (
    "occlusion_room",
    include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/occlusion_room/room.glb")),
    include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/occlusion_room/LICENSE.txt")),
);

/// The methods of the real interior: the grid methods and the engines' leak fixes.
const REAL_ENTRIES: [&str; 7] =
    ["point", "doi-paper", "doi", "point+validity", "point+apv", "point+vlm", "point+ddgi"];

const QUICK: Level = Level {
    samples: 64,
    plate_res: 64,
    reference_samples: 192,
    sweep: &[8, 12, 16, 24],
    memory_scales: &[0.5, 0.7, 1.0],
    view_width: 160,
    view_samples: 32,
};
const FULL: Level = Level {
    samples: 256,
    plate_res: 160,
    reference_samples: 1024,
    sweep: &[8, 12, 16, 24, 32],
    memory_scales: &[0.4, 0.5, 0.7, 1.0, 1.4, 2.0],
    view_width: 384,
    view_samples: 256,
};

/// The camera of a scene's views: `render`'s overview of the grid for the open scenes; in
/// the closed rooms, whose ceilings hide the overview, from a corner under the ceiling
/// (the interior's toward the window and its sun patch; the real interior's, in its file's
/// +Y-up frame, toward the far corner).
fn demo_camera(name: &str) -> &'static str {
    match name {
        "interior" => "5.6,0.4,2.4:2.6,4.6,0.6:80",
        "occlusion_room" => "4.5,3.5,4.5:-2,0.5,-2:80",
        _ => "overview",
    }
}

/// The comparison of built-in scene `scene`.
fn compare_args(scene: &str, out: PathBuf, level: &Level, args: &DemoArgs) -> CompareArgs {
    scene_compare_args(scene, format!("builtin:{scene}"), "z", out, level, args)
}

/// The comparison of the scene `spec` (a file or `builtin:NAME`) labelled `name`.
fn scene_compare_args(
    name: &str,
    spec: String,
    up: &str,
    out: PathBuf,
    level: &Level,
    args: &DemoArgs,
) -> CompareArgs {
    CompareArgs {
        scene: SceneArgs {
            scene: spec,
            up: up.into(),
            scale: 1.0,
            sky: None,
            ground: None,
            sun: None,
            no_sun: false,
            env: None,
        },
        grid: GridArgs { bounds: None, res: None, spacing: None, order: 3, max_memory_mib: None },
        sampling: SampleArgs {
            samples: level.samples,
            // Unbiased paths (2 bounces, then Russian roulette), all light.
            path: crate::setup::PathArgs::default(),
            seed: 1,
            threads: args.threads,
            fit: lightvol_sampler::node_fit::Fit::Average,
        },
        plate_height: None,
        plate_res: level.plate_res,
        methods: vec!["point".into(), "prefilter".into(), "doi-paper".into(), "doi".into()],
        gradient_estimator: None,
        memory_sweep: MEMORY_SWEEP_SCENES.contains(&name),
        sweep_scales: level.memory_scales.to_vec(),
        reference_samples: level.reference_samples,
        classify_dirs: 256,
        views: crate::compare_views::ViewArgs {
            cameras: vec![demo_camera(name).into()],
            view_width: level.view_width,
            view_height: None,
            view_samples: level.view_samples,
        },
        output: out,
        quiet: args.quiet,
    }
}

/// Relative RMSE against grid resolution on `city` for every method (one plate and
/// reference, re-used for every grid; lightvol-sampler's `eval::resolution_sweep`).
fn sweep(args: &DemoArgs, level: &Level) -> anyhow::Result<Plot> {
    let ca = compare_args("city", args.output.join("city"), level, args);
    let loaded = ca.scene.load()?;
    let base = loaded.grid.clone().context("built-in city has a grid")?;
    let height = loaded.plate_heights[0];
    let methods: Vec<_> = ca
        .methods
        .iter()
        .map(|name| Ok((name.clone(), parse_method(name)?)))
        .collect::<anyhow::Result<_>>()?;
    let entries = ca.methods.iter().map(|m| NamedEntry::parse(m)).collect::<Result<_, _>>()?;
    let c = config(&ca, entries, base, height, Vec::new(), None);
    let observer = ProgressBars::new(args.quiet);
    let series = crate::setup::with_threads(args.threads, || -> anyhow::Result<_> {
        let tracer = Tracer::new(&loaded.scene);
        let ctx = c.bake_context(Transport::new(&loaded.scene, &tracer, c.transport), &observer);
        let plate = Plate::build(&ctx.transport, &c.grid, &c.plate, c.seed, &observer).map_err(flag_error)?;
        Ok(resolution_sweep(&ctx, &c.grid, &plate, &methods, c.fit, level.sweep)?)
    })??;
    Ok(Plot {
        title: "city: relative RMSE of irradiance on the plate vs grid resolution".into(),
        x_label: "grid nodes along x".into(),
        y_label: "relative RMSE".into(),
        series: series
            .into_iter()
            .map(|s| (s.name, s.points.iter().map(|(nx, m)| (f64::from(*nx), m.rel_rmse)).collect()))
            .collect(),
    })
}

/// The error-vs-memory section: plot and numbers per scene (from `memory_sweep.json`).
fn memory_html(s: &mut String, sweeps: &[(String, serde_json::Value)]) {
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

/// The methods a person compares in a scene's views: point sampling, the engine baseline
/// with the lowest relative RMSE over the view's pixels, and `doi`, each beside the
/// path-traced view.
fn views_html(s: &mut String, scene: &str, r: &CompareReport) {
    for v in r.views.iter().flatten() {
        let rel = |m: &str| v.methods.get(m).and_then(|x| x["rel_rmse"].as_f64());
        let best = v
            .methods
            .keys()
            .filter(|m| lightvol_sampler::eval::table::is_engine_baseline(m))
            .filter_map(|m| rel(m).map(|e| (m.clone(), e)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let mut shown: Vec<(String, String)> = vec![("reference".into(), "path-traced reference".into())];
        for m in ["point".to_owned()].into_iter().chain(best.map(|b| b.0)).chain(["doi".to_owned()]) {
            if let Some(e) = rel(&m) {
                shown.push((m.clone(), format!("{m}: relative RMSE {e:.3}")));
            }
        }
        let _ = writeln!(
            s,
            "<p>View <i>{}</i> ({}×{} pixels, reference {} samples per pixel): the scene shaded by each volume.</p>\n<div>",
            v.camera, v.resolution[0], v.resolution[1], v.reference.samples
        );
        for (m, caption) in shown {
            let _ = writeln!(
                s,
                "<figure style=\"display:inline-block;margin:4px\"><img src=\"{scene}/view_{}_{m}.png\" alt=\"{caption}\" width=\"{}\"><figcaption>{caption}</figcaption></figure>",
                v.camera,
                v.resolution[0].max(320)
            );
        }
        s.push_str("</div>\n");
    }
}

fn html(reports: &[(String, CompareReport)], sweeps: &[(String, serde_json::Value)], quick: bool) -> String {
    let mut s = String::from(
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>lightvol demo</title>\n<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;}table{border-collapse:collapse;}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right;}img{image-rendering:pixelated;margin:4px;border:1px solid #ddd;}</style></head><body>\n<h1>lightvol: domain-of-interest sampling vs point sampling</h1>\n",
    );
    let _ = writeln!(
        s,
        "<p>Each scene is baked with every method at the same sample budget and evaluated on a horizontal plate (normal up) against a path-traced reference, as in Kontkanen &amp; Laine 2006, Fig. 6. Panels show method | reference; points outside the domain of interest (inside solids) are bright green. Error maps: blue too dark, red too bright (±50% of the mean). Settings: {}.</p>",
        if quick { "quick" } else { "full" }
    );
    for (scene, r) in reports {
        let _ = writeln!(
            s,
            "<h2>{scene}</h2>\n<p>plate at height {} m, {}×{} points, {} valid, {} near a surface; grid {}×{}×{}; reference {} samples per point.</p>",
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
            let g = |k: &str| v.get(k).and_then(serde_json::Value::as_f64).unwrap_or(f64::NAN);
            let rays =
                v.get("rays").and_then(|r| r.get("total")).and_then(serde_json::Value::as_u64).unwrap_or(0);
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
        views_html(&mut s, scene, r);
        for (name, _) in &r.methods {
            let _ = writeln!(
                s,
                "<div><b>{name}</b><br><img src=\"{scene}/panel_{name}.png\" alt=\"{name} | reference\"><img src=\"{scene}/error_{name}.png\" alt=\"{name} error\"></div>"
            );
        }
    }
    s.push_str("<h2>Grid resolution sweep (city)</h2>\n<img src=\"sweep.svg\" alt=\"relative RMSE vs resolution\"><p>Also as <a href=\"sweep.png\">PNG</a>.</p>\n");
    memory_html(&mut s, sweeps);
    s.push_str("</body></html>\n");
    s
}

/// Runs `lightvol demo`.
pub(crate) fn run(args: &DemoArgs) -> anyhow::Result<ExitCode> {
    let level = if args.quick { &QUICK } else { &FULL };
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    let mut reports = Vec::new();
    for scene in BUILTIN_NAMES {
        if !args.quiet {
            eprintln!("== {scene}");
        }
        let mut ca = compare_args(scene, args.output.join(scene), level, args);
        ca.methods.extend(EXTRA_ENTRIES.iter().map(|m| (*m).to_owned()));
        reports.push((scene.to_owned(), compare(&ca).with_context(|| format!("comparing on {scene}"))?));
    }
    let (name, bytes, licence) = REAL_INTERIOR;
    if !args.quiet {
        eprintln!("== {name}");
    }
    let dir = args.output.join(name);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let file = dir.join("room.glb");
    write_atomic(&file, bytes)?;
    write_atomic(&dir.join("LICENSE.txt"), licence.as_bytes())?;
    let mut ca = scene_compare_args(name, file.display().to_string(), "y", dir, level, args);
    ca.sampling.path.light = "sky+indirect".into();
    ca.methods = REAL_ENTRIES.iter().map(|m| (*m).to_owned()).collect();
    reports.push((name.to_owned(), compare(&ca).with_context(|| format!("comparing on {name}"))?));
    let mut sweeps = Vec::new();
    for scene in MEMORY_SWEEP_SCENES {
        let path = args.output.join(scene).join("memory_sweep.json");
        let text = std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
        sweeps.push((scene.to_owned(), serde_json::from_str(&text)?));
    }
    let plot = sweep(args, level)?;
    plot.write(&args.output.join("sweep"))?;
    write_atomic(&args.output.join("index.html"), html(&reports, &sweeps, args.quick).as_bytes())?;
    eprintln!("wrote {}", args.output.join("index.html").display());
    Ok(ExitCode::SUCCESS)
}
