//! `doi` against the leak fixes engines ship (lightvol-sampler's `baselines`: validity and
//! dilation, Unity APV, Unreal VLM, DDGI relocation), at equal samples per node, on every
//! built-in scene and every vendored real scene, the way engines bake probes: sky and
//! bounce light only (`--light sky+indirect`; the sun comes from shadow maps at run time).
//! Each scene is measured on its default grid (16 cells along the longest axis) on two
//! plates, its default one (the built-in scene's recommended plate, or 10% of the height
//! above the floor) and a second one ([`second_height`]), and in one view ([`camera`]: the
//! scene shaded by each method's volume, relative RMSE over pixels), against a path-traced
//! reference, through the CLI.
//!
//! Tolerances come from a two-seed noise floor measured at these settings (seeds 1 and 2,
//! `lightvol compare SCENE --light sky+indirect --samples 64 --plate-res 48
//! --reference-samples 256 --methods doi,point,point+validity,point+apv,point+vlm,point+ddgi
//! [--plate-height H] [--camera C --view-width 96 --view-samples 256] --seed S`): on each
//! plate and view, the largest change of any method's relative RMSE between the two seeds,
//! relative to their mean ([`noise_floor`], [`view_noise_floor`]). A comparison between two
//! methods holds if it holds within twice that (both sides carry the noise).

use std::path::Path;

use lightvol_scene::builtin::BUILTIN_NAMES;
use serde_json::Value;
use vendored::{VENDORED_SCENES, vendored};

mod vendored;

/// The engines' baselines.
const BASELINES: [&str; 4] = ["point+validity", "point+apv", "point+vlm", "point+ddgi"];

/// A plate's measured two-seed noise floor (module docs) and the method that set it, on the
/// default plate (`second == false`) or the second one ([`second_height`]).
fn noise_floor(scene: &str, second: bool) -> f64 {
    match (scene_name(scene).as_str(), second) {
        ("builtin:city", false) => 0.095,        // doi
        ("builtin:city", true) => 0.058,         // point+apv
        ("builtin:interior", false) => 0.036,    // point+validity
        ("builtin:interior", true) => 0.005,     // point+apv
        ("builtin:maze", false) => 0.044,        // point+apv
        ("builtin:maze", true) => 0.051,         // point+apv
        ("BreakfastRoom", false) => 0.107,       // doi
        ("BreakfastRoom", true) => 0.063,        // point+validity
        ("room", false) => 0.034,                // doi
        ("room", true) => 0.068,                 // doi
        ("living_room", false) => 0.008,         // point+apv
        ("living_room", true) => 0.022,          // doi
        ("zdm2", false) => 0.243,                // doi: 2,382 valid plate points, outside the map
        ("zdm2", true) => 0.127,                 // doi
        ("CornellBox-Original", false) => 0.060, // point+ddgi
        ("CornellBox-Original", true) => 0.101,  // point+apv
        (other, _) => panic!("no noise floor measured for {other}"),
    }
}

/// A view's measured two-seed noise floor (module docs) and the method that set it.
fn view_noise_floor(scene: &str) -> f64 {
    match scene_name(scene).as_str() {
        "builtin:city" => 0.173,        // doi
        "builtin:interior" => 0.076,    // doi
        "builtin:maze" => 0.098,        // doi
        "BreakfastRoom" => 0.129,       // doi
        "room" => 0.033,                // doi
        "living_room" => 0.009,         // doi
        "zdm2" => 0.152,                // doi
        "CornellBox-Original" => 0.026, // doi
        other => panic!("no view noise floor measured for {other}"),
    }
}

/// The camera of each scene's view (`compare --camera`): `overview` for the open scenes,
/// the file's own camera for the Breakfast Room, and inside the closed rooms (in the file's
/// axes) a corner under the ceiling looking across the room; the Cornell box from in front
/// of its open side.
fn camera(scene: &str) -> &'static str {
    match scene_name(scene).as_str() {
        "builtin:city" | "builtin:maze" | "zdm2" => "overview",
        "builtin:interior" => "5.6,0.4,2.4:2.6,4.6,0.6:80",
        "BreakfastRoom" => "gltf:0",
        "room" => "4.5,3.5,4.5:-2,0.5,-2:80",
        "living_room" => "3.5,1.5,10.5:-3,-0.5,-1:80",
        "CornellBox-Original" => "0,1,3.4:0,1,0:45",
        other => panic!("no camera for {other}"),
    }
}

/// The scene's label in the tables above: a built-in name as given, a file by its stem.
fn scene_name(scene: &str) -> String {
    Path::new(scene).file_stem().map_or(scene.to_owned(), |s| s.to_string_lossy().into_owned())
}

/// The second plate's height along the file's up axis: the built-in scenes' second
/// recommended height (the maze, which has one, at 2 m, just under its 2.5 m walls); in the
/// real scenes a height people's heads or a room's middle are at (the Breakfast Room 1.5 m,
/// the occlusion room 2 m, the living room 1.7 m above its floor, zdm2 y = 0 through its
/// corridors, the Cornell box half-way up).
fn second_height(scene: &str) -> &'static str {
    match scene_name(scene).as_str() {
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

/// `doi`'s mean relative RMSE over every plate and view may be this factor of the best
/// baseline's (Unity APV's): measured 0.588 × on seed 1 and 0.596 × on seed 2. Most of the
/// lead is in the closed rooms, whose walls are thinner than a cell: there `doi`'s lookups
/// leave out the nodes on the other side of the wall (its node reach), every baseline's
/// read them.
const MEAN_RATIO: f64 = 0.9;

/// Scenes where point sampling leaks dark near geometry, and `doi` must at least halve its
/// share of too-dark points there (measured on seed 1: Cornell box 0.025 against 0.175, city
/// 0.000 against 1.0, maze 0.000 against 0.58, zdm2 0.008 against 0.74: dark from inside
/// solids; the occlusion room 0.130 against 0.394: dark from the nodes outside its thin
/// walls, which its lookups leave out). Elsewhere it does not: on the living room point's
/// share is 0.105, about the noise of the measure (doi 0.007); on the interior 0.29 against
/// 0.42, the noise of 64 samples (every method's share of too-dark points over the whole
/// plate is 0.26 to 0.31 on the interior and the Breakfast Room; the interior's is checked
/// at 512 samples, [`doi_halves_the_interiors_dark_walls_above_the_noise`]); on the
/// Breakfast Room doi's near-geometry points are darker than point's (0.32 against 0.13;
/// 0.030 against 0.009 at 1024 samples), because point's are too bright: its nodes outside
/// the room's single-sided walls see the sky, and light the rim of the room (point's
/// `too_bright` 0.37, doi's 0.29).
const LEAKY: [&str; 5] = ["builtin:city", "builtin:maze", "zdm2", "CornellBox-Original", "room"];

fn run(args: &[&str]) {
    let code = lightvol::run_from_args(std::iter::once("lightvol").chain(args.iter().copied()));
    match code {
        Ok(c) => assert_eq!(c, std::process::ExitCode::SUCCESS),
        Err(e) => panic!("lightvol {}: {e:#}", args.join(" ")),
    }
}

fn compare(scene: &str, height: Option<&str>, view: Option<&str>) -> Value {
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
    ];
    if let Some(h) = height {
        args.extend(["--plate-height", h]);
    }
    if let Some(c) = view {
        args.extend(["--camera", c, "--view-width", "96", "--view-samples", "256"]);
    }
    report(&args)
}

/// Runs `lightvol` with `args` (a `compare` command line without its output options),
/// quietly, into a temporary folder, and returns the parsed `report.json`.
fn report(args: &[&str]) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let mut args = args.to_vec();
    args.extend(["--quiet", "-o", out]);
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

/// On every scene, on both plates and in the view, `doi`'s relative RMSE is at or below
/// every engine baseline's and point sampling's within twice the noise floor, its rays stay
/// within 1.25 × point's, it halves point's near-geometry darkness where point leaks
/// ([`LEAKY`]; on the default plates), and its mean over the plates and views is within
/// [`MEAN_RATIO`] of the best baseline's mean.
#[test]
fn doi_is_at_or_below_every_engine_baseline() {
    let mut sums = [0.0f64; 5];
    let mut n = 0.0;
    for scene in scenes() {
        let name = scene_name(&scene);
        for second in [false, true] {
            let r = compare(&scene, second.then(|| second_height(&scene)), (!second).then(|| camera(&scene)));
            let tol = 1.0 + 2.0 * noise_floor(&scene, second);
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
            if !second && LEAKY.contains(&name.as_str()) {
                assert!(dark("point") > 0.1, "{name}: point sampling must leak here");
                assert!(
                    dark("doi") <= 0.5 * dark("point"),
                    "{name}: too_dark_near {} against {}",
                    dark("doi"),
                    dark("point")
                );
            }
            n += 1.0;
            if !second {
                check_view(&scene, &r, &mut sums);
                n += 1.0;
            }
        }
    }
    let best = sums[1..].iter().copied().fold(f64::INFINITY, f64::min) / n;
    println!("means over {n} plates and views: doi {:.4}, best baseline {best:.4}", sums[0] / n);
    assert!(
        sums[0] / n <= MEAN_RATIO * best,
        "doi's mean {} against the best baseline's {best}",
        sums[0] / n
    );
}

/// `doi`'s view (relative RMSE over pixels) is at or below every engine baseline's and point
/// sampling's within twice the view's noise floor; adds the view's errors to `sums` (doi,
/// then [`BASELINES`]).
fn check_view(scene: &str, r: &Value, sums: &mut [f64; 5]) {
    let v = &r["views"][0]["methods"];
    let e = |m: &str| v[m]["rel_rmse"].as_f64().unwrap_or_else(|| panic!("view {m}.rel_rmse"));
    let tol = 1.0 + 2.0 * view_noise_floor(scene);
    let doi = e("doi");
    sums[0] += doi;
    let mut line = format!("{} (view {}): doi {doi:.4}", scene_name(scene), camera(scene));
    for (i, b) in BASELINES.iter().enumerate() {
        sums[i + 1] += e(b);
        line.push_str(&format!(" {b} {:.4}", e(b)));
    }
    line.push_str(&format!(" point {:.4}", e("point")));
    println!("{line}");
    for b in BASELINES.iter().chain(&["point"]) {
        assert!(doi <= tol * e(b), "{line}: doi {doi} against {b} {} (tolerance {tol})", e(b));
    }
}

/// On the interior, point sampling's darkness near the walls (its nodes inside the 0.3 m
/// walls) is hidden by the noise of 64 samples: there every method's share of too-dark
/// points over the whole plate is 0.26 to 0.29, near geometry `doi` 0.285 against point's
/// 0.420. At 512 samples per node and 2048 reference paths it stands out, and `doi` must
/// halve it (measured on seeds 1, 2 and 3: 0.058 against 0.343, 0.125 against 0.429, 0.125
/// against 0.393; at 1024 samples 0.012 against 0.329; at 256 samples seed 3 gave 0.237
/// against 0.468, over half, which is why this runs at 512).
#[test]
fn doi_halves_the_interiors_dark_walls_above_the_noise() {
    let r = report(&[
        "compare",
        "builtin:interior",
        "--light",
        "sky+indirect",
        "--samples",
        "512",
        "--plate-res",
        "48",
        "--reference-samples",
        "2048",
        "--methods",
        "doi,point",
    ]);
    let dark = |m: &str| r["methods"][m]["too_dark_near"].as_f64().unwrap();
    println!("interior at 512 samples: too_dark_near doi {:.3} point {:.3}", dark("doi"), dark("point"));
    assert!(dark("point") > 0.1, "point sampling must leak dark here: {}", dark("point"));
    assert!(dark("doi") <= 0.5 * dark("point"), "doi {} against point {}", dark("doi"), dark("point"));
}
