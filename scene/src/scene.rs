//! The scene: triangles with per-triangle diffuse materials, plus the lights.
//!
//! World frame: **+Z is up** (the SH polar axis of lightvol-sh). Loaders rotate +Y-up files
//! (glTF, most OBJ exports) into this frame, see [`UpAxis`].
//!
//! Front faces wind counter-clockwise: the geometric normal is `(v1 - v0) × (v2 - v0)`. A ray
//! with `dot(normal, direction) > 0` meets the back face; on a single-sided material that
//! is a *back-face hit* in the sense of Kontkanen & Laine 2006 §5.

use glam::{DVec2, DVec3, DVec4};

use crate::base_color::Texture;
use crate::error::SceneError;
pub use crate::instance::{Instance, Prototype};
use crate::lights::{Environment, PunctualLight, Sun};

/// How a material's base-colour alpha affects rays (glTF 2.0 §3.9.4 `alphaMode`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored: every hit is a surface.
    #[default]
    Opaque,
    /// Alpha-tested: a hit whose base-colour alpha (factor × texture at the hit's UV) is
    /// below `cutoff` is no surface, for every ray query (closest hit, occlusion, and so the
    /// domain-of-interest back-face test).
    Mask {
        /// `alphaCutoff` (glTF default 0.5).
        cutoff: f64,
    },
    /// Stochastic transparency: a hit is a surface with probability alpha, decided by a
    /// hash of the triangle and the ray, so results stay bit-identical across runs and
    /// thread counts (see [`crate::alpha`]).
    Blend,
}

impl AlphaMode {
    /// The glTF name (`OPAQUE`, `MASK`, `BLEND`).
    #[must_use]
    pub fn gltf_name(self) -> &'static str {
        match self {
            Self::Opaque => "OPAQUE",
            Self::Mask { .. } => "MASK",
            Self::Blend => "BLEND",
        }
    }
}

/// A diffuse material (Kontkanen & Laine 2006 Algorithm 2's `brdf`, Lambertian only).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name from the file (for reports).
    pub name: String,
    /// Diffuse albedo factor, linear RGB in [0, 1].
    pub albedo: [f64; 3],
    /// Optional base-colour texture (index into [`Scene::textures`]), multiplied by
    /// `albedo` at the hit's texture coordinates.
    pub albedo_texture: Option<u32>,
    /// Emitted radiance, linear RGB (W·sr⁻¹·m⁻² in scene units), from the front face (both
    /// faces if `double_sided`).
    pub emission: [f64; 3],
    /// Double-sided materials have no back face: both sides reflect and emit, and hitting
    /// them never marks a point as outside the domain of interest.
    pub double_sided: bool,
    /// Alpha handling of ray hits.
    pub alpha_mode: AlphaMode,
    /// Base-colour alpha factor (`baseColorFactor[3]`), multiplied by the texture's alpha.
    pub alpha: f64,
}

impl Material {
    /// A single-sided diffuse material.
    #[must_use]
    pub fn diffuse(name: &str, albedo: [f64; 3]) -> Self {
        Self {
            name: name.to_owned(),
            albedo,
            albedo_texture: None,
            emission: [0.0; 3],
            double_sided: false,
            alpha_mode: AlphaMode::Opaque,
            alpha: 1.0,
        }
    }

    /// A single-sided emitter with the given albedo.
    #[must_use]
    pub fn emitter(name: &str, albedo: [f64; 3], emission: [f64; 3]) -> Self {
        Self { emission, ..Self::diffuse(name, albedo) }
    }

    /// The same material, double-sided.
    #[must_use]
    pub fn two_sided(mut self) -> Self {
        self.double_sided = true;
        self
    }

    /// True when any emission channel is positive.
    #[must_use]
    pub fn is_emissive(&self) -> bool {
        self.emission.iter().any(|&e| e > 0.0)
    }
}

/// One triangle in world space (+Z up), counter-clockwise front face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Vertices.
    pub v: [DVec3; 3],
    /// Texture coordinates per vertex (zero when the file has none).
    pub uv: [DVec2; 3],
    /// Material index into [`Scene::materials`].
    pub material: u32,
}

impl Triangle {
    /// The unnormalised geometric normal `(v1 - v0) × (v2 - v0)` (length = twice the area).
    #[must_use]
    #[inline]
    pub fn cross(&self) -> DVec3 {
        (self.v[1] - self.v[0]).cross(self.v[2] - self.v[0])
    }

    /// Unit geometric normal (front side).
    #[must_use]
    #[inline]
    pub fn normal(&self) -> DVec3 {
        self.cross().normalize_or_zero()
    }

    /// Area.
    #[must_use]
    pub fn area(&self) -> f64 {
        0.5 * self.cross().length()
    }

    /// The point with barycentric weights `(1 - u - v, u, v)`.
    #[must_use]
    #[inline]
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        self.v[0] * (1.0 - u - v) + self.v[1] * u + self.v[2] * v
    }

    /// Interpolated texture coordinates.
    #[must_use]
    #[inline]
    pub fn uv_at(&self, u: f64, v: f64) -> DVec2 {
        self.uv[0] * (1.0 - u - v) + self.uv[1] * u + self.uv[2] * v
    }

    /// Centroid.
    #[must_use]
    pub fn centroid(&self) -> DVec3 {
        (self.v[0] + self.v[1] + self.v[2]) / 3.0
    }
}

/// Vertex attributes of one lightmap object (a glTF node's mesh instance, \[Ish11\] §2.1.1:
/// every static object gets its own coefficient maps). Arrays are vertex-indexed and in world
/// space; [`TriangleRef::vertices`] index them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshAttributes {
    /// Object name used in errors and output (the glTF mesh name, made unique by the loader).
    pub name: String,
    /// World-space positions.
    pub positions: Vec<DVec3>,
    /// Unit world-space shading normals (glTF `NORMAL`), if the file has them.
    pub normals: Option<Vec<DVec3>>,
    /// World-space tangents with handedness in `w` (glTF `TANGENT`): the bitangent is
    /// `w · normal × tangent` (MikkTSpace convention), if the file has them.
    pub tangents: Option<Vec<DVec4>>,
    /// Base texture coordinates (glTF `TEXCOORD_0`).
    pub uv0: Option<Vec<DVec2>>,
    /// Lightmap texture coordinates (glTF `TEXCOORD_1`).
    pub uv1: Option<Vec<DVec2>>,
}

/// Where a scene triangle came from: its object ([`Scene::meshes`]), its face index in that
/// object, and its three vertex indices (in the scene triangle's winding).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriangleRef {
    /// Index into [`Scene::meshes`].
    pub mesh: u32,
    /// Face index within the object (all primitives of the mesh counted in order).
    pub face: u32,
    /// Vertex indices into the object's attribute arrays, in the triangle's winding.
    pub vertices: [u32; 3],
}

/// A triangle is dropped as degenerate when twice its area is below this fraction of its
/// longest edge squared (its smallest angle is below ~1e-9 rad): f32 ray tests cannot hit
/// such slivers reliably, and their normals are noise.
pub const DEGENERATE_RELATIVE_AREA: f64 = 1e-9;

/// What a loader noticed besides errors.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadReport {
    /// Degenerate triangles skipped (see [`DEGENERATE_RELATIVE_AREA`]).
    pub degenerate_skipped: usize,
    /// Human-readable warnings (missing MTL or texture, unsupported features).
    pub warnings: Vec<String>,
    /// Triangles of the file's unique meshes, each mesh counted once however often it is
    /// instanced (equals the scene's triangle count for files without instancing).
    pub unique_triangles: usize,
    /// Mesh instances placed by the file (glTF node meshes and `EXT_mesh_gpu_instancing`
    /// instances; one per object for OBJ).
    pub instances: usize,
    /// The file's axis that points up (the loader's [`UpAxis`]).
    pub up: UpAxis,
    /// The extensions the file uses or requires, and what the loader did with each.
    pub extensions: Vec<ExtensionReport>,
}

/// One glTF extension the file names, and how the loader treated it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExtensionReport {
    /// The extension's name.
    pub name: String,
    /// Listed in `extensionsRequired`.
    pub required: bool,
    /// Where it appears (e.g. `materials`, `nodes`, `textures`), in first-seen order.
    pub used_in: Vec<String>,
    /// What the loader did: `supported`, or why it was ignored.
    pub treatment: String,
}

/// The axis that points up in a source file (lightvol-volume's [`lightvol_volume::frame`]);
/// the world frame of a [`Scene`] is always +Z up.
pub use lightvol_volume::frame::UpAxis;

/// The scene: geometry, materials, textures and lights. Build one with [`SceneBuilder`],
/// a loader ([`load_scene`](crate::load_scene)) or a built-in ([`builtin`](mod@crate::builtin)).
#[derive(Clone, Debug)]
pub struct Scene {
    /// A label (file name or built-in name).
    pub name: String,
    /// The triangles placed directly in the world frame (scene indices `0..len`; instanced
    /// geometry follows, see [`crate::instance`]).
    pub triangles: Vec<Triangle>,
    /// Meshes stored once in their own frame, placed by [`Scene::instances`].
    pub prototypes: Vec<Prototype>,
    /// Placements of [`Scene::prototypes`]; their triangles number after
    /// [`Scene::triangles`], in instance order.
    pub instances: Vec<Instance>,
    /// The materials.
    pub materials: Vec<Material>,
    /// Decoded textures.
    pub textures: Vec<Texture>,
    /// What surrounds the scene (uniform sky, lat-long map, or black).
    pub environment: Environment,
    /// An optional sun.
    pub sun: Option<Sun>,
    /// Point, spot and directional lights (glTF KHR_lights_punctual).
    pub punctual: Vec<PunctualLight>,
    /// Loader notes.
    pub report: LoadReport,
    /// Lightmap objects with their vertex attributes (empty for scenes without them).
    pub meshes: Vec<MeshAttributes>,
    /// Per triangle, its object and vertices: empty, or one entry per triangle (`None` for
    /// triangles that belong to no object). Code that edits [`Scene::triangles`] must keep it
    /// in step (or clear it).
    pub triangle_refs: Vec<Option<TriangleRef>>,
    /// Cameras from the file (glTF `cameras` placed by nodes), in the world frame.
    pub cameras: Vec<SceneCamera>,
}

/// A perspective camera from the scene file (glTF 2.0 §3.10), placed in the world frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneCamera {
    /// The camera's name, or `cameraN` after its index in the file.
    pub name: String,
    /// Eye position.
    pub position: DVec3,
    /// Unit view direction (the node's local -Z).
    pub forward: DVec3,
    /// Unit up direction (the node's local +Y).
    pub up: DVec3,
    /// Vertical field of view in radians (`yfov`).
    pub yfov: f64,
    /// Width / height (`aspectRatio`), when the file gives one.
    pub aspect: Option<f64>,
}

impl Scene {
    /// Axis-aligned bounds of the geometry (instances included).
    #[must_use]
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for t in &self.triangles {
            for v in t.v {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        for i in &self.instances {
            lo = lo.min(i.bounds.0);
            hi = hi.max(i.bounds.1);
        }
        (lo, hi)
    }

    /// A length used to offset secondary ray origins off surfaces: `1e-5` of the scene's
    /// extent plus its largest coordinate, i.e. about 100 f32 ulps at the scene's scale
    /// (the BVH intersects in f32).
    #[must_use]
    pub fn epsilon(&self) -> f64 {
        let (lo, hi) = self.bounds();
        RAY_EPSILON_RELATIVE * ((hi - lo).length() + lo.abs().max(hi.abs()).max_element())
    }

    /// Diffuse albedo of triangle `tri` at barycentrics `(u, v)`: factor × texture.
    #[must_use]
    pub fn albedo(&self, tri: u32, u: f64, v: f64) -> [f64; 3] {
        let (t, u, v) = self.stored_with_barycentrics(tri, u, v);
        let m = &self.materials[t.material as usize];
        match m.albedo_texture {
            Some(tex) => {
                let uv = t.uv_at(u, v);
                let c = self.textures[tex as usize].sample([uv.x, uv.y]);
                [m.albedo[0] * c[0], m.albedo[1] * c[1], m.albedo[2] * c[2]]
            }
            None => m.albedo,
        }
    }

    /// Base-colour alpha of triangle `tri` at barycentrics `(u, v)`: factor × texture alpha
    /// (glTF 2.0 §3.9.4); 1 for materials whose texture has no alpha channel.
    #[must_use]
    pub fn alpha(&self, tri: u32, u: f64, v: f64) -> f64 {
        let (t, u, v) = self.stored_with_barycentrics(tri, u, v);
        let m = &self.materials[t.material as usize];
        match m.albedo_texture {
            Some(tex) => {
                let uv = t.uv_at(u, v);
                m.alpha * self.textures[tex as usize].sample_alpha([uv.x, uv.y])
            }
            None => m.alpha,
        }
    }

    /// The stored triangle of `tri` with barycentrics `(u, v)` of the placed triangle
    /// carried to its vertex order (swapped under a mirroring instance, whose placed
    /// vertices 1 and 2 are the stored 2 and 1).
    fn stored_with_barycentrics(&self, tri: u32, u: f64, v: f64) -> (&Triangle, f64, f64) {
        match self.locate(tri) {
            crate::instance::Located::World(i) => (&self.triangles[i as usize], u, v),
            crate::instance::Located::Instanced { instance, local } => {
                let inst = &self.instances[instance as usize];
                let t = &self.prototypes[inst.prototype as usize].triangles[local as usize];
                if inst.mirrored() { (t, v, u) } else { (t, u, v) }
            }
        }
    }

    /// The material of triangle `tri`.
    #[must_use]
    #[inline]
    pub fn material_of(&self, tri: u32) -> &Material {
        &self.materials[self.stored_triangle(tri).material as usize]
    }
}

/// The faces of the axis-aligned box `lo..hi` as quads, counter-clockwise seen from outside
/// (`outward`) or from inside; `skip_bottom` leaves out the -Z face. Order: +X, -X, +Y, -Y,
/// +Z, -Z.
#[must_use]
pub fn box_faces(lo: DVec3, hi: DVec3, outward: bool, skip_bottom: bool) -> Vec<[DVec3; 4]> {
    let c = |x: usize, y: usize, z: usize| {
        DVec3::new(
            if x == 0 { lo.x } else { hi.x },
            if y == 0 { lo.y } else { hi.y },
            if z == 0 { lo.z } else { hi.z },
        )
    };
    // Each face listed counter-clockwise seen from outside.
    let faces = [
        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)], // +X
        [c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)], // -X
        [c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)], // +Y
        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)], // -Y
        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)], // +Z
        [c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)], // -Z
    ];
    faces
        .into_iter()
        .take(if skip_bottom { 5 } else { 6 })
        .map(|mut q| {
            if !outward {
                q.reverse();
            }
            q
        })
        .collect()
}

/// Relative size of the self-intersection offset, see [`Scene::epsilon`].
pub const RAY_EPSILON_RELATIVE: f64 = 1e-5;

/// Assembles a [`Scene`], validating as it goes.
#[derive(Debug, Default)]
pub struct SceneBuilder {
    scene_name: String,
    triangles: Vec<Triangle>,
    materials: Vec<Material>,
    textures: Vec<Texture>,
    report: LoadReport,
    meshes: Vec<MeshAttributes>,
    triangle_refs: Vec<Option<TriangleRef>>,
    prototypes: Vec<Prototype>,
    instances: Vec<Instance>,
    /// Cameras to attach.
    pub cameras: Vec<SceneCamera>,
    /// Lights to attach.
    pub environment: Environment,
    /// Sun to attach.
    pub sun: Option<Sun>,
    /// Punctual lights to attach.
    pub punctual: Vec<PunctualLight>,
}

impl SceneBuilder {
    /// An empty builder for a scene called `name`.
    #[must_use]
    pub fn new(name: &str) -> Self {
        Self { scene_name: name.to_owned(), ..Self::default() }
    }

    /// Adds a material, returning its index.
    ///
    /// # Errors
    /// [`SceneError::NonFinite`] if a factor is NaN or infinite.
    pub fn add_material(&mut self, m: Material) -> Result<u32, SceneError> {
        if !m.albedo.iter().chain(m.emission.iter()).all(|x| x.is_finite()) {
            return Err(SceneError::NonFinite { what: format!("material '{}'", m.name) });
        }
        self.materials.push(m);
        Ok(self.materials.len() as u32 - 1)
    }

    /// Adds a texture, returning its index.
    pub fn add_texture(&mut self, t: Texture) -> u32 {
        self.textures.push(t);
        self.textures.len() as u32 - 1
    }

    /// Records a warning.
    pub fn warn(&mut self, w: String) {
        self.report.warnings.push(w);
    }

    /// The loader notes so far, to fill in counts and extension reports.
    pub fn report_mut(&mut self) -> &mut LoadReport {
        &mut self.report
    }

    /// Number of materials so far.
    #[must_use]
    pub fn material_count(&self) -> usize {
        self.materials.len()
    }

    /// Adds a triangle. Returns `Ok(false)` (and counts it) when it is degenerate.
    ///
    /// # Errors
    /// [`SceneError::NonFinite`] for NaN/infinite coordinates, [`SceneError::BadMaterial`]
    /// for an unknown material.
    pub fn add_triangle(&mut self, v: [DVec3; 3], uv: [DVec2; 3], material: u32) -> Result<bool, SceneError> {
        let Some(tri) = self.checked(v, uv, material, self.triangles.len())? else { return Ok(false) };
        self.triangles.push(tri);
        if !self.triangle_refs.is_empty() {
            self.triangle_refs.push(None);
        }
        Ok(true)
    }

    /// Validates a triangle: `None` (counted) when it is degenerate.
    fn checked(
        &mut self,
        v: [DVec3; 3],
        uv: [DVec2; 3],
        material: u32,
        index: usize,
    ) -> Result<Option<Triangle>, SceneError> {
        if !v.iter().all(|p| p.is_finite()) {
            return Err(SceneError::NonFinite {
                what: format!("vertex of triangle {index} in scene '{}'", self.scene_name),
            });
        }
        if material as usize >= self.materials.len() {
            return Err(SceneError::BadMaterial { index: material, count: self.materials.len() });
        }
        let uv = if uv.iter().all(|t| t.is_finite()) { uv } else { [DVec2::ZERO; 3] };
        let tri = Triangle { v, uv, material };
        let longest = (v[1] - v[0])
            .length_squared()
            .max((v[2] - v[1]).length_squared())
            .max((v[0] - v[2]).length_squared());
        if !(tri.cross().length() > DEGENERATE_RELATIVE_AREA * longest) {
            self.report.degenerate_skipped += 1;
            return Ok(None);
        }
        Ok(Some(tri))
    }

    /// Starts a prototype (a mesh to instance), returning its index for
    /// [`add_prototype_triangle`](Self::add_prototype_triangle) and
    /// [`add_instance`](Self::add_instance).
    pub fn add_prototype(&mut self, name: &str) -> u32 {
        self.prototypes.push(Prototype { name: name.to_owned(), triangles: Vec::new() });
        self.prototypes.len() as u32 - 1
    }

    /// Adds a triangle, in the prototype's frame, to prototype `p`. Returns `Ok(false)` (and
    /// counts it) when it is degenerate there.
    ///
    /// # Errors
    /// As [`add_triangle`](Self::add_triangle), and [`SceneError::BadMesh`] for an unknown
    /// prototype.
    pub fn add_prototype_triangle(
        &mut self,
        p: u32,
        v: [DVec3; 3],
        uv: [DVec2; 3],
        material: u32,
    ) -> Result<bool, SceneError> {
        let Some(n) = self.prototypes.get(p as usize).map(|q| q.triangles.len()) else {
            return Err(SceneError::BadMesh(format!("prototype {p} of {}", self.prototypes.len())));
        };
        let Some(tri) = self.checked(v, uv, material, n)? else { return Ok(false) };
        self.prototypes[p as usize].triangles.push(tri);
        Ok(true)
    }

    /// Places prototype `p` with `to_world` (prototype frame → world frame).
    ///
    /// # Errors
    /// [`SceneError::BadMesh`] for an unknown prototype, [`SceneError::NonFinite`] for a
    /// transform with NaN or infinite entries.
    pub fn add_instance(&mut self, p: u32, to_world: glam::DAffine3) -> Result<(), SceneError> {
        if p as usize >= self.prototypes.len() {
            return Err(SceneError::BadMesh(format!("prototype {p} of {}", self.prototypes.len())));
        }
        if !to_world.is_finite() {
            return Err(SceneError::NonFinite {
                what: format!("instance transform in scene '{}'", self.scene_name),
            });
        }
        self.instances.push(Instance {
            prototype: p,
            to_world,
            first: 0,
            bounds: (DVec3::ZERO, DVec3::ZERO),
        });
        Ok(())
    }

    /// Adds a lightmap object's attributes, returning its index for [`TriangleRef::mesh`].
    pub fn add_mesh(&mut self, m: MeshAttributes) -> u32 {
        self.meshes.push(m);
        self.meshes.len() as u32 - 1
    }

    /// Adds a triangle that belongs to a lightmap object. Returns `Ok(false)` (and counts
    /// it) when it is degenerate.
    ///
    /// # Errors
    /// As [`add_triangle`](Self::add_triangle), and [`SceneError::BadMesh`] when `r` names
    /// an object or a vertex that does not exist.
    pub fn add_mesh_triangle(
        &mut self,
        v: [DVec3; 3],
        uv: [DVec2; 3],
        material: u32,
        r: TriangleRef,
    ) -> Result<bool, SceneError> {
        let Some(m) = self.meshes.get(r.mesh as usize) else {
            return Err(SceneError::BadMesh(format!("mesh {} of {}", r.mesh, self.meshes.len())));
        };
        if r.vertices.iter().any(|&i| i as usize >= m.positions.len()) {
            return Err(SceneError::BadMesh(format!(
                "face {} of mesh '{}' refers to vertex {:?} of {}",
                r.face,
                m.name,
                r.vertices,
                m.positions.len()
            )));
        }
        let kept = self.add_triangle(v, uv, material)?;
        if kept {
            // Earlier plain triangles get `None` (add_triangle only pads once refs exist).
            self.triangle_refs.resize(self.triangles.len(), None);
            self.triangle_refs[self.triangles.len() - 1] = Some(r);
        }
        Ok(kept)
    }

    /// Adds a planar quad `a b c d` (counter-clockwise seen from the front) as two triangles.
    ///
    /// # Errors
    /// As [`add_triangle`](Self::add_triangle).
    pub fn add_quad(&mut self, q: [DVec3; 4], material: u32) -> Result<(), SceneError> {
        let uv = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(1.0, 1.0), DVec2::new(0.0, 1.0)];
        self.add_triangle([q[0], q[1], q[2]], [uv[0], uv[1], uv[2]], material)?;
        self.add_triangle([q[0], q[2], q[3]], [uv[0], uv[2], uv[3]], material)?;
        Ok(())
    }

    /// Adds an axis-aligned box as 12 triangles with outward (`outward = true`) or inward
    /// normals. `skip_bottom` omits the -Z face (buildings standing on the ground).
    ///
    /// # Errors
    /// As [`add_triangle`](Self::add_triangle).
    pub fn add_box(
        &mut self,
        lo: DVec3,
        hi: DVec3,
        material: u32,
        outward: bool,
        skip_bottom: bool,
    ) -> Result<(), SceneError> {
        for q in box_faces(lo, hi, outward, skip_bottom) {
            self.add_quad(q, material)?;
        }
        Ok(())
    }

    /// Finishes the scene.
    ///
    /// # Errors
    /// [`SceneError::Empty`] when no triangle was kept.
    pub fn build(mut self) -> Result<Scene, SceneError> {
        crate::instance::finish_instances(
            self.triangles.len(),
            &self.prototypes,
            &mut self.instances,
            &self.scene_name,
        )?;
        if self.triangles.is_empty() && self.instances.is_empty() {
            return Err(SceneError::Empty(self.scene_name));
        }
        Ok(Scene {
            name: self.scene_name,
            triangles: self.triangles,
            prototypes: self.prototypes,
            instances: self.instances,
            materials: self.materials,
            textures: self.textures,
            environment: self.environment,
            sun: self.sun,
            punctual: self.punctual,
            report: self.report,
            meshes: self.meshes,
            triangle_refs: self.triangle_refs,
            cameras: self.cameras,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builder_skips_degenerate_and_rejects_nan() {
        let mut b = SceneBuilder::new("t");
        let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
        let ok = b.add_triangle([DVec3::ZERO, DVec3::X, DVec3::Y], [DVec2::ZERO; 3], m).unwrap();
        let collinear = b.add_triangle([DVec3::ZERO, DVec3::X, 2.0 * DVec3::X], [DVec2::ZERO; 3], m).unwrap();
        assert!(ok && !collinear);
        assert!(matches!(
            b.add_triangle([DVec3::ZERO, DVec3::X, DVec3::new(f64::NAN, 0.0, 0.0)], [DVec2::ZERO; 3], m),
            Err(SceneError::NonFinite { .. })
        ));
        assert!(matches!(
            b.add_triangle([DVec3::ZERO, DVec3::X, DVec3::Y], [DVec2::ZERO; 3], 9),
            Err(SceneError::BadMaterial { .. })
        ));
        let s = b.build().unwrap();
        assert_eq!(s.triangles.len(), 1);
        assert_eq!(s.report.degenerate_skipped, 1);
        assert!(matches!(SceneBuilder::new("e").build(), Err(SceneError::Empty(_))));
    }

    /// Every face of an outward box has its normal pointing away from the centre.
    #[test]
    fn box_normals_point_outward() {
        let mut b = SceneBuilder::new("box");
        let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
        let (lo, hi) = (DVec3::new(-1.0, -2.0, 0.0), DVec3::new(1.0, 1.0, 3.0));
        b.add_box(lo, hi, m, true, false).unwrap();
        let s = b.build().unwrap();
        assert_eq!(s.triangles.len(), 12);
        let centre = (lo + hi) / 2.0;
        let total: f64 = s.triangles.iter().map(Triangle::area).sum();
        assert!((total - 2.0 * (2.0 * 3.0 + 2.0 * 3.0 + 3.0 * 3.0)).abs() < 1e-12);
        for t in &s.triangles {
            assert!(t.normal().dot(t.centroid() - centre) > 0.0);
        }
    }
}
