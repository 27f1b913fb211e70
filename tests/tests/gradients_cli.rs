//! SH gradients through the CLI: `bake --gradients` writes [Oat05]'s SH irradiance
//! gradients into the native EXR, `info` reports them with [Oat05]'s memory accounting, the
//! Taylor lookup reads them back consistently, and `compare` reports the gradient lookups
//! with their memory. Bad options are refused with one line and no output file.

use lightvol_volume::gradient::{GradientLookup, coeffs_at};
use lightvol_volume::io::exr::{read_exr, read_exr_with_gradients};
use serde_json::Value;

mod common;
use common::{ok, run, s};

/// f32 storage of the gradients and coefficients: a Taylor value `c + g·d` recomputed in f64
/// from the file's f32 numbers agrees with the library's to f64 rounding of a few terms.
const F64_SUM_TOLERANCE: f64 = 1e-12;

/// Smallest accepted correlation between the basis gradients and the node differences: the
/// measured 0.85 less a margin for changes of the bake's sample streams (the estimator is
/// noisy at 32 samples per cell; 0.7 still means the gradients follow the field).
const MIN_CORRELATION: f64 = 0.7;

const COMMON: [&str; 8] = ["--samples", "32", "--res", "10,10,5", "--seed", "3", "--quiet", "--threads"];

/// bake --gradients (basis and central) → read back → the volume is the plain bake's, the
/// gradients are present and finite, the Taylor lookup is exact at the nodes and equals
/// `c + ∇c · d` from the nearest node elsewhere, and the basis estimator agrees with the
/// volume's own node-to-node central differences in the open air above the city.
#[test]
fn bake_gradients_round_trip_and_taylor_lookup() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (plain, basis, central) = (d.join("plain.exr"), d.join("basis.exr"), d.join("central.exr"));
    let mut a = vec!["bake", "builtin:city", "--method", "doi-paper", "-o", s(&plain)];
    a.extend_from_slice(&COMMON);
    a.push("2");
    ok(&a);
    let mut a = vec!["bake", "builtin:city", "--method", "doi-paper", "--gradients", "-o", s(&basis)];
    a.extend_from_slice(&COMMON);
    a.push("2");
    ok(&a);
    let mut a =
        vec!["bake", "builtin:city", "--method", "doi-paper", "--gradients", "central", "-o", s(&central)];
    a.extend_from_slice(&COMMON);
    a.push("1");
    ok(&a);

    let plain_vol = read_exr(&plain).unwrap();
    assert!(read_exr_with_gradients(&plain).unwrap().1.is_none(), "a plain bake has no gradients");
    let (vol, grad) = read_exr_with_gradients(&basis).unwrap();
    let grad = grad.expect("bake --gradients stores gradients");
    // Computing gradients does not change the bake.
    assert_eq!(vol.data(), plain_vol.data());
    assert_eq!(grad.nodes(), vol.spec().node_count());
    assert_eq!(grad.data().len(), vol.spec().node_count() * 9 * 9);
    assert!(grad.data().iter().any(|&g| g != 0.0));
    let (cvol, cgrad) = read_exr_with_gradients(&central).unwrap();
    assert_eq!(cvol.data(), plain_vol.data(), "central differences add projections, not bake samples");
    let cgrad = cgrad.expect("central gradients stored");
    assert_eq!(cgrad.data().len(), grad.data().len());
    assert!(cgrad.data().iter().any(|&g| g != 0.0));
    assert_ne!(cgrad.data(), grad.data(), "two different estimators");

    let spec = vol.spec();
    let cell = spec.cell_size();
    for node in [0, 57, 123, spec.node_count() - 1] {
        let [i, j, k] = spec.node_coords(node);
        let x = spec.node_position_world(i, j, k);
        // At a node the Taylor lookup returns the node's coefficients (the world -> grid ->
        // world round trip of the position leaves d ~ 1e-15, hence the f64 tolerance).
        let at = coeffs_at(&vol, &grad, GradientLookup::Taylor, x).unwrap();
        for (a, b) in at.iter().zip(vol.node(node)) {
            let b = f64::from(*b);
            assert!((a - b).abs() <= F64_SUM_TOLERANCE * b.abs().max(1.0), "{a} vs {b}");
        }
        // A point a third of a cell away (clamped into the box) is nearest to this node.
        let p: [f64; 3] = std::array::from_fn(|a| {
            let (lo, hi) = (spec.bounds().0[a], spec.bounds().1[a]);
            (x[a] + cell[a] / 3.0).clamp(lo, hi)
        });
        let at = coeffs_at(&vol, &grad, GradientLookup::Taylor, p).unwrap();
        for m in 0..27 {
            let g = grad.gradient(node, m / 3, m % 3);
            let want = f64::from(vol.node(node)[m]) + (0..3).map(|a| g[a] * (p[a] - x[a])).sum::<f64>();
            assert!(
                (at[m] - want).abs() <= F64_SUM_TOLERANCE * want.abs().max(1.0),
                "{m}: {} vs {want}",
                at[m]
            );
        }
    }

    // The basis estimator is a support-weighted mean gradient, so it follows the cell-scale
    // change of the field: the central difference of neighbouring node values. Pooled over
    // every interior node and the three axes (DC coefficient, red), the two correlate.
    // Measured at these settings: 0.85 (per layer and axis 0.55-0.97; the horizontal
    // gradients in open air are small and noisy). [Oat05]'s central differences at h = cell/16
    // measure the *local* derivative instead, which near shadow edges and walls is an order
    // of magnitude larger than the cell-scale change; they are not compared here.
    let [nx, ny, nz] = spec.res();
    let (mut sb, mut sf, mut sbf) = (0.0, 0.0, 0.0);
    for k in 1..nz - 1 {
        for j in 1..ny - 1 {
            for i in 1..nx - 1 {
                let node = spec.node_index(i, j, k);
                for a in 0..3 {
                    let (mut lo, mut hi) = ([i, j, k], [i, j, k]);
                    lo[a] -= 1;
                    hi[a] += 1;
                    let (lo, hi) =
                        (spec.node_index(lo[0], lo[1], lo[2]), spec.node_index(hi[0], hi[1], hi[2]));
                    let fd = f64::from(vol.node(hi)[0] - vol.node(lo)[0]) / (2.0 * cell[a]);
                    let g = grad.gradient(node, 0, 0)[a];
                    sb += g * g;
                    sf += fd * fd;
                    sbf += g * fd;
                }
            }
        }
    }
    let corr = sbf / (sb * sf).sqrt();
    println!("basis gradient vs node differences: correlation {corr:.3}");
    assert!(corr > MIN_CORRELATION, "basis gradient vs node differences: correlation {corr}");

    // info reports the gradients and [Oat05]'s floats per sample (order 3: 27 SH floats,
    // 108 with gradients; order 6: 108 and 432), and the run-time bytes they imply.
    ok(&["info", s(&basis)]);
    let info = lightvol_volume::info::describe_file(&basis).unwrap();
    assert_eq!(info["gradients"], Value::Bool(true));
    assert_eq!(info["memory"]["floats_per_node"].as_u64(), Some(108));
    assert_eq!(info["memory"]["runtime_bytes"].as_u64(), Some(10 * 10 * 5 * 108 * 4));
    let table = info["memory"]["floats_per_sample_by_order"].as_array().unwrap();
    let row = |order: u64| table.iter().find(|r| r["order"].as_u64() == Some(order)).unwrap();
    assert_eq!((row(3)["floats"].as_u64(), row(3)["floats_with_gradients"].as_u64()), (Some(27), Some(108)));
    assert_eq!((row(6)["floats"].as_u64(), row(6)["floats_with_gradients"].as_u64()), (Some(108), Some(432)));
    let info = lightvol_volume::info::describe_file(&plain).unwrap();
    assert_eq!(info["gradients"], Value::Bool(false));
    assert_eq!(info["memory"]["runtime_bytes"].as_u64(), Some(10 * 10 * 5 * 27 * 4));
}

/// `compare` with gradient lookups: one bake serves every lookup (same rays), each entry
/// reports its run-time memory in [Oat05]'s accounting (27 floats per node, 108 with
/// gradients), and the memory sweep writes its numbers and plot.
#[test]
fn compare_reports_gradient_lookups_with_memory() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cmp");
    ok(&[
        "compare",
        "builtin:city",
        "--samples",
        "32",
        "--plate-res",
        "32",
        "--reference-samples",
        "64",
        "--methods",
        "doi-paper,doi-paper+taylor,doi-paper+gtrilinear,doi-paper+hermite",
        "--memory-sweep",
        "--sweep-scales",
        "0.5,1",
        "--quiet",
        "-o",
        s(&out),
    ]);
    let r: Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let m = &r["methods"];
    let nodes = 16 * 16 * 7;
    assert_eq!(m["doi-paper"]["memory_bytes"].as_u64(), Some(nodes * 27 * 4));
    for name in ["doi-paper+taylor", "doi-paper+gtrilinear", "doi-paper+hermite"] {
        assert_eq!(m[name]["memory_bytes"].as_u64(), Some(nodes * 108 * 4), "{name}");
        assert_eq!(
            m[name]["rays"]["total"], m["doi-paper"]["rays"]["total"],
            "{name} reuses the doi-paper bake"
        );
        assert_eq!(m[name]["gradient_estimator"], "basis");
        let e = m[name]["rel_rmse"].as_f64().unwrap();
        println!("{name}: rel_rmse {e:.4} (doi-paper {:.4})", m["doi-paper"]["rel_rmse"].as_f64().unwrap());
        assert!(e.is_finite() && e > 0.0);
        assert!(out.join(format!("panel_{name}.png")).is_file());
    }
    let sweep: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("memory_sweep.json")).unwrap()).unwrap();
    let pts = sweep["points"].as_array().unwrap();
    // 2 scales x (uniform + 3 lookups + uniform doi + adaptive + adaptive1 + the adaptive
    // octree's bricks).
    assert_eq!(pts.len(), 16);
    let at = |series: &str, res0: u64| {
        pts.iter().find(|p| p["series"] == series && p["res"][0].as_u64() == Some(res0)).unwrap()
    };
    // Scale 1 is the compare grid itself: the same numbers as the doi entry.
    assert_eq!(at("uniform", 16)["rel_rmse"], m["doi-paper"]["rel_rmse"]);
    assert_eq!(at("uniform+hermite", 16)["rel_rmse"], m["doi-paper+hermite"]["rel_rmse"]);
    // Scale 0.5: 15 -> 8 cells, 6 -> 3 cells: 9 x 9 x 4 nodes.
    assert_eq!(at("uniform", 9)["memory_bytes"].as_u64(), Some(9 * 9 * 4 * 27 * 4));
    // The octrees at each scale stay within that uniform grid's bytes (series sorted by
    // memory, so the k-th point of each series is the k-th scale).
    let series = |name: &str| -> Vec<u64> {
        pts.iter().filter(|p| p["series"] == name).map(|p| p["memory_bytes"].as_u64().unwrap()).collect()
    };
    for octree in ["adaptive", "adaptive1"] {
        for (a, u) in series(octree).iter().zip(series("uniform")) {
            assert!(*a <= u, "{octree}: {a} bytes vs uniform {u}");
        }
    }
    // A finer uniform grid has a lower error on this plate.
    assert!(at("uniform", 16)["rel_rmse"].as_f64() < at("uniform", 9)["rel_rmse"].as_f64());
    for f in ["memory_sweep.svg", "memory_sweep.png"] {
        assert!(out.join(f).metadata().unwrap().len() > 100, "{f}");
    }
}

/// Bad gradient options: one line, an error, no output file.
#[test]
fn bad_gradient_options_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v.exr");
    let o = s(&out);
    let small = ["--samples", "4", "--res", "3,3,3", "--quiet"];
    let cases: [(&[&str], &str); 4] = [
        (&["--gradients", "basis", "--method", "point"], "--gradients basis needs cell samples"),
        (
            &["--method", "doi-paper", "--gradients", "central", "--fit", "lsq"],
            "cannot be combined with --gradients",
        ),
        (&["--gradients", "central", "--adaptive"], "--adaptive cannot be combined with --gradients"),
        (&["--gradients", "sideways"], "sideways"),
    ];
    for (extra, want) in cases {
        let mut a = vec!["bake", "builtin:maze", "-o", o];
        a.extend_from_slice(&small);
        a.extend_from_slice(extra);
        let err = run(&a).expect_err(&a.join(" "));
        assert!(err.contains(want), "{err}");
        assert!(!err.contains('\n'), "{err}");
        assert!(!out.exists(), "no output after: {err}");
        assert!(!dir.path().join("v.lvacc").exists());
    }
    let cmp = dir.path().join("cmp");
    let c = s(&cmp);
    for (extra, want) in [
        (["--methods", "doi+cubic"], "unknown gradient lookup 'cubic'"),
        (["--methods", "sideways+taylor"], "unknown method 'sideways'"),
    ] {
        let mut a = vec!["compare", "builtin:maze", "--samples", "4", "--quiet", "-o", c];
        a.extend_from_slice(&extra);
        let err = run(&a).expect_err(want);
        assert!(err.contains(want), "{err}");
        assert!(!cmp.join("report.json").exists());
    }
    let err = run(&["compare", "builtin:maze", "--memory-sweep", "--sweep-scales", "0", "--quiet", "-o", c])
        .expect_err("scale 0");
    assert!(err.contains("--sweep-scales"), "{err}");
    assert!(!cmp.join("memory_sweep.json").exists());
}
