//! Ray tracing with `obvhs` 0.4: a compressed-wide BVH (CwBvh) over the scene's triangles.
//!
//! Known obvhs 0.4 pitfalls handled here:
//! - the BVH reorders primitives: `primitive_id` indexes `primitive_indices`, which maps
//!   back to the scene's triangle order; we store the triangles in BVH order and keep the
//!   map (`order`) so every [`Hit::triangle`] is a *scene* index;
//! - `Triangle::compute_barycentric` is wrong in 0.4; we use
//!   `RtTriangle::compute_barycentric` (checked against an f64 reference in the tests);
//! - `ray_traverse_anyhit` visits *all* hits; shadow rays use `ray_traverse_miss`, which
//!   stops at the first hit.
//!
//! Intersection runs in f32 (obvhs' Möller-Trumbore). Hit data returned to callers is f64,
//! recomputed on the scene's f64 triangle where that is more accurate (normal, position).
//!
//! Alpha-tested and transparent materials are decided inside the traversal
//! ([`crate::alpha`]): a candidate hit that is no surface is rejected before it can become
//! the closest hit or block a shadow ray.

use std::time::Duration;

use glam::{DVec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::{Ray, RayHit};
use obvhs::rt_triangle::RtTriangle;
use obvhs::triangle::Triangle as ObTriangle;

use crate::alpha::{AlphaTable, ray_key};
use crate::scene::Scene;

/// A closest hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Triangle index in scene order.
    pub triangle: u32,
    /// Distance along the (unit) ray direction.
    pub t: f64,
    /// Barycentric weights `(u, v)` of vertices 1 and 2 (vertex 0 gets `1 - u - v`).
    pub bary: [f64; 2],
    /// Unit geometric normal of the triangle's front face.
    pub normal: DVec3,
    /// The ray met the triangle's back face (`dot(normal, dir) > 0`).
    pub from_behind: bool,
    /// A *back-face hit* in the sense of Kontkanen & Laine 2006 §5: `from_behind` on a
    /// single-sided material.
    pub back_face: bool,
    /// The material is single-sided.
    pub single_sided: bool,
}

/// BVH build quality presets (obvhs' own presets).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildQuality {
    /// `BvhBuildParams::fast_build`.
    Fast,
    /// `BvhBuildParams::medium_build` (the default: about Embree's build time, faster
    /// traversal).
    #[default]
    Medium,
    /// `BvhBuildParams::slow_build` (spatial pre-splits).
    Slow,
}

/// Closest-hit and occlusion queries over a [`Scene`].
pub struct Tracer {
    bvh: CwBvh,
    /// Triangles in BVH primitive order.
    tris: Vec<RtTriangle>,
    /// BVH primitive slot → scene triangle index.
    order: Vec<u32>,
    /// Per scene triangle: unit normal and whether back faces count (single-sided).
    normals: Vec<DVec3>,
    single_sided: Vec<bool>,
    /// Scene triangles (f64) for brute-force reference queries.
    scene_tris: Vec<[DVec3; 3]>,
    /// Alpha decisions for `MASK`/`BLEND` triangles.
    alpha: AlphaTable,
}

impl std::fmt::Debug for Tracer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tracer")
            .field("triangles", &self.tris.len())
            .field("nodes", &self.bvh.nodes.len())
            .finish()
    }
}

#[inline]
fn v3a(p: DVec3) -> Vec3A {
    Vec3A::new(p.x as f32, p.y as f32, p.z as f32)
}

/// An obvhs ray. Direction components equal to -0.0 are replaced by +0.0: obvhs 0.4 misses
/// everything along e.g. `(-0.0, -0.0, -1.0)` (found by `barycentrics_and_ids_in_scene_order`;
/// `x + 0.0` turns -0.0 into +0.0 and changes nothing else).
#[inline]
fn make_ray(origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Ray {
    Ray::new(v3a(origin), v3a(dir) + Vec3A::ZERO, tmin as f32, tmax.min(f64::from(f32::MAX)) as f32)
}

impl Tracer {
    /// Builds the BVH with the default (medium) quality.
    #[must_use]
    pub fn new(scene: &Scene) -> Self {
        Self::with_quality(scene, BuildQuality::Medium)
    }

    /// Builds the BVH with the given preset.
    #[must_use]
    pub fn with_quality(scene: &Scene, quality: BuildQuality) -> Self {
        let ob: Vec<ObTriangle> = scene
            .triangles
            .iter()
            .map(|t| ObTriangle { v0: v3a(t.v[0]), v1: v3a(t.v[1]), v2: v3a(t.v[2]) })
            .collect();
        let params = match quality {
            BuildQuality::Fast => BvhBuildParams::fast_build(),
            BuildQuality::Medium => BvhBuildParams::medium_build(),
            BuildQuality::Slow => BvhBuildParams::slow_build(),
        };
        let bvh = build_cwbvh_from_tris(&ob, params, &mut Duration::default());
        let order = bvh.primitive_indices.clone();
        let tris = order.iter().map(|&i| RtTriangle::from(&ob[i as usize])).collect();
        let normals = scene.triangles.iter().map(crate::scene::Triangle::normal).collect();
        let single_sided =
            scene.triangles.iter().map(|t| !scene.materials[t.material as usize].double_sided).collect();
        let scene_tris = scene.triangles.iter().map(|t| t.v).collect();
        Self { bvh, tris, order, normals, single_sided, scene_tris, alpha: AlphaTable::new(scene) }
    }

    /// Number of triangles whose hits need an alpha decision (`MASK` or `BLEND`).
    #[must_use]
    pub fn alpha_triangles(&self) -> usize {
        self.alpha.len()
    }

    /// The BLEND key of a ray (0 when the scene has no alpha triangles).
    #[inline]
    fn key(&self, origin: DVec3, dir: DVec3) -> u64 {
        if self.alpha.is_empty() { 0 } else { ray_key(origin, dir) }
    }

    /// The primitive test of BVH slot `slot`, with the alpha decision: `f32::INFINITY`
    /// (no hit) for a candidate that is no surface.
    #[inline]
    fn intersect(&self, r: &Ray, slot: usize, key: u64) -> f32 {
        let t = self.tris[slot].intersect(r);
        if self.alpha.is_empty() || t == f32::INFINITY {
            return t;
        }
        let tri = self.order[slot];
        if !self.alpha.needs_test(tri) {
            return t;
        }
        let b = self.tris[slot].compute_barycentric(r);
        if self.alpha.is_surface(tri, f64::from(b.x), f64::from(b.y), key) { t } else { f32::INFINITY }
    }

    /// Number of triangles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// True when there are no triangles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Unit front-face normal of scene triangle `tri`.
    #[must_use]
    #[inline]
    pub fn normal(&self, tri: u32) -> DVec3 {
        self.normals[tri as usize]
    }

    fn make_hit(&self, tri: u32, t: f64, bary: [f64; 2], dir: DVec3) -> Hit {
        let normal = self.normals[tri as usize];
        let from_behind = normal.dot(dir) > 0.0;
        Hit {
            triangle: tri,
            t,
            bary,
            normal,
            from_behind,
            back_face: from_behind && self.single_sided[tri as usize],
            single_sided: self.single_sided[tri as usize],
        }
    }

    /// Closest hit along `origin + t·dir`, `t ∈ [tmin, tmax]`; `dir` must be unit length.
    #[must_use]
    pub fn closest_hit(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<Hit> {
        let ray = make_ray(origin, dir, tmin, tmax);
        let mut hit = RayHit::none();
        let key = self.key(origin, dir);
        if !self.bvh.ray_traverse(ray, &mut hit, |r, id| self.intersect(r, id, key)) {
            return None;
        }
        let slot = hit.primitive_id as usize;
        let b = self.tris[slot].compute_barycentric(&ray);
        let tri = self.order[slot];
        Some(self.make_hit(tri, f64::from(hit.t), [f64::from(b.x), f64::from(b.y)], dir))
    }

    /// True when anything blocks `origin + t·dir` for `t ∈ [tmin, tmax]` (shadow rays).
    #[must_use]
    pub fn occluded(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> bool {
        let ray = make_ray(origin, dir, tmin, tmax);
        let key = self.key(origin, dir);
        !self.bvh.ray_traverse_miss(ray, |r, id| self.intersect(r, id, key))
    }

    /// Reference closest hit: the same f32 primitive test over every triangle in scene
    /// order, no BVH (for tests and diagnostics).
    #[must_use]
    pub fn closest_hit_brute_force(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<Hit> {
        let ray = make_ray(origin, dir, tmin, tmax);
        // Same acceptance rule as `CwBvh::ray_traverse`: strictly closer than the current tmax.
        let mut best: Option<(usize, f32)> = None;
        let key = self.key(origin, dir);
        for slot in 0..self.tris.len() {
            let d = self.intersect(&ray, slot, key);
            if d < best.map_or(ray.tmax, |b| b.1) {
                best = Some((slot, d));
            }
        }
        let (slot, t) = best?;
        let b = self.tris[slot].compute_barycentric(&ray);
        Some(self.make_hit(self.order[slot], f64::from(t), [f64::from(b.x), f64::from(b.y)], dir))
    }

    /// Reference closest hit in f64 (Möller-Trumbore, independent of obvhs), in scene
    /// order. Edge cases within ~1e-9 of an edge may differ from the f32 tracer.
    #[must_use]
    pub fn closest_hit_f64(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<Hit> {
        let mut best: Option<(u32, f64, [f64; 2])> = None;
        let key = self.key(origin, dir);
        for (i, v) in self.scene_tris.iter().enumerate() {
            if let Some((t, u, w)) = intersect_f64(v, origin, dir)
                && t >= tmin
                && t <= best.map_or(tmax, |b| b.1)
                && self.alpha.is_surface(i as u32, u, w, key)
            {
                best = Some((i as u32, t, [u, w]));
            }
        }
        let (tri, t, bary) = best?;
        Some(self.make_hit(tri, t, bary, dir))
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Material, SceneBuilder};
    use glam::DVec2;
    use lightvol_sh::lowdisc::SplitMix64;
    use lightvol_sh::sampling::sample_uniform_sphere;

    /// A soup of random triangles plus a closed box, some double-sided.
    fn soup(n: usize, seed: u64) -> Scene {
        let mut rng = SplitMix64::new(seed);
        let mut b = SceneBuilder::new("soup");
        let one = b.add_material(Material::diffuse("one", [0.5; 3])).unwrap();
        let two = b.add_material(Material::diffuse("two", [0.5; 3]).two_sided()).unwrap();
        for i in 0..n {
            let c = DVec3::new(rng.range(-10.0, 10.0), rng.range(-10.0, 10.0), rng.range(-10.0, 10.0));
            let mut p = || c + DVec3::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
            let v = [p(), p(), p()];
            b.add_triangle(v, [DVec2::ZERO; 3], if i % 3 == 0 { two } else { one }).unwrap();
        }
        b.add_box(DVec3::splat(-3.0), DVec3::splat(3.0), one, true, false).unwrap();
        b.build().unwrap()
    }

    /// The BVH agrees with a brute-force loop over all triangles on random
    /// rays — hit/miss, triangle, t and the back-face flag.
    #[test]
    fn bvh_matches_brute_force() {
        let scene = soup(2000, 1);
        let tr = Tracer::new(&scene);
        let mut rng = SplitMix64::new(2);
        let (mut hits, mut back) = (0, 0);
        for _ in 0..3000 {
            let o = DVec3::new(rng.range(-14.0, 14.0), rng.range(-14.0, 14.0), rng.range(-14.0, 14.0));
            let d = DVec3::from_array(sample_uniform_sphere([rng.next_f64(), rng.next_f64()]));
            let a = tr.closest_hit(o, d, 0.0, f64::INFINITY);
            let b = tr.closest_hit_brute_force(o, d, 0.0, f64::INFINITY);
            let c = tr.closest_hit_f64(o, d, 0.0, f64::INFINITY);
            match (a, b, c) {
                (None, None, None) => {}
                (Some(a), Some(b), Some(c)) => {
                    hits += 1;
                    back += usize::from(a.back_face);
                    // Same f32 primitive test: identical t; the triangle may differ only
                    // on an exact tie (two triangles at the same t).
                    assert_eq!(a.t, b.t);
                    if a.triangle != b.triangle {
                        continue;
                    }
                    assert_eq!((a.back_face, a.from_behind), (b.back_face, b.from_behind));
                    // f32 vs f64: t agrees to f32 precision of the scene scale (~30 units).
                    assert!((a.t - c.t).abs() < 1e-4 * (1.0 + c.t), "{} {}", a.t, c.t);
                    if a.triangle == c.triangle {
                        assert_eq!(a.back_face, c.back_face);
                        assert!((a.bary[0] - c.bary[0]).abs() < 1e-3 && (a.bary[1] - c.bary[1]).abs() < 1e-3);
                        let p = scene.triangles[a.triangle as usize].point(a.bary[0], a.bary[1]);
                        assert!((p - (o + d * a.t)).length() < 1e-3);
                    }
                }
                other => panic!("disagreement at {o} {d}: {other:?}"),
            }
        }
        // The test must exercise both outcomes and both faces.
        assert!(hits > 1000 && back > 100, "{hits} {back}");
    }

    /// Shadow queries agree with the closest hit; tmax excludes farther geometry.
    #[test]
    fn occlusion_matches_closest_hit() {
        let scene = soup(500, 3);
        let tr = Tracer::new(&scene);
        let mut rng = SplitMix64::new(4);
        for _ in 0..2000 {
            let o = DVec3::new(rng.range(-14.0, 14.0), rng.range(-14.0, 14.0), rng.range(-14.0, 14.0));
            let d = DVec3::from_array(sample_uniform_sphere([rng.next_f64(), rng.next_f64()]));
            let tmax = rng.range(0.0, 20.0);
            let closest = tr.closest_hit_brute_force(o, d, 0.0, tmax);
            assert_eq!(tr.occluded(o, d, 0.0, tmax), closest.is_some());
        }
    }

    /// Barycentrics follow the scene's vertex order even though the BVH reorders
    /// triangles (the `primitive_indices` pitfall).
    #[test]
    fn barycentrics_and_ids_in_scene_order() {
        let mut b = SceneBuilder::new("two");
        let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
        for k in 0..50 {
            let z = f64::from(k);
            b.add_triangle(
                [DVec3::new(0.0, 0.0, z), DVec3::new(4.0, 0.0, z), DVec3::new(0.0, 2.0, z)],
                [DVec2::ZERO; 3],
                m,
            )
            .unwrap();
        }
        let s = b.build().unwrap();
        let tr = Tracer::new(&s);
        for k in 0..50 {
            let h = tr.closest_hit(DVec3::new(1.0, 0.5, f64::from(k) + 0.5), -DVec3::Z, 0.0, 1.0).unwrap();
            assert_eq!(h.triangle, k);
            // Point (1, 0.5) = 0.25·v1 + 0.25·v2 + 0.5·v0.
            assert!((h.bary[0] - 0.25).abs() < 1e-6 && (h.bary[1] - 0.25).abs() < 1e-6, "{:?}", h.bary);
            assert!(!h.back_face && (h.t - 0.5).abs() < 1e-6);
            let h = tr.closest_hit(DVec3::new(1.0, 0.5, f64::from(k) - 0.5), DVec3::Z, 0.0, 1.0).unwrap();
            assert!(h.triangle == k && h.back_face && h.from_behind);
        }
    }
}
