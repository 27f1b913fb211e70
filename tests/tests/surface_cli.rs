//! `lightvol bake-surface` and `lightvol render --surface` end to end.

mod surface_util;

use std::path::Path;
use std::process::ExitCode;

use lightvol_hemibasis::bc::{self, BlockFormat, CompressedPlane};
use lightvol_hemibasis::encode::{DcTransfer, Encoding};
use lightvol_hemibasis::map::{CoeffMap, Plane, map_error};
use lightvol_hemibasis::plane_ktx2::{PlaneFormat, read_ktx2_plane};
use surface_util::{Mesh, plane, run, write_gltf};

/// The recomputed error of the files on disk against the JSON's `rel_rms`: the files hold
/// exactly the planes the CLI measured and the EXR exactly its f32 maps, so the two agree to
/// f64 summation rounding over a few hundred texels (~1e-15 relative); 1e-9 leaves room for
/// a different summation order, while any changed code value (one 8-bit step moves the
/// error by ~1e-4 relative) fails.
const FILE_ERROR_REL_TOL: f64 = 1e-9;

/// One object's f32 coefficient map and validity read straight from the EXR with the `exr`
/// crate (channels `cKK.R/G/B` and `valid`, one part per object), not with the CLI's reader.
struct ExrObject {
    name: String,
    width: usize,
    height: usize,
    /// `(y * width + x) * k + j`, RGB.
    data: Vec<[f32; 3]>,
    valid: Vec<f32>,
}

fn read_exr_objects(path: &Path, k: usize) -> Vec<ExrObject> {
    let img = exr::prelude::read_all_flat_layers_from_file(path).expect("surface EXR");
    img.layer_data
        .iter()
        .map(|layer| {
            let (width, height) = (layer.size.0, layer.size.1);
            let n = width * height;
            let channel = |name: &str| -> Vec<f32> {
                let c = layer
                    .channel_data
                    .list
                    .iter()
                    .find(|c| c.name.to_string() == name)
                    .unwrap_or_else(|| panic!("channel {name}"));
                (0..n).map(|i| c.sample_data.value_by_flat_index(i).to_f32()).collect()
            };
            let mut data = vec![[0.0f32; 3]; n * k];
            for j in 0..k {
                for (ch, c) in ["R", "G", "B"].iter().enumerate() {
                    for (i, v) in channel(&format!("c{j:02}.{c}")).into_iter().enumerate() {
                        data[i * k + j][ch] = v;
                    }
                }
            }
            let name = layer.attributes.layer_name.as_ref().expect("part name").to_string();
            ExrObject { name, width, height, data, valid: channel("valid") }
        })
        .collect()
}

/// How a coefficient plane is stored on disk.
#[derive(Clone, Copy)]
enum Stored {
    /// `<object>_cKK.png` (RGB8).
    Png,
    /// `<object>_cKK.ktx2` (RGBA8).
    Ktx2,
    /// `<object>_cKK.<bc1|bc7>.ktx2`.
    Block(BlockFormat),
}

/// Reads one stored plane back (hemibasis KTX2 reader + `bc::decompress`, or the PNG
/// decoder), with its sRGB tag (PNG: `None`, the file carries no format tag).
fn read_plane(dir: &Path, stem: &str, how: Stored) -> (Plane, Option<bool>) {
    match how {
        Stored::Png => {
            let img = image::open(dir.join(format!("{stem}.png"))).expect("png").to_rgb8();
            let texels = img.pixels().map(|p| [p[0], p[1], p[2], 255]).collect();
            (Plane { width: img.width() as usize, height: img.height() as usize, texels }, None)
        }
        Stored::Ktx2 => {
            let t = read_ktx2_plane(&std::fs::read(dir.join(format!("{stem}.ktx2"))).unwrap()).unwrap();
            assert_eq!(t.format, PlaneFormat::Rgba8);
            let texels = t.data.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
            (Plane { width: t.width, height: t.height, texels }, Some(t.srgb))
        }
        Stored::Block(f) => {
            let t = read_ktx2_plane(&std::fs::read(dir.join(format!("{stem}.{}.ktx2", f.name()))).unwrap())
                .unwrap();
            let format = if f == BlockFormat::Bc1 { PlaneFormat::Bc1 } else { PlaneFormat::Bc7 };
            assert_eq!(t.format, format);
            let c = CompressedPlane { format: f, width: t.width, height: t.height, blocks: t.data };
            (bc::decompress(&c), Some(t.srgb))
        }
    }
}

/// Decodes every written plane of `tag` in `out`, rebuilds the coefficient maps (the
/// shader's decode, [Ish11] Listing 2.2: DC through the sRGB curve, others `2 r v - r`),
/// and returns `map_error` over the covered texels against the EXR's maps scaled by the
/// JSON's `encode_scale` (what the CLI reports as `rel_rms`).
fn error_of_files(out: &Path, tag: &str, how: Stored) -> f64 {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(format!("{tag}.json"))).unwrap()).unwrap();
    let k = v["coefficients"].as_u64().unwrap() as usize;
    let scale = v["encode_scale"].as_f64().unwrap();
    let range = v["range"].as_f64().unwrap();
    let name = tag.trim_end_matches(|c: char| c.is_ascii_digit());
    let basis =
        lightvol_hemibasis::by_name(tag, k).or_else(|| lightvol_hemibasis::by_name(name, k)).expect("basis");
    let enc = Encoding { range, dc: DcTransfer::Srgb, quantize_8bit: true };
    let (mut orig, mut back) = (Vec::new(), Vec::new());
    for obj in read_exr_objects(&out.join(format!("{tag}.exr")), k) {
        let planes: Vec<Plane> = (0..k)
            .map(|j| {
                let (p, srgb) = read_plane(&out.join(tag), &format!("{}_c{j:02}", obj.name), how);
                assert_eq!((p.width, p.height), (obj.width, obj.height), "{tag} c{j:02}");
                if let Some(srgb) = srgb {
                    assert_eq!(srgb, basis.dc_index() == Some(j), "only the DC plane is sRGB");
                }
                p
            })
            .collect();
        let decoded = enc.decode_map(basis.as_ref(), &planes);
        for (i, &valid) in obj.valid.iter().enumerate() {
            if valid > 0.0 {
                orig.extend(
                    obj.data[i * k..(i + 1) * k].iter().map(|c| c.map(|x| (f64::from(x) * scale) as f32)),
                );
                back.extend_from_slice(&decoded.data[i * k..(i + 1) * k]);
            }
        }
    }
    let n = orig.len() / k;
    assert!(n > 0, "{tag}: no covered texels");
    let orig = CoeffMap { width: n, height: 1, len: k, data: orig };
    let back = CoeffMap { width: n, height: 1, len: k, data: back };
    map_error(basis.as_ref(), &orig, &back).rel_rms
}

/// Asserts that the files of `tag` decode to the JSON's reported error for `key`.
fn assert_files_measured(out: &Path, tag: &str, key: &str, how: Stored) {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(format!("{tag}.json"))).unwrap()).unwrap();
    let reported = v["encodings"][key]["rel_rms"].as_f64().unwrap();
    let from_files = error_of_files(out, tag, how);
    assert!(reported > 0.0, "{tag} {key}: a lossy storage reports 0");
    assert!(
        (from_files - reported).abs() <= FILE_ERROR_REL_TOL * reported,
        "{tag} {key}: files {from_files} vs reported {reported}"
    );
}

/// The grazing light of [Ish11] §3.2 in lightvol's +Z-up frame: a sun 5.7° above the
/// horizon (irradiance 5 on a facing surface) and a blue sky.
/// The sun, in the glTF scenes' +Y-up frame (internal +Z-up (1, 0.2, 0.1)).
const SUN: &str = "1,0.1,-0.2:5";
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
        assert!(v["lighting"].as_str().unwrap().contains("sky=[0.25, 0.35, 0.6]"), "{}", v["lighting"]);
        let k = v["coefficients"].as_u64().unwrap() as usize;
        // One BC1 and one BC7 KTX2 per coefficient, each readable.
        for j in 0..k {
            for f in ["bc1", "bc7"] {
                let p = out.join(tag).join(format!("floor_c{j:02}.{f}.ktx2"));
                let t = read_ktx2_plane(&std::fs::read(&p).unwrap()).unwrap();
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
        assert_eq!(v["encodings"]["bc1"]["storage"], "BC1 KTX2");
        assert_eq!(v["encodings"]["bc7"]["bytes_per_texel"], k as f64);
        assert_eq!(v["encodings"]["bc7"]["storage"], "BC7 KTX2");
        // No uncompressed textures were written: the 8-bit entry counts RGB8 as a PNG stores it.
        assert_eq!(v["encodings"]["rgb8"]["bytes_per_texel"], 3.0 * k as f64);
        assert_eq!(v["encodings"]["rgb8"]["storage"], "RGB8 PNG");
        // The files on disk are what was measured: decoded back, they give the reported error.
        assert_files_measured(&out, tag, "bc1", Stored::Block(BlockFormat::Bc1));
        assert_files_measured(&out, tag, "bc7", Stored::Block(BlockFormat::Bc7));
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
        "hl2,hbasis_mod4",
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
    // The PNGs decode to the reported 8-bit error (hl2: all planes range-compressed;
    // hbasis_mod4: the DC plane through the sRGB curve).
    assert_files_measured(&out, "hl2", "rgb8", Stored::Png);
    assert_files_measured(&out, "hbasis_mod4", "rgb8", Stored::Png);
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
        "--encode",
        "ktx2",
        "-o",
        m,
        "--quiet",
    ];
    assert_eq!(run(&bake), Ok(ExitCode::SUCCESS));
    // The uncompressed KTX2 planes (RGBA8, DC plane `_SRGB`) decode to the reported error.
    assert_files_measured(&maps, "hbasis_mod4", "rgb8", Stored::Ktx2);
    // Uncompressed KTX2 planes are RGBA8: 4 bytes per coefficient.
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(maps.join("hbasis_mod4.json")).unwrap()).unwrap();
    assert_eq!(v["encodings"]["rgb8"]["bytes_per_texel"], 16.0);
    assert_eq!(v["encodings"]["rgb8"]["storage"], "RGBA8 KTX2");
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
        "-1,1,1:0,0.1,0:50",
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

/// Runs `render --surface maps` of `scene` with `light` into `out` (tiny image).
fn render_surface(scene: &Path, maps: &Path, out: &Path, light: &[&str]) -> Result<ExitCode, String> {
    let mut args = vec!["render", scene.to_str().unwrap(), "--surface", maps.to_str().unwrap()];
    args.extend_from_slice(&["--camera", "0,1,0:0,0,0:40", "--width", "8", "--height", "6"]);
    args.extend_from_slice(&["--reference-samples", "2", "-o", out.to_str().unwrap()]);
    args.extend_from_slice(light);
    run(&args)
}

/// Bakes `basis` of `scene` under `light` into `out` (few samples: only the files matter).
fn quick_bake(scene: &Path, basis: &str, out: &Path, light: &[&str]) {
    let mut args = vec!["bake-surface", scene.to_str().unwrap(), "--basis", basis];
    args.extend_from_slice(&["--texels-per-unit", "2", "--samples", "8", "-o", out.to_str().unwrap()]);
    args.push("--quiet");
    args.extend_from_slice(light);
    assert_eq!(run(&args), Ok(ExitCode::SUCCESS));
}

#[test]
fn render_refuses_maps_baked_under_other_lighting_and_stale_maps() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_gltf(dir.path(), "plane.gltf", &[plane("floor")]);
    let (maps, other) = (dir.path().join("maps"), dir.path().join("other"));
    let sky_a = ["--sky", SKY];
    let sky_b = ["--sky", "0.5,0.5,0.5"];
    quick_bake(&scene, "hbasis_mod4", &maps, &sky_a);
    // Same lighting renders; another sky is refused, naming what differs, writing nothing.
    let ok = dir.path().join("ok");
    assert_eq!(render_surface(&scene, &maps, &ok, &sky_a), Ok(ExitCode::SUCCESS));
    let out = dir.path().join("refused");
    let err = render_surface(&scene, &maps, &out, &sky_b).unwrap_err();
    assert!(err.contains("other lighting") && err.contains("sky=[0.5, 0.5, 0.5]"), "{err}");
    assert!(!err.contains('\n'));
    assert!(!out.exists());
    // A sun the bake did not have is refused too.
    let err = render_surface(&scene, &maps, &out, &["--sky", SKY, "--sun", "0,1,0:1"]).unwrap_err();
    assert!(err.contains("other lighting") && err.contains("sun"), "{err}");
    assert!(!out.exists());
    // The bounce count is part of the lighting; the render takes it from the maps (the
    // reference is traced with the bake's bounces), so maps of another bounce count render.
    let maps0 = dir.path().join("maps0");
    quick_bake(&scene, "hbasis_mod4", &maps0, &["--sky", SKY, "--bounces", "0"]);
    assert_eq!(render_surface(&scene, &maps0, &dir.path().join("ok0"), &sky_a), Ok(ExitCode::SUCCESS));
    // A stale map baked under other lighting next to the current ones: refused, both named,
    // whichever lighting the render uses.
    quick_bake(&scene, "sh4", &other, &sky_b);
    std::fs::copy(other.join("sh4.exr"), maps.join("sh4.exr")).unwrap();
    for light in [sky_a, sky_b] {
        let err = render_surface(&scene, &maps, &out, &light).unwrap_err();
        assert!(err.contains("different lighting"), "{err}");
        assert!(err.contains("hbasis_mod4.exr") && err.contains("sh4.exr"), "{err}");
        assert!(!err.contains('\n'));
        assert!(!out.exists());
    }
}

#[test]
fn invalid_texels_are_read_from_the_exr_maps() {
    let dir = tempfile::tempdir().unwrap();
    // A wall through the floor (x = 0, normal +X, from 0.3 below to 0.3 above it): floor
    // sample points on its -X side see its back face.
    let mut wall = plane("wall");
    wall.positions = vec![[0.0, -0.3, -0.3], [0.0, 0.3, -0.3], [0.0, 0.3, 0.3], [0.0, -0.3, 0.3]];
    let scene = write_gltf(dir.path(), "pierced.gltf", &[plane("floor"), wall]);
    let maps = dir.path().join("maps");
    quick_bake(&scene, "hbasis_mod4", &maps, &["--sky", SKY]);
    let json = maps.join("hbasis_mod4.json");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let invalid = v["invalid_texels"].as_u64().unwrap();
    assert!(invalid > 0, "the pierced floor has invalid texels");
    std::fs::remove_file(&json).unwrap();
    let out = dir.path().join("shots");
    assert_eq!(render_surface(&scene, &maps, &out, &["--sky", SKY]), Ok(ExitCode::SUCCESS));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(r["invalid_texels"], invalid, "the sidecar JSON is gone; the EXR keeps the count");
}
