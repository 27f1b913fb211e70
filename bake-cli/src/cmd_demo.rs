//! `lightvol demo`: the main job on the built-in scenes and the embedded real interior. What
//! the demo compares (scenes, entries, cameras, the two levels, the studies) is
//! lightvol-eval's `demo`; this verb runs `compare` on each scene at its recommended
//! settings, sweeps the grid resolution, and writes an `index.html` that shows every panel,
//! the metrics and the plot (lightvol-eval's `report::index_html`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;
use lightvol_eval::demo::{self, DemoLevel};
use lightvol_eval::report::index_html;
use lightvol_eval::{NamedEntry, Plate, resolution_sweep};
use lightvol_scene::builtin::BUILTIN_NAMES;
use lightvol_scene::{Tracer, Transport};

use crate::cmd_compare::{CompareArgs, ProgressBars, compare, config, flag_error};
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

/// The demo's real interior ([`demo::REAL_INTERIOR`]), embedded so that the demo needs no
/// files (MIT licence, written next to its results as `LICENSE.txt`). It has no lights: a
/// uniform white sky through its openings, sky and bounce light only
/// (`--light sky+indirect`), as engines bake their probes.
const REAL_INTERIOR: (&str, &[u8], &str) = (
    demo::REAL_INTERIOR,
    include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/occlusion_room/room.glb")),
    include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/occlusion_room/LICENSE.txt")),
);

/// The sky change's sunset ([`demo::RELIGHT_SCENE`]): a lat-long EXR and its licence (CC0),
/// embedded like the real interior.
const SUNSET: (&[u8], &str) = (
    include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/env/sunset/sunset.exr")),
    include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/env/sunset/LICENSE.txt")),
);

/// The comparison of built-in scene `scene`.
fn compare_args(scene: &str, out: PathBuf, level: &DemoLevel, args: &DemoArgs) -> CompareArgs {
    scene_compare_args(scene, format!("builtin:{scene}"), "z", out, level, args)
}

/// The comparison of the scene `spec` (a file or `builtin:NAME`) labelled `name`.
fn scene_compare_args(
    name: &str,
    spec: String,
    up: &str,
    out: PathBuf,
    level: &DemoLevel,
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
            noise: None,
            max_samples: lightvol_core::samples::samples(lightvol_sampler::noise::DEFAULT_MAX_SAMPLES),
        },
        plate_height: None,
        plate_res: level.plate_res,
        methods: demo::BASE_ENTRIES.iter().map(|m| (*m).to_owned()).collect(),
        gradient_estimator: None,
        memory_sweep: demo::MEMORY_SWEEP_SCENES.contains(&name),
        sweep_scales: level.memory_scales.to_vec(),
        reference_samples: level.reference_samples,
        classify_dirs: 256,
        views: crate::compare_views::ViewArgs {
            cameras: vec![demo::camera(name).into()],
            view_width: level.view_width,
            view_height: None,
            view_samples: level.view_samples,
            engine_views: vec![lightvol_volume::EngineLookup::Three, lightvol_volume::EngineLookup::Bevy],
        },
        lookup: vec![lightvol_eval::ReadAs::default()],
        relight_from: None,
        output: out,
        quiet: args.quiet,
    }
}

/// Relative RMSE against grid resolution on `city` for every method (one plate and
/// reference, re-used for every grid; lightvol-eval's `resolution_sweep`).
fn sweep(args: &DemoArgs, level: &DemoLevel) -> anyhow::Result<Plot> {
    let ca = compare_args(demo::SWEEP_SCENE, args.output.join(demo::SWEEP_SCENE), level, args);
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
    Ok(demo::sweep_plot(series))
}

/// Runs `lightvol demo`.
pub(crate) fn run(args: &DemoArgs) -> anyhow::Result<ExitCode> {
    let level = if args.quick { &DemoLevel::QUICK } else { &DemoLevel::FULL };
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    let mut reports = Vec::new();
    for scene in BUILTIN_NAMES {
        if !args.quiet {
            eprintln!("== {scene}");
        }
        let mut ca = compare_args(scene, args.output.join(scene), level, args);
        ca.methods.extend(demo::EXTRA_ENTRIES.iter().map(|m| (*m).to_owned()));
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
    ca.methods = demo::REAL_ENTRIES.iter().map(|m| (*m).to_owned()).collect();
    reports.push((name.to_owned(), compare(&ca).with_context(|| format!("comparing on {name}"))?));
    reports.push(relight(args, level, &file)?);
    let mut sweeps = Vec::new();
    for scene in demo::MEMORY_SWEEP_SCENES {
        let path = args.output.join(scene).join("memory_sweep.json");
        let text = std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
        sweeps.push((scene.to_owned(), serde_json::from_str(&text)?));
    }
    let plot = sweep(args, level)?;
    crate::imaging::write_plot(&plot, &args.output.join("sweep"))?;
    write_atomic(&args.output.join("index.html"), index_html(&reports, &sweeps, args.quick).as_bytes())?;
    eprintln!("wrote {}", args.output.join("index.html").display());
    Ok(ExitCode::SUCCESS)
}

/// The sky change ([`demo::RELIGHT_SCENE`]): the real interior at `room` under the embedded
/// sunset, a fresh bake against the volumes relit from the white sky.
fn relight(
    args: &DemoArgs,
    level: &DemoLevel,
    room: &std::path::Path,
) -> anyhow::Result<(String, lightvol_eval::report::CompareReport)> {
    let name = demo::RELIGHT_SCENE;
    if !args.quiet {
        eprintln!("== {name}");
    }
    let dir = args.output.join(name);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let (bytes, licence) = SUNSET;
    let sunset = dir.join("sunset.exr");
    write_atomic(&sunset, bytes)?;
    write_atomic(&dir.join("LICENSE-sunset.txt"), licence.as_bytes())?;
    let mut ca = scene_compare_args(demo::REAL_INTERIOR, room.display().to_string(), "y", dir, level, args);
    ca.scene.env = Some(sunset);
    ca.sampling.path.light = "sky+indirect".into();
    ca.methods = demo::RELIGHT_ENTRIES.iter().map(|m| (*m).to_owned()).collect();
    ca.views.engine_views.clear();
    ca.relight_from = Some(demo::RELIGHT_FROM.to_owned());
    Ok((name.to_owned(), compare(&ca).with_context(|| format!("comparing on {name}"))?))
}
