//! [Ish11] §3.2, Fig. 3.5: on a normal-mapped plane under a grazing sun and sky, the
//! 6-coefficient H-basis is within 1.5× the relative RMSE of 9-coefficient SH against the
//! path-traced reference, and Half-Life 2 (3 coefficients) is worse than both.

mod surface_util;

use std::process::ExitCode;

use surface_util::{plane, run, write_gltf};

/// Sun 5.7° above the horizon (irradiance 5 on a facing surface) and a blue sky, +Z up.
/// The sun, in the glTF scenes' +Y-up frame (internal +Z-up (1, 0.2, 0.1)).
const SUN: &str = "1,0.1,-0.2:5";
const SKY: &str = "0.25,0.35,0.6";
// Measured (seed 1, 4096 bake and 8192 reference samples): sh9 0.0806, hbasis6 0.0927
// (ratio 1.15), hl2 0.329;
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
        "0,1,0:0,0,0:40",
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

/// Bakes `hbasis_mod6` maps of the plane under `light` and renders them with flat normals
/// (every pixel shades the geometric normal, tangent-space `(0, 0, 1)`); returns the report.
fn flat_render(light: &[&str], samples: &str, reference_samples: &str) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_gltf(dir.path(), "plane.gltf", &[plane("floor")]);
    let (maps, shots) = (dir.path().join("maps"), dir.path().join("render"));
    let (s, m) = (scene.to_str().unwrap(), maps.to_str().unwrap());
    let mut bake = vec!["bake-surface", s, "--basis", "hbasis_mod6", "--texels-per-unit", "4"];
    bake.extend_from_slice(&["--samples", samples, "-o", m, "--quiet"]);
    bake.extend_from_slice(light);
    assert_eq!(run(&bake), Ok(ExitCode::SUCCESS));
    let mut render = vec!["render", s, "--surface", m, "--normal-map", "flat", "--camera", "0,1,0:0,0,0:40"];
    render.extend_from_slice(&["--width", "16", "--height", "12", "--reference-samples", reference_samples]);
    render.extend_from_slice(&["-o", shots.to_str().unwrap()]);
    render.extend_from_slice(light);
    assert_eq!(run(&render), Ok(ExitCode::SUCCESS));
    for f in ["lightmap.png", "lightmap4.png", "hbasis_mod6.png"] {
        assert!(shots.join(f).is_file(), "{f}");
    }
    serde_json::from_str(&std::fs::read_to_string(shots.join("report.json")).unwrap()).unwrap()
}

/// f32 maps and f32 image values: the LOD sums at the pole agree to a few f32 ulps.
const LOD_AGREEMENT_TOL: f64 = 1e-6;
/// Sun only, a point sun (angular radius 0) overhead: next-event estimation sees it with
/// weight 1 in the bake and in the reference and no other light exists, so both are
/// deterministic (Monte Carlo error 0); what remains is f32 rounding of the maps (~1e-7
/// relative; measured 0.015625033 against 1/64 = 0.015625).
const SUN_ONLY_TOL: f64 = 1e-5;
/// Sky only: the E_20 offset and the SH truncation vanish (see the test), so the LOD value
/// differs from the reference by Monte Carlo noise alone (256 bake samples per texel, 64
/// reference samples per pixel). Measured rel RMSE 0.0033 (seed 1); the bound leaves 6×, and
/// is still below the sun case's 1/64 offset.
const SKY_ONLY_MC_TOL: f64 = 0.012;

/// [Ish11] Listing 2.2: the levels of detail of the modified H-basis at the
/// geometric normal. `H2 … H6` vanish at `n = (0, 0, 1)`, so `lightmap` (1 coefficient),
/// `lightmap4` (4) and `hbasis_mod6` (6) shade identically there; the value is the 3-band SH
/// irradiance at the normal less `sqrt(5)/(8 sqrt(π)) E_20` (`lightvol_hemibasis::lod`), and
/// the reference is the true irradiance `reference_surface_irradiance` at `(0, 0, 1)`.
///
/// - Point sun of irradiance `s` overhead: the true irradiance is `s`; 3-band SH gives
///   `s Σ_{l≤2} A_l (2l+1)/(4π) = 17 s / 16` (truncation `+s/16`); `E_20 = A_2 s y_20(pole)`
///   and the offset `sqrt(5)/(8 sqrt(π)) E_20 = 5 s / 64`: the maps read `s (1 - 1/64)`, a
///   relative error of exactly 1/64 at every pixel (computed below from lightvol-sh's
///   `A_l`, not typed in).
/// - Uniform sky `L` over the hemisphere: `E_20 ∝ ∫_0^1 (3z² - 1) dz = 0`, and every even
///   band `l ≥ 2` of the hemisphere's indicator integrates to 0 (odd `l ≥ 3` have `A_l = 0`),
///   so the maps read `π L` = the reference, up to Monte Carlo error.
#[test]
fn lod_levels_at_the_geometric_normal_match_the_reference_up_to_the_e20_offset() {
    use lightvol_sh::irradiance::cosine_lobe_factor;
    use std::f64::consts::PI;
    let s = 5.0;
    let y20_pole = (5.0 / (4.0 * PI)).sqrt();
    let e_sh3: f64 = (0..3).map(|l| s * cosine_lobe_factor(l) * f64::from(2 * l + 1) / (4.0 * PI)).sum();
    let offset = 5f64.sqrt() / (8.0 * PI.sqrt()) * cosine_lobe_factor(2) * s * y20_pole;
    let expected = ((e_sh3 - offset) - s).abs() / s;
    assert!((expected - 1.0 / 64.0).abs() < 1e-15, "closed form {expected}");

    let sun = flat_render(&["--sun", "0,1,0:5:0"], "16", "4");
    let err = |r: &serde_json::Value, b: &str| r["bases"][b]["rel_rmse"].as_f64().unwrap();
    for b in ["lightmap", "lightmap4", "hbasis_mod6"] {
        let e = err(&sun, b);
        assert!((e - expected).abs() < SUN_ONLY_TOL, "sun only, {b}: {e} vs {expected}");
    }
    assert_eq!(sun["bases"]["lightmap4"]["coefficients"], 4);
    assert_eq!(sun["bases"]["lightmap4"]["bytes_per_texel"], 12);

    let sky = flat_render(&["--sky", SKY], "256", "64");
    let full = err(&sky, "hbasis_mod6");
    println!("sky only: rel RMSE {full}");
    assert!(full < SKY_ONLY_MC_TOL, "sky only: {full}");
    for b in ["lightmap", "lightmap4"] {
        let e = err(&sky, b);
        assert!((e - full).abs() <= LOD_AGREEMENT_TOL * full, "sky only, {b}: {e} vs {full}");
    }
}
