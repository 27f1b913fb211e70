//! Ray tracing with `obvhs` 0.4: compressed-wide BVHs (CwBvh) over the scene's triangles.
//!
//! Two levels: one bottom-level BVH over the directly placed triangles and one per
//! prototype, in the prototype's frame ([`crate::instance`]), and a top-level BVH over the
//! placements. A ray meets a placement's box in the top level, is carried into the
//! prototype's frame by the inverse transform (direction unnormalised, so `t` is the same
//! parameter in both frames) and continues in the prototype's BVH. A scene without
//! instances has one bottom level and no top level: its rays take exactly the one-level
//! path. Instanced triangles are intersected in their prototype's frame in f32, so their
//! `t` and barycentrics differ from a flattened copy's by f32 rounding of the transform
//! (`instanced_and_flattened_agree` states by how much).
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

use glam::{DAffine3, DVec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::{build_cwbvh, build_cwbvh_from_tris};
use obvhs::ray::{Ray, RayHit};
use obvhs::rt_triangle::RtTriangle;
use obvhs::triangle::Triangle as ObTriangle;
use rayon::prelude::*;

use crate::alpha::{AlphaTable, ray_key};
use crate::instance::place;
use crate::scene::Scene;
use crate::triangle::Triangle;

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

/// One bottom-level BVH: the directly placed triangles, or one prototype's.
struct Blas {
    bvh: CwBvh,
    /// Triangles in BVH primitive order, in the BVH's own frame.
    tris: Vec<RtTriangle>,
    /// BVH primitive slot → triangle index within this geometry.
    order: Vec<u32>,
    /// Per triangle: unit normal in the BVH's frame.
    normals: Vec<DVec3>,
    /// Per triangle: back faces count (single-sided material).
    single_sided: Vec<bool>,
    /// Vertices (f64, the BVH's frame) for the reference queries.
    source: Vec<[DVec3; 3]>,
    /// Stored index ([`AlphaTable`]) of triangle 0.
    stored_base: u32,
}

/// A placement of a [`Blas`]: the directly placed triangles (identity) or an instance.
struct Placement {
    blas: u32,
    /// Scene index of triangle 0.
    first: u32,
    /// `None` for the identity.
    to_world: Option<DAffine3>,
    /// World → BVH frame.
    to_local: DAffine3,
    /// The transform mirrors: barycentrics `(u, v)` swap (the placed triangle's vertices 1
    /// and 2 are the prototype's 2 and 1).
    mirrored: bool,
}

/// Scenes that place at most this many triangles are traced through one BVH over their
/// placed triangles ([`Levels::Auto`]): the tracer then takes about 350 bytes per placed
/// triangle at its build peak (under 400 MB here, see [`crate::estimate`]), and one level is
/// faster than two wherever instances overlap (measured on the Breakfast Room, 24 instances
/// of 17 meshes, `lightvol bench --embree --levels one|two`: closest hits 1.2× and occlusion
/// 1.4× faster in one level).
pub const FLATTEN_AT_MOST: usize = 1 << 20;

/// How a [`Tracer`] arranges an instanced scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Levels {
    /// One level up to [`FLATTEN_AT_MOST`] placed triangles, two above: memory stays
    /// proportional to unique triangles where that matters.
    #[default]
    Auto,
    /// One BVH over every placed triangle.
    One,
    /// A BVH per prototype under a top-level BVH over the placements.
    Two,
}

/// Closest-hit and occlusion queries over a [`Scene`].
pub struct Tracer {
    blas: Vec<Blas>,
    /// Ordered by `first`.
    placements: Vec<Placement>,
    /// Over `placements`; `None` when the only placement is the identity (one level).
    tlas: Option<CwBvh>,
    /// Scene triangles (instances included).
    count: usize,
    /// Alpha decisions for `MASK`/`BLEND` triangles.
    alpha: AlphaTable,
}

impl std::fmt::Debug for Tracer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tracer")
            .field("triangles", &self.count)
            .field("unique_triangles", &self.unique_len())
            .field("placements", &self.placements.len())
            .field("nodes", &self.blas.iter().map(|b| b.bvh.nodes.len()).sum::<usize>())
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

/// obvhs skips a BVH node whose box the ray leaves before `t = 1e-4` (`cwbvh::node::EPSILON`,
/// a clamp of the box test's entry distance). Placement boxes are widened by this much, so
/// that the top level never drops a hit that the placement's own BVH would find.
const TLAS_PAD: f64 = 1e-4;

/// The f32 box of f64 bounds, widened by [`TLAS_PAD`] and one f32 step outward on each side
/// so that rounding cannot shrink it.
fn outward_aabb(lo: DVec3, hi: DVec3) -> Aabb {
    let down = |x: f64| ((x - TLAS_PAD) as f32).next_down();
    let up = |x: f64| ((x + TLAS_PAD) as f32).next_up();
    Aabb {
        min: Vec3A::new(down(lo.x), down(lo.y), down(lo.z)),
        max: Vec3A::new(up(hi.x), up(hi.y), up(hi.z)),
    }
}

fn build_params(quality: BuildQuality) -> BvhBuildParams {
    match quality {
        BuildQuality::Fast => BvhBuildParams::fast_build(),
        BuildQuality::Medium => BvhBuildParams::medium_build(),
        BuildQuality::Slow => BvhBuildParams::slow_build(),
    }
}

impl Blas {
    fn new(scene: &Scene, source: &[Triangle], stored_base: u32, quality: BuildQuality) -> Self {
        let ob: Vec<ObTriangle> =
            source.iter().map(|t| ObTriangle { v0: v3a(t.v[0]), v1: v3a(t.v[1]), v2: v3a(t.v[2]) }).collect();
        let bvh = build_cwbvh_from_tris(&ob, build_params(quality), &mut Duration::default());
        let order = bvh.primitive_indices.clone();
        let tris = order.iter().map(|&i| RtTriangle::from(&ob[i as usize])).collect();
        let normals = source.iter().map(Triangle::normal).collect();
        let single_sided =
            source.iter().map(|t| !scene.materials[t.material as usize].double_sided).collect();
        Self {
            bvh,
            tris,
            order,
            normals,
            single_sided,
            source: source.iter().map(|t| t.v).collect(),
            stored_base,
        }
    }
}

impl Placement {
    /// The directly placed triangles: bottom level 0, unmoved.
    fn identity() -> Self {
        Self { blas: 0, first: 0, to_world: None, to_local: DAffine3::IDENTITY, mirrored: false }
    }

    /// The ray in this placement's BVH frame (the same `t` parametrises both).
    #[inline]
    fn local_ray(&self, origin: DVec3, dir: DVec3, tmin: f32, tmax: f32) -> Ray {
        match self.to_world {
            None => Ray::new(v3a(origin), v3a(dir) + Vec3A::ZERO, tmin, tmax),
            Some(_) => Ray::new(
                v3a(self.to_local.transform_point3(origin)),
                v3a(self.to_local.transform_vector3(dir)) + Vec3A::ZERO,
                tmin,
                tmax,
            ),
        }
    }
}

impl Tracer {
    /// Builds the BVH with the default (medium) quality.
    #[must_use]
    pub fn new(scene: &Scene) -> Self {
        Self::with_quality(scene, BuildQuality::Medium)
    }

    /// Builds the BVHs with the given preset, in the levels [`Levels::Auto`] chooses.
    #[must_use]
    pub fn with_quality(scene: &Scene, quality: BuildQuality) -> Self {
        Self::build(scene, quality, Levels::Auto)
    }

    /// Builds the BVHs with the given preset and levels (bottom levels in parallel; each
    /// build is deterministic, so the tracer is the same on any thread count).
    #[must_use]
    pub fn build(scene: &Scene, quality: BuildQuality, levels: Levels) -> Self {
        let one = match levels {
            Levels::Auto => scene.triangle_count() <= FLATTEN_AT_MOST,
            Levels::One => true,
            Levels::Two => false,
        };
        if one && scene.is_instanced() {
            let placed: Vec<Triangle> = scene.world_triangles().collect();
            return Self {
                blas: vec![Blas::new(scene, &placed, 0, quality)],
                placements: vec![Placement::identity()],
                tlas: None,
                count: placed.len(),
                alpha: AlphaTable::from_triangles(scene, placed.iter()),
            };
        }
        let mut sources: Vec<(&[Triangle], u32)> = vec![(&scene.triangles, 0)];
        let mut stored = scene.triangles.len() as u32;
        for p in &scene.prototypes {
            sources.push((&p.triangles, stored));
            stored += p.triangles.len() as u32;
        }
        let blas: Vec<Blas> =
            sources.par_iter().map(|&(src, base)| Blas::new(scene, src, base, quality)).collect();
        let mut placements = Vec::with_capacity(scene.instances.len() + 1);
        let mut boxes = Vec::with_capacity(scene.instances.len() + 1);
        if !scene.triangles.is_empty() || scene.instances.is_empty() {
            placements.push(Placement::identity());
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for t in &scene.triangles {
                for v in t.v {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            boxes.push(outward_aabb(lo, hi));
        }
        for inst in &scene.instances {
            placements.push(Placement {
                blas: inst.prototype + 1,
                first: inst.first,
                to_world: Some(inst.to_world),
                to_local: inst.to_world.inverse(),
                mirrored: inst.mirrored(),
            });
            boxes.push(outward_aabb(inst.bounds.0, inst.bounds.1));
        }
        let one_level = placements.len() == 1 && placements[0].to_world.is_none();
        let tlas = (!one_level).then(|| build_cwbvh(&boxes, build_params(quality), &mut Duration::default()));
        Self { blas, placements, tlas, count: scene.triangle_count(), alpha: AlphaTable::new(scene) }
    }

    /// Number of triangles whose hits need an alpha decision (`MASK` or `BLEND`), counted
    /// as stored (a prototype's once).
    #[must_use]
    pub fn alpha_triangles(&self) -> usize {
        self.alpha.len()
    }

    /// The BLEND key of a ray (0 when the scene has no alpha triangles).
    #[inline]
    fn key(&self, origin: DVec3, dir: DVec3) -> u64 {
        if self.alpha.is_empty() { 0 } else { ray_key(origin, dir) }
    }

    /// The primitive test of BVH slot `slot` of placement `p`, with the alpha decision:
    /// `f32::INFINITY` (no hit) for a candidate that is no surface.
    #[inline]
    fn intersect(&self, b: &Blas, p: &Placement, r: &Ray, slot: usize, key: u64) -> f32 {
        let t = b.tris[slot].intersect(r);
        if self.alpha.is_empty() || t == f32::INFINITY {
            return t;
        }
        let local = b.order[slot];
        let stored = b.stored_base + local;
        if !self.alpha.needs_test(stored) {
            return t;
        }
        let bc = b.tris[slot].compute_barycentric(r);
        if self.alpha.is_surface(stored, p.first + local, f64::from(bc.x), f64::from(bc.y), key) {
            t
        } else {
            f32::INFINITY
        }
    }

    /// Number of scene triangles (instances included).
    #[must_use]
    pub fn len(&self) -> usize {
        self.count
    }

    /// Number of triangles stored in the BVHs (each prototype once).
    #[must_use]
    pub fn unique_len(&self) -> usize {
        self.blas.iter().map(|b| b.tris.len()).sum()
    }

    /// Number of placements the top level holds (1 without instances).
    #[must_use]
    pub fn placements(&self) -> usize {
        self.placements.len()
    }

    /// True when there are no triangles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The placement of scene triangle `tri` and its index in the placement's geometry.
    #[inline]
    fn locate(&self, tri: u32) -> (&Placement, u32) {
        let k = self.placements.partition_point(|p| p.first <= tri).saturating_sub(1);
        let p = &self.placements[k];
        (p, tri - p.first)
    }

    /// Unit front-face normal, in the world frame, of triangle `local` of placement `p`:
    /// for an instance, the normal of the placed f64 triangle ([`place`]), computed as
    /// [`Triangle::normal`] computes it on a flattened copy, so the two agree bit for bit
    /// (a shading frame built from it then does not flip where a component is near zero).
    #[inline]
    fn world_normal(&self, p: &Placement, local: u32) -> DVec3 {
        let b = &self.blas[p.blas as usize];
        match &p.to_world {
            None => b.normals[local as usize],
            Some(m) => {
                let v = b.source[local as usize];
                place(m, &Triangle { v, uv: [glam::DVec2::ZERO; 3], material: 0 }).normal()
            }
        }
    }

    /// Unit front-face normal of scene triangle `tri`.
    #[must_use]
    #[inline]
    pub fn normal(&self, tri: u32) -> DVec3 {
        let (p, local) = self.locate(tri);
        self.world_normal(p, local)
    }

    /// The hit on triangle `local` of placement `p`; `bary` in the BVH frame's vertex order.
    fn make_hit(&self, p: &Placement, local: u32, t: f64, bary: [f64; 2], dir: DVec3) -> Hit {
        let normal = self.world_normal(p, local);
        let single_sided = self.blas[p.blas as usize].single_sided[local as usize];
        let from_behind = normal.dot(dir) > 0.0;
        Hit {
            triangle: p.first + local,
            t,
            bary: if p.mirrored { [bary[1], bary[0]] } else { bary },
            normal,
            from_behind,
            back_face: from_behind && single_sided,
            single_sided,
        }
    }

    /// Closest hit along `origin + t·dir`, `t ∈ [tmin, tmax]`; `dir` must be unit length.
    #[must_use]
    pub fn closest_hit(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<Hit> {
        let ray = make_ray(origin, dir, tmin, tmax);
        let key = self.key(origin, dir);
        let Some(tlas) = &self.tlas else {
            let (p, b) = (&self.placements[0], &self.blas[0]);
            let mut hit = RayHit::none();
            if !b.bvh.ray_traverse(ray, &mut hit, |r, id| self.intersect(b, p, r, id, key)) {
                return None;
            }
            let slot = hit.primitive_id as usize;
            let bc = b.tris[slot].compute_barycentric(&ray);
            return Some(self.make_hit(
                p,
                b.order[slot],
                f64::from(hit.t),
                [f64::from(bc.x), f64::from(bc.y)],
                dir,
            ));
        };
        // (placement, slot, the ray in its frame)
        let mut best: Option<(usize, usize, Ray)> = None;
        let mut top = RayHit::none();
        tlas.ray_traverse(ray, &mut top, |r, tslot| {
            let k = tlas.primitive_indices[tslot] as usize;
            let p = &self.placements[k];
            let b = &self.blas[p.blas as usize];
            let local = p.local_ray(origin, dir, r.tmin, r.tmax);
            let mut hit = RayHit::none();
            if b.bvh.ray_traverse(local, &mut hit, |lr, id| self.intersect(b, p, lr, id, key)) {
                best = Some((k, hit.primitive_id as usize, local));
                hit.t
            } else {
                f32::INFINITY
            }
        });
        let (k, slot, local) = best?;
        let p = &self.placements[k];
        let b = &self.blas[p.blas as usize];
        let bc = b.tris[slot].compute_barycentric(&local);
        Some(self.make_hit(p, b.order[slot], f64::from(top.t), [f64::from(bc.x), f64::from(bc.y)], dir))
    }

    /// True when anything blocks `origin + t·dir` for `t ∈ [tmin, tmax]` (shadow rays).
    #[must_use]
    pub fn occluded(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> bool {
        let ray = make_ray(origin, dir, tmin, tmax);
        let key = self.key(origin, dir);
        let Some(tlas) = &self.tlas else {
            let (p, b) = (&self.placements[0], &self.blas[0]);
            return !b.bvh.ray_traverse_miss(ray, |r, id| self.intersect(b, p, r, id, key));
        };
        !tlas.ray_traverse_miss(ray, |r, tslot| {
            let p = &self.placements[tlas.primitive_indices[tslot] as usize];
            let b = &self.blas[p.blas as usize];
            let local = p.local_ray(origin, dir, r.tmin, r.tmax);
            // Any value below tmax tells the top level that the ray is blocked.
            if b.bvh.ray_traverse_miss(local, |lr, id| self.intersect(b, p, lr, id, key)) {
                f32::INFINITY
            } else {
                f32::NEG_INFINITY
            }
        })
    }

    /// Reference closest hit: the same f32 primitive test (in each placement's frame) over
    /// every triangle, no BVH (for tests and diagnostics).
    #[must_use]
    pub fn closest_hit_brute_force(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<Hit> {
        let ray = make_ray(origin, dir, tmin, tmax);
        // Same acceptance rule as `CwBvh::ray_traverse`: strictly closer than the current tmax.
        let mut best: Option<(usize, usize, f32, Ray)> = None;
        let key = self.key(origin, dir);
        for (k, p) in self.placements.iter().enumerate() {
            let b = &self.blas[p.blas as usize];
            let local = p.local_ray(origin, dir, ray.tmin, ray.tmax);
            for slot in 0..b.tris.len() {
                let d = self.intersect(b, p, &local, slot, key);
                if d < best.map_or(ray.tmax, |x| x.2) {
                    best = Some((k, slot, d, local));
                }
            }
        }
        let (k, slot, t, local) = best?;
        let p = &self.placements[k];
        let b = &self.blas[p.blas as usize];
        let bc = b.tris[slot].compute_barycentric(&local);
        Some(self.make_hit(p, b.order[slot], f64::from(t), [f64::from(bc.x), f64::from(bc.y)], dir))
    }

    /// Reference closest hit in f64 (Möller-Trumbore, independent of obvhs), in scene
    /// order, on the triangles placed in the world frame. Edge cases within ~1e-9 of an
    /// edge may differ from the f32 tracer.
    #[must_use]
    pub fn closest_hit_f64(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<Hit> {
        let mut best: Option<(usize, u32, f64, [f64; 2])> = None;
        let key = self.key(origin, dir);
        for (k, p) in self.placements.iter().enumerate() {
            let b = &self.blas[p.blas as usize];
            for (i, &v) in b.source.iter().enumerate() {
                let w = match p.to_world {
                    None => v,
                    Some(m) => place(&m, &Triangle { v, uv: [glam::DVec2::ZERO; 3], material: 0 }).v,
                };
                if let Some((t, u, v)) = intersect_f64(&w, origin, dir)
                    && t >= tmin
                    && t <= best.map_or(tmax, |x| x.2)
                {
                    // Alpha reads the stored vertex order: swap back under a mirror.
                    let (su, sv) = if p.mirrored { (v, u) } else { (u, v) };
                    if self.alpha.is_surface(b.stored_base + i as u32, p.first + i as u32, su, sv, key) {
                        best = Some((k, i as u32, t, [su, sv]));
                    }
                }
            }
        }
        let (k, local, t, bary) = best?;
        Some(self.make_hit(&self.placements[k], local, t, bary, dir))
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
    use crate::builder::SceneBuilder;
    use crate::material::Material;
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
