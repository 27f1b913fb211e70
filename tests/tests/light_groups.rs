//! `bake --light-groups` and `relight`, end to end: a bake split by light group keeps the
//! whole bake bit for bit, its groups sum to it, a relit volume is the scaled sum of its
//! groups through the lookup, and bad requests are one-line errors that write nothing.

use std::path::Path;

use lightvol_volume::IrradianceVolume;
use lightvol_volume::io::exr::read_exr;
use lightvol_volume::io::groups::read_grouped_exr;

mod common;
use common::{ok, run, s};

const SCENE: &str = "builtin:interior";

/// A photographed sunset sky (the repository's `data/env/sunset`, CC0).
const SUNSET_PHOTO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/env/sunset/sunset.exr");

fn bake(dir: &Path, name: &str, extra: &[&str]) -> std::path::PathBuf {
    let out = dir.join(name);
    let mut args = vec!["bake", SCENE, "--samples", "24", "--quiet", "-o", s(&out)];
    if !extra.contains(&"--seed") {
        args.extend(["--seed", "4"]);
    }
    args.extend_from_slice(extra);
    ok(&args);
    out
}

fn largest(v: &IrradianceVolume) -> f64 {
    v.data().iter().fold(0.0f64, |m, &x| m.max(f64::from(x.abs())))
}

#[test]
fn grouped_bake_keeps_the_whole_and_relights_linearly() {
    let dir = tempfile::tempdir().unwrap();
    let plain = read_exr(&bake(dir.path(), "plain.exr", &[])).unwrap();
    let grouped_path = bake(dir.path(), "grouped.exr", &["--light-groups", "each"]);
    let grouped = read_grouped_exr(&grouped_path).unwrap();
    assert_eq!(grouped.names(), ["sky", "sun"]);
    // The whole bake, as any reader of the file sees it, is the ungrouped bake bit for bit.
    assert_eq!(read_exr(&grouped_path).unwrap().data(), plain.data());
    assert_eq!(grouped.total().data(), plain.data());
    // One thread or two: the same bytes.
    let one = bake(dir.path(), "one.exr", &["--light-groups", "each", "--threads", "1"]);
    assert_eq!(std::fs::read(&one).unwrap(), std::fs::read(&grouped_path).unwrap());

    // Each group and the whole are rounded to f32 once from exact sums: the groups' sum is
    // within three half-ulps of the largest magnitude.
    let scale =
        (0..2).flat_map(|g| grouped.layer(g).iter()).fold(largest(&plain), |m, &x| m.max(f64::from(x.abs())));
    let bound = 3.0 * f64::from(f32::EPSILON) / 2.0 * scale / largest(&plain);
    assert!(grouped.sum_error() <= bound, "{} > {bound}", grouped.sum_error());
    for g in 0..2 {
        assert!(grouped.layer(g).iter().any(|&v| v > 0.0), "group {g} carries light");
    }

    let relit = |name: &str, args: &[&str]| {
        let out = dir.path().join(name);
        let mut a = vec!["relight", s(&grouped_path), "-o", s(&out)];
        a.extend_from_slice(args);
        ok(&a);
        read_exr(&out).unwrap()
    };
    let all = relit("all.exr", &[]);
    let sun3 = relit("sun3.exr", &["--scale", "sun=3"]);
    let sun = relit("sun.exr", &["--group", "sun"]);
    let warm = relit("warm.exr", &["--scale", "sky=0;sun=1,0.5,0.25"]);
    // Through the lookup: three times the sun adds twice the sun's irradiance, and a
    // coloured sun alone scales the sun's channels.
    let (lo, hi) = plain.spec().bounds();
    let mut lit = 0;
    for k in 0..200 {
        let f = [(k as f64 * 0.371) % 1.0, (k as f64 * 0.613) % 1.0, (k as f64 * 0.177) % 1.0];
        let p: [f32; 3] = std::array::from_fn(|a| (lo[a] + f[a] * (hi[a] - lo[a])) as f32);
        let n = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, -0.6, 0.8]][k % 3];
        let (e1, e3, es, ew) =
            (all.irradiance(p, n), sun3.irradiance(p, n), sun.irradiance(p, n), warm.irradiance(p, n));
        for c in 0..3 {
            let want = f64::from(e1[c]) + 2.0 * f64::from(es[c]);
            // f32 lookups of volumes rounded once each: 1e-5 of the magnitudes involved.
            let tol = 1e-5 * (f64::from(e1[c].abs()) + 3.0 * f64::from(es[c].abs())).max(1e-3);
            assert!((f64::from(e3[c]) - want).abs() <= tol, "point {k} ch {c}: {} vs {want}", e3[c]);
            let want = f64::from(es[c]) * [1.0, 0.5, 0.25][c];
            assert!((f64::from(ew[c]) - want).abs() <= 1e-5 * want.abs().max(1e-3), "point {k} ch {c}");
        }
        lit += usize::from(es[0] > 0.01 * e1[0]);
    }
    assert!(lit > 20, "the sun lights {lit} of 200 points");
}

/// `export` of a grouped volume: the whole bake at the output, each group beside it in the
/// same format, and a manifest naming them; the exported groups sum to the exported whole
/// within f16 rounding.
#[test]
fn grouped_exports_carry_every_group() {
    let dir = tempfile::tempdir().unwrap();
    let grouped = bake(dir.path(), "g.exr", &["--light-groups", "day=sky;light=sun"]);
    let out = dir.path().join("room.ktx2");
    ok(&["export", s(&grouped), "--format", "ktx2", "-o", s(&out)]);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("room.light_groups.json")).unwrap())
            .unwrap();
    assert_eq!(manifest["whole"], "room.ktx2");
    let open = |name: &str| match lightvol_volume::open(&dir.path().join(name)).unwrap() {
        lightvol_volume::AnyVolume::Uniform(v) => v,
        _ => panic!("{name} is a uniform volume"),
    };
    let whole = open("room.ktx2");
    let groups: Vec<IrradianceVolume> = manifest["groups"]
        .as_array()
        .unwrap()
        .iter()
        .zip(["day", "light"])
        .map(|(g, name)| {
            assert_eq!(g["name"], name);
            open(g["file"].as_str().unwrap())
        })
        .collect();
    assert_eq!(groups.len(), 2);
    assert_eq!(groups[0].weights(), whole.weights());
    let scale = groups.iter().chain([&whole]).map(largest).fold(0.0, f64::max);
    // Three values rounded to f16 (half an ulp is 2^-11 relative each).
    let tol = 3.0 * scale / 2048.0;
    for (i, &w) in whole.data().iter().enumerate() {
        let sum = f64::from(groups[0].data()[i]) + f64::from(groups[1].data()[i]);
        assert!((sum - f64::from(w)).abs() <= tol, "value {i}: {sum} vs {w}");
    }
    // The stacked texture the generated sampling code reads holds the same f16 groups (the
    // built-in scene is +Z up, so the file frame is lightvol's and no rotation intervenes).
    assert_eq!(manifest["stacked"], "room.groups.ktx2");
    let (sidecar, stacked, layers) =
        lightvol_volume::io::ktx2_groups::read_groups_ktx2(&dir.path().join("room.groups.ktx2")).unwrap();
    assert_eq!(stacked.names, ["day", "light"]);
    assert_eq!(sidecar.grid.res, whole.spec().res());
    for (g, layer) in layers.iter().enumerate() {
        assert_eq!(layer.as_slice(), groups[g].data(), "group {g}");
    }
    // Opened as a volume, it says what it is in one line.
    let e = run(&["info", s(&dir.path().join("room.groups.ktx2"))]).unwrap_err();
    assert!(e.contains("stacked light-group texture") && e.contains("day, light"), "{e}");
}

/// Shards of a bake with light groups and a sky transfer merge into the whole bake's file,
/// byte for byte, in any order.
#[test]
fn grouped_shards_merge_to_the_whole_bake() {
    let dir = tempfile::tempdir().unwrap();
    let split = ["--light-groups", "each", "--sky-transfer", "2", "--no-sun", "--sky", "0.5,0.6,0.8"];
    let whole = bake(dir.path(), "whole.exr", &split);
    let shards: Vec<std::path::PathBuf> = (0..3)
        .map(|k| {
            let shard = format!("{k}/3");
            let mut a = split.to_vec();
            a.extend(["--shard", Box::leak(shard.into_boxed_str())]);
            bake(dir.path(), &format!("s{k}.exr"), &a)
        })
        .collect();
    let merged = dir.path().join("merged.exr");
    ok(&["merge", s(&shards[2]), s(&shards[0]), s(&shards[1]), "-o", s(&merged)]);
    assert_eq!(std::fs::read(&merged).unwrap(), std::fs::read(&whole).unwrap());
    let g = read_grouped_exr(&merged).unwrap();
    assert_eq!(g.names(), ["sky.sh00", "sky.sh01", "sky.sh02", "sky.sh03"]);
    // The merged file records the baked sky (a step at the horizon, which order 2 holds
    // only to its band limit), so its as-baked error can be measured.
    assert!(g.baked_sky().is_some() && g.sum_error().is_finite());
}

#[test]
fn bad_light_group_requests_are_one_line_errors_that_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v.exr");
    for (args, says) in [
        (vec!["--light-groups", "day=moon"], "matches none of the scene's lights (sky, sun)"),
        (vec!["--light-groups", "a=sky;b=s*"], "is in groups"),
        (
            vec!["--light-groups", "each", "--method", "point+apv"],
            "cannot be combined with an engine baseline",
        ),
        (vec!["--light-groups", "each", "--gradients"], "cannot be combined with gradients"),
    ] {
        let mut a = vec!["bake", SCENE, "--samples", "4", "--quiet", "-o", s(&out)];
        a.extend_from_slice(&args);
        let e = run(&a).unwrap_err();
        assert!(e.contains(says), "{args:?}: {e}");
        assert!(!out.exists(), "{args:?} wrote a file");
    }
    let plain = bake(dir.path(), "plain.exr", &[]);
    let e = run(&["relight", s(&plain), "-o", s(&out)]).unwrap_err();
    assert!(e.contains("no light groups"), "{e}");
    let grouped = bake(dir.path(), "g.exr", &["--light-groups", "each"]);
    for (args, says) in [
        (vec!["--scale", "moon=2"], "the volume has sky, sun"),
        (vec!["--scale", "sun=x"], "not a finite number"),
        (vec!["--group", "moon"], "no light group"),
    ] {
        let mut a = vec!["relight", s(&grouped), "-o", s(&out)];
        a.extend_from_slice(&args);
        let e = run(&a).unwrap_err();
        assert!(e.contains(says), "{args:?}: {e}");
        assert!(!out.exists(), "{args:?} wrote a file");
    }
}

/// Relative RMS difference of two volumes' irradiance at every node with domain weight,
/// for the six axis normals.
fn node_difference(a: &IrradianceVolume, b: &IrradianceVolume) -> f64 {
    let spec = b.spec();
    let [nx, ny, nz] = spec.res();
    let (mut num, mut den) = (0.0, 0.0);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let node = spec.node_index(i, j, k);
                if b.weights()[node] == 0.0 {
                    continue;
                }
                let p = spec.node_position_world(i, j, k).map(|v| v as f32);
                for n in [
                    [1.0, 0.0, 0.0],
                    [-1.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                    [0.0, -1.0, 0.0],
                    [0.0, 0.0, 1.0],
                    [0.0, 0.0, -1.0],
                ] {
                    let (ea, eb) = (a.irradiance(p, n), b.irradiance(p, n));
                    for c in 0..3 {
                        num += (f64::from(ea[c]) - f64::from(eb[c])).powi(2);
                        den += f64::from(eb[c]).powi(2);
                    }
                }
            }
        }
    }
    (num / den).sqrt()
}

/// The repository's synthetic sunset sky (`data/env/gradient`): a warm band low in the
/// west fading to a deep blue zenith, a dark ground (+Z up, the internal frame the loader
/// reads maps in).
const SUNSET_GRADIENT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/env/gradient/gradient.exr");
/// The repository's CIE overcast sky (`data/env/overcast`).
const OVERCAST: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/env/overcast/overcast.exr");

/// Texel `(x, y)` of a 64 × 32 lat-long map of the formula its `SOURCE.txt` gives.
fn generated_sky(overcast: bool, x: usize, y: usize) -> [f32; 3] {
    let (w, h) = (64.0, 32.0);
    let theta = (y as f64 + 0.5) / h * std::f64::consts::PI;
    let phi = (x as f64 + 0.5) / w * 2.0 * std::f64::consts::PI;
    let z = theta.cos();
    let rgb = match (overcast, z < 0.0) {
        (true, true) => [0.1; 3],
        (true, false) => [(1.0 + 2.0 * z) / 3.0; 3],
        (false, true) => [0.08, 0.07, 0.06],
        (false, false) => {
            let warm = (0.5 + 0.5 * phi.cos()).powi(3) * (1.0 - z).powi(4);
            [0.15 + 2.5 * warm, 0.2 + 1.0 * warm, 0.6 * z + 0.2]
        }
    };
    rgb.map(|c| c as f32)
}

/// The generated skies the relighting is measured under are their formulas, texel for
/// texel (so that a user can remake them).
#[test]
fn generated_skies_are_their_formulas() {
    use exr::prelude::*;
    for (path, overcast) in [(SUNSET_GRADIENT, false), (OVERCAST, true)] {
        let img = read_first_rgba_layer_from_file(
            path,
            |r, _| (r.width(), vec![[0f32; 3]; r.width() * r.height()]),
            |(w, px): &mut (usize, Vec<[f32; 3]>), p, (r, g, b, _): (f32, f32, f32, f32)| {
                px[p.y() * *w + p.x()] = [r, g, b];
            },
        )
        .unwrap();
        let size = img.layer_data.size;
        assert_eq!((size.width(), size.height()), (64, 32), "{path}");
        let (w, px) = &img.layer_data.channel_data.pixels;
        for (k, texel) in px.iter().enumerate() {
            assert_eq!(*texel, generated_sky(overcast, k % w, k / w), "{path} texel {k}");
        }
    }
}

/// A sky transfer relit with a new sky against fresh bakes of that sky, sun off: two
/// uniform skies (sky and ground), whose relit volume traces the same paths as the fresh
/// bake of the same seed, and a sunset map, which the fresh bake samples by importance.
#[test]
fn sky_transfer_relights_to_fresh_bakes_of_new_skies() {
    let dir = tempfile::tempdir().unwrap();
    let transfer = bake(dir.path(), "t.exr", &["--sky-transfer", "3", "--no-sun", "--seed", "1"]);
    for (name, sky) in [
        ("even", vec!["--sky", "0.6,0.7,0.9", "--ground", "0.6,0.7,0.9"]),
        ("sunset-uniform", vec!["--sky", "1,0.5,0.2", "--ground", "0.1,0.1,0.1"]),
        ("overcast", vec!["--sky", "0.7,0.7,0.75", "--ground", "0.3,0.3,0.3"]),
        ("sunset-map", vec!["--env", SUNSET_GRADIENT]),
        ("sunset-photo", vec!["--env", SUNSET_PHOTO]),
    ] {
        let relit = dir.path().join(format!("{name}.exr"));
        let mut a = vec!["relight", s(&transfer), "-o", s(&relit)];
        match sky[0] {
            "--sky" => {
                let joined = format!("{}:{}", sky[1], sky[3]);
                a.extend(["--sky", Box::leak(joined.into_boxed_str())]);
            }
            _ => a.extend(["--env", sky[1]]),
        }
        ok(&a);
        let fresh: Vec<IrradianceVolume> = ["1", "2"]
            .iter()
            .map(|seed| {
                let out = dir.path().join(format!("{name}-{seed}.exr"));
                let mut a = vec![
                    "bake",
                    SCENE,
                    "--samples",
                    "24",
                    "--no-sun",
                    "--quiet",
                    "-o",
                    s(&out),
                    "--seed",
                    seed,
                ];
                a.extend(sky.iter().copied());
                ok(&a);
                read_exr(&out).unwrap()
            })
            .collect();
        let relit = read_exr(&relit).unwrap();
        let (same_seed, other_seed, noise) = (
            node_difference(&relit, &fresh[0]),
            node_difference(&relit, &fresh[1]),
            node_difference(&fresh[1], &fresh[0]),
        );
        eprintln!(
            "{name}: relit vs seed 1 {same_seed:.4}, vs seed 2 {other_seed:.4}, two-seed noise {noise:.4}"
        );
        if name == "even" {
            // A sky equal to its ground is Y_0 alone: the relit volume is the fresh bake of
            // the same seed up to f32 rounding (the same paths, the same terms).
            assert!(same_seed < 1e-5, "{name}: {same_seed}");
        } else {
            // Otherwise the relit volume carries the sky's band-limit error (a step at the
            // horizon, or the map's sunset, seen through the window), and is still closer to
            // the fresh bake on the same paths than another seed's bake is.
            assert!(same_seed < noise, "{name}: {same_seed} vs noise {noise}");
        }
        assert!(other_seed < 1.5 * noise, "{name}: {other_seed} vs noise {noise}");
    }
}

/// Lighting scenarios: each scenario of the file is the bake under its lights alone, bit for
/// bit; the whole is the first; a blend is the weighted sum; bad requests are one line.
#[test]
fn scenarios_are_their_bakes_and_blend() {
    let dir = tempfile::tempdir().unwrap();
    let noon = "sun:0.3,0.2,1:6";
    let dusk = "sun:1,0.1,0.08:2;sky:0.3,0.25,0.4:0.05,0.05,0.05";
    let file = bake(
        dir.path(),
        "sc.exr",
        &["--scenario", &format!("noon={noon}") as &str, "--scenario", &format!("dusk={dusk}") as &str],
    );
    let g = read_grouped_exr(&file).unwrap();
    assert_eq!(g.names(), ["scenario.noon", "scenario.dusk"]);
    let fresh_noon = read_exr(&bake(dir.path(), "noon.exr", &["--sun", "0.3,0.2,1:6"])).unwrap();
    let fresh_dusk = read_exr(&bake(
        dir.path(),
        "dusk.exr",
        &["--sun", "1,0.1,0.08:2", "--sky", "0.3,0.25,0.4", "--ground", "0.05,0.05,0.05"],
    ))
    .unwrap();
    assert_eq!(g.layer(0), fresh_noon.data());
    assert_eq!(g.layer(1), fresh_dusk.data());
    assert_eq!(read_exr(&file).unwrap().data(), fresh_noon.data());
    let blend = dir.path().join("blend.exr");
    ok(&["relight", s(&file), "--blend", "noon=0.25;dusk=0.75", "-o", s(&blend)]);
    let b = read_exr(&blend).unwrap();
    for (i, &v) in b.data().iter().enumerate() {
        let want = 0.25 * f64::from(fresh_noon.data()[i]) + 0.75 * f64::from(fresh_dusk.data()[i]);
        // One f32 rounding of the f64 blend.
        assert!((f64::from(v) - want).abs() <= want.abs() * f64::from(f32::EPSILON), "{i}");
    }
    let out = dir.path().join("x.exr");
    for (args, says) in [
        (vec!["--scenario", "a=sun:1,0,0:1"], "at least two"),
        (vec!["--scenario", "a=moon", "--scenario", "b=no-sun"], "'moon' is not"),
        (vec!["--scenario", "a=no-sun", "--scenario", "a=no-sun"], "given twice"),
        (
            vec!["--scenario", "a=no-sun", "--scenario", "b=no-sun", "--shard", "0/2", "--fit", "lsq"],
            "--scenario cannot be combined with shards or a kept accumulator with a fit other than the average",
        ),
    ] {
        let mut a = vec!["bake", SCENE, "--samples", "4", "--quiet", "-o", s(&out)];
        a.extend_from_slice(&args);
        let e = run(&a).unwrap_err();
        assert!(e.contains(says), "{args:?}: {e}");
        assert!(!out.exists(), "{args:?} wrote a file");
    }
    let e = run(&["relight", s(&file), "--blend", "noon=1;moon=0", "-o", s(&out)]).unwrap_err();
    assert!(e.contains("the volume has noon, dusk"), "{e}");

    // Shards of the scenario bake merge, in any order, into the whole file byte for byte.
    let shards: Vec<std::path::PathBuf> = (0..3)
        .map(|k| {
            let shard = format!("{k}/3");
            bake(
                dir.path(),
                &format!("sc{k}.exr"),
                &[
                    "--scenario",
                    &format!("noon={noon}") as &str,
                    "--scenario",
                    &format!("dusk={dusk}") as &str,
                    "--shard",
                    &shard as &str,
                ],
            )
        })
        .collect();
    let merged = dir.path().join("sc-merged.exr");
    ok(&["merge", s(&shards[1]), s(&shards[2]), s(&shards[0]), "-o", s(&merged)]);
    assert_eq!(std::fs::read(&merged).unwrap(), std::fs::read(&file).unwrap());
}

/// `compare BASE+relit`: baked under `--relight-from` and relit to the comparison's sky.
/// Relit from the very sky the comparison uses (a sky equal to its ground, which order 3
/// holds exactly) it measures what the fresh bake measures; relit from another sky it is
/// measured against the same reference, and without `--relight-from` it is refused.
#[test]
fn compare_measures_relit_volumes_against_fresh_bakes() {
    let report = |from: &str| -> serde_json::Value {
        let dir = tempfile::tempdir().unwrap();
        ok(&[
            "compare",
            "builtin:city",
            "--samples",
            "16",
            "--plate-res",
            "24",
            "--reference-samples",
            "64",
            "--methods",
            "doi,doi+relit,doi+skyocc",
            "--sky",
            "0.6,0.7,0.9",
            "--ground",
            "0.6,0.7,0.9",
            "--relight-from",
            from,
            "--quiet",
            "-o",
            s(dir.path()),
        ]);
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap()).unwrap()
    };
    let rmse = |r: &serde_json::Value, m: &str| r["methods"][m]["rel_rmse"].as_f64().unwrap();
    let same = report("sky:0.6,0.7,0.9:0.6,0.7,0.9");
    // The same paths and terms, rounded to f32 in another order.
    assert!((rmse(&same, "doi+relit") - rmse(&same, "doi")).abs() < 1e-5, "{same}");
    // APV's sky occlusion relit from the same sky is not the fresh bake: one grey albedo
    // and L1 stand in for the bounced light.
    let occ = rmse(&same, "doi+skyocc");
    assert!(occ.is_finite() && (occ - rmse(&same, "doi")).abs() > 1e-4, "{same}");
    // Each relit entry is also measured against the fresh bake of the comparison's sky.
    let vs_fresh = |r: &serde_json::Value, m: &str| {
        assert_eq!(r["methods"][m]["vs_fresh"]["method"], "doi", "{m}");
        r["methods"][m]["vs_fresh"]["rel_rmse"].as_f64().unwrap()
    };
    assert!(vs_fresh(&same, "doi+relit") < 1e-5, "{same}");
    assert!(vs_fresh(&same, "doi+skyocc") > 1e-3, "{same}");
    assert!(same["methods"]["doi"].get("vs_fresh").is_none());
    // Beside it, the sky's band-limit error at the transfer's order: none for a uniform sky.
    assert_eq!(same["methods"]["doi+relit"]["sky_order"], 3, "{same}");
    assert!(same["methods"]["doi+relit"]["sky_band_limit"].as_f64().unwrap() < 1e-4, "{same}");
    let other = report("sky:0.2,0.2,0.3");
    assert!(rmse(&other, "doi+relit").is_finite() && rmse(&other, "doi+relit") > 0.0);
    let dir = tempfile::tempdir().unwrap();
    let e = run(&[
        "compare",
        "builtin:city",
        "--samples",
        "4",
        "--methods",
        "doi+relit",
        "--quiet",
        "-o",
        s(dir.path()),
    ])
    .unwrap_err();
    assert!(e.contains("--relight-from"), "{e}");
}
