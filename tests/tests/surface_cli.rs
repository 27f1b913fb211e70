//! `lightvol bake-surface` and `lightvol render --surface` end to end (issue 10).

mod surface_util;

use std::process::ExitCode;

use surface_util::{Mesh, plane, run, write_gltf};

/// The grazing light of seed 003 §3.2 in lightvol's +Z-up frame: a sun 5.7° above the
/// horizon (irradiance 5 on a facing surface) and a blue sky.
const SUN: &str = "1,0.2,0.1:5";
const SKY: &str = "0.25,0.35,0.6";

#[test]
fn bake_writes_maps_encodings_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_gltf(dir.path(), "plane.gltf", &[plane("floor")]);
    let out = dir.path().join("maps");
    let (s, o) = (scene.to_str().unwrap(), out.to_str().unwrap());
    let args = [
        "bake-surface",
        s,
        "--basis",
        "hbasis_mod6,sh9",
        "--texels-per-unit",
        "4",
        "--samples",
        "64",
        "--sky",
        SKY,
        "--sun",
        SUN,
        "--compress",
        "bc7,bc1",
        "-o",
        o,
        "--quiet",
    ];
    assert_eq!(run(&args), Ok(ExitCode::SUCCESS));
    for tag in ["hbasis_mod6", "sh9"] {
        assert!(out.join(format!("{tag}.exr")).is_file());
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(format!("{tag}.json"))).unwrap()).unwrap();
        assert_eq!(v["basis"], tag);
        assert_eq!(v["objects"][0]["name"], "floor");
        assert_eq!(v["invalid_texels"], 0, "an open plane has no invalid texels");
        let k = v["coefficients"].as_u64().unwrap() as usize;
        // One BC1 and one BC7 KTX2 per coefficient, each readable.
        for j in 0..k {
            for f in ["bc1", "bc7"] {
                let p = out.join(tag).join(format!("floor_c{j:02}.{f}.ktx2"));
                let t = lightvol_hemibasis::texture::read_ktx2_plane(&std::fs::read(&p).unwrap()).unwrap();
                assert_eq!(t.srgb, j == 0, "only the DC plane is sRGB");
            }
        }
        // Every storage's error is reported, within the stated bounds of lightvol-hemibasis's
        // storage test (8-bit and BC7 2.5%, BC1 12%), with BC7 below BC1.
        for (e, bound) in [("rgb8", 0.025), ("bc7", 0.025), ("bc1", 0.12)] {
            let r = v["encodings"][e]["rel_rms"].as_f64().unwrap();
            assert!((0.0..bound).contains(&r), "{tag} {e}: {r}");
        }
        assert!(v["encodings"]["bc7"]["rel_rms"].as_f64() < v["encodings"]["bc1"]["rel_rms"].as_f64());
        assert_eq!(v["encodings"]["bc1"]["bytes_per_texel"], 0.5 * k as f64);
    }
}

#[test]
fn png_encoding_writes_one_image_per_coefficient() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_gltf(dir.path(), "plane.gltf", &[plane("floor")]);
    let out = dir.path().join("maps");
    let args = [
        "bake-surface",
        scene.to_str().unwrap(),
        "--basis",
        "hl2",
        "--uv",
        "0",
        "--texels-per-unit",
        "3",
        "--samples",
        "16",
        "--sky",
        SKY,
        "--encode",
        "png",
        "--quantity",
        "radiosity",
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ];
    assert_eq!(run(&args), Ok(ExitCode::SUCCESS));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("hl2.json")).unwrap()).unwrap();
    assert_eq!(v["uv_set"], "TEXCOORD_0");
    assert_eq!(v["quantity"], "radiosity");
    assert_eq!(v["encodings"]["rgb8"]["bytes_per_texel"], 9.0);
    for j in 0..3 {
        let png = std::fs::read(out.join("hl2").join(format!("floor_c{j:02}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    }
    assert!(!out.join("hl2").join("floor_c03.png").exists());
}

#[test]
fn bad_input_is_one_clear_line_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("never");
    let o = out.to_str().unwrap();
    // No TEXCOORD_1.
    let mut m = plane("no_lightmap_uvs");
    m.uv1 = None;
    let s = write_gltf(dir.path(), "missing.gltf", &[m]);
    let err = run(&["bake-surface", s.to_str().unwrap(), "-o", o, "--quiet"]).unwrap_err();
    assert!(err.contains("no_lightmap_uvs") && err.contains("TEXCOORD_1"), "{err}");
    assert!(!err.contains('\n'));
    // Two triangles of one mesh on the same lightmap UV triangle.
    let p = [[-0.5, 0.0, -0.5], [-0.5, 0.0, 0.5], [0.5, 0.0, 0.5], [0.5, 0.0, -0.5]];
    let uv = [[0.1, 0.1], [0.1, 0.9], [0.9, 0.9]];
    let m = Mesh {
        name: "overlapping",
        positions: vec![p[0], p[1], p[2], p[0], p[2], p[3]],
        uv0: None,
        uv1: Some(vec![uv[0], uv[1], uv[2], uv[0], uv[1], uv[2]]),
        indices: vec![[0, 1, 2], [3, 4, 5]],
    };
    let s = write_gltf(dir.path(), "overlap.gltf", &[m]);
    let err = run(&["bake-surface", s.to_str().unwrap(), "-o", o, "--quiet", "--texels-per-unit", "8"])
        .unwrap_err();
    assert!(err.contains("overlapping") && err.contains("overlap"), "{err}");
    assert!(!err.contains('\n'));
    // Unknown basis, and --uv out of range: caught before loading anything.
    let s = write_gltf(dir.path(), "ok.gltf", &[plane("floor")]);
    let err = run(&["bake-surface", s.to_str().unwrap(), "--basis", "sh5", "-o", o]).unwrap_err();
    assert!(err.contains("sh5"), "{err}");
    assert!(run(&["bake-surface", s.to_str().unwrap(), "--uv", "2", "-o", o]).is_err());
    assert!(
        run(&["bake-surface", s.to_str().unwrap(), "--encode", "png", "--compress", "bc1", "-o", o]).is_err()
    );
    assert!(!out.exists(), "a failed bake left {}", out.display());
    // Rendering from a folder without maps.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let r = dir.path().join("r");
    let err = run(&[
        "render",
        s.to_str().unwrap(),
        "--surface",
        empty.to_str().unwrap(),
        "-o",
        r.to_str().unwrap(),
    ])
    .unwrap_err();
    assert!(err.contains("no coefficient maps"), "{err}");
    assert!(!r.exists());
}

#[test]
fn render_matches_maps_to_objects_and_refuses_another_scene() {
    let dir = tempfile::tempdir().unwrap();
    // A floor and a wall standing on it (wall: x = 0 plane, normal +X).
    let mut wall = plane("wall");
    wall.positions = vec![[0.0, 0.0, -0.3], [0.0, 0.6, -0.3], [0.0, 0.6, 0.3], [0.0, 0.0, 0.3]];
    let two = write_gltf(dir.path(), "two.gltf", &[plane("floor"), wall]);
    let maps = dir.path().join("maps");
    let m = maps.to_str().unwrap();
    let bake = [
        "bake-surface",
        two.to_str().unwrap(),
        "--basis",
        "hbasis_mod4",
        "--texels-per-unit",
        "4",
        "--samples",
        "32",
        "--sky",
        SKY,
        "--sun",
        SUN,
        "-o",
        m,
        "--quiet",
    ];
    assert_eq!(run(&bake), Ok(ExitCode::SUCCESS));
    let shots = dir.path().join("shots");
    let render = [
        "render",
        two.to_str().unwrap(),
        "--sky",
        SKY,
        "--sun",
        SUN,
        "--surface",
        m,
        "--camera",
        "-1,-1,1:0,0,0.1:50",
        "--width",
        "24",
        "--height",
        "16",
        "--reference-samples",
        "8",
        "-o",
        shots.to_str().unwrap(),
    ];
    assert_eq!(run(&render), Ok(ExitCode::SUCCESS));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(shots.join("report.json")).unwrap()).unwrap();
    assert!(report["pixels"].as_u64().unwrap() > 0);
    // The modified H-basis brings its lowest level of detail, the plain lightmap.
    assert_eq!(report["bases"]["lightmap"]["bytes_per_texel"], 3);
    assert_eq!(report["bases"]["hbasis_mod4"]["bytes_per_texel"], 12);
    // The same maps against a scene with other objects: one clear error, no output.
    let one = write_gltf(dir.path(), "one.gltf", &[plane("floor")]);
    let other = dir.path().join("other");
    let mut r = render;
    r[1] = one.to_str().unwrap();
    r[r.len() - 1] = other.to_str().unwrap();
    let err = run(&r).unwrap_err();
    assert!(err.contains("do not match"), "{err}");
    assert!(!other.exists());
}
