//! `lightvol render` shades with the glTF's interpolated vertex normals, as engines and
//! Cycles do, not with the face normals: a floor whose vertex normals lean 36.87° towards
//! +x, seen from above, under a field whose irradiance depends on the normal's x, shows the
//! irradiance for the leaning normal (with the face normal it would show the field's
//! constant part alone).

mod common;

use common::{ok, s};
use lightvol_scene::load::gltf::base64_encode;
use lightvol_volume::io::exr::{ExrOptions, write_exr};
use lightvol_volume::up_axis::UpAxis;
use lightvol_volume::{BakeMetadata, GridSpec, IrradianceVolume};

/// Y_00 and the l = 1 constant of the real SH basis (sqrt(1/4π), sqrt(3/4π)).
const Y00: f64 = 0.282_094_791_773_878_1;
const Y1: f64 = 0.488_602_511_902_919_9;

/// A 2 m floor at y = 0 (+Y up), facing +y, every vertex normal `n`.
fn floor_gltf(path: &std::path::Path, n: [f32; 3]) {
    let pos: [[f32; 3]; 4] = [[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]];
    let idx: [u16; 6] = [0, 2, 1, 0, 3, 2];
    let mut buf: Vec<u8> = pos.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    buf.extend([n; 4].iter().flatten().flat_map(|v| v.to_le_bytes()));
    buf.extend(idx.iter().flat_map(|v| v.to_le_bytes()));
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":2}}]}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,0,-1],"max":[1,0,1]}},
{{"bufferView":1,"componentType":5126,"count":4,"type":"VEC3"}},{{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":48}},{{"buffer":0,"byteOffset":96,"byteLength":12}}],
"buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        buf.len(),
        base64_encode(&buf)
    );
    std::fs::write(path, json).unwrap();
}

#[test]
fn render_shades_with_the_vertex_normals() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("floor.gltf");
    let lean = [0.6f32, 0.8, 0.0];
    floor_gltf(&scene, lean);
    // A constant field (internal frame, +Z up): E(n) = π Y00 c0 + (2π/3) Y1 c_x n_x with the
    // x-aligned coefficient (index 3) c_x; file x is internal x.
    let (c0, cx) = (1.0, 0.5);
    let spec = GridSpec::new([-1.5, -1.5, -0.5], [1.5, 1.5, 1.5], [3, 3, 3]).unwrap();
    let vol = IrradianceVolume::from_fn(spec, 4, |_| vec![[c0; 3], [0.0; 3], [0.0; 3], [cx; 3]]).unwrap();
    let meta = BakeMetadata { frame: UpAxis::Y, ..vol.metadata().clone() };
    let vol_path = dir.path().join("field.exr");
    write_exr(&vol_path, &vol.with_metadata(meta), &ExrOptions::default()).unwrap();
    let out = dir.path().join("view.exr");
    ok(&[
        "render",
        s(&scene),
        "--volume",
        s(&vol_path),
        "--quantity",
        "irradiance",
        "--camera",
        "0,3,0.3:0,0,0:30",
        "--width",
        "9",
        "--height",
        "9",
        "--quiet",
        "-o",
        s(&out),
    ]);
    let img = exr::prelude::read_all_flat_layers_from_file(&out).unwrap();
    let red = img.layer_data[0].channel_data.list.iter().find(|c| c.name.to_string() == "R").unwrap();
    let centre = f64::from(red.sample_data.values_as_f32().nth(4 * 9 + 4).unwrap());
    let pi = std::f64::consts::PI;
    let want = pi * Y00 * c0 + 2.0 * pi / 3.0 * Y1 * cx * f64::from(lean[0]);
    let face = pi * Y00 * c0;
    // f32 coefficients and pixels: 1e-6 relative.
    assert!(
        (centre - want).abs() <= 1e-6 * want,
        "centre {centre}, vertex normals give {want}, the face normal {face}"
    );
}
