//! glTF 2.0 (`.gltf`, `.glb`) loading: every node of the default scene with its transform,
//! `EXT_mesh_gpu_instancing` instances, `baseColorFactor` × `baseColorTexture` (with
//! `KHR_texture_transform`), base-colour alpha with `alphaMode`, `emissiveFactor` ×
//! `KHR_materials_emissive_strength`, `doubleSided`, `KHR_lights_punctual`, perspective
//! cameras, and accessors of every type (`KHR_mesh_quantization`, sparse, non-indexed).
//!
//! The loader reads the JSON itself (serde_json) rather than through a validating glTF
//! crate: real exports bend the specification in ways that must degrade to a warning, not
//! a refusal (a texture whose only image is DDS, a vendor material extension listed as
//! required, `images[]` naming files that are absent), and every index and offset is
//! checked here so that a corrupt file is a one-line error, never a panic. What it does
//! with each extension is in [`extensions`] and in [`LoadReport::extensions`].
//!
//! A mesh that the default scene places more than once (by several nodes, or by
//! `EXT_mesh_gpu_instancing`) is stored once as a [`Prototype`](crate::instance::Prototype)
//! and placed by [`Instance`](crate::instance::Instance)s, so memory grows with unique
//! triangles ([`crate::instance`]); [`LoadOptions::flatten_instances`] writes every
//! placement out instead. Every mesh placed once, and with `flatten_instances` every
//! placement, becomes a lightmap object ([`MeshAttributes`]) with its world-space
//! `NORMAL`, `TANGENT`, `TEXCOORD_0` and `TEXCOORD_1` (for the surface bake,
//! lightvol-surface); each such triangle records its object and vertices
//! ([`Scene::triangle_refs`]).

mod accessor;
pub(crate) mod container;
pub use container::base64_encode;
pub mod extensions;
mod material;

use std::collections::HashMap;
use std::path::Path;

use glam::{DAffine3, DMat3, DMat4, DQuat, DVec2, DVec3, DVec4};
use serde_json::Value;

use crate::builder::SceneBuilder;
use crate::error::SceneError;
use crate::lights::PunctualLight;
use crate::load::options::LoadOptions;
use crate::scene::{LoadReport, Scene, SceneCamera};
use crate::triangle::{MeshAttributes, TriangleRef};
use material::{MaterialUse, Materials};

/// Loads a glTF 2.0 file. Textures that cannot be used leave their material on its factor
/// with a warning; non-triangle primitives are skipped with a warning.
///
/// # Errors
/// [`SceneError::NotFound`], [`SceneError::Io`], [`SceneError::Gltf`] (one line naming
/// what is wrong), [`SceneError::NonFinite`], [`SceneError::Empty`].
pub fn load_gltf(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
    if !path.is_file() {
        return Err(SceneError::NotFound(path.to_owned()));
    }
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io { path: path.to_owned(), source })?;
    let name = path.file_name().map_or_else(|| "gltf".to_owned(), |n| n.to_string_lossy().into_owned());
    load_gltf_slice(&bytes, path.parent(), &name, opts).map_err(|e| match e {
        SceneError::Gltf { message, .. } => SceneError::Gltf { path: path.to_owned(), message },
        e => e,
    })
}

/// Loads glTF 2.0 from memory (`.gltf` text or `.glb` bytes). External buffers and images
/// are read relative to `base`; with `None`, only embedded data (`data:` URIs, the GLB
/// chunk) is available. `name` labels the scene and its errors.
///
/// # Errors
/// As [`load_gltf`].
pub fn load_gltf_slice(
    bytes: &[u8],
    base: Option<&Path>,
    name: &str,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let gerr = |message: String| SceneError::Gltf { path: name.into(), message: one_line(&message) };
    let doc = container::parse(bytes).map_err(gerr)?;
    let (reports, ext_warnings) = extensions::classify(&doc.json).map_err(gerr)?;
    let buffers = container::load_buffers(&doc, base).map_err(gerr)?;
    let mut loader = Loader {
        json: &doc.json,
        buffers: &buffers,
        opts: *opts,
        b: SceneBuilder::new(name),
        meshes: HashMap::new(),
        prototypes: HashMap::new(),
        object_names: HashMap::new(),
        scene_name: name.to_owned(),
        unstored: std::cell::Cell::new(0),
    };
    for w in ext_warnings {
        loader.b.warn(w);
    }
    {
        let report: &mut LoadReport = loader.b.report_mut();
        report.extensions = reports;
        report.up = opts.up;
    }
    let mut materials = Materials::new(&doc.json, &buffers, base, *opts);
    materials.decode_all();
    loader.walk(&mut materials).map_err(|e| match e {
        SceneError::Gltf { message, .. } => gerr(message),
        // These quote names from the file (meshes, lights), which may hold line breaks.
        SceneError::NonFinite { what } => SceneError::NonFinite { what: one_line(&what) },
        SceneError::BadMesh(what) => SceneError::BadMesh(one_line(&what)),
        e => e,
    })?;
    loader.b.build()
}

/// Error messages are one line.
fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A primitive decoded once per mesh, in the mesh's local frame.
#[derive(Debug)]
struct Primitive {
    positions: Vec<DVec3>,
    normals: Option<Vec<DVec3>>,
    tangents: Option<Vec<DVec4>>,
    /// `TEXCOORD_n` sets by `n`.
    uvs: HashMap<u32, Vec<DVec2>>,
    /// Triangle list (strips and fans converted).
    indices: Vec<u32>,
    material: Option<u64>,
}

struct Loader<'a> {
    json: &'a Value,
    buffers: &'a [Vec<u8>],
    opts: LoadOptions,
    b: SceneBuilder,
    meshes: HashMap<u64, std::rc::Rc<Vec<Primitive>>>,
    /// Mesh index → its prototype, for meshes placed more than once.
    prototypes: HashMap<u64, u32>,
    object_names: HashMap<String, usize>,
    scene_name: String,
    /// Values read so far from accessors without a bufferView (see [`Loader::charge`]).
    unstored: std::cell::Cell<u64>,
}

fn arr<'v>(v: &'v Value, key: &str) -> &'v [Value] {
    v.get(key).and_then(Value::as_array).map_or(&[], Vec::as_slice)
}

fn f64s<const N: usize>(v: Option<&Value>, default: [f64; N]) -> [f64; N] {
    let mut out = default;
    if let Some(a) = v.and_then(Value::as_array) {
        for (o, x) in out.iter_mut().zip(a) {
            *o = x.as_f64().unwrap_or(f64::NAN);
        }
    }
    out
}

fn gltf_err(message: String) -> SceneError {
    SceneError::Gltf { path: std::path::PathBuf::new(), message }
}

/// A node's local transform: `matrix`, else `T · R · S` (glTF 2.0 §3.5.3).
fn local_transform(node: &Value) -> DMat4 {
    if let Some(m) = node.get("matrix") {
        return DMat4::from_cols_array(&f64s(Some(m), DMat4::IDENTITY.to_cols_array()));
    }
    let t = f64s(node.get("translation"), [0.0; 3]);
    let r = f64s(node.get("rotation"), [0.0, 0.0, 0.0, 1.0]);
    let s = f64s(node.get("scale"), [1.0; 3]);
    DMat4::from_scale_rotation_translation(
        DVec3::from_array(s),
        DQuat::from_xyzw(r[0], r[1], r[2], r[3]).normalize(),
        DVec3::from_array(t),
    )
}

impl Loader<'_> {
    /// Charges the zeros that reading accessor `a` allocates without the file storing them
    /// (no bufferView) to one budget for the whole load, [`accessor::MAX_UNBACKED_VALUES`]:
    /// each reference to such an accessor, a few bytes of JSON, allocates its values anew,
    /// so a cap per accessor alone let a thousand primitives sharing one take gigabytes.
    fn charge(&self, a: u64) -> Result<(), String> {
        let total = self.unstored.get().saturating_add(accessor::unstored_values(self.json, a));
        if total > accessor::MAX_UNBACKED_VALUES {
            return Err(format!(
                "accessor {a}: accessors without a bufferView come to {total} values, more than the reader's limit of {} for data the file does not store",
                accessor::MAX_UNBACKED_VALUES
            ));
        }
        self.unstored.set(total);
        Ok(())
    }

    fn root_matrix(&self) -> DMat4 {
        let (up, s) = (self.opts.up, self.opts.scale);
        DMat4::from_cols(
            DVec3::from_array(up.to_world(DVec3::X.to_array())).extend(0.0) * s,
            DVec3::from_array(up.to_world(DVec3::Y.to_array())).extend(0.0) * s,
            DVec3::from_array(up.to_world(DVec3::Z.to_array())).extend(0.0) * s,
            DVec4::W,
        )
    }

    fn walk(&mut self, materials: &mut Materials<'_>) -> Result<(), SceneError> {
        let json = self.json;
        let nodes = arr(json, "nodes");
        let scenes = arr(json, "scenes");
        let roots: Vec<u64> = match json.get("scene").and_then(Value::as_u64).or(if scenes.is_empty() {
            None
        } else {
            Some(0)
        }) {
            Some(s) => {
                let sc =
                    scenes.get(s as usize).ok_or_else(|| gltf_err(format!("scene {s} does not exist")))?;
                arr(sc, "nodes").iter().filter_map(Value::as_u64).collect()
            }
            None => {
                // No scene: every node that is nobody's child is a root.
                let mut child = vec![false; nodes.len()];
                for n in nodes {
                    for c in arr(n, "children").iter().filter_map(Value::as_u64) {
                        if let Some(x) = child.get_mut(c as usize) {
                            *x = true;
                        }
                    }
                }
                (0..nodes.len() as u64).filter(|&i| !child[i as usize]).collect()
            }
        };
        let mut visited = vec![false; nodes.len()];
        // (mesh, transform) in node order; placed after the walk, once the number of
        // placements of each mesh is known.
        let mut placements: Vec<(u64, DMat4)> = Vec::new();
        let root = self.root_matrix();
        let mut stack: Vec<(u64, DMat4)> = roots.into_iter().rev().map(|n| (n, root)).collect();
        while let Some((ni, parent)) = stack.pop() {
            let node = nodes.get(ni as usize).ok_or_else(|| gltf_err(format!("node {ni} does not exist")))?;
            if std::mem::replace(&mut visited[ni as usize], true) {
                return Err(gltf_err(format!("node {ni} is reached twice (glTF nodes must form a tree)")));
            }
            let world = parent * local_transform(node);
            if !world.is_finite() {
                return Err(SceneError::NonFinite {
                    what: format!("transform of node {ni} in {}", self.scene_name),
                });
            }
            for c in arr(node, "children").iter().rev().filter_map(Value::as_u64) {
                stack.push((c, world));
            }
            if let Some(l) = node.pointer("/extensions/KHR_lights_punctual/light").and_then(Value::as_u64) {
                self.add_light(l, &world)?;
            }
            if let Some(c) = node.get("camera").and_then(Value::as_u64) {
                self.add_camera(c, &world)?;
            }
            let Some(mesh) = node.get("mesh").and_then(Value::as_u64) else { continue };
            if node.get("skin").is_some() {
                self.b.warn(format!("node {ni}: skinned mesh placed in its bind pose"));
            }
            let instances = self.instances(node, ni)?;
            for m in instances.iter().map(|i| world * *i) {
                if !m.is_finite() {
                    return Err(SceneError::NonFinite { what: format!("instance transform of node {ni}") });
                }
                placements.push((mesh, m));
            }
        }
        let mut uses: HashMap<u64, usize> = HashMap::new();
        for &(mesh, _) in &placements {
            *uses.entry(mesh).or_default() += 1;
        }
        for (mesh, m) in placements {
            if uses[&mesh] > 1 && !self.opts.flatten_instances {
                let p = self.prototype(materials, mesh)?;
                self.b.report_mut().instances += 1;
                self.b.add_instance(p, DAffine3::from_mat4(m))?;
            } else {
                self.add_instance(materials, mesh, &m)?;
            }
        }
        Ok(())
    }

    /// The prototype of mesh `index`: its triangles in the mesh's frame, decoded once.
    fn prototype(&mut self, materials: &mut Materials<'_>, index: u64) -> Result<u32, SceneError> {
        if let Some(&p) = self.prototypes.get(&index) {
            return Ok(p);
        }
        let prims = self.mesh(index)?;
        let name = arr(self.json, "meshes")[index as usize]
            .get("name")
            .and_then(Value::as_str)
            .map_or_else(|| format!("mesh{index}"), str::to_owned);
        let p = self.b.add_prototype(&name);
        for (pi, prim) in prims.iter().enumerate() {
            let mu: MaterialUse = materials
                .get(&mut self.b, prim.material)
                .map_err(|e| gltf_err(format!("mesh '{name}' primitive {pi}: {e}")))?;
            let base_uv = prim.uvs.get(&mu.uv_set);
            for (f, tri) in prim.indices.chunks_exact(3).enumerate() {
                let ids = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
                let v = ids.map(|i| prim.positions[i]);
                if !v.iter().all(|q| q.is_finite()) {
                    return Err(SceneError::NonFinite {
                        what: format!("vertex of face {f} in mesh '{name}' of {}", self.scene_name),
                    });
                }
                let uv = ids.map(|i| {
                    let t = base_uv.and_then(|u| u.get(i)).copied().unwrap_or(DVec2::ZERO);
                    mu.uv_transform.as_ref().map_or(t, |m| material::apply(m, t))
                });
                self.b.add_prototype_triangle(p, v, uv, mu.id)?;
            }
        }
        self.prototypes.insert(index, p);
        Ok(p)
    }

    /// The instance transforms of a node: `EXT_mesh_gpu_instancing`'s TRS per instance, or
    /// one identity.
    fn instances(&self, node: &Value, ni: u64) -> Result<Vec<DMat4>, SceneError> {
        let Some(ext) = node.pointer("/extensions/EXT_mesh_gpu_instancing/attributes") else {
            return Ok(vec![DMat4::IDENTITY]);
        };
        let read = |k: &str| -> Result<Option<accessor::Values>, SceneError> {
            let at = |e: String| gltf_err(format!("node {ni} EXT_mesh_gpu_instancing {k}: {e}"));
            let Some(a) = ext.get(k).and_then(Value::as_u64) else { return Ok(None) };
            self.charge(a).map_err(at)?;
            let v = accessor::read(self.json, self.buffers, a).map_err(at)?;
            // Every instance copies the mesh, so instances must be stored: zeros of an
            // accessor without a bufferView (a few bytes of JSON) used to place thousands of
            // coincident copies of a large mesh.
            let stored = accessor::stored_elements(self.json, a);
            if v.len() as u64 > stored {
                return Err(at(format!(
                    "accessor {a} stores {stored} of its {} instances (no bufferView)",
                    v.len()
                )));
            }
            Ok(Some(v))
        };
        let (t, r, s) = (read("TRANSLATION")?, read("ROTATION")?, read("SCALE")?);
        let counts: Vec<usize> =
            [&t, &r, &s].iter().filter_map(|v| v.as_ref().map(accessor::Values::len)).collect();
        let Some(&n) = counts.first() else { return Ok(vec![DMat4::IDENTITY]) };
        if counts.iter().any(|&c| c != n) {
            return Err(gltf_err(format!(
                "node {ni}: EXT_mesh_gpu_instancing attributes have different counts {counts:?}"
            )));
        }
        Ok((0..n)
            .map(|i| {
                let tt = t.as_ref().map_or([0.0; 3], |v| v.get::<3>(i));
                let rr = r.as_ref().map_or([0.0, 0.0, 0.0, 1.0], |v| v.get::<4>(i));
                let ss = s.as_ref().map_or([1.0; 3], |v| v.get::<3>(i));
                DMat4::from_scale_rotation_translation(
                    DVec3::from_array(ss),
                    DQuat::from_xyzw(rr[0], rr[1], rr[2], rr[3]).normalize(),
                    DVec3::from_array(tt),
                )
            })
            .collect())
    }

    /// Decodes mesh `index` once.
    fn mesh(&mut self, index: u64) -> Result<std::rc::Rc<Vec<Primitive>>, SceneError> {
        if let Some(m) = self.meshes.get(&index) {
            return Ok(m.clone());
        }
        let mesh = arr(self.json, "meshes")
            .get(index as usize)
            .ok_or_else(|| gltf_err(format!("mesh {index} does not exist")))?;
        let mname = mesh
            .get("name")
            .and_then(Value::as_str)
            .map_or_else(|| format!("mesh {index}"), |n| format!("mesh '{n}'"));
        let mut prims = Vec::new();
        for (p, prim) in arr(mesh, "primitives").iter().enumerate() {
            let at = |e: String| gltf_err(format!("{mname} primitive {p}: {e}"));
            let mode = prim.get("mode").and_then(Value::as_u64).unwrap_or(4);
            if !matches!(mode, 4..=6) {
                self.b.warn(format!("{mname} primitive {p}: mode {mode} (points or lines) skipped"));
                continue;
            }
            let attrs = prim.get("attributes");
            let attr = |k: &str| attrs.and_then(|a| a.get(k)).and_then(Value::as_u64);
            let Some(pos) = attr("POSITION") else {
                self.b.warn(format!("{mname} primitive {p}: no POSITION, skipped"));
                continue;
            };
            let read = |a: u64| {
                self.charge(a).and_then(|()| accessor::read(self.json, self.buffers, a)).map_err(&at)
            };
            let positions: Vec<DVec3> = {
                let v = read(pos)?;
                (0..v.len()).map(|i| DVec3::from_array(v.get::<3>(i))).collect()
            };
            let normals = attr("NORMAL")
                .map(|a| {
                    read(a)
                        .map(|v| (0..v.len()).map(|i| DVec3::from_array(v.get::<3>(i))).collect::<Vec<_>>())
                })
                .transpose()?;
            let tangents = attr("TANGENT")
                .map(|a| {
                    read(a)
                        .map(|v| (0..v.len()).map(|i| DVec4::from_array(v.get::<4>(i))).collect::<Vec<_>>())
                })
                .transpose()?;
            let mut uvs = HashMap::new();
            for set in 0..8u32 {
                if let Some(a) = attr(&format!("TEXCOORD_{set}")) {
                    let v = read(a)?;
                    uvs.insert(set, (0..v.len()).map(|i| DVec2::from_array(v.get::<2>(i))).collect());
                }
            }
            let raw: Vec<u32> = match prim.get("indices").and_then(Value::as_u64) {
                Some(a) => self
                    .charge(a)
                    .and_then(|()| accessor::read_indices(self.json, self.buffers, a))
                    .map_err(at)?,
                None => (0..positions.len() as u32).collect(),
            };
            let indices: Vec<u32> = match mode {
                4 => raw.chunks_exact(3).flatten().copied().collect(),
                // Strips: triangle i is (i, i+1, i+2), every other one reversed (glTF 2.0 §3.7.2.1).
                5 => raw
                    .windows(3)
                    .enumerate()
                    .flat_map(|(i, w)| if i % 2 == 0 { [w[0], w[1], w[2]] } else { [w[1], w[0], w[2]] })
                    .collect(),
                // Fans: (0, i+1, i+2).
                _ => raw.windows(2).skip(1).flat_map(|w| [raw[0], w[0], w[1]]).collect(),
            };
            if let Some(&bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(at(format!("index {bad} is out of range ({} vertices)", positions.len())));
            }
            let material = prim.get("material").and_then(Value::as_u64);
            let r = self.b.report_mut();
            r.unique_triangles += indices.len() / 3;
            prims.push(Primitive { positions, normals, tangents, uvs, indices, material });
        }
        let rc = std::rc::Rc::new(prims);
        self.meshes.insert(index, rc.clone());
        Ok(rc)
    }

    /// Places one instance of mesh `index` with transform `world` as one lightmap object.
    fn add_instance(
        &mut self,
        materials: &mut Materials<'_>,
        index: u64,
        world: &DMat4,
    ) -> Result<(), SceneError> {
        let prims = self.mesh(index)?;
        self.b.report_mut().instances += 1;
        let mesh_json = &arr(self.json, "meshes")[index as usize];
        let base_name = mesh_json
            .get("name")
            .and_then(Value::as_str)
            .map_or_else(|| format!("mesh{index}"), str::to_owned);
        let seen = self.object_names.entry(base_name.clone()).or_insert(0);
        *seen += 1;
        let object_name = if *seen == 1 { base_name } else { format!("{base_name}#{seen}") };
        // A mirroring transform flips the winding (glTF 2.0 §3.7.4).
        let flip = world.determinant() < 0.0;
        let linear = DMat3::from_mat4(*world);
        // Normals transform with the inverse transpose; tangents with the matrix, and their
        // handedness flips with a mirroring transform (the bitangent is w · n × t).
        let normal_matrix = if linear.determinant() != 0.0 { linear.inverse().transpose() } else { linear };
        let handed = if flip { -1.0 } else { 1.0 };
        let mut attrs = MeshAttributes { name: object_name.clone(), ..MeshAttributes::default() };
        let (mut normals, mut tangents, mut uv0, mut uv1) =
            (Some(Vec::new()), Some(Vec::new()), Some(Vec::new()), Some(Vec::new()));
        let mut faces: Vec<Face> = Vec::new();
        for (p, prim) in prims.iter().enumerate() {
            let mu: MaterialUse = materials
                .get(&mut self.b, prim.material)
                .map_err(|e| gltf_err(format!("mesh '{object_name}' primitive {p}: {e}")))?;
            let positions: Vec<DVec3> = prim.positions.iter().map(|&q| world.transform_point3(q)).collect();
            let nv = positions.len();
            let base_vertex = attrs.positions.len();
            attrs.positions.extend_from_slice(&positions);
            extend_or_drop(&mut uv0, prim.uvs.get(&0).cloned(), nv);
            extend_or_drop(&mut uv1, prim.uvs.get(&1).cloned(), nv);
            extend_or_drop(
                &mut normals,
                prim.normals
                    .as_ref()
                    .map(|n| n.iter().map(|&q| (normal_matrix * q).normalize_or_zero()).collect()),
                nv,
            );
            extend_or_drop(
                &mut tangents,
                prim.tangents.as_ref().map(|t| {
                    t.iter()
                        .map(|q| {
                            (linear * q.truncate()).normalize_or_zero().extend(if q.w < 0.0 {
                                -handed
                            } else {
                                handed
                            })
                        })
                        .collect()
                }),
                nv,
            );
            let base_uv = prim.uvs.get(&mu.uv_set);
            for (f, tri) in prim.indices.chunks_exact(3).enumerate() {
                let mut ids = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
                if flip {
                    ids.swap(1, 2);
                }
                let v = ids.map(|i| positions[i]);
                if !v.iter().all(|q| q.is_finite()) {
                    return Err(SceneError::NonFinite {
                        what: format!("vertex of face {f} in mesh '{object_name}' of {}", self.scene_name),
                    });
                }
                let uv = ids.map(|i| {
                    let t = base_uv.and_then(|u| u.get(i)).copied().unwrap_or(DVec2::ZERO);
                    mu.uv_transform.as_ref().map_or(t, |m| material::apply(m, t))
                });
                faces.push((ids.map(|i| i + base_vertex), v, uv, mu.id));
            }
        }
        attrs.normals = normals;
        attrs.tangents = tangents;
        attrs.uv0 = uv0;
        attrs.uv1 = uv1;
        let object = self.b.add_mesh(attrs);
        for (face, (ids, v, uv, mat)) in faces.into_iter().enumerate() {
            let r = TriangleRef { mesh: object, face: face as u32, vertices: ids.map(|i| i as u32) };
            self.b.add_mesh_triangle(v, uv, mat, r)?;
        }
        Ok(())
    }

    fn add_camera(&mut self, index: u64, world: &DMat4) -> Result<(), SceneError> {
        let cam = arr(self.json, "cameras")
            .get(index as usize)
            .ok_or_else(|| gltf_err(format!("camera {index} does not exist")))?;
        let name =
            cam.get("name").and_then(Value::as_str).map_or_else(|| format!("camera{index}"), str::to_owned);
        let Some(p) = cam.get("perspective") else {
            self.b.warn(format!(
                "camera '{name}': {} camera skipped (only perspective cameras are used)",
                cam.get("type").and_then(Value::as_str).unwrap_or("unknown")
            ));
            return Ok(());
        };
        let yfov = p.get("yfov").and_then(Value::as_f64).unwrap_or(f64::NAN);
        let aspect = p.get("aspectRatio").and_then(Value::as_f64);
        let forward = world.transform_vector3(-DVec3::Z).normalize_or_zero();
        let up = world.transform_vector3(DVec3::Y).normalize_or_zero();
        if !(yfov > 0.0 && yfov < std::f64::consts::PI)
            || forward == DVec3::ZERO
            || up == DVec3::ZERO
            || aspect.is_some_and(|a| !(a > 0.0 && a.is_finite()))
        {
            self.b.warn(format!("camera '{name}': invalid yfov, aspect ratio or transform; skipped"));
            return Ok(());
        }
        self.b.cameras.push(SceneCamera {
            name,
            position: world.transform_point3(DVec3::ZERO),
            forward,
            up,
            yfov,
            aspect,
        });
        Ok(())
    }

    fn add_light(&mut self, index: u64, world: &DMat4) -> Result<(), SceneError> {
        let light = self
            .json
            .pointer("/extensions/KHR_lights_punctual/lights")
            .and_then(|l| l.get(index as usize))
            .ok_or_else(|| gltf_err(format!("light {index} does not exist")))?;
        let name = light.get("name").and_then(Value::as_str).unwrap_or("?");
        let color = f64s(light.get("color"), [1.0; 3]);
        let i = light.get("intensity").and_then(Value::as_f64).unwrap_or(1.0);
        // Intensity is per steradian in metres; positions were scaled by `scale`, so W/sr at a
        // distance scaled by `scale` falls off by scale²: keep irradiance invariant.
        let s2 = self.opts.scale * self.opts.scale;
        let (intensity, irradiance) = (color.map(|c| c * i * s2), color.map(|c| c * i));
        // The products too: finite factors such as 1e308 × 10 overflow.
        if !color.iter().chain(&intensity).chain(&irradiance).all(|c| c.is_finite()) || !i.is_finite() {
            return Err(SceneError::NonFinite { what: format!("light '{name}'") });
        }
        let position = world.transform_point3(DVec3::ZERO);
        // Lights shine along local -Z.
        let axis = world.transform_vector3(-DVec3::Z).normalize_or_zero();
        let l = match light.get("type").and_then(Value::as_str).unwrap_or("") {
            "point" => PunctualLight::Point { position, intensity },
            "spot" => {
                let inner = light.pointer("/spot/innerConeAngle").and_then(Value::as_f64).unwrap_or(0.0);
                let outer = light
                    .pointer("/spot/outerConeAngle")
                    .and_then(Value::as_f64)
                    .unwrap_or(std::f64::consts::FRAC_PI_4);
                PunctualLight::Spot { position, axis, intensity, inner, outer }
            }
            "directional" => PunctualLight::Directional { to_light: -axis, irradiance },
            other => {
                self.b.warn(format!("light '{name}': unknown type {other:?}, skipped"));
                return Ok(());
            }
        };
        if light.get("range").is_some() {
            self.b.warn(format!("light '{name}': range ignored (physical inverse-square falloff)"));
        }
        let index = self.b.punctual.len();
        self.b.punctual_names.resize(index, String::new());
        self.b.punctual_names.push(light.get("name").and_then(Value::as_str).unwrap_or("").to_owned());
        self.b.punctual.push(l);
        Ok(())
    }
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

#[cfg(test)]
mod tests;
