//! One triangle of a scene, in world space (+Z up), with its texture coordinates and material,
//! and where a loaded triangle came from (its lightmap object and vertices).

use glam::{DVec2, DVec3, DVec4};

/// One triangle in world space (+Z up), counter-clockwise front face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Vertices.
    pub v: [DVec3; 3],
    /// Texture coordinates per vertex (zero when the file has none).
    pub uv: [DVec2; 3],
    /// Material index into [`Scene::materials`](crate::Scene::materials).
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

/// Where a scene triangle came from: its object ([`Scene::meshes`](crate::Scene::meshes)), its face index in that
/// object, and its three vertex indices (in the scene triangle's winding).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriangleRef {
    /// Index into [`Scene::meshes`](crate::Scene::meshes).
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

/// Double-precision Möller-Trumbore: `(t, u, v)` with barycentric weights `u` (vertex 1)
/// and `v` (vertex 2), both faces.
#[must_use]
pub fn intersect_f64(v: &[DVec3; 3], o: DVec3, d: DVec3) -> Option<(f64, f64, f64)> {
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - v[0];
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let w = d.dot(q) * inv;
    if w < 0.0 || u + w > 1.0 {
        return None;
    }
    Some((e2.dot(q) * inv, u, w))
}
