//! Fixtures.

use super::*;

pub(crate) fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes")
}

pub(crate) fn u64_of(v: &Value) -> usize {
    v.as_u64().expect("fixture field is an unsigned integer") as usize
}

/// A document to mutate: its JSON, its binary buffer, and the folder its files are read from.
pub(crate) struct Fixture {
    pub(crate) json: Value,
    pub(crate) bin: Vec<u8>,
    pub(crate) base: PathBuf,
}

/// The breakfast room with every primitive cut to its first [`TRIANGLES_PER_PRIMITIVE`]
/// triangles (vertices renumbered, same interleaved layout), the buffer as
/// [`BIN_PLACEHOLDER`] and the raster images as [`TINY_PNG`]. Also returns the number of
/// triangles kept (what the loader reports as `unique_triangles`).
pub(crate) fn breakfast_room() -> (Fixture, usize) {
    let base = scenes_dir().join("breakfast_room");
    let text = std::fs::read(base.join("BreakfastRoom.gltf")).expect("vendored BreakfastRoom.gltf");
    let old = std::fs::read(base.join("BreakfastRoom.bin")).expect("vendored BreakfastRoom.bin");
    let mut json: Value = serde_json::from_slice(&text).expect("BreakfastRoom.gltf is JSON");
    let views = json["bufferViews"].clone();
    assert_eq!(views.as_array().map(Vec::len), Some(2), "one vertex view, one index view");
    let (vertex_view, index_view) = (&views[0], &views[1]);
    let stride = u64_of(&vertex_view["byteStride"]);
    let (mut vertices, mut indices) = (Vec::new(), Vec::new());
    let mut kept = 0;
    let meshes = json["meshes"].as_array().expect("meshes").len();
    for m in 0..meshes {
        let prims = json["meshes"][m]["primitives"].as_array().expect("primitives").len();
        for p in 0..prims {
            let prim = json["meshes"][m]["primitives"][p].clone();
            // Indices: the first triangles, renumbered in order of first use.
            let ia = u64_of(&prim["indices"]);
            let acc = &json["accessors"][ia];
            assert_eq!((acc["componentType"].as_u64(), acc["bufferView"].as_u64()), (Some(5125), Some(1)));
            let at = u64_of(&index_view["byteOffset"]) + acc["byteOffset"].as_u64().unwrap_or(0) as usize;
            let n = u64_of(&acc["count"]).min(3 * TRIANGLES_PER_PRIMITIVE);
            let mut renumber: HashMap<u32, u32> = HashMap::new();
            let mut order = Vec::new();
            let index_start = indices.len();
            for k in 0..n {
                let o = at + 4 * k;
                let v = u32::from_le_bytes(old[o..o + 4].try_into().expect("4 bytes"));
                let next = renumber.len() as u32;
                let new = *renumber.entry(v).or_insert_with(|| {
                    order.push(v);
                    next
                });
                indices.extend_from_slice(&new.to_le_bytes());
            }
            kept += n / 3;
            json["accessors"][ia]["byteOffset"] = json!(index_start);
            json["accessors"][ia]["count"] = json!(n);
            // Attributes: the used vertices, each attribute at its old offset within the stride.
            let attrs: Vec<usize> =
                prim["attributes"].as_object().expect("attributes").values().map(u64_of).collect();
            let first =
                attrs.iter().map(|&a| u64_of(&json["accessors"][a]["byteOffset"])).min().expect("attributes");
            let vertex_start = vertices.len();
            vertices.resize(vertex_start + order.len() * stride, 0);
            for &a in &attrs {
                let acc = &json["accessors"][a];
                assert_eq!(
                    (acc["componentType"].as_u64(), acc["bufferView"].as_u64()),
                    (Some(5126), Some(0))
                );
                let components = match acc["type"].as_str() {
                    Some("VEC2") => 2,
                    Some("VEC3") => 3,
                    Some("VEC4") => 4,
                    t => panic!("attribute type {t:?}"),
                };
                let rel = u64_of(&acc["byteOffset"]) - first;
                assert!(rel + 4 * components <= stride);
                let mut lo = vec![f64::INFINITY; components];
                let mut hi = vec![f64::NEG_INFINITY; components];
                for (new, &old_v) in order.iter().enumerate() {
                    let src = u64_of(&vertex_view["byteOffset"])
                        + u64_of(&acc["byteOffset"])
                        + old_v as usize * stride;
                    let dst = vertex_start + rel + new * stride;
                    vertices[dst..dst + 4 * components].copy_from_slice(&old[src..src + 4 * components]);
                    for c in 0..components {
                        let x = f64::from(f32::from_le_bytes(
                            old[src + 4 * c..src + 4 * c + 4].try_into().expect("4 bytes"),
                        ));
                        lo[c] = lo[c].min(x);
                        hi[c] = hi[c].max(x);
                    }
                }
                let acc = &mut json["accessors"][a];
                acc["byteOffset"] = json!(vertex_start + rel);
                acc["count"] = json!(order.len());
                if acc.get("min").is_some() {
                    acc["min"] = json!(lo);
                    acc["max"] = json!(hi);
                }
            }
        }
    }
    json["bufferViews"][0]["byteOffset"] = json!(0);
    json["bufferViews"][0]["byteLength"] = json!(vertices.len());
    json["bufferViews"][1]["byteOffset"] = json!(vertices.len());
    json["bufferViews"][1]["byteLength"] = json!(indices.len());
    vertices.extend_from_slice(&indices);
    json["buffers"] = json!([{"byteLength": vertices.len(), "uri": BIN_PLACEHOLDER}]);
    for image in json["images"].as_array_mut().expect("images") {
        if matches!(image["mimeType"].as_str(), Some("image/jpeg" | "image/png")) {
            image["uri"] = json!(TINY_PNG);
            image["mimeType"] = json!("image/png");
        }
    }
    (Fixture { json, bin: vertices, base }, kept)
}

pub(crate) const CHUNK_JSON: u32 = 0x4E4F_534A;
pub(crate) const CHUNK_BIN: u32 = 0x004E_4942;

/// The living room GLB split into its JSON and BIN chunks.
pub(crate) fn living_room() -> Fixture {
    let base = scenes_dir().join("living_room");
    let glb = std::fs::read(base.join("living_room.glb")).expect("vendored living_room.glb");
    let word = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().expect("4 bytes"));
    assert_eq!(&glb[..4], b"glTF");
    let (mut json, mut bin) = (None, None);
    let mut at = 12;
    while at < glb.len() {
        let (len, kind) = (word(at) as usize, word(at + 4));
        let data = &glb[at + 8..at + 8 + len];
        match kind {
            CHUNK_JSON => json = Some(serde_json::from_slice(data).expect("GLB JSON chunk")),
            CHUNK_BIN => bin = Some(data.to_vec()),
            _ => {}
        }
        at += 8 + len.next_multiple_of(4);
    }
    Fixture { json: json.expect("JSON chunk"), bin: bin.expect("BIN chunk"), base }
}
