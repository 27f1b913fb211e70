//! The central claim of Kontkanen & Laine 2006 ([KL06] §8, Fig. 6), reproduced through the
//! CLI: at equal sample budget, domain-of-interest sampling removes the dark leaks of point
//! sampling, measured against a path-traced reference on horizontal plates.
//!
//! Settings are reduced from the demo's (smaller plates, fewer samples) but honest: the
//! recommended grids of the built-in scenes, the default bounces, seeded streams.

use std::path::Path;

use serde_json::Value;

fn run(args: &[&str]) {
    let code = lightvol::run_from_args(std::iter::once("lightvol").chain(args.iter().copied()));
    match code {
        Ok(c) => assert_eq!(c, std::process::ExitCode::SUCCESS),
        Err(e) => panic!("lightvol {}: {e:#}", args.join(" ")),
    }
}

fn report(dir: &Path) -> Value {
    let text = std::fs::read_to_string(dir.join("report.json")).expect("report.json");
    serde_json::from_str(&text).expect("report.json parses")
}

fn metric(r: &Value, method: &str, key: &str) -> f64 {
    r["methods"][method][key].as_f64().unwrap_or_else(|| panic!("methods.{method}.{key} missing"))
}

fn total_rays(r: &Value, method: &str) -> f64 {
    r["methods"][method]["rays"]["total"].as_f64().unwrap()
}

fn summary(r: &Value) -> String {
    ["point", "prefilter", "doi-paper", "doi"]
        .iter()
        .filter(|m| r["methods"].get(**m).is_some())
        .map(|m| {
            format!(
                "{m}: rel_rmse {:.4} too_dark {:.4} too_dark_near {:.4} too_bright {:.4} rays {}",
                metric(r, m, "rel_rmse"),
                metric(r, m, "too_dark"),
                metric(r, m, "too_dark_near"),
                metric(r, m, "too_bright"),
                total_rays(r, m)
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// City: doi removes at least 90% of point sampling's near-surface dark
/// points, cuts the relative RMSE by at least 20%, and traces at most 1.25x the rays.
#[test]
fn city_doi_beats_point_sampling() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    run(&[
        "compare",
        "builtin:city",
        "--samples",
        "64",
        "--plate-res",
        "48",
        "--reference-samples",
        "128",
        "--quiet",
        "-o",
        out,
    ]);
    let r = report(dir.path());
    println!("{}", summary(&r));
    assert!(r["plate"]["valid_points"].as_u64().unwrap() > 500, "the plate must have valid points");
    let (dark_doi, dark_point) = (metric(&r, "doi", "too_dark_near"), metric(&r, "point", "too_dark_near"));
    assert!(dark_point > 0.2, "point sampling must show the leak this test is about ({dark_point})");
    assert!(dark_doi <= 0.1 * dark_point, "too_dark_near doi {dark_doi} vs point {dark_point}");
    assert!(metric(&r, "doi", "rel_rmse") <= 0.8 * metric(&r, "point", "rel_rmse"));
    assert!(total_rays(&r, "doi") <= 1.25 * total_rays(&r, "point"));
    // The outputs a person looks at exist.
    for f in ["plate.exr", "panel_doi.png", "panel_point.png", "panel_prefilter.png", "error_doi.png"] {
        assert!(dir.path().join(f).metadata().unwrap().len() > 0, "{f}");
    }
    // Without --camera there are no views.
    assert!(r.get("views").is_none());
    let names = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap());
    assert!(names.filter(|n| n.starts_with("view_")).count() == 0);
}

/// A street of the city at eye height, looking east along the street between the second
/// and third rows of blocks.
const STREET: &str = "-28,0.3,1.7:10,0,1.2:60";

/// `compare --camera` on the city, seen from above (`overview`) and from a street: every
/// view has a path-traced image and one per method, and a `views` entry with its size,
/// samples and per-method metrics over the pixels that see a surface inside the grid; the
/// scene shaded by the doi volume is closer to the path-traced view than shaded by the
/// point-sampled one (measured 0.13 vs 0.63 from above, 0.27 vs 0.65 in the street); the
/// reference view is the image `render --reference` writes for the same camera.
#[test]
fn city_views_doi_beats_point_sampling() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let view = ["--view-width", "96", "--view-height", "64", "--view-samples", "32"];
    let mut args = vec![
        "compare",
        "builtin:city",
        "--samples",
        "32",
        "--plate-res",
        "24",
        "--reference-samples",
        "64",
        "--methods",
        "point,doi",
        "--camera",
        "overview",
        "--camera",
        STREET,
        "--quiet",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend(view);
    run(&args);
    let r = report(&out);
    let views = r["views"].as_array().expect("views section");
    let labels: Vec<&str> = views.iter().map(|v| v["camera"].as_str().unwrap()).collect();
    assert_eq!(labels, ["overview", "cam1"]);
    for v in views {
        let label = v["camera"].as_str().unwrap();
        assert_eq!(v["resolution"], serde_json::json!([96, 64]));
        assert_eq!(v["reference"]["samples"], 32);
        assert!(v["reference"]["mean"].as_f64().unwrap() > 0.0);
        let (surface, measured) =
            (v["surface_pixels"].as_u64().unwrap(), v["measured_pixels"].as_u64().unwrap());
        assert!(
            measured > 1000 && measured <= surface && surface <= 96 * 64,
            "{label}: {measured} {surface}"
        );
        let rel = |m: &str| v["methods"][m]["rel_rmse"].as_f64().unwrap();
        println!("view {label}: point {:.4} doi {:.4}", rel("point"), rel("doi"));
        assert!(rel("doi") < 0.6 * rel("point"), "{label}: doi {} vs point {}", rel("doi"), rel("point"));
        for m in ["reference", "point", "doi"] {
            let img = image::open(out.join(format!("view_{label}_{m}.png"))).unwrap();
            assert_eq!((img.width(), img.height()), (96, 64), "{label} {m}");
        }
    }
    // The path-traced views are `render --reference`'s images: the overview frames the
    // built-in's grid, which is the compared grid.
    for (label, camera) in [("overview", None), ("cam1", Some(STREET))] {
        let png = dir.path().join(format!("render_{label}.png"));
        let mut render = vec!["render", "builtin:city", "--reference", "--reference-samples", "32"];
        render.extend(["--width", "96", "--height", "64", "-o", png.to_str().unwrap()]);
        let spec;
        if let Some(c) = camera {
            spec = format!("--camera={c}");
            render.push(&spec);
        }
        run(&render);
        let view = std::fs::read(out.join(format!("view_{label}_reference.png"))).unwrap();
        assert!(
            std::fs::read(&png).unwrap() == view,
            "{label}: compare's reference view differs from render's"
        );
    }
}

/// Bad view options are one clear line each, before the output folder is made (a camera
/// that sees nothing inside the grid: before anything is baked or written into it).
#[test]
fn bad_view_options_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let err = |extra: &[&str]| {
        let mut args = vec!["compare", "builtin:maze", "--quiet", "-o", out.to_str().unwrap()];
        args.extend(extra);
        let e = lightvol::run_from_args(std::iter::once("lightvol").chain(args.iter().copied())).unwrap_err();
        let written = out.read_dir().map(|d| d.count()).unwrap_or(0);
        assert!(written == 0, "{extra:?} wrote into {}", out.display());
        assert!(!out.exists() || extra[0].starts_with("--camera="), "{extra:?} made {}", out.display());
        format!("{e:#}").replace('\n', " ")
    };
    assert_eq!(
        err(&["--camera", "overview", "--view-samples", "0"]),
        "invalid value '0' for '--view-samples <VIEW_SAMPLES>': must be at least 1"
    );
    assert_eq!(
        err(&["--camera", "1,2,3"]),
        "--camera: expected EYE_X,EYE_Y,EYE_Z:TARGET_X,TARGET_Y,TARGET_Z[:FOV_DEG]"
    );
    assert_eq!(err(&["--camera", "gltf:0"]), "--camera gltf:0: the scene file has no perspective camera");
    let e = err(&["--camera", "overview", "--view-width", "0"]);
    assert_eq!(e, "--view-width/--view-height: image size 0x128 must be positive and at most 64 Mpixels");
    let e = err(&["--camera", "overview", "--camera", "overview"]);
    assert!(e.contains("two --camera options") && e.contains("'overview'"), "{e}");
    let e = err(&["--camera=0,0,60:0,1,100"]);
    assert_eq!(e, "--camera: view 'cam0' sees no surface inside the grid");
}

/// Runs `compare` on the interior at reduced settings (the recommended ~0.3 m grid, 256
/// samples per cell, 2048 reference paths per plate point) and returns the report.
fn interior(height: &str, fit: &str) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    run(&[
        "compare",
        "builtin:interior",
        "--plate-height",
        height,
        "--samples",
        "256",
        "--plate-res",
        "40",
        "--reference-samples",
        "2048",
        "--methods",
        "point,doi-paper,doi",
        "--fit",
        fit,
        "--quiet",
        "-o",
        out,
    ]);
    let r = report(dir.path());
    println!("interior at {height} m, --fit {fit}:\n{}", summary(&r));
    r
}

/// Interior ([KL06] Fig. 6c): the recommended grid has node layers inside the walls,
/// floor and ceiling, and the plates are crossed by the sun patch under the window.
///
/// - With the least-squares node fit (`--fit lsq`, lightvol-sampler's `fit` module), the
///   paper's method (`doi-paper`) has a lower relative RMSE than point sampling on both
///   plates and fewer near-surface dark points.
/// - With the paper's plain Eq. 6 average (`--fit average`), doi-paper removes most of point
///   sampling's near-surface darkness, but its double filtering (weighting, then trilinear
///   reconstruction) smears the sun patch, which dominates the RMSE: measured 0.71 vs 0.59
///   for point at 1.2 m, so the RMSE claim is asserted for the least-squares fit only.
/// - The default `doi` takes no fit (its nodes are point samples or support averages).
#[test]
fn interior_doi_beats_point_sampling() {
    for height in ["0.6", "1.2"] {
        let r = interior(height, "lsq");
        let (doi, point) = (metric(&r, "doi-paper", "rel_rmse"), metric(&r, "point", "rel_rmse"));
        assert!(doi < point, "rel_rmse at {height} m: doi {doi} vs point {point}");
        let (dark_doi, dark_point) =
            (metric(&r, "doi-paper", "too_dark_near"), metric(&r, "point", "too_dark_near"));
        assert!(dark_point > 0.2, "point sampling must show the dark leak ({dark_point})");
        assert!(dark_doi < dark_point, "too_dark_near at {height} m: doi {dark_doi} vs point {dark_point}");
        assert!(total_rays(&r, "doi-paper") <= 1.25 * total_rays(&r, "point"));
        // The default doi point-samples the nodes in the open room, so its RMSE is point's
        // (measured 0.857 against 0.857 at 0.6 m, 0.595 against 0.594 at 1.2 m: the sun patch
        // dominates both), but the nodes in the walls are moved out or integrated: measured
        // too_dark_near 0.17 against 0.29 and 0.20 against 0.52.
        let (dark_new, dark_point) =
            (metric(&r, "doi", "too_dark_near"), metric(&r, "point", "too_dark_near"));
        assert!(
            dark_new < 0.7 * dark_point,
            "too_dark_near at {height} m: doi {dark_new} vs point {dark_point}"
        );
        assert!(total_rays(&r, "doi") <= 1.25 * total_rays(&r, "point"));
    }
    let r = interior("0.6", "average");
    let (dark_doi, dark_point) =
        (metric(&r, "doi-paper", "too_dark_near"), metric(&r, "point", "too_dark_near"));
    assert!(dark_doi <= 0.5 * dark_point, "Eq. 6 too_dark_near doi {dark_doi} vs point {dark_point}");
    assert!(metric(&r, "doi-paper", "too_dark") < metric(&r, "point", "too_dark"));
}

/// Cornell box (real data): nodes inside the two blocks and behind the
/// single-sided walls must not darken the valid space around the blocks.
#[test]
fn cornell_box_blocks_do_not_darken_the_room() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let obj = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/cornell_box/cornell_box.obj");
    run(&[
        "compare",
        obj,
        "--up",
        "y",
        "--plate-height",
        "100",
        "--samples",
        "32",
        "--plate-res",
        "32",
        "--reference-samples",
        "128",
        "--methods",
        "point,doi",
        "--quiet",
        "-o",
        out,
    ]);
    let r = report(dir.path());
    println!("{}", summary(&r));
    let (dark_doi, dark_point) = (metric(&r, "doi", "too_dark_near"), metric(&r, "point", "too_dark_near"));
    // Point sampling shows dark halos around the blocks; doi does not.
    assert!(dark_point > 0.1, "{dark_point}");
    assert!(dark_doi < 0.25 * dark_point, "too_dark_near doi {dark_doi} vs point {dark_point}");
    assert!(metric(&r, "doi", "too_dark") < 0.05);
}

/// The path-traced reference itself. A plate above a ground plane under a uniform sky
/// of radiance L sees only the sky: E = π L exactly. The per-point estimates' scatter gives
/// the Monte Carlo error of their mean; the mean must lie within 4 standard errors (plus
/// f32 storage rounding) of π L, and the bias must be below 1%. (The reference samples
/// cosine-weighted directions, so for a constant sky every sample is exactly π L and the
/// measured standard error is 0: the estimator is unbiased *and* noise-free here.)
#[test]
fn reference_matches_uniform_sky() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("ground.obj");
    // A 20 m ground quad, +Z up, facing up.
    std::fs::write(&obj, "v -10 -10 0\nv 10 -10 0\nv 10 10 0\nv -10 10 0\nf 1 2 3 4\n").unwrap();
    let out = dir.path().join("out");
    run(&[
        "compare",
        obj.to_str().unwrap(),
        "--up",
        "z",
        "--sky",
        "0.5,0.5,0.5",
        "--bounds",
        "-5,-5,0.5,5,5,3",
        "--res",
        "3,3,3",
        "--plate-height",
        "1",
        "--plate-res",
        "12",
        "--reference-samples",
        "64",
        "--samples",
        "8",
        "--methods",
        "doi",
        "--quiet",
        "-o",
        out.to_str().unwrap(),
    ]);
    // Read the per-point truth back from plate.exr.
    let img = exr::prelude::read_all_flat_layers_from_file(out.join("plate.exr")).expect("plate.exr");
    let layer = &img.layer_data[0];
    let truth =
        layer.channel_data.list.iter().find(|c| c.name.to_string() == "truth").expect("truth channel");
    let v: Vec<f64> = truth.sample_data.values_as_f32().map(f64::from).collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let std_err = (var / n).sqrt();
    let want = std::f64::consts::PI * 0.5;
    println!("reference mean {mean} vs pi L = {want}, standard error {std_err}");
    // f32 storage of the plate adds ~1e-7 relative.
    assert!((mean - want).abs() <= 4.0 * std_err + 1e-6 * want, "mean {mean}, std err {std_err}");
    assert!((mean - want).abs() < 0.01 * want);
    let r = report(&out);
    assert_eq!(r["plate"]["valid_points"].as_u64(), Some(144));
}

/// The engine baselines run through `compare` beside point and doi at equal samples per
/// node: on the city (whose buildings are closed solids, so grid nodes inside them see back
/// faces) each one finds invalid or moved probes, counts its validity rays, and every one
/// of them is closer to the truth than naive point sampling; only APV moves probes and
/// invalidates them, and only its memory counts a validity mask. (Whether doi beats them is
/// what the comparison measures; it is not asserted here.)
#[test]
fn engine_baselines_run_through_compare() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    run(&[
        "compare",
        "builtin:city",
        "--samples",
        "32",
        "--plate-res",
        "24",
        "--reference-samples",
        "64",
        "--methods",
        "point,point+validity,point+apv,point+vlm,point+ddgi,doi",
        "--quiet",
        "-o",
        out.to_str().unwrap(),
    ]);
    let r = report(&out);
    println!("{}", summary(&r));
    let point = metric(&r, "point", "rel_rmse");
    for b in ["point+validity", "point+apv", "point+vlm", "point+ddgi"] {
        let m = &r["methods"][b];
        let touched = m["invalid_nodes"].as_u64().unwrap() + m["moved_nodes"].as_u64().unwrap();
        assert!(touched > 0, "{b} changed no probe");
        assert!(total_rays(&r, b) > total_rays(&r, "point"), "{b}: validity rays not counted");
        assert!(metric(&r, b, "rel_rmse") < point, "{b} is not better than point sampling");
    }
    assert_eq!(r["methods"]["point+vlm"]["moved_nodes"], 0, "VLM does not move probes");
    assert_eq!(r["methods"]["point+validity"]["moved_nodes"], 0, "point+validity does not move probes");
    assert!(
        r["methods"]["point+apv"]["moved_nodes"].as_u64().unwrap() > 0,
        "APV's virtual offset moved nothing"
    );
    // The APV volume keeps its validity mask: one byte per node beyond the uniform grid's.
    let nodes = r["methods"]["point"]["nodes"].as_u64().unwrap();
    assert_eq!(
        r["methods"]["point+apv"]["memory_bytes"].as_u64().unwrap(),
        r["methods"]["point"]["memory_bytes"].as_u64().unwrap() + nodes
    );
    assert_eq!(r["methods"]["point+ddgi"]["invalid_nodes"], 0, "DDGI relocates instead of invalidating");
}
