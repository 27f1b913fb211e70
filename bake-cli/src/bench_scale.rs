//! `lightvol bench --bakes`: bake wall time and peak memory at scale. Each bake runs as its
//! own `lightvol bake --json` process (so its peak resident memory is its own), over:
//!
//! - the vendored real scenes under `--data`;
//! - grid layouts of the vendored occlusion room (1, 4 × 4, 8 × 8 and 32 × 32 rooms at a
//!   10 m pitch, [`lightvol_scene::layout`]) on one fixed grid, so that time and memory
//!   show what instanced triangles cost at equal unique triangles, grid and rays;
//! - the built-in scenes.
//!
//! `lightvol bench --whole-bake [--vs OTHER]` times one bake as users run it (the Breakfast
//! Room at 0.2 m and 256 samples) from outside its process, beside another executable's.

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

/// The whole-bake figure's scene (under `--data`): a bake as users run it, with the
/// default method, at [`WHOLE_BAKE_SPACING`] and [`WHOLE_BAKE_SAMPLES`].
const WHOLE_BAKE_SCENE: &str = "breakfast_room/BreakfastRoom.gltf";
/// The whole bake's grid spacing (scene units).
const WHOLE_BAKE_SPACING: f64 = 0.2;
/// The whole bake's samples per cell.
const WHOLE_BAKE_SAMPLES: u32 = 256;

/// One whole bake by `exe` into `out`, timed from outside the process: wall seconds.
fn timed_bake(exe: &Path, scene: &Path, out: &Path) -> anyhow::Result<f64> {
    let (spacing, samples) = (WHOLE_BAKE_SPACING.to_string(), WHOLE_BAKE_SAMPLES.to_string());
    let t0 = std::time::Instant::now();
    let o = Command::new(exe)
        .arg("bake")
        .arg(scene)
        .args(["--spacing", &spacing, "--samples", &samples, "--quiet", "-o"])
        .arg(out)
        .output()
        .with_context(|| format!("running {}", exe.display()))?;
    let wall = t0.elapsed().as_secs_f64();
    if !o.status.success() {
        bail!("{} failed: {}", exe.display(), String::from_utf8_lossy(&o.stderr).trim());
    }
    Ok(wall)
}

/// The median of `v` (the mean of the middle two for an even count).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

/// `bench --whole-bake`: the wall time of the Breakfast Room baked at 0.2 m and 256
/// samples, `runs` times, each run its own process; with `vs` (another lightvol
/// executable) the same bake by it, the two alternating run by run so that drift in the
/// machine's speed falls on both, with the ratio of the medians and whether both wrote
/// the same bytes.
pub(crate) fn whole_bake(data: &Path, vs: Option<&Path>, runs: u32) -> anyhow::Result<Value> {
    let scene = data.join(WHOLE_BAKE_SCENE);
    if runs == 0 {
        bail!("--bake-runs must be at least 1");
    }
    if !scene.is_file() {
        bail!("{} not found (--data names the folder of the vendored scenes)", scene.display());
    }
    let exe = std::env::current_exe().context("locating the lightvol executable")?;
    let dir = tempfile::tempdir().context("creating a temporary directory")?;
    let (ours_out, theirs_out) = (dir.path().join("ours.exr"), dir.path().join("theirs.exr"));
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    for run in 0..runs {
        ours.push(timed_bake(&exe, &scene, &ours_out)?);
        if let Some(vs) = vs {
            theirs.push(timed_bake(vs, &scene, &theirs_out)?);
        }
        eprintln!("whole bake: run {} of {runs}", run + 1);
    }
    let ours_median = median(ours.clone());
    let mut report = json!({
        "scene": WHOLE_BAKE_SCENE,
        "spacing": WHOLE_BAKE_SPACING,
        "samples": WHOLE_BAKE_SAMPLES,
        "runs": runs,
        "wall_seconds": ours,
        "median_wall_seconds": ours_median,
    });
    if let Some(vs) = vs {
        let theirs_median = median(theirs.clone());
        let same = std::fs::read(&ours_out).context("reading our bake")?
            == std::fs::read(&theirs_out).context("reading the other bake")?;
        report["vs"] = json!({
            "executable": vs.display().to_string(),
            "wall_seconds": theirs,
            "median_wall_seconds": theirs_median,
            "speedup": theirs_median / ours_median,
            "same_bytes": same,
        });
    }
    Ok(report)
}
