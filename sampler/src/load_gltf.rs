//! glTF 2.0 (`.gltf`, `.glb`) loading: every node of the default scene with its transform,
//! `baseColorFactor` × `baseColorTexture`, `emissiveFactor` ×
//! `KHR_materials_emissive_strength`, `doubleSided`, and `KHR_lights_punctual`.
//!
//! Every node's mesh instance also becomes a lightmap object ([`MeshAttributes`]) with its
//! world-space `NORMAL`, `TANGENT`, `TEXCOORD_0` and `TEXCOORD_1` (for the surface bake,
//! [`crate::surface`]); each scene triangle records its object and vertices
//! ([`Scene::triangle_refs`]).

use std::collections::HashMap;
use std::path::Path;

use glam::{DMat3, DMat4, DVec2, DVec3, DVec4};

use crate::error::SceneError;
use crate::lights::PunctualLight;
use crate::load_obj::LoadOptions;
use crate::scene::{Material, MeshAttributes, Scene, SceneBuilder, TriangleRef};
use crate::texture::{Texture, srgb_to_linear};

/// Checks that every mesh primitive's accessor indices exist, before `gltf` validates the
/// document: gltf-json 1.4 indexes `accessors[POSITION]` unchecked in its validation and
/// panics on a dangling index. Anything that does not parse is left to `gltf` to report.
fn check_accessor_indices(bytes: &[u8]) -> Result<(), String> {
    let json: &[u8] = if bytes.starts_with(b"glTF") {
        match gltf::Glb::from_slice(bytes) {
            Ok(glb) => return check_json(&glb.json),
            Err(_) => return Ok(()),
        }
    } else {
        bytes
    };
    check_json(json)
}

fn check_json(json: &[u8]) -> Result<(), String> {
    let Ok(root) = gltf::json::Root::from_slice(json) else {
        return Ok(());
    };
    let n = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let indices = prim.indices.iter().map(|i| ("indices".to_owned(), i.value()));
            let attributes = prim.attributes.iter().map(|(k, v)| (format!("attribute {k:?}"), v.value()));
            for (what, index) in indices.chain(attributes) {
                if index >= n {
                    return Err(format!(
                        "mesh {m} primitive {p}: {what} refers to accessor {index}, but the file has {n} accessors"
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Loads a glTF 2.0 file. A texture that cannot be read or decoded is a warning; the
/// material then uses its factor. Non-triangle primitives are skipped with a warning.
///
/// # Errors
/// [`SceneError::NotFound`], [`SceneError::Gltf`], [`SceneError::NonFinite`],
/// [`SceneError::Empty`].
pub fn load_gltf(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
    if !path.is_file() {
        return Err(SceneError::NotFound(path.to_owned()));
    }
    let gerr = |e: gltf::Error| SceneError::Gltf { path: path.to_owned(), message: e.to_string() };
    let bytes = std::fs::read(path)
        .map_err(|e| SceneError::Gltf { path: path.to_owned(), message: e.to_string() })?;
    check_accessor_indices(&bytes).map_err(|message| SceneError::Gltf { path: path.to_owned(), message })?;
    let gltf::Gltf { document: doc, blob } = gltf::Gltf::from_slice(&bytes).map_err(gerr)?;
    let base = path.parent();
    let buffers = gltf::import_buffers(&doc, base, blob).map_err(gerr)?;
    let name = path.file_name().map_or_else(|| "gltf".to_owned(), |n| n.to_string_lossy().into_owned());
    let mut b = SceneBuilder::new(&name);

    // Textures: decoded on first use; `None` after a failure (warned once).
    let mut images: HashMap<usize, Option<u32>> = HashMap::new();
    let mut mat_ids: HashMap<Option<usize>, u32> = HashMap::new();
    let Some(scene) = doc.default_scene().or_else(|| doc.scenes().next()) else {
        return Err(SceneError::Empty(name));
    };
    let root = DMat4::from_cols(
        opts.up.to_world(DVec3::X).extend(0.0) * opts.scale,
        opts.up.to_world(DVec3::Y).extend(0.0) * opts.scale,
        opts.up.to_world(DVec3::Z).extend(0.0) * opts.scale,
        DVec4::W,
    );
    let mut stack: Vec<(gltf::Node<'_>, DMat4)> = scene.nodes().map(|n| (n, root)).collect();
    let mut object_names: HashMap<String, usize> = HashMap::new();
    while let Some((node, parent)) = stack.pop() {
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        for child in node.children() {
            stack.push((child, world));
        }
        if let Some(light) = node.light() {
            add_light(&mut b, &light, &world, opts.scale);
        }
        let Some(mesh) = node.mesh() else { continue };
        // A mirroring transform flips the winding (glTF 2.0 §3.7.4).
        let flip = world.determinant() < 0.0;
        let linear = DMat3::from_mat4(world);
        // Normals transform with the inverse transpose; tangents with the matrix, and their
        // handedness flips with a mirroring transform (the bitangent is w · n × t).
        let normal_matrix = if linear.determinant() != 0.0 { linear.inverse().transpose() } else { linear };
        let base_name = mesh.name().map_or_else(|| format!("mesh{}", mesh.index()), str::to_owned);
        let seen = object_names.entry(base_name.clone()).or_insert(0);
        *seen += 1;
        let object_name = if *seen == 1 { base_name } else { format!("{base_name}#{seen}") };
        let mut attrs = MeshAttributes { name: object_name, ..MeshAttributes::default() };
        let (mut normals, mut tangents, mut uv0, mut uv1) =
            (Some(Vec::new()), Some(Vec::new()), Some(Vec::new()), Some(Vec::new()));
        // Faces of all primitives: object vertex ids, positions, base UVs, material.
        let mut faces: Vec<Face> = Vec::new();
        for prim in mesh.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                b.warn(format!(
                    "mesh '{}': primitive mode {:?} skipped",
                    mesh.name().unwrap_or("?"),
                    prim.mode()
                ));
                continue;
            }
            let gm = prim.material();
            let key = gm.index();
            let mat = match mat_ids.get(&key) {
                Some(&m) => m,
                None => {
                    let m = convert_material(&mut b, &gm, &buffers, base, &mut images, opts)?;
                    mat_ids.insert(key, m);
                    m
                }
            };
            let tex_set = gm.pbr_metallic_roughness().base_color_texture().map_or(0, |t| t.tex_coord());
            let reader = prim.reader(|buf| buffers.get(buf.index()).map(|d| &d.0[..]));
            let Some(positions) = reader.read_positions() else { continue };
            let positions: Vec<DVec3> =
                positions.map(|p| world.transform_point3(DVec3::from_array(p.map(f64::from)))).collect();
            let uvs: Vec<DVec2> = reader
                .read_tex_coords(tex_set)
                .map(|t| t.into_f32().map(|q| DVec2::new(f64::from(q[0]), f64::from(q[1]))).collect())
                .unwrap_or_default();
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            let base_vertex = attrs.positions.len();
            let nv = positions.len();
            attrs.positions.extend_from_slice(&positions);
            let read_set = |set: u32| -> Option<Vec<DVec2>> {
                reader
                    .read_tex_coords(set)
                    .map(|t| t.into_f32().map(|q| DVec2::new(f64::from(q[0]), f64::from(q[1]))).collect())
            };
            extend_or_drop(&mut uv0, read_set(0), nv);
            extend_or_drop(&mut uv1, read_set(1), nv);
            extend_or_drop(
                &mut normals,
                reader.read_normals().map(|it| {
                    it.map(|q| (normal_matrix * DVec3::from_array(q.map(f64::from))).normalize_or_zero())
                        .collect()
                }),
                nv,
            );
            let handed = if flip { -1.0 } else { 1.0 };
            extend_or_drop(
                &mut tangents,
                reader.read_tangents().map(|it| {
                    it.map(|q| {
                        let t = (linear * DVec3::new(f64::from(q[0]), f64::from(q[1]), f64::from(q[2])))
                            .normalize_or_zero();
                        t.extend(if q[3] < 0.0 { -handed } else { handed })
                    })
                    .collect()
                }),
                nv,
            );
            for (f, tri) in indices.chunks_exact(3).enumerate() {
                let mut ids = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
                if flip {
                    ids.swap(1, 2);
                }
                if ids.iter().any(|&i| i >= positions.len()) {
                    return Err(SceneError::Gltf {
                        path: path.to_owned(),
                        message: format!("index out of range in face {f}"),
                    });
                }
                let v = ids.map(|i| positions[i]);
                if !v.iter().all(|p| p.is_finite()) {
                    return Err(SceneError::NonFinite {
                        what: format!(
                            "vertex of face {f} in mesh '{}' of {name}",
                            mesh.name().unwrap_or("?")
                        ),
                    });
                }
                let uv = ids.map(|i| uvs.get(i).copied().unwrap_or(DVec2::ZERO));
                faces.push((ids.map(|i| i + base_vertex), v, uv, mat));
            }
        }
        attrs.normals = normals;
        attrs.tangents = tangents;
        attrs.uv0 = uv0;
        attrs.uv1 = uv1;
        let object = b.add_mesh(attrs);
        for (face, (ids, v, uv, mat)) in faces.into_iter().enumerate() {
            let r = TriangleRef { mesh: object, face: face as u32, vertices: ids.map(|i| i as u32) };
            b.add_mesh_triangle(v, uv, mat, r)?;
        }
    }
    b.build()
}

/// One face while an object is assembled: object vertex ids, positions, base UVs, material.
type Face = ([usize; 3], [DVec3; 3], [DVec2; 3], u32);

/// Appends a primitive's attribute array to the object's, or drops the object's array when
/// this primitive lacks the attribute (or has the wrong count): a set is present for an
/// object only when every primitive has it.
fn extend_or_drop<T>(acc: &mut Option<Vec<T>>, part: Option<Vec<T>>, vertices: usize) {
    match (acc.as_mut(), part) {
        (Some(a), Some(p)) if p.len() == vertices => a.extend(p),
        _ => *acc = None,
    }
}

fn convert_material(
    b: &mut SceneBuilder,
    gm: &gltf::Material<'_>,
    buffers: &[gltf::buffer::Data],
    base: Option<&Path>,
    images: &mut HashMap<usize, Option<u32>>,
    opts: &LoadOptions,
) -> Result<u32, SceneError> {
    let pbr = gm.pbr_metallic_roughness();
    let f = pbr.base_color_factor();
    let name = gm.name().unwrap_or("default");
    let mut m = Material::diffuse(name, [f[0], f[1], f[2]].map(f64::from));
    let strength = f64::from(gm.emissive_strength().unwrap_or(1.0));
    m.emission = gm.emissive_factor().map(|e| f64::from(e) * strength);
    m.double_sided = gm.double_sided() || opts.force_double_sided;
    if gm.emissive_texture().is_some() {
        b.warn(format!("material '{name}': emissive texture ignored, using emissiveFactor"));
    }
    if let Some(info) = pbr.base_color_texture() {
        let img = info.texture().source();
        let idx = img.index();
        let id = match images.get(&idx) {
            Some(id) => *id,
            None => {
                let id = match gltf::image::Data::from_source(img.source(), base, buffers) {
                    Ok(data) => match texture_from_gltf(&data) {
                        Some(t) => Some(b.add_texture(t)),
                        None => {
                            b.warn(format!(
                                "material '{name}': texture format {:?} unsupported; using factor",
                                data.format
                            ));
                            None
                        }
                    },
                    Err(e) => {
                        b.warn(format!("material '{name}': texture {idx} not loaded ({e}); using factor"));
                        None
                    }
                };
                images.insert(idx, id);
                id
            }
        };
        m.albedo_texture = id;
    }
    b.add_material(m)
}

/// Converts decoded glTF image data (sRGB for base colour, glTF 2.0 §3.9.2) to linear RGB.
fn texture_from_gltf(d: &gltf::image::Data) -> Option<Texture> {
    use gltf::image::Format;
    let (ch, bytes) = match d.format {
        Format::R8 => (1, 1),
        Format::R8G8 => (2, 1),
        Format::R8G8B8 => (3, 1),
        Format::R8G8B8A8 => (4, 1),
        Format::R16 => (1, 2),
        Format::R16G16 => (2, 2),
        Format::R16G16B16 => (3, 2),
        Format::R16G16B16A16 => (4, 2),
        _ => return None,
    };
    let stride = ch * bytes;
    let n = d.width as usize * d.height as usize;
    if d.pixels.len() < n * stride {
        return None;
    }
    let read = |i: usize, c: usize| -> f64 {
        let c = c.min(ch - 1).min(2);
        let o = i * stride + c * bytes;
        if bytes == 1 {
            f64::from(d.pixels[o]) / 255.0
        } else {
            f64::from(u16::from_le_bytes([d.pixels[o], d.pixels[o + 1]])) / 65535.0
        }
    };
    let texels = (0..n)
        .map(|i| {
            if ch == 2 {
                // Luminance + alpha: grey.
                let g = srgb_to_linear(read(i, 0)) as f32;
                [g; 3]
            } else {
                [0, 1, 2].map(|c| srgb_to_linear(read(i, c)) as f32)
            }
        })
        .collect();
    Texture::from_linear(d.width, d.height, texels)
}

fn add_light(b: &mut SceneBuilder, light: &gltf::khr_lights_punctual::Light<'_>, world: &DMat4, scale: f64) {
    use gltf::khr_lights_punctual::Kind;
    let color = light.color().map(f64::from);
    let i = f64::from(light.intensity());
    let position = world.transform_point3(DVec3::ZERO);
    // Lights shine along local -Z.
    let axis = world.transform_vector3(-DVec3::Z).normalize_or_zero();
    // Intensity is per steradian in metres; positions were scaled by `scale`, so W/sr at a
    // distance scaled by `scale` falls off by scale²: keep irradiance invariant.
    let s2 = scale * scale;
    let l = match light.kind() {
        Kind::Point => PunctualLight::Point { position, intensity: color.map(|c| c * i * s2) },
        Kind::Spot { inner_cone_angle, outer_cone_angle } => PunctualLight::Spot {
            position,
            axis,
            intensity: color.map(|c| c * i * s2),
            inner: f64::from(inner_cone_angle),
            outer: f64::from(outer_cone_angle),
        },
        Kind::Directional => PunctualLight::Directional { to_light: -axis, irradiance: color.map(|c| c * i) },
    };
    if light.range().is_some() {
        b.warn(format!(
            "light '{}': range ignored (physical inverse-square falloff)",
            light.name().unwrap_or("?")
        ));
    }
    b.punctual.push(l);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::UpAxis;

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

    fn base64_encode(data: &[u8]) -> String {
        const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut out = String::new();
        for c in data.chunks(3) {
            let n = (u32::from(c[0]) << 16)
                | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
                | u32::from(*c.get(2).unwrap_or(&0));
            for k in 0..4 {
                if k <= c.len() {
                    out.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
                } else {
                    out.push('=');
                }
            }
        }
        out
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

    /// Dangling accessor indices (which make gltf-json 1.4's validation index out of
    /// bounds and panic) are a clear error, in .gltf and in .glb files.
    #[test]
    fn dangling_accessor_is_an_error_not_a_panic() {
        let d = tempfile::tempdir().unwrap();
        let json = r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":5}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]}"#;
        let p = d.path().join("dangling.gltf");
        std::fs::write(&p, json).unwrap();
        let e = load_gltf(&p, &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("refers to accessor 5"), "{e}");
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
        assert!(e.to_string().contains("refers to accessor 5"), "{e}");
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
        let lin = srgb_to_linear(188.0 / 255.0);
        assert!((s.albedo(0, 1.0, 0.0)[1] - 0.5 * lin).abs() < 1e-6);
        std::fs::write(&p, text("missing.png")).unwrap();
        let s = load_gltf(&p, &LoadOptions::default()).unwrap();
        assert_eq!(s.materials[0].albedo_texture, None);
        assert_eq!(s.albedo(0, 0.3, 0.3), [0.5; 3]);
        assert!(s.report.warnings.iter().any(|w| w.contains("texture")));
    }
}
