//! One small synthetic file per quirk of real exports.

use super::*;

/// Builds a glTF document around one binary buffer (embedded as a data URI).
#[derive(Default)]
struct Doc {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Doc {
    /// Appends raw bytes as a buffer view (4-byte aligned), returning its index.
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let off = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.views.push(json!({"buffer": 0, "byteOffset": off, "byteLength": bytes.len()}));
        self.views.len() - 1
    }

    fn accessor(&mut self, a: Value) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// f32 accessor of `ty` with the given values.
    fn f32s(&mut self, ty: &str, v: &[f32]) -> usize {
        let n = match ty {
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            _ => 1,
        };
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessor(json!({"bufferView": view, "componentType": 5126, "count": v.len() / n, "type": ty}))
    }

    /// The document with `rest` merged into the root.
    fn json(&self, rest: Value) -> String {
        let mut root = json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": self.bin.len(), "uri": format!("data:application/octet-stream;base64,{}", base64_encode(&self.bin))}],
            "bufferViews": self.views,
            "accessors": self.accessors,
        });
        for (k, v) in rest.as_object().unwrap() {
            root[k] = v.clone();
        }
        root.to_string()
    }
}

fn png_rgba(w: u32, h: u32, px: impl Fn(u32, u32) -> [u8; 4]) -> Vec<u8> {
    let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(px(x, y)));
    let mut png = Vec::new();
    image::DynamicImage::ImageRgba8(img)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png
}

const Z_UP: LoadOptions =
    LoadOptions { up: UpAxis::Z, scale: 1.0, force_double_sided: false, flatten_instances: false };

fn load_str(text: &str) -> Result<Scene, SceneError> {
    load_gltf_slice(text.as_bytes(), None, "synthetic.gltf", &Z_UP)
}

/// A unit quad in z = 0 (two triangles, facing +Z) with UVs u = x, v = y.
fn quad(d: &mut Doc) -> (usize, usize) {
    let pos = d.f32s("VEC3", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0]);
    let uv = d.f32s("VEC2", &[0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0]);
    assert_eq!(uv, 1, "quad_mesh callers pass accessor 1 as TEXCOORD_0");
    let idx: Vec<u8> = [0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()).collect();
    let view = d.view(&idx);
    let ind = d.accessor(json!({"bufferView": view, "componentType": 5123, "count": 6, "type": "SCALAR"}));
    (pos, ind)
}

fn quad_mesh(pos: usize, ind: usize, uv: usize, material: Value) -> Value {
    let mut prim = json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "indices": ind});
    if !material.is_null() {
        prim["material"] = material;
    }
    json!([{"name": "quad", "primitives": [prim]}])
}

/// A texture with no `source` (its only image comes through `MSFT_texture_dds`) loads the
/// geometry, keeps the factor, and warns once for the material, naming it and the reason.
#[test]
fn texture_without_source_uses_the_factor() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let text = d.json(json!({
        "extensionsUsed": ["MSFT_texture_dds"],
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}],
        "meshes": quad_mesh(pos, ind, 1, 0.into()),
        "materials": [{"name": "banner", "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.4, 0.5, 1], "baseColorTexture": {"index": 0}}}],
        "textures": [{"extensions": {"MSFT_texture_dds": {"source": 0}}}],
        "images": [{"uri": "banner.dds", "mimeType": "image/vnd-ms.dds"}]
    }));
    let s = load_str(&text).unwrap();
    assert_eq!(s.triangles.len(), 2);
    assert_eq!(s.materials[0].albedo_texture, None);
    assert_eq!(s.albedo(0, 0.2, 0.2), [0.3, 0.4, 0.5]);
    let w: Vec<_> = s.report.warnings.iter().filter(|w| w.contains("banner")).collect();
    assert_eq!(w.len(), 1, "{:?}", s.report.warnings);
    assert!(w[0].contains("no PNG/JPEG source, only MSFT_texture_dds"), "{}", w[0]);
}

/// A DDS-only image cannot be decoded: factor and a warning. A texture whose core source is
/// a PNG beside a DDS alternative uses the PNG (the Breakfast Room's layout).
#[test]
fn dds_only_image_uses_the_factor_and_core_png_is_preferred() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let dds = format!("data:image/vnd-ms.dds;base64,{}", base64_encode(b"DDS \x7c\0\0\0\x07\x10\0\0"));
    let png = format!("data:image/png;base64,{}", base64_encode(&png_rgba(1, 1, |_, _| [255, 0, 0, 255])));
    let text = d.json(json!({
        "nodes": [{"mesh": 0}, {"mesh": 1}], "scenes": [{"nodes": [0, 1]}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": 1}, "indices": ind, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": 1}, "indices": ind, "material": 1}]}],
        "materials": [
            {"name": "dds_only", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "baseColorTexture": {"index": 0}}},
            {"name": "png_and_dds", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}}],
        "textures": [{"source": 0}, {"source": 1, "extensions": {"MSFT_texture_dds": {"source": 0}}}],
        "images": [{"uri": dds}, {"uri": png}]
    }));
    let s = load_str(&text).unwrap();
    assert_eq!(s.triangles.len(), 4);
    assert_eq!(s.materials[0].albedo_texture, None);
    assert!(
        s.report.warnings.iter().any(|w| w.contains("dds_only") && w.contains("is DDS")),
        "{:?}",
        s.report.warnings
    );
    // The PNG is pure red: linear (1, 0, 0).
    assert!(s.materials[1].albedo_texture.is_some());
    assert_eq!(s.albedo(2, 0.3, 0.3), [1.0, 0.0, 0.0]);
    assert!(!s.report.warnings.iter().any(|w| w.contains("png_and_dds")));
}

/// A required extension that only materials use warns and loads; one that a primitive uses
/// is a one-line error naming the extension and the primitive.
#[test]
fn required_extensions_by_location() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let text = d.json(json!({
        "extensionsUsed": ["AMD_split_roughnessMetallic"], "extensionsRequired": ["AMD_split_roughnessMetallic"],
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}],
        "meshes": quad_mesh(pos, ind, 1, 0.into()),
        "materials": [{"name": "m", "extensions": {"AMD_split_roughnessMetallic": {"roughnessTexture": {"index": 0}}}}]
    }));
    let s = load_str(&text).unwrap();
    assert_eq!(s.triangles.len(), 2);
    assert!(s.report.warnings.contains(
        &"AMD_split_roughnessMetallic: material extension not supported, core material used".to_owned()
    ));
    let e = &s.report.extensions[0];
    assert!(e.required && e.used_in == ["materials"], "{e:?}");
    let text = d.json(json!({
        "extensionsUsed": ["KHR_draco_mesh_compression"], "extensionsRequired": ["KHR_draco_mesh_compression"],
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}],
        "meshes": [{"name": "statue", "primitives": [{"attributes": {"POSITION": pos}, "indices": ind,
            "extensions": {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}}]}]
    }));
    let e = load_str(&text).unwrap_err().to_string();
    assert_eq!(
        e,
        "glTF error in synthetic.gltf: KHR_draco_mesh_compression (required) on mesh 'statue' primitive 0: geometry extension not supported; export without it"
    );
}

/// `KHR_mesh_quantization`: normalized i16 positions under a node scale, and plain u8
/// positions, give the exact coordinates; normalized i8 normals are unit after transform.
#[test]
fn quantized_positions_and_normals() {
    let mut d = Doc::default();
    let q: Vec<u8> = [0i16, 0, 0, 32767, 0, 0, 0, 32767, 0].iter().flat_map(|v| v.to_le_bytes()).collect();
    let v16 = d.view(&q);
    let p16 = d.accessor(
        json!({"bufferView": v16, "componentType": 5122, "normalized": true, "count": 3, "type": "VEC3"}),
    );
    // u8 positions, 4-byte stride (padding byte per vertex), not normalized.
    let v8 = d.view(&[0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0]);
    d.views[v8]["byteStride"] = 4.into();
    let p8 = d.accessor(json!({"bufferView": v8, "componentType": 5121, "count": 3, "type": "VEC3"}));
    let vn = d.view(&[0, 0, 127, 0, 0, 0, 127, 0, 0, 0, 127, 0]);
    d.views[vn]["byteStride"] = 4.into();
    let n8 = d.accessor(
        json!({"bufferView": vn, "componentType": 5120, "normalized": true, "count": 3, "type": "VEC3"}),
    );
    let text = d.json(json!({
        "extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"],
        "nodes": [{"mesh": 0, "scale": [4, 4, 4]}, {"mesh": 1, "translation": [0, 0, 1]}], "scenes": [{"nodes": [0, 1]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": p16, "NORMAL": n8}}]}, {"primitives": [{"attributes": {"POSITION": p8}}]}]
    }));
    let s = load_str(&text).unwrap();
    assert!(s.report.warnings.iter().all(|w| w.contains("no material")), "{:?}", s.report.warnings);
    assert_eq!(s.triangles.len(), 2);
    assert_eq!(s.triangles[0].v, [DVec3::ZERO, DVec3::new(4.0, 0.0, 0.0), DVec3::new(0.0, 4.0, 0.0)]);
    assert_eq!(
        s.triangles[1].v,
        [DVec3::new(0.0, 0.0, 1.0), DVec3::new(2.0, 0.0, 1.0), DVec3::new(0.0, 2.0, 1.0)]
    );
    let n = s.meshes[0].normals.as_ref().unwrap();
    assert!(n.iter().all(|n| (*n - DVec3::Z).length() < 1e-15), "{n:?}");
    assert_eq!(s.report.extensions[0].treatment, "supported");
}

/// Shading normals: the file's vertex normals blended with the hit's barycentrics and
/// normalised (what engines shade with); none for a mesh without `NORMAL`.
#[test]
fn shading_normals_interpolate_the_vertex_normals() {
    let mut d = Doc::default();
    let f32s = |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
    let vp = d.view(&f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]));
    let pos = d.accessor(json!({"bufferView": vp, "componentType": 5126, "count": 3, "type": "VEC3",
        "min": [0, 0, 0], "max": [1, 1, 0]}));
    let vn = d.view(&f32s(&[0.0, 0.0, 1.0, 0.6, 0.0, 0.8, 0.0, 0.6, 0.8]));
    let nrm = d.accessor(json!({"bufferView": vn, "componentType": 5126, "count": 3, "type": "VEC3"}));
    let text = d.json(json!({
        "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [0, 0, 1]}], "scenes": [{"nodes": [0, 1]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm}}]},
                   {"primitives": [{"attributes": {"POSITION": pos}}]}]
    }));
    let s = load_str(&text).unwrap();
    // f32 normals of unit length to 1e-7; the blend and its normalisation in f64.
    const TOL: f64 = 1e-6;
    let at_vertex = s.shading_normal(0, 1.0, 0.0).unwrap();
    assert!((at_vertex - DVec3::new(0.6, 0.0, 0.8)).length() < TOL, "{at_vertex}");
    let centre = s.shading_normal(0, 1.0 / 3.0, 1.0 / 3.0).unwrap();
    assert!((centre - DVec3::new(0.6, 0.6, 2.6).normalize()).length() < TOL, "{centre}");
    assert_eq!(s.shading_normal(1, 0.2, 0.2), None);
}

/// `KHR_texture_transform` on the base colour: an offset of half the texture width moves
/// every lookup onto the other texel.
#[test]
fn texture_transform_moves_the_lookup() {
    let png = format!(
        "data:image/png;base64,{}",
        base64_encode(&png_rgba(2, 1, |x, _| if x == 0 { [255, 255, 255, 255] } else { [0, 0, 0, 255] }))
    );
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let mk = |ext: Value| {
        d.json(json!({
            "extensionsUsed": ["KHR_texture_transform"],
            "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}],
            "meshes": quad_mesh(pos, ind, 1, 0.into()),
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": ext}}}],
            "textures": [{"source": 0, "sampler": 0}], "samplers": [{"wrapS": 33071, "wrapT": 33071}],
            "images": [{"uri": png}]
        }))
    };
    // Vertex 0 of triangle 0 has uv (0, 0), inside the white texel (clamped).
    let plain = load_str(&mk(json!({}))).unwrap();
    assert_eq!(plain.albedo(0, 0.0, 0.0), [1.0; 3]);
    let moved = load_str(&mk(json!({"KHR_texture_transform": {"offset": [0.75, 0.0]}}))).unwrap();
    assert_eq!(moved.triangles[0].uv[0], DVec2::new(0.75, 0.0));
    assert_eq!(moved.albedo(0, 0.0, 0.0), [0.0; 3]);
    // The lightmap UVs stay untransformed.
    assert_eq!(moved.meshes[0].uv0.as_ref().unwrap()[0], DVec2::ZERO);
}

/// `EXT_mesh_gpu_instancing`: each instance places the mesh at node × instance TRS; the
/// mesh's triangles are stored once, as a prototype. Flattened, each instance is an object
/// with its own triangles, numbered as the instanced scene numbers them.
#[test]
fn gpu_instancing_places_every_instance() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let t = d.f32s("VEC3", &[0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 0.0, 10.0, 0.0]);
    // Rotation: identity, identity, a half turn about Z (quaternion (0, 0, 1, 0)).
    let r = d.f32s("VEC4", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0]);
    let text = d.json(json!({
        "extensionsUsed": ["EXT_mesh_gpu_instancing"],
        "nodes": [{"mesh": 0, "translation": [0, 0, 5], "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": t, "ROTATION": r}}}}],
        "scenes": [{"nodes": [0]}],
        "meshes": quad_mesh(pos, ind, 1, Value::Null)
    }));
    let s = load_str(&text).unwrap();
    assert_eq!((s.triangles.len(), s.prototypes.len(), s.instances.len()), (0, 1, 3));
    assert_eq!((s.triangle_count(), s.unique_triangle_count()), (6, 2));
    assert!(s.meshes.is_empty());
    assert_eq!((s.report.unique_triangles, s.report.instances), (2, 3));
    assert_eq!(s.triangle(2).v[1], DVec3::new(11.0, 0.0, 5.0));
    // The half turn maps (1, 0) to (-1, 0) around the instance's origin (0, 10, 5).
    assert!((s.triangle(4).v[1] - DVec3::new(-1.0, 10.0, 5.0)).length() < 1e-12, "{}", s.triangle(4).v[1]);
    assert_eq!(s.instances[2].bounds.0, DVec3::new(-1.0, 9.0, 5.0));

    let flat = load_gltf_slice(
        text.as_bytes(),
        None,
        "synthetic.gltf",
        &LoadOptions { flatten_instances: true, ..Z_UP },
    )
    .unwrap();
    assert_eq!((flat.triangles.len(), flat.instances.len()), (6, 0));
    assert_eq!(flat.meshes.len(), 3);
    assert_eq!((flat.report.unique_triangles, flat.report.instances), (2, 3));
    assert_eq!(flat.meshes.iter().map(|m| m.name.as_str()).collect::<Vec<_>>(), ["quad", "quad#2", "quad#3"]);
    for i in 0..6 {
        let (a, b) = (s.triangle(i), flat.triangles[i as usize]);
        assert_eq!(a.uv, b.uv);
        for k in 0..3 {
            // The same transform applied as an affine map instead of a 4x4 matrix.
            assert!((a.v[k] - b.v[k]).length() < 1e-12, "{i}: {a:?} {b:?}");
        }
    }
}

/// Instances come from stored data: an instancing accessor without a bufferView (zeros,
/// but for its sparse entries) is an error rather than that many coincident copies of the
/// mesh. 1000 such instances of the living room's largest mesh used to take 488 MiB.
#[test]
fn gpu_instancing_needs_stored_instances() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let zeros = d.accessor(json!({"componentType": 5126, "count": 1000, "type": "VEC3"}));
    let text = d.json(json!({
        "nodes": [{"mesh": 0, "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": zeros}}}}],
        "scenes": [{"nodes": [0]}],
        "meshes": quad_mesh(pos, ind, 1, Value::Null)
    }));
    let e = load_str(&text).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "glTF error in synthetic.gltf: node 0 EXT_mesh_gpu_instancing TRANSLATION: accessor {zeros} stores 0 of its 1000 instances (no bufferView)"
        )
    );
    // Fully sparse (every instance stored) is fine.
    let sidx = d.view(&[0, 1]);
    let sval =
        d.view(&[1.0f32, 0.0, 0.0, 2.0, 0.0, 0.0].iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>());
    let sparse = d.accessor(json!({"componentType": 5126, "count": 2, "type": "VEC3",
        "sparse": {"count": 2, "indices": {"bufferView": sidx, "componentType": 5121}, "values": {"bufferView": sval}}}));
    let text = d.json(json!({
        "nodes": [{"mesh": 0, "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": sparse}}}}],
        "scenes": [{"nodes": [0]}],
        "meshes": quad_mesh(pos, ind, 1, Value::Null)
    }));
    let s = load_str(&text).unwrap();
    assert_eq!((s.report.instances, s.triangle(2).v[0]), (2, DVec3::new(2.0, 0.0, 0.0)));
}

/// Zeros of accessors without a bufferView are budgeted for the whole load, not per
/// accessor: every primitive that refers to one allocates its values again, so 1000
/// primitives sharing a 2^20-value one used to take gigabytes from a few KB of JSON.
#[test]
fn unstored_zeros_are_budgeted_per_load() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let zeros = d.accessor(json!({"componentType": 5126, "count": 200_000, "type": "VEC3"}));
    let prim = |normal: usize| json!({"attributes": {"POSITION": pos, "NORMAL": normal}, "indices": ind});
    let doc = |prims: Vec<Value>| {
        d.json(json!({"nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "meshes": [{"primitives": prims}]}))
    };
    // One reference (600000 values) is within the budget (the normals, of the wrong count, are dropped) ...
    let s = load_str(&doc(vec![prim(zeros)])).unwrap();
    assert_eq!(s.triangles.len(), 2);
    // ... a second one is not.
    let e = load_str(&doc(vec![prim(zeros), prim(zeros)])).unwrap_err().to_string();
    assert!(e.ends_with(&format!("primitive 1: accessor {zeros}: accessors without a bufferView come to 1200000 values, more than the reader's limit of 1048576 for data the file does not store")), "{e}");
}

/// Sparse accessors substitute values; non-indexed primitives and triangle strips and fans
/// are triangulated as glTF 2.0 §3.7.2.1 says.
#[test]
fn sparse_non_indexed_strips_and_fans() {
    let mut d = Doc::default();
    let base = d.f32s("VEC3", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0]);
    let sidx = d.view(&[3]);
    let sval = d.view(&[2.0f32, 2.0, 0.0].iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>());
    let mut sparse = d.accessors[base].clone();
    sparse["sparse"] = json!({"count": 1, "indices": {"bufferView": sidx, "componentType": 5121}, "values": {"bufferView": sval}});
    let sp = d.accessor(sparse);
    let text = d.json(json!({
        "nodes": [{"mesh": 0}, {"mesh": 1}, {"mesh": 2}], "scenes": [{"nodes": [0, 1, 2]}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": sp}, "mode": 5}]},
            {"primitives": [{"attributes": {"POSITION": base}, "mode": 6}]},
            {"primitives": [{"attributes": {"POSITION": base}, "mode": 1}]}]
    }));
    let s = load_str(&text).unwrap();
    // Strip of 4 vertices: (0,1,2) and (2,1,3) reordered to keep the winding; the sparse
    // value moved vertex 3 to (2, 2, 0).
    assert_eq!(s.triangles.len(), 4);
    assert_eq!(
        s.triangles[1].v,
        [DVec3::new(0.0, 1.0, 0.0), DVec3::new(1.0, 0.0, 0.0), DVec3::new(2.0, 2.0, 0.0)]
    );
    assert!(s.triangles[..2].iter().all(|t| t.normal().z > 0.0), "strip winding");
    // Fan: (0, 1, 2), (0, 2, 3).
    assert_eq!(s.triangles[3].v, [DVec3::ZERO, DVec3::new(0.0, 1.0, 0.0), DVec3::new(1.0, 1.0, 0.0)]);
    assert!(s.report.warnings.iter().any(|w| w.contains("mode 1")), "{:?}", s.report.warnings);
}

/// The alpha test in every ray query: a leaf quad whose left half is transparent (alpha 0)
/// and right half opaque, `MASK` with cutoff 0.5. A ray through the left half reaches the
/// floor below (closest hit), is not shadowed (occlusion), and sees no back face of the leaf
/// from below; the same quad `OPAQUE` blocks it.
#[test]
fn mask_leaf_lets_light_through_masked_texels() {
    let png = format!(
        "data:image/png;base64,{}",
        base64_encode(&png_rgba(2, 1, |x, _| [40, 160, 40, if x == 0 { 0 } else { 255 }]))
    );
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let mk = |mode: &str| {
        d.json(json!({
            "nodes": [{"mesh": 0, "translation": [0, 0, 1]}, {"mesh": 1, "scale": [4, 4, 1], "translation": [-1, -1, 0]}],
            "scenes": [{"nodes": [0, 1]}],
            "meshes": [quad_mesh(pos, ind, 1, 0.into())[0].clone(), quad_mesh(pos, ind, 1, 1.into())[0].clone()],
            "materials": [{"name": "leaf", "alphaMode": mode, "alphaCutoff": 0.5,
                "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}, {"name": "floor"}],
            "textures": [{"source": 0, "sampler": 0}], "samplers": [{"wrapS": 33071, "wrapT": 33071}],
            "images": [{"uri": png}]
        }))
    };
    let masked = load_str(&mk("MASK")).unwrap();
    assert_eq!(masked.materials[0].alpha_mode, crate::AlphaMode::Mask { cutoff: 0.5 });
    let opaque = load_str(&mk("OPAQUE")).unwrap();
    let down = -DVec3::Z;
    let through = DVec3::new(0.2, 0.5, 2.0); // over the transparent texel
    let solid = DVec3::new(0.8, 0.5, 2.0); // over the opaque texel
    let (tm, to) = (crate::Tracer::new(&masked), crate::Tracer::new(&opaque));
    assert!(tm.alpha_triangles() == 2 && to.alpha_triangles() == 0);
    // Masked: the ray passes the leaf (z = 1) and hits the floor (z = 0) at t = 2.
    let h = tm.closest_hit(through, down, 0.0, f64::INFINITY).unwrap();
    assert!((h.t - 2.0).abs() < 1e-6, "{h:?}");
    assert!(!tm.occluded(through, down, 0.0, 1.5));
    assert!((tm.closest_hit_f64(through, down, 0.0, f64::INFINITY).unwrap().t - 2.0).abs() < 1e-9);
    assert!((tm.closest_hit_brute_force(through, down, 0.0, f64::INFINITY).unwrap().t - 2.0).abs() < 1e-6);
    // From below, the transparent texel is no back face: nothing above within 1.5.
    assert!(tm.closest_hit(DVec3::new(0.2, 0.5, 0.5), DVec3::Z, 0.0, 1.5).is_none());
    // The opaque texel stops it in both scenes; the opaque scene stops both rays.
    assert!((tm.closest_hit(solid, down, 0.0, f64::INFINITY).unwrap().t - 1.0).abs() < 1e-6);
    assert!(tm.occluded(solid, down, 0.0, 1.5));
    assert!((to.closest_hit(through, down, 0.0, f64::INFINITY).unwrap().t - 1.0).abs() < 1e-6);
    assert!(to.occluded(through, down, 0.0, 1.5));
    let below = to.closest_hit(DVec3::new(0.2, 0.5, 0.5), DVec3::Z, 0.0, 1.5).unwrap();
    assert!(below.back_face);
}

/// `BLEND` is stochastic transparency: over 4096 distinct rays a pane of alpha 0.25 stops
/// a fraction within 4σ = 4·√(0.25·0.75/4096) ≈ 0.027 of 0.25, closest hit and occlusion
/// agree ray by ray, and a second tracer gives the same answers (no hidden state).
#[test]
fn blend_passes_one_minus_alpha() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let text = d.json(json!({
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}],
        "meshes": quad_mesh(pos, ind, 1, 0.into()),
        "materials": [{"name": "pane", "alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.25]}}]
    }));
    let s = load_str(&text).unwrap();
    let (a, b) = (crate::Tracer::new(&s), crate::Tracer::new(&s));
    let n = 4096;
    let mut stopped = 0;
    for i in 0..n {
        let o = DVec3::new((f64::from(i % 64) + 0.5) / 64.0, (f64::from(i / 64) + 0.5) / 64.0, 1.0);
        let hit = a.closest_hit(o, -DVec3::Z, 0.0, 2.0).is_some();
        assert_eq!(hit, a.occluded(o, -DVec3::Z, 0.0, 2.0));
        assert_eq!(hit, b.closest_hit(o, -DVec3::Z, 0.0, 2.0).is_some());
        stopped += u32::from(hit);
    }
    let f = f64::from(stopped) / f64::from(n);
    let sigma = (0.25f64 * 0.75 / f64::from(n)).sqrt();
    assert!((f - 0.25).abs() < 4.0 * sigma, "{f}");
}

/// Cameras: a perspective camera node gives its eye, view direction (local -Z), up and
/// yfov in the world frame; an orthographic one is skipped with a warning.
#[test]
fn cameras_are_placed_in_the_world_frame() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let text = d.json(json!({
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [1, 2, 3]}, {"camera": 1}], "scenes": [{"nodes": [0, 1, 2]}],
        "meshes": quad_mesh(pos, ind, 1, Value::Null),
        "cameras": [{"name": "eye", "type": "perspective", "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.1}},
                    {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0, "zfar": 1}}]
    }));
    // +Y-up file: the camera at file (1, 2, 3) looking along file -Z.
    let s = load_gltf_slice(text.as_bytes(), None, "c.gltf", &LoadOptions::default()).unwrap();
    assert_eq!(s.cameras.len(), 1);
    let c = &s.cameras[0];
    assert_eq!((c.name.as_str(), c.yfov, c.aspect), ("eye", 0.8, Some(1.5)));
    assert_eq!(c.position, DVec3::new(1.0, -3.0, 2.0));
    assert!((c.forward - DVec3::Y).length() < 1e-15 && (c.up - DVec3::Z).length() < 1e-15);
    assert!(s.report.warnings.iter().any(|w| w.contains("orthographic")));
}

/// Node cycles and shared children are errors, not infinite loops.
#[test]
fn node_cycles_are_errors() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let text = d.json(json!({
        "nodes": [{"mesh": 0, "children": [1]}, {"children": [0]}], "scenes": [{"nodes": [0]}],
        "meshes": quad_mesh(pos, ind, 1, Value::Null)
    }));
    assert!(load_str(&text).unwrap_err().to_string().contains("reached twice"));
}

/// Errors that quote a name from the file stay one line when the name holds line breaks
/// (a mesh named "\n" whose vertices overflow to infinity used to give a two-line message;
/// found by `tests/gltf_fuzz.rs`).
#[test]
fn names_with_line_breaks_keep_errors_one_line() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let mut meshes = quad_mesh(pos, ind, 1, Value::Null);
    meshes[0]["name"] = json!("first\nsecond\r\n");
    let text = d.json(json!({
        "nodes": [{"mesh": 0, "translation": [1e308, 0, 0], "scale": [1e308, 1, 1]}],
        "scenes": [{"nodes": [0]}], "meshes": meshes,
    }));
    let e = load_str(&text).unwrap_err();
    assert!(matches!(e, SceneError::NonFinite { .. }), "{e}");
    assert_eq!(
        e.to_string(),
        "non-finite value in vertex of face 0 in mesh 'first second ' of synthetic.gltf"
    );
    let text = d.json(json!({
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "name": "lamp\n2", "intensity": 1e308, "color": [1e308, 1, 1]}]}},
        "nodes": [{"mesh": 0}, {"extensions": {"KHR_lights_punctual": {"light": 0}}}],
        "scenes": [{"nodes": [0, 1]}], "meshes": quad_mesh(pos, ind, 1, Value::Null),
    }));
    assert_eq!(load_str(&text).unwrap_err().to_string(), "non-finite value in light 'lamp 2'");
}

/// A light whose colour and intensity are finite but whose product is not (1e308 × 2) is
/// an error like a non-finite factor; it used to reach the scene as an infinite light.
#[test]
fn overflowing_light_intensity_is_non_finite() {
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    for (ty, color, intensity) in [("point", 1e308, 2.0), ("spot", 2.0, 1e308), ("directional", 1e200, 1e200)]
    {
        let text = d.json(json!({
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": ty, "name": "sun", "intensity": intensity, "color": [color, 1, 1]}]}},
            "nodes": [{"mesh": 0}, {"extensions": {"KHR_lights_punctual": {"light": 0}}}],
            "scenes": [{"nodes": [0, 1]}], "meshes": quad_mesh(pos, ind, 1, Value::Null),
        }));
        let e = load_str(&text).unwrap_err();
        assert!(matches!(e, SceneError::NonFinite { .. }), "{ty}: {e}");
    }
}

/// An image larger than `MAX_TEXELS` is refused from its header, before anything is
/// decoded, and the material keeps its factor with a warning. A 261 KB grey PNG of
/// 16384 × 16384 used to decode into 4.3 GB of texture; here the header alone (IHDR, an
/// empty IDAT, IEND) makes the point without the pixels.
#[test]
fn oversized_image_is_refused_before_decoding() {
    fn chunk(png: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        let mut c = !0u32;
        for &b in kind.iter().chain(data) {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 == 1 { (c >> 1) ^ 0xEDB8_8320 } else { c >> 1 };
            }
        }
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        png.extend_from_slice(kind);
        png.extend_from_slice(data);
        png.extend_from_slice(&(!c).to_be_bytes());
    }
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let ihdr: Vec<u8> = [16384u32.to_be_bytes(), 16384u32.to_be_bytes()]
        .concat()
        .into_iter()
        .chain([8, 0, 0, 0, 0])
        .collect();
    chunk(&mut png, b"IHDR", &ihdr);
    chunk(&mut png, b"IDAT", &[]);
    chunk(&mut png, b"IEND", &[]);
    let mut d = Doc::default();
    let (pos, ind) = quad(&mut d);
    let text = d.json(json!({
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}],
        "meshes": quad_mesh(pos, ind, 1, 0.into()),
        "materials": [{"name": "huge", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}],
        "images": [{"uri": format!("data:image/png;base64,{}", base64_encode(&png))}],
    }));
    let s = load_str(&text).unwrap();
    assert!(s.textures.is_empty() && s.materials[0].albedo_texture.is_none());
    assert_eq!(
        s.report.warnings,
        [
            "material 'huge': base colour texture 0 not used (image 0 is 16384×16384, more than the 67108864 texels a texture may have); factor used"
        ]
    );
}
