//! Ray tracing over the scene's triangles with lightvol's wide BVH ([`crate::wide`]): obvhs
//! builds a binary BVH (PLOC, reinsertion, optional pre-splits), which is collapsed into
//! 8-wide nodes with four-triangle leaves and traversed with the SIMD kernel the machine
//! runs, chosen at run time ([`Isa`]).
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
//! Intersection is the watertight test of Woop, Benthin & Wald 2013
//! ([`crate::watertight`]) in f32: no ray slips through an edge two triangles share. The
//! closest hit is the least `(t, triangle)` pair, so that ties between triangles at the
//! same distance resolve the same way whatever the traversal order or kernel; every
//! kernel returns the same hit as [`Tracer::closest_hit_brute_force`], bit for bit. Hit
//! data returned to callers is f64, recomputed on the scene's f64 triangle where that is
//! more accurate (normal, position).
//!
//! Alpha-tested and transparent materials are decided inside the traversal
//! ([`crate::alpha`]): a candidate hit that is no surface is rejected before it can become
//! the closest hit or block a shadow ray.

use glam::{DAffine3, DVec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::triangle::Triangle as ObTriangle;
use rayon::prelude::*;

use crate::alpha::{AlphaTable, ray_key};
use crate::instance::place;
use crate::scene::Scene;
use crate::triangle::Triangle;
use crate::triangle::intersect_f64;
use crate::watertight::{RawHit, intersect_raw};
use crate::wide::dispatch::run;
use crate::wide::kernel::RayK;
use crate::wide::traverse::{Best, Filter};
use crate::wide::{Isa, WideBvh, build};

mod query;

use query::{ClosestQuery, OcclusionQuery, SceneRay};

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

/// BVH build quality presets (obvhs' own presets for the binary tree).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildQuality {
    /// `BvhBuildParams::fast_build`.
    Fast,
    /// `BvhBuildParams::medium_build` (the default).
    #[default]
    Medium,
    /// `BvhBuildParams::slow_build` (spatial pre-splits).
    Slow,
}

/// One bottom-level BVH: the directly placed triangles, or one prototype's.
struct Blas {
    /// Its primitives are triangle indices within this geometry.
    bvh: WideBvh,
    /// Per triangle: unit normal in the BVH's frame, and whether back faces count
    /// (single-sided material); one record, so that a hit reads one cache line.
    faces: Vec<(DVec3, bool)>,
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
/// of 17 meshes, `lightvol bench --embree --levels one|two --rays 300000`: closest hits
/// 1.03× and occlusion 1.8× faster in one level).
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
    tlas: Option<WideBvh>,
    /// Scene triangles (instances included).
    count: usize,
    /// Alpha decisions for `MASK`/`BLEND` triangles.
    alpha: AlphaTable,
    /// The traversal kernel.
    isa: Isa,
}

impl std::fmt::Debug for Tracer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tracer")
            .field("triangles", &self.count)
            .field("unique_triangles", &self.unique_len())
            .field("placements", &self.placements.len())
            .field("nodes", &self.blas.iter().map(|b| b.bvh.nodes.len()).sum::<usize>())
            .field("isa", &self.isa)
            .finish()
    }
}

#[inline]
fn v3a(p: DVec3) -> Vec3A {
    Vec3A::new(p.x as f32, p.y as f32, p.z as f32)
}

#[inline]
fn f32x3(p: DVec3) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

/// Placement boxes are widened by this much: the top level tests a placement's world box
/// with the world ray, the bottom level its own boxes with the ray carried into the
/// prototype's frame in f64 and rounded to f32, and the two roundings must not drop a hit
/// the bottom level would find.
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
        let bvh = build::from_triangles(&ob, build_params(quality));
        let faces =
            source.iter().map(|t| (t.normal(), !scene.materials[t.material as usize].double_sided)).collect();
        Self { bvh, faces, source: source.iter().map(|t| t.v).collect(), stored_base }
    }

    /// Triangle `local` in the f32 frame the kernels test.
    fn triangle_f32(&self, local: usize) -> [[f32; 3]; 3] {
        self.source[local].map(f32x3)
    }
}

impl Placement {
    /// The directly placed triangles: bottom level 0, unmoved.
    fn identity() -> Self {
        Self { blas: 0, first: 0, to_world: None, to_local: DAffine3::IDENTITY, mirrored: false }
    }

    /// The ray in this placement's BVH frame (the same `t` parametrises both).
    #[inline(always)]
    fn local_ray(&self, origin: DVec3, dir: DVec3, tmin: f32, tmax: f32) -> RayK {
        match self.to_world {
            None => RayK::new(f32x3(origin), f32x3(dir), tmin, tmax),
            Some(_) => RayK::new(
                f32x3(self.to_local.transform_point3(origin)),
                f32x3(self.to_local.transform_vector3(dir)),
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
    /// build is deterministic, so the tracer is the same on any thread count). The kernel
    /// is the fastest this machine runs, or the one [`crate::wide::ISA_ENV`]
    /// names ([`Isa::from_env`]; an unusable name falls back to the fastest).
    #[must_use]
    pub fn build(scene: &Scene, quality: BuildQuality, levels: Levels) -> Self {
        let isa = Isa::from_env().unwrap_or_else(|_| Isa::best());
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
                isa,
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
        let tlas = (!one_level).then(|| build::from_boxes(&boxes, build_params(quality)));
        Self { blas, placements, tlas, count: scene.triangle_count(), alpha: AlphaTable::new(scene), isa }
    }

    /// The traversal kernel this tracer runs.
    #[must_use]
    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// Traverses with kernel `isa` from now on; an error (naming the kernels this machine
    /// runs) where it cannot run here. Every kernel returns the same hits.
    pub fn set_isa(&mut self, isa: Isa) -> Result<(), String> {
        if !isa.is_available() {
            return Err(format!(
                "this machine cannot run the {isa} kernel (it runs {})",
                Isa::available_names()
            ));
        }
        self.isa = isa;
        Ok(())
    }

    /// Bytes the BVHs occupy (nodes, leaves and triangle packs, both levels).
    #[must_use]
    pub fn bvh_bytes(&self) -> usize {
        self.blas.iter().map(|b| b.bvh.bytes()).sum::<usize>() + self.tlas.as_ref().map_or(0, WideBvh::bytes)
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

    /// The query of the ray `origin + t·dir`, `t ∈ [tmin, tmax]`, in f32.
    fn scene_ray(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> SceneRay<'_> {
        SceneRay {
            tracer: self,
            origin,
            dir,
            tmin: tmin as f32,
            tmax: tmax.min(f64::from(f32::MAX)) as f32,
            key: self.key(origin, dir),
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
        self.blas.iter().map(|b| b.source.len()).sum()
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
            None => b.faces[local as usize].0,
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
        let single_sided = self.blas[p.blas as usize].faces[local as usize].1;
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

    /// The [`Hit`] of a kernel's result on scene triangle `tri`.
    fn finish(&self, tri: u32, raw: &RawHit, dir: DVec3) -> Hit {
        let (p, local) = self.locate(tri);
        let [u, v] = raw.bary12();
        self.make_hit(p, local, f64::from(raw.t), [f64::from(u), f64::from(v)], dir)
    }

    /// Closest hit along `origin + t·dir`, `t ∈ [tmin, tmax]`; `dir` must be unit length.
    #[must_use]
    pub fn closest_hit(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<Hit> {
        let (tri, raw) = run(self.isa, &ClosestQuery(self.scene_ray(origin, dir, tmin, tmax)))?;
        Some(self.finish(tri, &raw, dir))
    }

    /// True when anything blocks `origin + t·dir` for `t ∈ [tmin, tmax]` (shadow rays).
    #[must_use]
    pub fn occluded(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> bool {
        run(self.isa, &OcclusionQuery(self.scene_ray(origin, dir, tmin, tmax)))
    }

    /// Reference closest hit: the same f32 watertight test (in each placement's frame) over
    /// every triangle, no BVH, the least `(t, triangle)` pair; every kernel's
    /// [`Tracer::closest_hit`] equals it bit for bit.
    #[must_use]
    pub fn closest_hit_brute_force(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<Hit> {
        let r = self.scene_ray(origin, dir, tmin, tmax);
        let mut best = Best::new(r.tmax);
        for k in 0..self.placements.len() {
            let filter = r.filter(k);
            let local = filter.placement.local_ray(origin, dir, r.tmin, r.tmax);
            for prim in 0..filter.blas.source.len() as u32 {
                if let Some(hit) =
                    intersect_raw(&local.shear, &filter.blas.triangle_f32(prim as usize), r.tmin, r.tmax)
                {
                    best.offer(filter.id(prim), hit, || filter.accept(prim, &hit));
                }
            }
        }
        let raw = best.hit?;
        Some(self.finish(best.id, &raw, dir))
    }

    /// Reference closest hit in f64 (Möller-Trumbore, independent of the f32 test), in
    /// scene order, on the triangles placed in the world frame. Edge cases within ~1e-9 of
    /// an edge may differ from the f32 tracer.
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

#[cfg(test)]
mod tests;
