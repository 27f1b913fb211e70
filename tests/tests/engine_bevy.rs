//! What a Bevy user gets: `lightvol export --format bevy` read the way Bevy reads it and
//! sampled the way Bevy's shader samples it, on the same room written as a +Y-up glTF and
//! as its +Z-up OBJ twin.
//!
//! The client below re-implements, line by line, `irradiance_volume_light` of
//! `crates/bevy_pbr/src/light_probe/irradiance_volume.wesl` (bevyengine/bevy at commit
//! 190a5aca; the same lines, 59-91, are `src/light_probe/irradiance_volume.wgsl` of the
//! bevy_pbr 0.19.1 crate that `clients/bevy` runs): `unit_pos = light_from_world · P`;
//! `stp = clamp((unit_pos + 0.5) · resolution, 0.5, resolution − 0.5)`; `uvw = stp /
//! atlas_resolution`; the negative faces at `+0.5` in `v` where `N < 0`, the Y and Z faces
//! at `+1/3` and `+2/3` in `w`; `textureSampleLevel` (linear filtering, clamped) of the three
//! faces; `rgb_x N.x² + rgb_y N.y² + rgb_z N.z²` times the probe's intensity.
//! `light_from_world` is the inverse of the probe entity's `Transform` (`T · R · S`), which
//! the export's JSON gives. Bevy's KTX2 loader hands the level data to the GPU as stored
//! (RGBA16F, or RGB9E5 decoded by the sampler).
//!
//! Checked: for both frames and both texel formats, at every voxel centre and at random
//! points, with the six axis normals of the *file's* frame, the client equals lightvol's own
//! `E/π` (the native volume's f64 lookup at the same physical point and normal) within the
//! texel rounding. Negative controls: swapping the positive and negative faces, texels in
//! `E` instead of `E/π`, and reading the Y-up export's axes as internal axes each fail by
//! far more than the tolerance. The JSON's `Transform` puts every voxel centre on its node.

mod common;
#[allow(dead_code, reason = "shared test helpers, of which this test uses the glTF writer")]
mod surface_util;

use std::path::{Path, PathBuf};

use common::{ok, s};
use lightvol_volume::IrradianceVolume;
use lightvol_volume::frame::UpAxis;
use lightvol_volume::io::exr::read_exr;
use surface_util::{Mesh, write_gltf};

/// The room in glTF's +Y-up frame: a 4 m floor, a wall along one side and a 1 m block,
/// every face counter-clockwise seen from outside.
fn room_yup() -> (Vec<[f32; 3]>, Vec<[u16; 3]>) {
    let mut p: Vec<[f32; 3]> = Vec::new();
    let mut t: Vec<[u16; 3]> = Vec::new();
    let mut quad = |q: [[f32; 3]; 4]| {
        let b = p.len() as u16;
        p.extend_from_slice(&q);
        t.push([b, b + 1, b + 2]);
        t.push([b, b + 2, b + 3]);
    };
    // Floor (normal +Y) and a wall at x = -2 (normal +X).
    quad([[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]);
    quad([[-2.0, 0.0, -2.0], [-2.0, 2.0, -2.0], [-2.0, 2.0, 2.0], [-2.0, 0.0, 2.0]]);
    // A block [0, 1] × [0, 1] × [-0.5, 0.5]: top, four sides.
    let (x0, x1, y1, z0, z1) = (0.0, 1.0, 1.0, -0.5, 0.5);
    quad([[x0, y1, z0], [x0, y1, z1], [x1, y1, z1], [x1, y1, z0]]);
    quad([[x1, 0.0, z0], [x1, y1, z0], [x1, y1, z1], [x1, 0.0, z1]]);
    quad([[x0, 0.0, z1], [x0, y1, z1], [x0, y1, z0], [x0, 0.0, z0]]);
    quad([[x0, 0.0, z1], [x1, 0.0, z1], [x1, y1, z1], [x0, y1, z1]]);
    quad([[x1, 0.0, z0], [x0, 0.0, z0], [x0, y1, z0], [x1, y1, z0]]);
    (p, t)
}

/// The OBJ twin: the same room with every vertex rotated into +Z up, `(x, y, z) → (x, −z, y)`.
fn write_obj_twin(dir: &Path, p: &[[f32; 3]], t: &[[u16; 3]]) -> PathBuf {
    let mut obj = String::new();
    for v in p {
        let w = UpAxis::Y.to_world(v.map(f64::from));
        obj += &format!("v {} {} {}\n", w[0], w[1], w[2]);
    }
    for f in t {
        obj += &format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    let path = dir.join("room_zup.obj");
    std::fs::write(&path, obj).unwrap();
    path
}

/// The room as a +Y-up glTF and as its +Z-up OBJ twin, written into `dir`.
fn twin_scenes(dir: &Path) -> (PathBuf, PathBuf) {
    let (p, t) = room_yup();
    let gltf = write_gltf(
        dir,
        "room_yup.gltf",
        &[Mesh { name: "room", positions: p.clone(), uv0: None, uv1: None, indices: t.clone() }],
    );
    (gltf, write_obj_twin(dir, &p, &t))
}

/// A Bevy KTX2 as Bevy's loader reads it: dimensions, format and RGB texels as f32.
struct Texture {
    dims: [usize; 3],
    rgb: Vec<[f32; 3]>,
}

fn load_texture(path: &Path) -> Texture {
    let bytes = std::fs::read(path).unwrap();
    let r = ktx2::Reader::new(&bytes[..]).unwrap();
    let h = r.header();
    let dims = [h.pixel_width as usize, h.pixel_height as usize, h.pixel_depth as usize];
    let data = r.levels().next().unwrap().data;
    let rgb = match h.format {
        Some(ktx2::Format::R16G16B16A16_SFLOAT) => data
            .chunks_exact(8)
            .map(|c| std::array::from_fn(|i| half::f16::from_le_bytes([c[2 * i], c[2 * i + 1]]).to_f32()))
            .collect(),
        // E5B9G9R9_UFLOAT_PACK32 as the Vulkan spec decodes it: m · 2^(e − 15 − 9).
        Some(ktx2::Format::E5B9G9R9_UFLOAT_PACK32) => data
            .chunks_exact(4)
            .map(|c| {
                let t = u32::from_le_bytes(c.try_into().unwrap());
                let scale = 2f32.powi((t >> 27) as i32 - 24);
                [t & 0x1ff, (t >> 9) & 0x1ff, (t >> 18) & 0x1ff].map(|m| m as f32 * scale)
            })
            .collect(),
        f => panic!("format {f:?}"),
    };
    Texture { dims, rgb }
}

/// `textureSampleLevel` with linear filtering and clamp-to-edge addressing at normalised
/// coordinates `uvw`.
fn sample_linear(t: &Texture, uvw: [f32; 3]) -> [f32; 3] {
    let c: [f32; 3] = std::array::from_fn(|a| uvw[a] * t.dims[a] as f32 - 0.5);
    let i0: [i64; 3] = std::array::from_fn(|a| c[a].floor() as i64);
    let f: [f32; 3] = std::array::from_fn(|a| c[a] - c[a].floor());
    let mut out = [0.0f32; 3];
    for corner in 0..8 {
        let mut w = 1.0f32;
        let mut idx = [0usize; 3];
        for a in 0..3 {
            let bit = (corner >> a) & 1;
            w *= if bit == 1 { f[a] } else { 1.0 - f[a] };
            idx[a] = (i0[a] + bit as i64).clamp(0, t.dims[a] as i64 - 1) as usize;
        }
        let texel = t.rgb[(idx[2] * t.dims[1] + idx[1]) * t.dims[0] + idx[0]];
        for ch in 0..3 {
            out[ch] += w * texel[ch];
        }
    }
    out
}

/// How the client may (mis)read the faces: the negative controls.
#[derive(Clone, Copy, PartialEq)]
enum Read {
    AsBevy,
    SwappedFaces,
}

/// Bevy's `irradiance_volume_light` for one probe (module docs), in f32.
fn bevy_light(
    t: &Texture,
    light_from_world: &[[f32; 4]; 3],
    intensity: f32,
    p: [f32; 3],
    n: [f32; 3],
    read: Read,
) -> [f32; 3] {
    let atlas = t.dims.map(|d| d as f32);
    let res = [atlas[0], atlas[1] / 2.0, atlas[2] / 3.0];
    let unit: [f32; 3] = std::array::from_fn(|r| {
        light_from_world[r][0] * p[0]
            + light_from_world[r][1] * p[1]
            + light_from_world[r][2] * p[2]
            + light_from_world[r][3]
    });
    let stp: [f32; 3] = std::array::from_fn(|a| ((unit[a] + 0.5) * res[a]).clamp(0.5, res[a] - 0.5));
    let uvw: [f32; 3] = std::array::from_fn(|a| stp[a] / atlas[a]);
    let neg: [f32; 3] = std::array::from_fn(|a| {
        let negative = n[a] < 0.0;
        let pick = if read == Read::SwappedFaces { !negative } else { negative };
        if pick { 0.5 } else { 0.0 }
    });
    let face = |a: usize| sample_linear(t, [uvw[0], uvw[1] + neg[a], uvw[2] + a as f32 / 3.0]);
    let (x, y, z) = (face(0), face(1), face(2));
    std::array::from_fn(|c| (x[c] * n[0] * n[0] + y[c] * n[1] * n[1] + z[c] * n[2] * n[2]) * intensity)
}

/// The inverse of an affine 3×4 matrix (f64), rounded to f32 as a GPU uniform.
fn inverse_affine(m: [[f64; 4]; 3]) -> [[f32; 4]; 3] {
    let a = |r: usize, c: usize| m[r][c];
    let det = a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1))
        - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0))
        + a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
    let inv3: [[f64; 3]; 3] = [
        [
            (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) / det,
            (a(0, 2) * a(2, 1) - a(0, 1) * a(2, 2)) / det,
            (a(0, 1) * a(1, 2) - a(0, 2) * a(1, 1)) / det,
        ],
        [
            (a(1, 2) * a(2, 0) - a(1, 0) * a(2, 2)) / det,
            (a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0)) / det,
            (a(0, 2) * a(1, 0) - a(0, 0) * a(1, 2)) / det,
        ],
        [
            (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0)) / det,
            (a(0, 1) * a(2, 0) - a(0, 0) * a(2, 1)) / det,
            (a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0)) / det,
        ],
    ];
    std::array::from_fn(|r| {
        let t = -(0..3).map(|c| inv3[r][c] * m[c][3]).sum::<f64>();
        [inv3[r][0] as f32, inv3[r][1] as f32, inv3[r][2] as f32, t as f32]
    })
}

/// Bevy's `Transform::compute_affine` (`T · R · S`) from the export's JSON.
fn transform_matrix(json: &serde_json::Value) -> [[f64; 4]; 3] {
    let v = |k: &str, i: usize| json["transform"][k][i].as_f64().unwrap();
    let (t, q, s) = (
        [v("translation", 0), v("translation", 1), v("translation", 2)],
        [0, 1, 2, 3].map(|i| v("rotation", i)),
        [0, 1, 2].map(|i| v("scale", i)),
    );
    let [x, y, z, w] = q;
    let r = [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ];
    std::array::from_fn(|i| [r[i][0] * s[0], r[i][1] * s[1], r[i][2] * s[2], t[i]])
}

/// One export, and everything needed to check it against the native volume.
struct Case {
    frame: UpAxis,
    native: IrradianceVolume,
    tex: Texture,
    world_from_light: [[f64; 4]; 3],
    intensity: f32,
    /// Relative tolerance of the texels' rounding.
    tol: f64,
}

/// Largest error of the client against lightvol's E/π over voxel centres and random points
/// (file-frame positions and axis normals), relative to the largest E/π; `read` and the
/// other knobs make the negative controls.
fn max_rel_error(c: &Case, read: Read, texel_scale: f32, axes_as_internal: bool) -> f64 {
    let spec = c.native.spec();
    let [nx, ny, nz] = spec.res();
    let light_from_world = inverse_affine(c.world_from_light);
    let mut points: Vec<[f64; 3]> = Vec::new();
    for node in 0..spec.node_count() {
        let [i, j, k] = spec.node_coords(node);
        points.push(spec.node_position_world(i, j, k));
    }
    let (lo, hi) = spec.bounds();
    let mut st = 0x5eed_u64;
    for _ in 0..400 {
        points.push(std::array::from_fn(|a| {
            st ^= st << 13;
            st ^= st >> 7;
            st ^= st << 17;
            lo[a] + (hi[a] - lo[a]) * ((st >> 11) as f64 / (1u64 << 53) as f64)
        }));
    }
    let _ = (nx, ny, nz);
    let scaled =
        Texture { dims: c.tex.dims, rgb: c.tex.rgb.iter().map(|t| t.map(|v| v * texel_scale)).collect() };
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    for p_int in &points {
        let p_file = c.frame.to_file(*p_int);
        for a in 0..3 {
            for sign in [1.0, -1.0] {
                let mut n_file = [0.0; 3];
                n_file[a] = sign;
                // What lightvol says: E/π at the same physical point and normal.
                let n_int = if axes_as_internal { n_file } else { c.frame.to_world(n_file) };
                let want = c.native.irradiance_reference(*p_int, n_int).map(|v| v / std::f64::consts::PI);
                let got = bevy_light(
                    &scaled,
                    &light_from_world,
                    c.intensity,
                    p_file.map(|v| v as f32),
                    n_file.map(|v| v as f32),
                    read,
                );
                for ch in 0..3 {
                    worst = worst.max((f64::from(got[ch]) - want[ch]).abs());
                    scale = scale.max(want[ch].abs());
                }
            }
        }
    }
    worst / scale
}

fn bake_and_export(dir: &Path, scene: &Path, frame: UpAxis, tag: &str, format: &str) -> Case {
    let (bounds, res, sun) = match frame {
        UpAxis::Y => ("-1.9,0.1,-1.9,1.9,1.9,1.9", "5,4,6", "0.4,1,0.3:4"),
        UpAxis::Z => ("-1.9,-1.9,0.1,1.9,1.9,1.9", "5,6,4", "0.4,-0.3,1:4"),
    };
    let vol = dir.join(format!("{tag}.exr"));
    // The paper's method: the tolerances below were derived for its values (the export does
    // not depend on the method, and the default `doi` leaves nodes near zero whose rgb9e5
    // relative error the shared exponent inflates).
    let mut a = vec!["bake", s(scene), "--method", "doi-paper", "--bounds", bounds, "--res", res];
    a.extend(["--samples", "16", "--seed", "5"]);
    a.extend(["--sky", "0.3,0.4,0.6", "--sun", sun, "--bounces", "1", "--quiet", "-o", s(&vol)]);
    if frame == UpAxis::Z {
        a.extend(["--up", "z"]);
    }
    ok(&a);
    let ktx = dir.join(format!("{tag}-{format}.ktx2"));
    ok(&["export", s(&vol), "--format", "bevy", "--bevy-format", format, "-o", s(&ktx)]);
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(lightvol_volume::io::sidecar::sidecar_path(&ktx)).unwrap(),
    )
    .unwrap();
    assert_eq!(json["frame"], frame.name());
    assert_eq!(json["intensity"], 1.0);
    let native = read_exr(&vol).unwrap();
    assert_eq!(native.metadata().frame, frame);
    // f16: 2^-11 relative per texel; RGB9E5: half a step of the shared exponent, 2^-9 of
    // the largest channel; plus the f32 filtering arithmetic.
    let tol = if format == "rgb9e5" { 2.2e-3 } else { 6e-4 };
    Case {
        frame,
        native,
        tex: load_texture(&ktx),
        world_from_light: transform_matrix(&json),
        intensity: json["intensity"].as_f64().unwrap() as f32,
        tol,
    }
}

#[test]
fn bevy_client_reproduces_lightvol_in_both_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (gltf, obj) = twin_scenes(d);
    let mut natives = Vec::new();
    for (scene, frame, tag) in [(&gltf, UpAxis::Y, "yup"), (&obj, UpAxis::Z, "zup")] {
        for format in ["rgba16f", "rgb9e5"] {
            let c = bake_and_export(d, scene, frame, tag, format);
            let e = max_rel_error(&c, Read::AsBevy, 1.0, false);
            eprintln!(
                "{tag} {format}: Bevy client vs lightvol E/π, max relative error {e:.2e} (tolerance {:.1e})",
                c.tol
            );
            assert!(e < c.tol, "{tag} {format}: {e}");
            // Negative controls: each misreading fails by far more than the tolerance.
            let swapped = max_rel_error(&c, Read::SwappedFaces, 1.0, false);
            let pi = max_rel_error(&c, Read::AsBevy, std::f32::consts::PI, false);
            assert!(swapped > 20.0 * c.tol, "{tag}: swapped faces only {swapped}");
            assert!(pi > 20.0 * c.tol, "{tag}: π-scaled texels only {pi}");
            if frame == UpAxis::Y {
                let axes = max_rel_error(&c, Read::AsBevy, 1.0, true);
                assert!(axes > 20.0 * c.tol, "Y-up export read with internal axes only {axes}");
            }
            // The Transform, applied as Bevy applies it, puts every voxel centre on its node;
            // the texture runs along the file's axes (the native grid laid out in them).
            let file = lightvol_volume::frame::to_file_frame(&c.native, frame).unwrap();
            let spec = file.spec();
            assert!(spec.placement().is_none());
            let res = spec.res();
            let cs = spec.cell_size();
            let spacing = cs[0].min(cs[1]).min(cs[2]);
            for node in 0..spec.node_count() {
                let v = spec.node_coords(node);
                let unit: [f64; 3] =
                    std::array::from_fn(|a| (f64::from(v[a]) + 0.5) / f64::from(res[a]) - 0.5);
                let m = c.world_from_light;
                let w: [f64; 3] = std::array::from_fn(|r| {
                    m[r][0] * unit[0] + m[r][1] * unit[1] + m[r][2] * unit[2] + m[r][3]
                });
                let node_file = spec.node_position_world(v[0], v[1], v[2]);
                for a in 0..3 {
                    assert!(
                        (w[a] - node_file[a]).abs() <= 1e-6 * spacing,
                        "voxel {v:?}: {w:?} vs {node_file:?}"
                    );
                }
            }
            natives.push(c.native);
        }
    }
    // `--camera` in each file's frame: the same view of the same volume, pixel for pixel.
    let shots: Vec<Vec<u8>> =
        [(&gltf, "yup", "3,2.5,3.5:0,0.5,0:45", "y"), (&obj, "zup", "3,-3.5,2.5:0,0,0.5:45", "z")]
            .iter()
            .map(|(scene, tag, cam, up)| {
                let png = d.join(format!("{tag}-view.png"));
                let vol = d.join(format!("{tag}.exr"));
                ok(&[
                    "render",
                    s(scene),
                    "--up",
                    up,
                    "--volume",
                    s(&vol),
                    "--camera",
                    cam,
                    "--width",
                    "24",
                    "--height",
                    "16",
                    "--sky",
                    "0.3,0.4,0.6",
                    "-o",
                    s(&png),
                ]);
                std::fs::read(&png).unwrap()
            })
            .collect();
    assert!(shots[0] == shots[1], "the same camera in the two frames renders differently");
    // The same physical bake: the glTF's and the OBJ twin's volumes are the same in the
    // internal frame, bit for bit (the rotation between the frames is exact).
    assert_eq!(natives[0].data(), natives[2].data(), "the Y-up glTF and the Z-up OBJ bake differently");
    assert_eq!(natives[0].spec().bounds(), natives[2].spec().bounds());
}

/// The numbers of `docs/ENGINES.md`'s worked example: one node's red channel with
/// `L_00 = 1`, `L_10 = 0.5`, looked up, exported from the Y-up frame, and as Bevy's face.
#[test]
fn worked_example_of_the_engine_doc() {
    use lightvol_volume::{BakeMetadata, GridSpec};
    let spec = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
    let mut data = vec![0.0f32; 8 * 9 * 3];
    for node in 0..8 {
        data[node * 27] = 1.0; // L_00, red
        data[node * 27 + 2 * 3] = 0.5; // L_10, red
    }
    let vol = IrradianceVolume::new(spec, 9, data, vec![1.0; 8]).unwrap();
    let e_up = vol.irradiance_reference([0.5; 3], [0.0, 0.0, 1.0])[0];
    let e_down = vol.irradiance_reference([0.5; 3], [0.0, 0.0, -1.0])[0];
    // The doc's eight digits; f64 sums of f32 coefficients 1 and 0.5 (exact), so the only
    // error is the doc's rounding.
    const DOC_DIGITS: f64 = 5e-9;
    assert!((e_up - 1.397_890_28).abs() < DOC_DIGITS, "{e_up}");
    assert!((e_down - 0.374_563_57).abs() < DOC_DIGITS, "{e_down}");
    assert!((e_up / std::f64::consts::PI - 0.444_962_30).abs() < DOC_DIGITS);
    // From a Y-up file: the lobe is along the file's +Y (index 1), not its z (index 2).
    let yup = vol.clone().with_metadata(BakeMetadata { frame: UpAxis::Y, ..BakeMetadata::default() });
    let file = lightvol_volume::frame::to_file_frame(&yup, UpAxis::Y).unwrap();
    let c = file.node(0);
    assert!((c[3] - 0.5).abs() < 1e-7 && c[6].abs() < 1e-7, "{:?}", &c[..12]);
    // Bevy's +Y face (Face::ALL order +X, -X, +Y, ...) holds E/π rounded to f16.
    let bytes =
        lightvol_volume::io::bevy::bevy_to_bytes(&yup, lightvol_volume::io::bevy::BevyFormat::Rgba16f)
            .unwrap();
    let bevy = lightvol_volume::io::bevy::bevy_from_bytes(&bytes).unwrap();
    assert_eq!(bevy.cubes[0][2][0], 0.445_068_36);
}

/// Coordinates round-trip in the file's frame: the grid a Y-up glTF bake reports (JSON and
/// `info`) is the `--bounds`/`--res` it was given, in the glTF's axes, and baking again
/// from the reported values gives the same file; a Z-up OBJ reports its own axes. Exports
/// of uniform and adaptive volumes say which frame they are in.
#[test]
fn coordinates_round_trip_in_the_file_frame() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (gltf, obj) = twin_scenes(d);
    for (scene, frame, bounds, res) in [
        (&gltf, UpAxis::Y, [-1.9, 0.1, -1.7, 1.8, 1.9, 1.6], [5u32, 4, 6]),
        (&obj, UpAxis::Z, [-1.9, -1.7, 0.1, 1.8, 1.6, 1.9], [5, 6, 4]),
    ] {
        let b = bounds.map(|v| v.to_string()).join(",");
        let r = res.map(|v| v.to_string()).join(",");
        let up = if frame == UpAxis::Z { "z" } else { "y" };
        let bake = |out: &Path, b: &str, r: &str| {
            ok(&[
                "bake",
                s(scene),
                "--up",
                up,
                "--bounds",
                b,
                "--res",
                r,
                "--samples",
                "4",
                "--quiet",
                "--sky",
                "0.5,0.5,0.5",
                "-o",
                s(out),
            ]);
        };
        let first = d.join(format!("{up}-1.exr"));
        bake(&first, &b, &r);
        // What `info` and the bake report (the same `FileGrid`) say.
        let info = lightvol_volume::info::describe_file(&first).unwrap();
        let native = read_exr(&first).unwrap();
        let report =
            serde_json::to_value(lightvol_volume::frame::FileGrid::of(native.spec(), frame)).unwrap();
        assert_eq!(info["grid"]["frame"], frame.name());
        assert_eq!(report["frame"], frame.name());
        assert_eq!(info["grid"]["bounds"], report["bounds"]);
        assert_eq!(info["grid"]["res"], report["res"]);
        let got_b: Vec<f64> = report["bounds"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|c| c.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()))
            .collect();
        let got_r: Vec<u32> =
            report["res"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as u32).collect();
        assert_eq!(got_b, bounds.to_vec(), "{up}: reported bounds");
        assert_eq!(got_r, res.to_vec(), "{up}: reported res");
        // Feed the report back: the same grid, the same file.
        let again = d.join(format!("{up}-2.exr"));
        let b2 = got_b.iter().map(f64::to_string).collect::<Vec<_>>().join(",");
        let r2 = got_r.iter().map(u32::to_string).collect::<Vec<_>>().join(",");
        bake(&again, &b2, &r2);
        assert!(
            std::fs::read(&first).unwrap() == std::fs::read(&again).unwrap(),
            "{up}: the reported grid is another grid"
        );
        // Exports record their frame, also when resampled from an adaptive volume.
        let oct = d.join(format!("{up}-oct.exr"));
        ok(&[
            "bake",
            s(scene),
            "--up",
            up,
            "--bounds",
            &b,
            "--res",
            &r,
            "--samples",
            "4",
            "--quiet",
            "--adaptive",
            "--max-level",
            "1",
            "--depth-rays",
            "4",
            "--sky",
            "0.5,0.5,0.5",
            "-o",
            s(&oct),
        ]);
        for v in [&first, &oct] {
            let k = d.join(format!("{up}-{}.ktx2", v.file_stem().unwrap().to_string_lossy()));
            ok(&["export", s(v), "--format", "ktx2", "-o", s(&k)]);
            let bytes = std::fs::read(&k).unwrap();
            let r = ktx2::Reader::new(&bytes[..]).unwrap();
            let (_, json) = r.key_value_data().find(|(key, _)| *key == "lightvol.sidecar").unwrap();
            let sc: serde_json::Value =
                serde_json::from_slice(json.strip_suffix(&[0]).unwrap_or(json)).unwrap();
            assert_eq!(sc["frame"], frame.name(), "{}", k.display());
            assert_eq!(sc["source_frame"], frame.name(), "{}", k.display());
        }
    }
}

/// Every SH texture export (KTX2, DDS, three.js's atlas) of the Y-up glTF room's bake and
/// of its Z-up OBJ twin's reads back through `volume::open` to the native volume: the same
/// grid in the same frame and every node's coefficients within f16 rounding; the sidecar
/// beside it names the grid `info` prints for the native file. (The Bevy export, an
/// ambient cube, is read back by [`bevy_client_reproduces_lightvol_in_both_frames`].)
///
/// Tolerance: the export rotates a Y-up volume's coefficients into the file's axes (an
/// orthogonal map within each band), rounds them to f16 (2^-11 relative) and the reader
/// rotates them back, so each coefficient moves by at most 2^-11 times the norm of its band
/// (per channel), with 1% for the f32 arithmetic of the rotations.
#[test]
fn sh_textures_of_real_bakes_read_back_in_both_frames() {
    const F16_BAND: f64 = 1.01 / 2048.0;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (gltf, obj) = twin_scenes(d);
    for (scene, frame, tag) in [(&gltf, UpAxis::Y, "y"), (&obj, UpAxis::Z, "z")] {
        let case = bake_and_export(d, scene, frame, tag, "rgba16f");
        let native_path = d.join(format!("{tag}.exr"));
        let info = lightvol_volume::info::describe_file(&native_path).unwrap()["grid"].clone();
        for format in ["ktx2", "dds", "three"] {
            let out = d.join(format!("{tag}-{format}.{}", if format == "dds" { "dds" } else { "ktx2" }));
            ok(&["export", s(&native_path), "--format", format, "-o", s(&out)]);
            let lightvol_volume::AnyVolume::Uniform(back) = lightvol_volume::open(&out).unwrap() else {
                panic!("{format}: a uniform grid")
            };
            let native = &case.native;
            assert_eq!(back.spec(), native.spec(), "{tag} {format}");
            assert_eq!(back.metadata().frame, frame, "{tag} {format}");
            let k = native.coeffs();
            for i in 0..native.spec().node_count() {
                let (a, b) = (native.node(i), back.node(i));
                for ch in 0..3 {
                    for band in 0..native.bands() {
                        let js = band * band..(band + 1) * (band + 1);
                        let norm = js.clone().map(|j| f64::from(a[3 * j + ch]).powi(2)).sum::<f64>().sqrt();
                        for j in js.filter(|&j| j < k) {
                            let e = (f64::from(a[3 * j + ch]) - f64::from(b[3 * j + ch])).abs();
                            assert!(
                                e <= F16_BAND * norm + 1e-30,
                                "{tag} {format} node {i} coeff {j}: {a:?} vs {b:?}"
                            );
                        }
                    }
                }
            }
            let side: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(lightvol_volume::io::sidecar::sidecar_path(&out)).unwrap(),
            )
            .unwrap();
            assert_eq!(side["file_grid"]["res"], info["res"], "{tag} {format}");
            assert_eq!(side["file_grid"]["bounds"], info["bounds"], "{tag} {format}");
            assert_eq!(side["file_grid"]["frame"], frame.name(), "{tag} {format}");
            assert_eq!(side["grid"]["to_world"], serde_json::Value::Null, "{tag} {format}: file axes");
            let want_lookup = if format == "three" { "three" } else { "lightvol" };
            assert_eq!(side["lookup"], want_lookup, "{tag} {format}");
            let exported = lightvol_volume::info::describe_file(&out).unwrap()["grid"].clone();
            assert_eq!(exported["res"], info["res"], "{tag} {format}: info of the export");
            assert_eq!(exported["bounds"], info["bounds"], "{tag} {format}: info of the export");
        }
    }
}
