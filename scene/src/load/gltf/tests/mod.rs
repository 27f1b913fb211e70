//! Loader tests on small embedded glTF documents.

use super::*;
use crate::scene::UpAxis;
use container::base64_encode;
use lightvol_core::color::srgb_decode;
use serde_json::json;

/// A minimal embedded glTF: one triangle under a node translated by (0, 0, 5) and
/// rotated, a material with emissive strength, a spot light.
fn gltf_text(double_sided: bool) -> String {
    // Three vertices (0,0,0), (1,0,0), (0,1,0) as f32 little endian, base64.
    let mut bytes = Vec::new();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in v {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    let b64 = base64_encode(&bytes);
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [
  {{"type": "spot", "color": [1, 0.5, 0.25], "intensity": 8, "spot": {{"innerConeAngle": 0.1, "outerConeAngle": 0.5}}}}]}}}},
  "scene": 0,
  "scenes": [{{"nodes": [0, 1]}}],
  "nodes": [
{{"mesh": 0, "translation": [0, 0, 5], "scale": [2, 2, 2]}},
{{"extensions": {{"KHR_lights_punctual": {{"light": 0}}}}, "translation": [0, 3, 0]}}
  ],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "material": 0}}]}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.25, 0.125, 1]}},
             "emissiveFactor": [1, 0.5, 0], "doubleSided": {double_sided},
             "extensions": {{"KHR_materials_emissive_strength": {{"emissiveStrength": 4}}}}}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [0, 0, 0], "max": [1, 1, 0]}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
  "buffers": [{{"byteLength": 36, "uri": "data:application/octet-stream;base64,{b64}"}}]
}}"#
    )
}

#[test]
fn transforms_materials_and_lights() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("t.gltf");
    std::fs::write(&p, gltf_text(true)).unwrap();
    let s = load_gltf(&p, &LoadOptions::default()).unwrap();
    assert_eq!(s.triangles.len(), 1);
    let t = &s.triangles[0];
    // File (0,0,5) + 2·(1,0,0) = (2,0,5) → world (2,-5,0) with +Y-up conversion.
    assert_eq!(t.v[1], DVec3::new(2.0, -5.0, 0.0));
    // File normal +Z → world -Y; winding preserved by the rotation.
    assert!((t.normal() - DVec3::new(0.0, -1.0, 0.0)).length() < 1e-12);
    let m = &s.materials[0];
    assert_eq!(m.albedo, [0.5, 0.25, 0.125]);
    assert_eq!(m.emission, [4.0, 2.0, 0.0]);
    assert!(m.double_sided);
    match s.punctual[..] {
        [PunctualLight::Spot { position, axis, intensity, inner, outer }] => {
            assert_eq!(position, DVec3::new(0.0, 0.0, 3.0));
            // Local -Z (file) → world +Y.
            assert!((axis - DVec3::Y).length() < 1e-12);
            assert_eq!(intensity, [8.0, 4.0, 2.0]);
            assert!((inner - 0.1).abs() < 1e-7 && (outer - 0.5).abs() < 1e-7);
        }
        _ => panic!("expected one spot light: {:?}", s.punctual),
    }
    // +Z-up option leaves coordinates alone.
    let s = load_gltf(&p, &LoadOptions { up: UpAxis::Z, ..Default::default() }).unwrap();
    assert_eq!(s.triangles[0].v[1], DVec3::new(2.0, 0.0, 5.0));
}

#[test]
fn mirrored_node_keeps_front_face() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("m.gltf");
    let text = gltf_text(false).replace(r#""scale": [2, 2, 2]"#, r#""scale": [-1, 1, 1]"#);
    std::fs::write(&p, text).unwrap();
    let s = load_gltf(&p, &LoadOptions { up: UpAxis::Z, ..Default::default() }).unwrap();
    // Mirrored in x: the triangle (0,0),(−1,0),(0,1) keeps facing +Z because the
    // winding is flipped with the determinant.
    assert!((s.triangles[0].normal() - DVec3::Z).length() < 1e-12);
    assert!(!s.materials[0].double_sided);
}

#[test]
fn missing_buffer_is_a_clear_error() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("b.gltf");
    let text = gltf_text(false);
    let start = text.find("data:application").unwrap();
    let end = text[start..].find('"').unwrap() + start;
    std::fs::write(&p, format!("{}missing.bin{}", &text[..start], &text[end..])).unwrap();
    let e = load_gltf(&p, &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, SceneError::Gltf { .. }), "{e}");
    assert!(matches!(
        load_gltf(&d.path().join("none.glb"), &LoadOptions::default()),
        Err(SceneError::NotFound(_))
    ));
}

/// Dangling accessor indices are a clear error, in .gltf and in .glb files.
#[test]
fn dangling_accessor_is_an_error_not_a_panic() {
    let d = tempfile::tempdir().unwrap();
    let json = r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":5}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]}"#;
    let p = d.path().join("dangling.gltf");
    std::fs::write(&p, json).unwrap();
    let e = load_gltf(&p, &LoadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("accessor 5 does not exist"), "{e}");
    // The same JSON as the only chunk of a GLB (padded to 4 bytes with spaces).
    let mut chunk = json.as_bytes().to_vec();
    while !chunk.len().is_multiple_of(4) {
        chunk.push(b' ');
    }
    let mut glb = Vec::new();
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(12 + 8 + chunk.len() as u32).to_le_bytes());
    glb.extend_from_slice(&(chunk.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&chunk);
    let p = d.path().join("dangling.glb");
    std::fs::write(&p, glb).unwrap();
    let e = load_gltf(&p, &LoadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("accessor 5 does not exist"), "{e}");
}

/// baseColorTexture (a PNG in a data URI) is decoded, linearised and sampled at the
/// hit's TEXCOORD_0; a missing image file only warns and keeps the factor.
#[test]
fn base_color_texture_and_missing_image() {
    let mut png = Vec::new();
    let img = image::RgbImage::from_fn(2, 1, |x, _| {
        if x == 0 { image::Rgb([255, 255, 255]) } else { image::Rgb([188, 188, 188]) }
    });
    image::DynamicImage::ImageRgb8(img)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let mut bytes = Vec::new();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in v {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    // UVs: vertex 0 on texel 0's centre, vertices 1 and 2 on texel 1's centre.
    for uv in [[0.25f32, 0.5], [0.75, 0.5], [0.75, 0.5]] {
        for c in uv {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    let text = |uri: &str| {
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "material": 0}}]}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.5, 0.5, 1], "baseColorTexture": {{"index": 0}}}}}}],
  "textures": [{{"source": 0}}], "images": [{{"uri": "{uri}"}}],
  "accessors": [
{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
{{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 24}}],
  "buffers": [{{"byteLength": 60, "uri": "data:application/octet-stream;base64,{}"}}]}}"#,
            base64_encode(&bytes)
        )
    };
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("tex.gltf");
    std::fs::write(&p, text(&format!("data:image/png;base64,{}", base64_encode(&png)))).unwrap();
    let s = load_gltf(&p, &LoadOptions { up: UpAxis::Z, ..Default::default() }).unwrap();
    assert!(s.report.warnings.is_empty(), "{:?}", s.report.warnings);
    assert_eq!(s.textures.len(), 1);
    // White texel × 0.5 at vertex 0; sRGB 188 → linear 0.5029 × 0.5 at vertex 1.
    assert!((s.albedo(0, 0.0, 0.0)[0] - 0.5).abs() < 1e-6);
    let lin = srgb_decode(188.0 / 255.0);
    assert!((s.albedo(0, 1.0, 0.0)[1] - 0.5 * lin).abs() < 1e-6);
    std::fs::write(&p, text("missing.png")).unwrap();
    let s = load_gltf(&p, &LoadOptions::default()).unwrap();
    assert_eq!(s.materials[0].albedo_texture, None);
    assert_eq!(s.albedo(0, 0.3, 0.3), [0.5; 3]);
    assert!(s.report.warnings.iter().any(|w| w.contains("texture")));
}

mod quirks;
