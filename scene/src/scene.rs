//! The scene: triangles with per-triangle diffuse materials, plus the lights.
//!
//! World frame: **+Z is up** (the SH polar axis of lightvol-sh). Loaders rotate +Y-up files
//! (glTF, most OBJ exports) into this frame, see [`UpAxis`].
//!
//! Front faces wind counter-clockwise: the geometric normal is `(v1 - v0) × (v2 - v0)`. A ray
//! with `dot(normal, direction) > 0` meets the back face; on a single-sided material that
//! is a *back-face hit* in the sense of Kontkanen & Laine 2006 §5.

use glam::DVec3;

use crate::base_color::Texture;
use crate::instance::{Instance, Located, Prototype};
use crate::lights::{Environment, PunctualLight, Sun};
use crate::material::Material;
use crate::triangle::{MeshAttributes, Triangle, TriangleRef};

/// What a loader noticed besides errors.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadReport {
    /// Degenerate triangles skipped (see [`DEGENERATE_RELATIVE_AREA`](crate::triangle::DEGENERATE_RELATIVE_AREA)).
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

/// The scene: geometry, materials, textures and lights. Build one with [`SceneBuilder`](crate::builder::SceneBuilder),
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
    /// Names of [`Scene::punctual`]'s lights, in the same order (glTF `name`); a light past
    /// its end is unnamed ([`Scene::punctual_name`]).
    pub punctual_names: Vec<String>,
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

    /// The interpolated shading normal of triangle `tri` at barycentrics `(u, v)`: the
    /// file's vertex normals (glTF `NORMAL`, in the world frame) blended with the
    /// barycentric weights `(1 − u − v, u, v)` and normalised, as engines shade; `None`
    /// for triangles without vertex normals (OBJ files, built-in scenes, instanced meshes)
    /// or where the blend vanishes.
    #[must_use]
    pub fn shading_normal(&self, tri: u32, u: f64, v: f64) -> Option<DVec3> {
        let Located::World(i) = self.locate(tri) else { return None };
        let r = self.triangle_refs.get(i as usize)?.as_ref()?;
        let normals = self.meshes.get(r.mesh as usize)?.normals.as_ref()?;
        let [a, b, c] = r.vertices.map(|k| normals.get(k as usize).copied());
        (a? * (1.0 - u - v) + b? * u + c? * v).try_normalize()
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
            Located::World(i) => (&self.triangles[i as usize], u, v),
            Located::Instanced { instance, local } => {
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

    /// The name of punctual light `i`: its name in the file, or `lightN` after its index
    /// when it has none.
    #[must_use]
    pub fn punctual_name(&self, i: usize) -> String {
        self.punctual_names.get(i).filter(|n| !n.is_empty()).cloned().unwrap_or_else(|| format!("light{i}"))
    }
}

/// Relative size of the self-intersection offset, see [`Scene::epsilon`].
pub const RAY_EPSILON_RELATIVE: f64 = 1e-5;

/// Triangles and their placements: the scene numbering across directly placed and
/// instanced geometry ([`crate::instance`]).
impl Scene {
    /// Number of scene triangles: those placed directly plus every instance's.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
            + self
                .instances
                .iter()
                .map(|i| self.prototypes[i.prototype as usize].triangles.len())
                .sum::<usize>()
    }

    /// Number of triangles stored: those placed directly plus each prototype's once.
    #[must_use]
    pub fn unique_triangle_count(&self) -> usize {
        self.triangles.len() + self.prototypes.iter().map(|p| p.triangles.len()).sum::<usize>()
    }

    /// True when the scene has instances (its geometry is not all in [`Scene::triangles`]).
    #[must_use]
    #[inline]
    pub fn is_instanced(&self) -> bool {
        !self.instances.is_empty()
    }

    /// Where scene triangle `tri` is stored.
    ///
    /// # Panics
    /// When `tri` is not below [`triangle_count`](Self::triangle_count).
    #[must_use]
    #[inline]
    pub fn locate(&self, tri: u32) -> Located {
        let n = self.triangles.len() as u32;
        if tri < n {
            return Located::World(tri);
        }
        let k = self.instances.partition_point(|i| i.first <= tri) - 1;
        let inst = &self.instances[k];
        let local = tri - inst.first;
        assert!(
            (local as usize) < self.prototypes[inst.prototype as usize].triangles.len(),
            "triangle {tri} out of range"
        );
        Located::Instanced { instance: k as u32, local }
    }

    /// Scene triangle `tri` as stored: its material and UVs are the placed triangle's, its
    /// vertices are in its prototype's frame when it is instanced (use
    /// [`triangle`](Self::triangle) for world positions).
    #[must_use]
    #[inline]
    pub fn stored_triangle(&self, tri: u32) -> &Triangle {
        match self.locate(tri) {
            Located::World(i) => &self.triangles[i as usize],
            Located::Instanced { instance, local } => {
                let p = self.instances[instance as usize].prototype;
                &self.prototypes[p as usize].triangles[local as usize]
            }
        }
    }

    /// Scene triangle `tri` in the world frame.
    #[must_use]
    #[inline]
    pub fn triangle(&self, tri: u32) -> Triangle {
        match self.locate(tri) {
            Located::World(i) => self.triangles[i as usize],
            Located::Instanced { instance, local } => {
                let inst = &self.instances[instance as usize];
                inst.place(&self.prototypes[inst.prototype as usize].triangles[local as usize])
            }
        }
    }

    /// Every scene triangle in the world frame, in scene order.
    pub fn world_triangles(&self) -> impl Iterator<Item = Triangle> + '_ {
        self.triangles.iter().copied().chain(self.instances.iter().flat_map(move |inst| {
            self.prototypes[inst.prototype as usize].triangles.iter().map(move |t| inst.place(t))
        }))
    }

    /// Every scene triangle as stored ([`stored_triangle`](Self::stored_triangle)) with its
    /// scene index and its instance, in scene order: for passes that need materials or UVs
    /// only, without transforming anything.
    pub fn stored_triangles(&self) -> impl Iterator<Item = (u32, &Triangle, Option<&Instance>)> + '_ {
        let n = self.triangles.len() as u32;
        self.triangles.iter().zip(0..n).map(|(t, i)| (i, t, None)).chain(self.instances.iter().flat_map(
            move |inst| {
                let tris = &self.prototypes[inst.prototype as usize].triangles;
                tris.iter().zip(inst.first..).map(move |(t, i)| (i, t, Some(inst)))
            },
        ))
    }

    /// The same scene with every instance written out into [`Scene::triangles`], in scene
    /// order (so triangle indices are unchanged). Lightmap objects keep their references to
    /// the directly placed triangles; instanced triangles have none.
    #[must_use]
    pub fn flattened(&self) -> Scene {
        let mut s = self.clone();
        let direct = s.triangles.len();
        s.triangles = self.world_triangles().collect();
        if !s.triangle_refs.is_empty() {
            s.triangle_refs.resize(s.triangles.len(), None);
        }
        debug_assert!(s.triangles.len() >= direct);
        s.prototypes.clear();
        s.instances.clear();
        s
    }
}
