//! Issue 10 acceptance 2 (seed 003 §3.2, Fig. 3.5): on a normal-mapped plane under a grazing
//! sun and sky, the 6-coefficient H-basis is within 1.5× the relative RMSE of 9-coefficient
//! SH against the path-traced reference, and Half-Life 2 (3 coefficients) is worse than
//! both.

mod surface_util;

use std::process::ExitCode;

use surface_util::{plane, run, write_gltf};

/// Sun 5.7° above the horizon (irradiance 5 on a facing surface) and a blue sky, +Z up.
const SUN: &str = "1,0.2,0.1:5";
const SKY: &str = "0.25,0.35,0.6";
// Measured (seeds 1-3): sh9 0.0670-0.0672, hbasis6 0.0770-0.0772 (ratio 1.15), hl2 0.273;
// the reference's Monte Carlo noise is below 1e-4 of these (128 vs 8192 samples per pixel
// agree to 4 digits), so the assertions test the bases, not the noise.

/// The thesis's bound: 6 H-basis coefficients come within this factor of 9 SH coefficients.
const HBASIS6_OVER_SH9: f64 = 1.5;

#[test]
fn hbasis6_is_close_to_sh9_and_hl2_is_worst_on_a_bumpy_plane() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_gltf(dir.path(), "plane.gltf", &[plane("floor")]);
    let (maps, shots) = (dir.path().join("maps"), dir.path().join("render"));
    let s = scene.to_str().unwrap();
    let bake = [
        "bake-surface",
        s,
        "--basis",
        "sh9,hbasis6,hl2",
        "--texels-per-unit",
        "4",
        "--samples",
        "512",
        "--sky",
        SKY,
        "--sun",
        SUN,
        "-o",
        maps.to_str().unwrap(),
        "--quiet",
    ];
    assert_eq!(run(&bake), Ok(ExitCode::SUCCESS));
    let render = [
        "render",
        s,
        "--sky",
        SKY,
        "--sun",
        SUN,
        "--surface",
        maps.to_str().unwrap(),
        "--normal-map",
        "procedural:3:1.5",
        "--camera",
        "0,0,1:0,0,0:40",
        "--width",
        "40",
        "--height",
        "30",
        "--reference-samples",
        "128",
        "-o",
        shots.to_str().unwrap(),
    ];
    assert_eq!(run(&render), Ok(ExitCode::SUCCESS));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(shots.join("report.json")).unwrap()).unwrap();
    println!("{report:#}");
    let err = |b: &str| report["bases"][b]["rel_rmse"].as_f64().unwrap();
    let (sh9, h6, hl2) = (err("sh9"), err("hbasis6"), err("hl2"));
    assert!(h6 <= HBASIS6_OVER_SH9 * sh9, "hbasis6 {h6} vs sh9 {sh9}");
    assert!(hl2 > sh9 && hl2 > h6, "hl2 {hl2} vs sh9 {sh9}, hbasis6 {h6}");
    assert_eq!(report["bases"]["hbasis6"]["bytes_per_texel"], 18);
    assert_eq!(report["bases"]["sh9"]["bytes_per_texel"], 27);
    assert_eq!(report["invalid_texels"], 0);
    assert_eq!(report["pixels"], 40 * 30, "the plane fills the view");
    for f in ["reference.png", "sh9.png", "hbasis6.png", "hl2.png", "sheet.png"] {
        assert!(shots.join(f).is_file(), "{f}");
    }
}
