//! Per-scene surface geometry: which lightmap object each triangle belongs to, its lightmap
//! UVs and its per-corner tangent frames. Built once per scene and UV set; renderers use it
//! to find the map, texel and tangent frame of a ray hit.

use glam::{DVec2, DVec3, DVec4};

use super::tangent::{MikkInput, TangentFrame, mikktspace_tangents};
use super::{SurfaceError, UvSet};
use lightvol_scene::scene::Scene;

/// One lightmap object: the triangles of a glTF mesh instance.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceObject {
    /// Object name (from [`MeshAttributes::name`](lightvol_scene::triangle::MeshAttributes)).
    pub name: String,
    /// Index into [`Scene::meshes`].
    pub mesh: u32,
    /// Scene triangle indices, in face order.
    pub triangles: Vec<u32>,
    /// The largest singular value of the UV → world Jacobian over the object's triangles
    /// (world units per UV unit along the most stretched direction).
    pub max_world_per_uv: f64,
    /// Surface area (world units²).
    pub area: f64,
}

/// Surface attributes of one scene triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleSurface {
    /// Index into [`SurfaceGeometry::objects`].
    pub object: u32,
    /// Face index within the object's mesh (for error messages).
    pub face: u32,
    /// Lightmap UVs of the corners.
    pub uv: [DVec2; 3],
    /// Shading normals of the corners (the geometric normal where the file has none).
    pub normals: [DVec3; 3],
    /// Tangents of the corners, `w` = handedness.
    pub tangents: [DVec4; 3],
}

/// The surface attributes of a scene (see the module docs).
#[derive(Clone, Debug)]
pub struct SurfaceGeometry {
    uv_set: UvSet,
    objects: Vec<SurfaceObject>,
    tris: Vec<Option<TriangleSurface>>,
    geometric: Vec<DVec3>,
}

/// A UV triangle whose doubled area is below this fraction of its longest edge squared has no
/// usable texel footprint (the same relative test as
/// [`DEGENERATE_RELATIVE_AREA`](lightvol_scene::triangle::DEGENERATE_RELATIVE_AREA) for positions).
pub const DEGENERATE_UV_RELATIVE_AREA: f64 = 1e-9;

/// Lightmap UVs may exceed `[0, 1]` by this much (f32 storage of exactly 0 or 1 after a
/// modelling tool's transforms); anything further out is an error.
pub const UV_RANGE_TOLERANCE: f64 = 1e-6;

impl SurfaceGeometry {
    /// Collects the lightmap objects of `scene` with the UV set `uv_set`, checks that every
    /// lightmap UV is finite and in `[0, 1]` and that no UV triangle is degenerate, and builds
    /// the tangent frames (glTF `TANGENT` if present, else MikkTSpace on the base UVs, or on the
    /// lightmap UVs for objects without `TEXCOORD_0`). Objects without triangles are skipped.
    ///
    /// # Errors
    /// [`SurfaceError::NoLightmapObjects`], [`SurfaceError::MissingUvSet`],
    /// [`SurfaceError::UvOutOfRange`], [`SurfaceError::DegenerateUv`],
    /// [`SurfaceError::Tangents`], [`SurfaceError::InconsistentScene`].
    pub fn new(scene: &Scene, uv_set: UvSet) -> Result<Self, SurfaceError> {
        let nt = scene.triangles.len();
        if !scene.triangle_refs.is_empty() && scene.triangle_refs.len() != nt {
            return Err(SurfaceError::InconsistentScene(format!(
                "{} triangle references for {nt} triangles",
                scene.triangle_refs.len()
            )));
        }
        // Triangles per mesh, in scene order (= face order for the loaders).
        let mut per_mesh: Vec<Vec<u32>> = vec![Vec::new(); scene.meshes.len()];
        for (i, r) in scene.triangle_refs.iter().enumerate() {
            if let Some(r) = r {
                let list = per_mesh.get_mut(r.mesh as usize).ok_or_else(|| {
                    SurfaceError::InconsistentScene(format!("triangle {i} refers to mesh {}", r.mesh))
                })?;
                list.push(i as u32);
            }
        }
        let geometric: Vec<DVec3> =
            scene.triangles.iter().map(lightvol_scene::triangle::Triangle::normal).collect();
        let mut objects = Vec::new();
        let mut tris = vec![None; nt];
        for (mesh_index, tri_ids) in per_mesh.iter().enumerate() {
            if tri_ids.is_empty() {
                continue;
            }
            let mesh = &scene.meshes[mesh_index];
            let object = objects.len() as u32;
            let nv = mesh.positions.len();
            let luv = match uv_set {
                UvSet::Lightmap => mesh.uv1.as_ref(),
                UvSet::Base => mesh.uv0.as_ref(),
            }
            .ok_or_else(|| SurfaceError::MissingUvSet { mesh: mesh.name.clone(), set: uv_set })?;
            let inconsistent = |what: &str| {
                SurfaceError::InconsistentScene(format!(
                    "mesh '{}': {what} count differs from positions",
                    mesh.name
                ))
            };
            if luv.len() != nv {
                return Err(inconsistent("UV"));
            }
            if mesh.normals.as_ref().is_some_and(|n| n.len() != nv) {
                return Err(inconsistent("normal"));
            }
            if mesh.tangents.as_ref().is_some_and(|t| t.len() != nv) {
                return Err(inconsistent("tangent"));
            }
            if mesh.uv0.as_ref().is_some_and(|t| t.len() != nv) {
                return Err(inconsistent("TEXCOORD_0"));
            }
            let refs: Vec<_> =
                tri_ids.iter().map(|&i| scene.triangle_refs[i as usize].expect("listed")).collect();
            // Range and degeneracy, in face order.
            let mut max_scale: f64 = 0.0;
            let mut area = 0.0;
            for (&ti, r) in tri_ids.iter().zip(&refs) {
                let uv = r.vertices.map(|v| luv[v as usize]);
                for p in uv {
                    let ok = |x: f64| {
                        x.is_finite() && (-UV_RANGE_TOLERANCE..=1.0 + UV_RANGE_TOLERANCE).contains(&x)
                    };
                    if !(ok(p.x) && ok(p.y)) {
                        return Err(SurfaceError::UvOutOfRange {
                            mesh: mesh.name.clone(),
                            triangle: r.face,
                            uv: [p.x, p.y],
                        });
                    }
                }
                let t = &scene.triangles[ti as usize];
                let s = world_per_uv(t.v, uv).ok_or_else(|| SurfaceError::DegenerateUv {
                    mesh: mesh.name.clone(),
                    triangle: r.face,
                })?;
                max_scale = max_scale.max(s);
                area += t.area();
            }
            // Tangent frames per corner.
            let faces: Vec<[u32; 3]> = refs.iter().map(|r| r.vertices).collect();
            let corner_tangents: Vec<[DVec4; 3]> = match &mesh.tangents {
                Some(t) => faces.iter().map(|f| f.map(|v| t[v as usize])).collect(),
                None => {
                    let uvs = mesh.uv0.as_deref().unwrap_or(luv);
                    mikktspace_tangents(&MikkInput {
                        positions: &mesh.positions,
                        normals: mesh.normals.as_deref(),
                        uvs,
                        faces: &faces,
                    })
                    .map_err(|message| SurfaceError::Tangents { mesh: mesh.name.clone(), message })?
                }
            };
            for ((&ti, r), tan) in tri_ids.iter().zip(&refs).zip(corner_tangents) {
                let g = geometric[ti as usize];
                let normals = match &mesh.normals {
                    Some(n) => r.vertices.map(|v| {
                        let n = n[v as usize];
                        // A missing or reversed shading normal falls back to the face's.
                        if n.dot(g) > 0.0 { n } else { g }
                    }),
                    None => [g; 3],
                };
                tris[ti as usize] = Some(TriangleSurface {
                    object,
                    face: r.face,
                    uv: r.vertices.map(|v| luv[v as usize]),
                    normals,
                    tangents: tan,
                });
            }
            objects.push(SurfaceObject {
                name: mesh.name.clone(),
                mesh: mesh_index as u32,
                triangles: tri_ids.clone(),
                max_world_per_uv: max_scale,
                area,
            });
        }
        if objects.is_empty() {
            return Err(SurfaceError::NoLightmapObjects);
        }
        Ok(Self { uv_set, objects, tris, geometric })
    }

    /// The UV set the lightmap coordinates come from.
    #[must_use]
    pub fn uv_set(&self) -> UvSet {
        self.uv_set
    }

    /// The lightmap objects (the order of the baked maps).
    #[must_use]
    pub fn objects(&self) -> &[SurfaceObject] {
        &self.objects
    }

    /// Surface attributes of scene triangle `tri` (`None` when it belongs to no object).
    #[must_use]
    #[inline]
    pub fn triangle(&self, tri: u32) -> Option<&TriangleSurface> {
        self.tris.get(tri as usize)?.as_ref()
    }

    /// The object (index into [`objects`](Self::objects) and the baked maps) of `tri`.
    #[must_use]
    pub fn object_of(&self, tri: u32) -> Option<usize> {
        self.triangle(tri).map(|t| t.object as usize)
    }

    /// Lightmap UV at barycentrics `(u, v)` (weights `1-u-v, u, v` of corners 0, 1, 2).
    #[must_use]
    pub fn lightmap_uv(&self, tri: u32, bary: [f64; 2]) -> Option<[f64; 2]> {
        let t = self.triangle(tri)?;
        let [u, v] = bary;
        Some((t.uv[0] * (1.0 - u - v) + t.uv[1] * u + t.uv[2] * v).to_array())
    }

    /// Unit geometric (face) normal of scene triangle `tri`.
    #[must_use]
    pub fn geometric_normal(&self, tri: u32) -> DVec3 {
        self.geometric[tri as usize]
    }

    /// Tangent frame at barycentrics `(u, v)`: normal and tangent interpolated, normalised and
    /// orthogonalised ([`TangentFrame::from_normal_tangent`]), handedness from the sign of the
    /// interpolated `w`.
    #[must_use]
    pub fn frame(&self, tri: u32, bary: [f64; 2]) -> Option<TangentFrame> {
        let t = self.triangle(tri)?;
        let [u, v] = bary;
        let w = [1.0 - u - v, u, v];
        let n = t.normals[0] * w[0] + t.normals[1] * w[1] + t.normals[2] * w[2];
        let tg = t.tangents[0] * w[0] + t.tangents[1] * w[1] + t.tangents[2] * w[2];
        let n = if n.dot(self.geometric[tri as usize]) > 0.0 { n } else { self.geometric[tri as usize] };
        Some(TangentFrame::from_normal_tangent(n, tg.truncate(), tg.w))
    }
}

/// World units per UV unit along the most stretched direction of one triangle: the largest
/// singular value of the Jacobian `[dP/du dP/dv]`; `None` for a degenerate UV triangle.
#[must_use]
pub fn world_per_uv(p: [DVec3; 3], uv: [DVec2; 3]) -> Option<f64> {
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let det = d1.perp_dot(d2);
    let longest = d1.length_squared().max(d2.length_squared()).max((uv[2] - uv[1]).length_squared());
    if !(det.abs() > DEGENERATE_UV_RELATIVE_AREA * longest) {
        return None;
    }
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let dpdu = (e1 * d2.y - e2 * d1.y) / det;
    let dpdv = (e2 * d1.x - e1 * d2.x) / det;
    let (a, c, b) = (dpdu.length_squared(), dpdv.length_squared(), dpdu.dot(dpdv));
    let s2 = 0.5 * (a + c) + (0.25 * (a - c) * (a - c) + b * b).sqrt();
    Some(s2.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest singular value against a brute-force maximum of |J d| over unit UV
    /// directions d.
    #[test]
    fn world_per_uv_is_the_largest_stretch() {
        const TOL: f64 = 1e-6; // 1e5 directions: angular step 6e-5, quadratic error ~2e-9 relative
        let p = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(3.0, 0.5, 1.0), DVec3::new(-0.5, 2.0, 0.2)];
        let uv = [DVec2::new(0.1, 0.1), DVec2::new(0.4, 0.15), DVec2::new(0.2, 0.6)];
        let s = world_per_uv(p, uv).unwrap();
        let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let mut best: f64 = 0.0;
        for k in 0..100_000 {
            let a = std::f64::consts::PI * f64::from(k) / 100_000.0;
            let d = DVec2::new(a.cos(), a.sin());
            // Solve d = α d1 + β d2 and map to α e1 + β e2.
            let det = d1.perp_dot(d2);
            let (al, be) = (d.perp_dot(d2) / det, d1.perp_dot(d) / det);
            best = best.max((e1 * al + e2 * be).length());
        }
        assert!((s - best).abs() < TOL * s, "{s} vs {best}");
        assert!(world_per_uv(p, [DVec2::ZERO, DVec2::X, DVec2::X * 2.0]).is_none());
    }
}
