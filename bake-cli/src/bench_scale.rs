//! `lightvol bench --bakes`: bake wall time and peak memory at scale. Each bake runs as its
//! own `lightvol bake --json` process (so its peak resident memory is its own), over:
//!
//! - the vendored real scenes under `--data`;
//! - grid layouts of the vendored occlusion room (1, 4 × 4, 8 × 8 and 32 × 32 rooms at a
//!   10 m pitch, [`lightvol_scene::layout`]) on one fixed grid, so that time and memory
//!   show what instanced triangles cost at equal unique triangles, grid and rays;
//! - the built-in scenes.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, bail};
use serde_json::{Value, json};

/// The layouts: rooms per side.
const LAYOUT_SIDES: [u32; 4] = [1, 4, 8, 32];

/// The vendored scenes baked, relative to `--data`.
const VENDORED: [&str; 5] = [
    "breakfast_room/BreakfastRoom.gltf",
    "occlusion_room/room.glb",
    "living_room/living_room.glb",
    "zdm2/zdm2.glb",
    "cornell_original/CornellBox-Original.obj",
];

/// Runs one `lightvol bake --json` and returns its report.
fn bake(exe: &Path, scene: &str, extra: &[&str], samples: u32, out: &Path) -> anyhow::Result<Value> {
    let samples = samples.to_string();
    let mut cmd = Command::new(exe);
    cmd.args(["bake", scene, "--method", "doi-paper", "--json", "--quiet", "--samples", &samples, "-o"])
        .arg(out)
        .args(extra);
    let o = cmd.output().with_context(|| format!("running {}", exe.display()))?;
    if !o.status.success() {
        bail!("bake of {scene} failed: {}", String::from_utf8_lossy(&o.stderr).trim());
    }
    serde_json::from_slice(&o.stdout).with_context(|| format!("reading the bake report of {scene}"))
}

/// The figures of one bake report.
fn row(label: &str, r: &Value) -> Value {
    let mib = |k: &str| r[k].as_f64().map(|b| b / f64::from(1u32 << 20));
    json!({
        "scene": label,
        "triangles": r["triangles"],
        "unique_triangles": r["unique_triangles"],
        "instances": r["instances"],
        "grid": r["grid"]["res"],
        "rays": r["rays"]["total"],
        "bvh_seconds": r["bvh_seconds"],
        "bake_seconds": r["seconds"],
        "total_seconds": r["total_seconds"],
        "estimated_mib": mib("estimated_memory_bytes"),
        "peak_mib": mib("peak_memory_bytes"),
    })
}

/// Bakes everything and returns the report (see the module docs).
pub(crate) fn run(data: &Path, samples: u32) -> anyhow::Result<Value> {
    let exe = std::env::current_exe().context("locating the lightvol executable")?;
    let dir = tempfile::tempdir().context("creating a temporary directory")?;
    let out = dir.path().join("bake.exr");
    let mut rows = Vec::new();
    for rel in VENDORED {
        let path = data.join(rel);
        if !path.is_file() {
            bail!("{} not found (--data names the folder of the vendored scenes)", path.display());
        }
        let r = bake(&exe, &path.to_string_lossy(), &[], samples, &out)?;
        eprintln!("baked {rel}");
        rows.push(row(rel, &r));
    }
    let room = data.join("occlusion_room/room.glb");
    let mut layouts = Vec::new();
    for side in LAYOUT_SIDES {
        let path: PathBuf = lightvol_scene::layout::write_grid_layout(&room, dir.path(), [side, side], 10.0)
            .with_context(|| format!("writing the {side}x{side} layout"))?;
        // One grid for every layout: the 32 × 32 layout's extent (file frame, +Y up).
        let r = bake(
            &exe,
            &path.to_string_lossy(),
            &["--bounds", "-5,0.25,-5,315,4.75,315", "--res", "65,3,65"],
            samples,
            &out,
        )?;
        eprintln!("baked the {side}x{side} layout");
        layouts.push(row(&format!("occlusion room, {side}x{side} layout"), &r));
        std::fs::remove_file(&path).ok();
    }
    let mut builtins = Vec::new();
    for name in lightvol_scene::builtin::BUILTIN_NAMES {
        let r = bake(&exe, &format!("builtin:{name}"), &[], samples, &out)?;
        builtins.push(row(&format!("builtin:{name}"), &r));
    }
    Ok(json!({
        "samples": samples,
        "method": "doi-paper",
        "vendored": rows,
        "layouts": layouts,
        "builtin": builtins,
    }))
}
