//! `doi` against the leak fixes engines ship (lightvol-sampler's `baselines`: validity and
//! dilation, Unity APV, Unreal VLM, DDGI relocation), at equal samples per node, on every
//! built-in scene and every vendored real scene, the way engines bake probes: sky and
//! bounce light only (`--light sky+indirect`; the sun comes from shadow maps at run time).
//! Each scene is measured on its default grid (16 cells along the longest axis) and on two
//! plates, its default one (the built-in scene's recommended plate, or 10% of the height
//! above the floor) and a second one ([`second_height`]), against a path-traced reference,
//! through the CLI.
//!
//! Tolerances come from a two-seed noise floor measured at these settings (seeds 1 and 2,
//! `lightvol compare SCENE --light sky+indirect --samples 64 --plate-res 48
//! --reference-samples 256 --methods doi,point,point+validity,point+apv,point+vlm,point+ddgi
//! [--plate-height H] --seed S`): on each plate, the largest change of any method's relative
//! RMSE between the two seeds, relative to their mean ([`noise_floor`]). A comparison
//! between two methods holds if it holds within twice that (both sides carry the noise).

use std::path::Path;

use lightvol_sampler::builtin::BUILTIN_NAMES;
use serde_json::Value;
use vendored::{VENDORED_SCENES, vendored};

mod vendored;

/// The engines' baselines.
const BASELINES: [&str; 4] = ["point+validity", "point+apv", "point+vlm", "point+ddgi"];

/// A plate's measured two-seed noise floor (module docs) and the method that set it, on the
/// default plate (`second == false`) or the second one ([`second_height`]).
fn noise_floor(scene: &str, second: bool) -> f64 {
    let name = Path::new(scene).file_stem().map_or(scene, |s| s.to_str().unwrap());
    match (name, second) {
        ("builtin:city", false) => 0.091,        // point+validity
        ("builtin:city", true) => 0.086,         // point+vlm
        ("builtin:interior", false) => 0.047,    // doi
        ("builtin:interior", true) => 0.069,     // doi
        ("builtin:maze", false) => 0.044,        // point+apv
        ("builtin:maze", true) => 0.051,         // point+ddgi
        ("BreakfastRoom", false) => 0.104,       // point+apv
        ("BreakfastRoom", true) => 0.159,        // doi
        ("room", false) => 0.010,                // point+ddgi
        ("room", true) => 0.007,                 // point+apv
        ("living_room", false) => 0.008,         // point+apv
        ("living_room", true) => 0.004,          // point+vlm
        ("zdm2", false) => 0.198,                // doi: 2,382 valid plate points, outside the map
        ("zdm2", true) => 0.073,                 // doi
        ("CornellBox-Original", false) => 0.060, // point+ddgi
        ("CornellBox-Original", true) => 0.101,  // point+apv
        (other, _) => panic!("no noise floor measured for {other}"),
    }
}

/// The second plate's height along the file's up axis: the built-in scenes' second
/// recommended height (the maze, which has one, at 2 m, just under its 2.5 m walls); in the
/// real scenes a height people's heads or a room's middle are at (the Breakfast Room 1.5 m,
/// the occlusion room 2 m, the living room 1.7 m above its floor, zdm2 y = 0 through its
/// corridors, the Cornell box half-way up).
fn second_height(scene: &str) -> &'static str {
    let name = Path::new(scene).file_stem().map_or(scene, |s| s.to_str().unwrap());
    match name {
        "builtin:city" => "6.0",
        "builtin:interior" => "1.2",
        "builtin:maze" => "2.0",
        "BreakfastRoom" => "1.5",
        "room" => "2.0",
        "living_room" => "0.2",
        "zdm2" => "0.0",
        "CornellBox-Original" => "1.0",
        other => panic!("no second plate for {other}"),
    }
}

/// The mean of `doi`'s relative RMSE over every plate may exceed the best baseline's by
/// this factor: measured 0.97 × Unity APV's on seed 1 and 1.007 × on seed 2 (parity within
/// the noise; `doi` is ahead on the default plates, 0.96 × on both seeds, and level on the
/// second ones, 0.99 × and 1.05 ×).
const MEAN_RATIO: f64 = 1.03;

/// On the built-in interior `doi` is behind point sampling and DDGI (which moves no probe
/// there, so it is point sampling): its nodes in the open room are point's, and its nodes in
/// the 0.3 m walls, moved just inside the room or averaged over their support, come out
/// brighter than the room next to the walls (too_bright 0.151 against 0.135 at 128 samples).
/// Measured 1.063 and 1.100 × DDGI's relative RMSE on the two seeds on the default plate,
/// 1.025 and 1.102 on the second; the bound is the larger plus the plate's noise floor.
const INTERIOR_RATIO: f64 = 1.15;

/// Scenes where point sampling leaks dark from inside solids, and `doi` must at least halve
/// its share of too-dark points near geometry (measured: Cornell box 0.028 against 0.175,
/// city 0.016 against 1.0, maze 0.005 against 0.58, zdm2 0.012 against 0.74). Elsewhere it
/// does not: on the living room nothing is single-sided, so doi is point; on the Breakfast
/// Room doi's near-geometry points are darker than point's (0.44 against 0.13: the nodes
/// that see the back faces of its single-sided slats and panels are moved next to them or
/// averaged over supports that reach into the shade).
const LEAKY: [&str; 4] = ["builtin:city", "builtin:maze", "zdm2", "CornellBox-Original"];

fn run(args: &[&str]) {
    let code = lightvol::run_from_args(std::iter::once("lightvol").chain(args.iter().copied()));
    match code {
        Ok(c) => assert_eq!(c, std::process::ExitCode::SUCCESS),
        Err(e) => panic!("lightvol {}: {e:#}", args.join(" ")),
    }
}

fn compare(scene: &str, height: Option<&str>) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let methods = format!("doi,point,{}", BASELINES.join(","));
    let mut args = vec![
        "compare",
        scene,
        "--light",
        "sky+indirect",
        "--samples",
        "64",
        "--plate-res",
        "48",
        "--reference-samples",
        "256",
        "--methods",
        &methods,
        "--quiet",
        "-o",
        out,
    ];
    if let Some(h) = height {
        args.extend(["--plate-height", h]);
    }
    run(&args);
    let text = std::fs::read_to_string(dir.path().join("report.json")).expect("report.json");
    serde_json::from_str(&text).expect("report.json parses")
}

fn rmse(r: &Value, m: &str) -> f64 {
    r["methods"][m]["rel_rmse"].as_f64().unwrap_or_else(|| panic!("{m}.rel_rmse"))
}

fn scenes() -> Vec<String> {
    let builtins = BUILTIN_NAMES.iter().map(|n| format!("builtin:{n}"));
    builtins.chain(VENDORED_SCENES.iter().map(|rel| vendored(rel).to_str().unwrap().to_owned())).collect()
}

/// On every scene and both plates `doi`'s relative RMSE is at or below every engine
/// baseline's and point sampling's within twice the plate's noise floor (the interior:
/// [`INTERIOR_RATIO`]), its rays stay within 1.25 × point's, it halves point's
/// near-geometry darkness where point leaks ([`LEAKY`]; on the default plates), and its mean
/// over the plates is within [`MEAN_RATIO`] of the best baseline's mean.
#[test]
fn doi_is_at_or_below_every_engine_baseline() {
    let mut sums = [0.0f64; 5];
    let mut n = 0.0;
    for scene in scenes() {
        let name = Path::new(&scene).file_stem().map_or(scene.clone(), |s| s.to_string_lossy().into_owned());
        for second in [false, true] {
            let r = compare(&scene, second.then(|| second_height(&scene)));
            let tol = if scene == "builtin:interior" {
                INTERIOR_RATIO
            } else {
                1.0 + 2.0 * noise_floor(&scene, second)
            };
            let doi = rmse(&r, "doi");
            sums[0] += doi;
            let mut line = format!("{name} (plate {}): doi {doi:.4}", r["plate"]["height"]);
            for (i, b) in BASELINES.iter().enumerate() {
                let e = rmse(&r, b);
                sums[i + 1] += e;
                line.push_str(&format!(" {b} {e:.4}"));
                assert!(doi <= tol * e, "{line}: doi {doi} against {b} {e} (tolerance {tol})");
            }
            let point = rmse(&r, "point");
            line.push_str(&format!(" point {point:.4}"));
            println!("{line}");
            assert!(doi <= tol * point, "{line}: doi {doi} against point {point}");
            let rays = |m: &str| r["methods"][m]["rays"]["total"].as_f64().unwrap();
            assert!(rays("doi") <= 1.25 * rays("point"), "{line}: doi's rays");
            let dark = |m: &str| r["methods"][m]["too_dark_near"].as_f64().unwrap();
            if !second && (LEAKY.contains(&scene.as_str()) || LEAKY.contains(&name.as_str())) {
                assert!(dark("point") > 0.1, "{name}: point sampling must leak here");
                assert!(
                    dark("doi") <= 0.5 * dark("point"),
                    "{name}: too_dark_near {} against {}",
                    dark("doi"),
                    dark("point")
                );
            }
            n += 1.0;
        }
    }
    let best = sums[1..].iter().copied().fold(f64::INFINITY, f64::min) / n;
    println!("means over {n} plates: doi {:.4}, best baseline {best:.4}", sums[0] / n);
    assert!(
        sums[0] / n <= MEAN_RATIO * best,
        "doi's mean {} against the best baseline's {best}",
        sums[0] / n
    );
}
