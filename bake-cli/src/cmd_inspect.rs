//! `lightvol inspect SCENE [--json]`: what the loader understood of a scene file — unique
//! and instanced triangles, objects, materials with alpha mode and sidedness, extensions and
//! how each was treated, lights, cameras, bounds in the file's axes and in lightvol's
//! internal +Z-up frame, and every warning (lightvol-scene's `scene_summary`). The first
//! place to look when a bake looks wrong.

use std::process::ExitCode;

use anyhow::Context;
use clap::Args;
use lightvol_scene::scene_summary::{summarize, text};

use crate::setup::SceneArgs;

/// `lightvol inspect`.
#[derive(Debug, Args)]
pub(crate) struct InspectArgs {
    /// Scene and lights, as for `bake`.
    #[command(flatten)]
    pub(crate) scene: SceneArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    pub(crate) json: bool,
    /// Write to this file (atomically) instead of standard output.
    #[arg(short, long)]
    pub(crate) output: Option<std::path::PathBuf>,
}

/// Runs `lightvol inspect`.
pub(crate) fn run(args: &InspectArgs) -> anyhow::Result<ExitCode> {
    let loaded = args.scene.load_quiet()?;
    let up = loaded.frame;
    let s = summarize(&loaded.label, &loaded.scene, up, &loaded.memory);
    let body = if args.json {
        serde_json::to_string_pretty(&s).context("serialising the summary")? + "\n"
    } else {
        text(&s)
    };
    match &args.output {
        Some(p) => {
            crate::imaging::write_atomic(p, body.as_bytes())
                .with_context(|| format!("writing {}", p.display()))?;
        }
        None => print!("{body}"),
    }
    Ok(ExitCode::SUCCESS)
}
