//! Memory a scene will take, estimated before its geometry is loaded: a pass over the glTF
//! JSON (accessor counts, instance counts, image headers) or the OBJ's face lines, so that
//! a scene too large for memory is refused in one line instead of aborting mid-load.
//!
//! A mesh the file places more than once is stored once and placed by instances
//! ([`crate::instance`]); a mesh placed once is written out in the world frame with its
//! lightmap object. So the geometry and the tracer grow with *unique* triangles plus
//! instances:
//!
//! - geometry: per directly placed triangle a [`Triangle`] and its `Option<TriangleRef>`,
//!   and its lightmap object's vertex attributes per vertex ([`VERTEX_BYTES`]); per
//!   prototype triangle a [`Triangle`]; per instance an [`Instance`] and the loader's
//!   placement record;
//! - tracer ([`crate::Tracer`]): per stored triangle its share of a four-triangle leaf pack
//!   and its primitive slot, the unit normal with the sidedness flag and the f64 copy, plus
//!   the BVH nodes and the
//!   build's transient arrays ([`BVH_BUILD_BYTES_PER_TRIANGLE`], measured); per placement
//!   its transforms and the top level's share ([`TLAS_BYTES_PER_PLACEMENT`]). A scene that
//!   places at most [`FLATTEN_AT_MOST`](crate::bvh::FLATTEN_AT_MOST) triangles is traced
//!   through one level: then the tracer's bytes are per *placed* triangle, plus the placed
//!   triangles written out for its build;
//! - textures: 4 bytes per texel, the 8-bit RGBA codes a texture keeps (it decodes them
//!   at lookup, [`crate::base_color::Texture`]); while one image decodes, its decoded copy
//!   lives beside it for a moment, which the largest scenes' triangles dwarf.
//!
//! Loaded with [`LoadOptions::flatten_instances`](crate::LoadOptions) (the surface bake),
//! every placement is written out, and the model is [`SceneMemory::from_counts`] of the
//! placed triangles and vertices.

use std::path::Path;

use glam::DVec3;
use serde_json::Value;

use crate::error::SceneError;
use crate::instance::Instance;
use crate::triangle::{Triangle, TriangleRef};

/// Bytes the BVH build (obvhs' binary BVH at medium quality, collapsed into the wide BVH)
/// holds per triangle beyond the arrays the tracer keeps: primitive bounds, Morton codes
/// and the PLOC clustering buffers and binary nodes during the build, then the collapse's
/// cost table (eight f32 per binary node, about 64 bytes per triangle) beside the binary
/// nodes while the wide nodes are written. Measured as the peak-RSS growth of building the
/// tracer for 400 k triangles, less the tracer's own arrays: 263 bytes, rounded up to 320
/// so that allocator and platform differences stay inside the model; the test
/// `tracer_estimate_bounds_the_measured_peak` keeps it honest (the model at most twice the
/// measured peak, never below it).
pub const BVH_BUILD_BYTES_PER_TRIANGLE: u64 = 320;

/// Bytes the tracer holds per placement: its transforms (world → local, normal matrix, the
/// placement record: about 200 bytes), its f32 box, and the top-level BVH build's arrays
/// (as for triangles, [`BVH_BUILD_BYTES_PER_TRIANGLE`]).
pub const TLAS_BYTES_PER_PLACEMENT: u64 = 200 + 32 + BVH_BUILD_BYTES_PER_TRIANGLE;

/// Bytes per instance in the scene and the loader: the [`Instance`] and the loader's
/// `(mesh, 4×4 matrix)` placement record.
#[must_use]
pub fn instance_bytes() -> u64 {
    (size_of::<Instance>() + size_of::<(u64, glam::DMat4)>()) as u64
}

/// Bytes of a lightmap object's attributes per vertex: position, normal, tangent (f64) and
/// two UV sets (f64).
pub const VERTEX_BYTES: u64 = (3 + 3 + 4 + 2 + 2) * 8;

/// Texture bytes per texel: the 8-bit RGBA codes a loaded texture keeps.
pub const TEXEL_BYTES: u64 = 4;

/// The tracer's own arrays per triangle (see the module docs).
#[must_use]
pub fn tracer_bytes_per_triangle() -> u64 {
    // A leaf pack of four triangles and its four primitive slots, shared by at least two
    // triangles (leaves hold subtrees of one to eight in one or two packs; measured 3.0 to
    // 3.2 a pack on the vendored scenes).
    let pack = (size_of::<crate::wide::Tri4>() + 4 * crate::wide::LEAF_SIZE) as u64 / 2;
    pack + size_of::<(DVec3, bool)>() as u64 + size_of::<[DVec3; 3]>() as u64
}

/// The geometry's bytes per triangle (see the module docs).
#[must_use]
pub fn geometry_bytes_per_triangle() -> u64 {
    (size_of::<Triangle>() + size_of::<Option<TriangleRef>>()) as u64
}

/// What a scene will take, by consumer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SceneMemory {
    /// Triangles placed (every instance counted).
    pub triangles: u64,
    /// Triangles stored: the directly placed ones plus each prototype's once.
    pub unique_triangles: u64,
    /// Instances (placements of prototypes); 0 when flattened.
    pub instances: u64,
    /// Vertices whose attributes are kept for lightmap objects.
    pub vertices: u64,
    /// Texels of all images.
    pub texels: u64,
    /// Bytes of triangles and vertex attributes.
    pub geometry_bytes: u64,
    /// Bytes of the ray tracer (BVH and its arrays, build peak).
    pub tracer_bytes: u64,
    /// Bytes of decoded textures.
    pub texture_bytes: u64,
}

impl SceneMemory {
    /// From counts of a flattened scene (every triangle placed directly), by the module's
    /// model.
    #[must_use]
    pub fn from_counts(triangles: u64, vertices: u64, texels: u64) -> Self {
        Self {
            triangles,
            unique_triangles: triangles,
            instances: 0,
            vertices,
            texels,
            geometry_bytes: triangles
                .saturating_mul(geometry_bytes_per_triangle())
                .saturating_add(vertices.saturating_mul(VERTEX_BYTES)),
            tracer_bytes: triangles
                .saturating_mul(tracer_bytes_per_triangle() + BVH_BUILD_BYTES_PER_TRIANGLE),
            texture_bytes: texels.saturating_mul(TEXEL_BYTES),
        }
    }

    /// From the counts of a glTF loaded with instancing, by the module's model.
    #[must_use]
    pub fn instanced(c: &GltfCounts, texels: u64) -> Self {
        let stored = c.direct_triangles.saturating_add(c.prototype_triangles);
        let placed = c.triangles();
        let placements = c.instances.saturating_add(u64::from(c.direct_triangles > 0));
        Self {
            triangles: placed,
            unique_triangles: stored,
            instances: c.instances,
            vertices: c.direct_vertices,
            texels,
            geometry_bytes: c
                .direct_triangles
                .saturating_mul(geometry_bytes_per_triangle())
                .saturating_add(c.direct_vertices.saturating_mul(VERTEX_BYTES))
                .saturating_add(c.prototype_triangles.saturating_mul(size_of::<Triangle>() as u64))
                .saturating_add(c.instances.saturating_mul(instance_bytes())),
            tracer_bytes: if placed <= crate::bvh::FLATTEN_AT_MOST as u64 {
                // One level over the placed triangles, written out for the build when some
                // are instanced.
                let copy = if c.instances > 0 { size_of::<Triangle>() as u64 } else { 0 };
                placed.saturating_mul(tracer_bytes_per_triangle() + BVH_BUILD_BYTES_PER_TRIANGLE + copy)
            } else {
                stored
                    .saturating_mul(tracer_bytes_per_triangle() + BVH_BUILD_BYTES_PER_TRIANGLE)
                    .saturating_add(placements.saturating_mul(TLAS_BYTES_PER_PLACEMENT))
            },
            texture_bytes: texels.saturating_mul(TEXEL_BYTES),
        }
    }

    /// All of it.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.geometry_bytes.saturating_add(self.tracer_bytes).saturating_add(self.texture_bytes)
    }

    /// The largest consumer, named for a message.
    #[must_use]
    pub fn biggest(&self) -> (&'static str, u64) {
        [
            ("geometry", self.geometry_bytes),
            ("ray tracer", self.tracer_bytes),
            ("textures", self.texture_bytes),
        ]
        .into_iter()
        .max_by_key(|&(_, b)| b)
        .expect("three entries")
    }
}

/// This process's peak resident memory (`VmHWM` of `/proc/self/status`), to set beside an
/// estimate; `None` where that file is missing (not Linux).
#[must_use]
pub fn peak_resident_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let kib: u64 = s.lines().find(|l| l.starts_with("VmHWM:"))?.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Estimates the memory of the scene file at `path` without loading its geometry (a glTF's
/// JSON and image headers; an OBJ's face lines). Built-in scenes are small and not
/// estimated.
///
/// # Errors
/// [`SceneError::NotFound`], I/O errors, and a glTF whose JSON does not parse (the loader
/// would refuse it too).
pub fn estimate_scene(path: &Path, flatten_instances: bool) -> Result<SceneMemory, SceneError> {
    if !path.is_file() {
        return Err(SceneError::NotFound(path.to_owned()));
    }
    let io = |source| SceneError::Io { path: path.to_owned(), source };
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if ext.as_deref() == Some("obj") {
        let text = std::fs::read(path).map_err(io)?;
        return Ok(obj_counts(&text));
    }
    let bytes = std::fs::read(path).map_err(io)?;
    let doc = crate::load::gltf::container::parse(&bytes)
        .map_err(|message| SceneError::Gltf { path: path.to_owned(), message })?;
    let counts = gltf_counts(&doc.json);
    // Images stored in buffers are measured from their headers; the buffers are read only
    // when some image lives in one (the load reads them again).
    let in_buffers = arr(&doc.json, "images").iter().any(|i| i.get("bufferView").is_some());
    let buffers = if in_buffers {
        crate::load::gltf::container::load_buffers(&doc, path.parent()).unwrap_or_default()
    } else {
        Vec::new()
    };
    let texels = gltf_texels(&doc.json, &buffers, path.parent());
    Ok(if flatten_instances {
        SceneMemory::from_counts(counts.triangles(), counts.placed_vertices, texels)
    } else {
        SceneMemory::instanced(&counts, texels)
    })
}

/// Triangles (faces with `n` corners give `n − 2`) and corners of an OBJ.
#[must_use]
pub fn obj_counts(text: &[u8]) -> SceneMemory {
    let (mut tris, mut verts) = (0u64, 0u64);
    for line in text.split(|&b| b == b'\n') {
        let line = line.trim_ascii_start();
        if let Some(rest) = line.strip_prefix(b"f ").or_else(|| line.strip_prefix(b"f\t")) {
            let corners = rest.split(|b| b.is_ascii_whitespace()).filter(|w| !w.is_empty()).count() as u64;
            tris += corners.saturating_sub(2);
            verts += corners;
        }
    }
    SceneMemory::from_counts(tris, verts, 0)
}

fn arr<'v>(v: &'v Value, key: &str) -> &'v [Value] {
    v.get(key).and_then(Value::as_array).map_or(&[], Vec::as_slice)
}

fn accessor_count(json: &Value, a: Option<u64>) -> u64 {
    a.and_then(|a| arr(json, "accessors").get(a as usize))
        .and_then(|x| x.get("count"))
        .and_then(Value::as_u64)
        .unwrap_or(0)
}

/// What a glTF places, counted from its JSON ([`gltf_counts`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GltfCounts {
    /// Triangles of meshes placed once.
    pub direct_triangles: u64,
    /// Vertices of meshes placed once.
    pub direct_vertices: u64,
    /// Triangles of meshes placed more than once, each counted once.
    pub prototype_triangles: u64,
    /// Placements of meshes placed more than once.
    pub instances: u64,
    /// Triangles those placements place.
    pub instanced_triangles: u64,
    /// Vertices of every placement (the flattened scene's lightmap vertices).
    pub placed_vertices: u64,
}

impl GltfCounts {
    /// Triangles placed in all.
    #[must_use]
    pub fn triangles(&self) -> u64 {
        self.direct_triangles.saturating_add(self.instanced_triangles)
    }
}

/// What every mesh placement of the file's nodes comes to: per primitive, `count / 3`
/// triangles for triangle lists and `count − 2` for strips and fans (`count` of the
/// indices, else of `POSITION`), each node's mesh placed once or `EXT_mesh_gpu_instancing`
/// count times. A mesh placed more than once is a prototype, as the loader makes it.
#[must_use]
pub fn gltf_counts(json: &Value) -> GltfCounts {
    let meshes = arr(json, "meshes");
    let per_mesh: Vec<(u64, u64)> = meshes
        .iter()
        .map(|m| {
            arr(m, "primitives").iter().fold((0u64, 0u64), |(t, v), p| {
                let positions =
                    accessor_count(json, p.pointer("/attributes/POSITION").and_then(Value::as_u64));
                let count = match p.get("indices").and_then(Value::as_u64) {
                    Some(i) => accessor_count(json, Some(i)),
                    None => positions,
                };
                let tris = match p.get("mode").and_then(Value::as_u64).unwrap_or(4) {
                    4 => count / 3,
                    5 | 6 => count.saturating_sub(2),
                    _ => 0,
                };
                (t.saturating_add(tris), v.saturating_add(positions))
            })
        })
        .collect();
    // Placements per mesh; every node counted once (nodes form a tree; the loader refuses
    // anything else).
    let mut uses = vec![0u64; meshes.len()];
    for n in arr(json, "nodes") {
        let Some(mesh) = n.get("mesh").and_then(Value::as_u64) else { continue };
        let Some(u) = uses.get_mut(mesh as usize) else { continue };
        let inst = n
            .pointer("/extensions/EXT_mesh_gpu_instancing/attributes")
            .and_then(|a| {
                ["TRANSLATION", "ROTATION", "SCALE"].iter().find_map(|k| a.get(*k).and_then(Value::as_u64))
            })
            .map_or(1, |a| accessor_count(json, Some(a)).max(1));
        *u = u.saturating_add(inst);
    }
    let mut c = GltfCounts::default();
    for (&(t, v), &n) in per_mesh.iter().zip(&uses) {
        c.placed_vertices = c.placed_vertices.saturating_add(v.saturating_mul(n));
        match n {
            0 => {}
            1 => {
                c.direct_triangles = c.direct_triangles.saturating_add(t);
                c.direct_vertices = c.direct_vertices.saturating_add(v);
            }
            _ => {
                c.prototype_triangles = c.prototype_triangles.saturating_add(t);
                c.instances = c.instances.saturating_add(n);
                c.instanced_triangles = c.instanced_triangles.saturating_add(t.saturating_mul(n));
            }
        }
    }
    c
}

/// Texels of every image, from the image headers (in a buffer, in `data:` URIs or in files
/// beside the glTF); an image whose header cannot be read counts 0 (the loader falls back
/// to the factor for it).
fn gltf_texels(json: &Value, buffers: &[Vec<u8>], base: Option<&Path>) -> u64 {
    let views = arr(json, "bufferViews");
    arr(json, "images")
        .iter()
        .map(|img| {
            let dims = if let Some(v) = img.get("bufferView").and_then(Value::as_u64) {
                views.get(v as usize).and_then(|view| {
                    let off = view.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
                    let len = view.get("byteLength").and_then(Value::as_u64)? as usize;
                    let buffer = buffers.get(view.get("buffer").and_then(Value::as_u64)? as usize)?;
                    let data = buffer.get(off..off.checked_add(len)?)?;
                    image::ImageReader::new(std::io::Cursor::new(data))
                        .with_guessed_format()
                        .ok()?
                        .into_dimensions()
                        .ok()
                })
            } else if let Some(uri) = img.get("uri").and_then(Value::as_str) {
                if uri.starts_with("data:") {
                    crate::load::gltf::container::read_uri(uri, base).ok().and_then(|d| {
                        image::ImageReader::new(std::io::Cursor::new(d))
                            .with_guessed_format()
                            .ok()?
                            .into_dimensions()
                            .ok()
                    })
                } else {
                    base.and_then(|b| {
                        image::ImageReader::open(b.join(uri))
                            .ok()?
                            .with_guessed_format()
                            .ok()?
                            .into_dimensions()
                            .ok()
                    })
                }
            } else {
                None
            };
            dims.map_or(0, |(w, h)| u64::from(w) * u64::from(h))
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The model's bytes per triangle from the types, and the counts of a glTF with an
    /// instanced mesh (two primitives: a list and a strip) and a plain node.
    #[test]
    fn counts_follow_the_file() {
        let json: Value = serde_json::from_str(
            r#"{"accessors":[{"count":9},{"count":12},{"count":6},{"count":1000}],
                "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1},{"attributes":{"POSITION":2},"mode":5}]}],
                "nodes":[{"mesh":0,"extensions":{"EXT_mesh_gpu_instancing":{"attributes":{"TRANSLATION":3}}}},{"mesh":0},{"children":[0,1]}]}"#,
        )
        .unwrap();
        // Per instance: 12/3 + (6 − 2) = 8 triangles, 9 + 6 = 15 vertices; 1000 + 1 instances.
        let c = gltf_counts(&json);
        assert_eq!((c.triangles(), c.placed_vertices), (8 * 1001, 15 * 1001));
        assert_eq!((c.prototype_triangles, c.instances, c.direct_triangles), (8, 1001, 0));
        let obj = obj_counts(b"v 0 0 0\nf 1 2 3\nf 1 2 3 4\n  f 1 2 3 4 5\n# f 1 2 3\n");
        assert_eq!((obj.triangles, obj.vertices), (1 + 2 + 3, 12));
        let m = SceneMemory::from_counts(10, 20, 30);
        assert_eq!(m.geometry_bytes, 10 * geometry_bytes_per_triangle() + 20 * VERTEX_BYTES);
        assert_eq!(m.total(), m.geometry_bytes + m.tracer_bytes + 30 * TEXEL_BYTES);
        // Triangle: 9 + 6 f64 and a u32, padded to 8 (128); TriangleRef: 5 u32 and the
        // Option tag (24).
        assert_eq!(geometry_bytes_per_triangle(), 128 + 24);
    }
}
