//! The tracer's two queries, closest hit and occlusion, written once over the traversal
//! kernel ([`crate::wide::kernel::Kernel`]) and instantiated for each by
//! [`crate::wide::dispatch::run`]: one level (the directly placed triangles' BVH) or two
//! (the top-level BVH over placements, each placement met continuing in its own BVH with
//! the ray carried into its frame).

use glam::DVec3;

use super::{Blas, Placement, Tracer, f32x3};
use crate::watertight::RawHit;
use crate::wide::kernel::{Kernel, Query, RayK};
use crate::wide::traverse::{Any, Best, Closest, Filter, Visit, walk};
use crate::wide::{EMPTY, WideBvh};

/// Identifies and filters the triangles of one placement.
pub(super) struct PlacementFilter<'a> {
    tracer: &'a Tracer,
    pub(super) blas: &'a Blas,
    pub(super) placement: &'a Placement,
    key: u64,
}

impl Filter for PlacementFilter<'_> {
    #[inline(always)]
    fn id(&self, prim: u32) -> u32 {
        self.placement.first + prim
    }

    #[inline(always)]
    fn accept(&self, prim: u32, hit: &RawHit) -> bool {
        let alpha = &self.tracer.alpha;
        if alpha.is_empty() {
            return true;
        }
        let stored = self.blas.stored_base + prim;
        if !alpha.needs_test(stored) {
            return true;
        }
        let [u, v] = hit.bary12();
        alpha.is_surface(stored, self.placement.first + prim, f64::from(u), f64::from(v), self.key)
    }
}

/// A ray query against the whole scene, in world space.
pub(super) struct SceneRay<'a> {
    pub(super) tracer: &'a Tracer,
    pub(super) origin: DVec3,
    pub(super) dir: DVec3,
    pub(super) tmin: f32,
    pub(super) tmax: f32,
    pub(super) key: u64,
}

impl<'a> SceneRay<'a> {
    /// The ray in the world frame (for the top level).
    #[inline(always)]
    fn world(&self) -> RayK {
        RayK::new(f32x3(self.origin), f32x3(self.dir), self.tmin, self.tmax)
    }

    /// The ray in the frame of `filter`'s placement.
    #[inline(always)]
    fn local(&self, filter: &PlacementFilter<'_>) -> RayK {
        filter.placement.local_ray(self.origin, self.dir, self.tmin, self.tmax)
    }

    /// The placements of top-level leaf `leaf`, each with the ray in its frame.
    #[inline(always)]
    fn placements<'b>(
        &'b self,
        bvh: &'b WideBvh,
        leaf: u32,
    ) -> impl Iterator<Item = (PlacementFilter<'a>, RayK)> + 'b {
        bvh.leaf_prims(leaf).iter().filter(|&&k| k != EMPTY).map(move |&k| {
            let filter = self.filter(k as usize);
            let local = self.local(&filter);
            (filter, local)
        })
    }

    pub(super) fn filter(&self, k: usize) -> PlacementFilter<'a> {
        let placement = &self.tracer.placements[k];
        PlacementFilter {
            tracer: self.tracer,
            blas: &self.tracer.blas[placement.blas as usize],
            placement,
            key: self.key,
        }
    }
}

/// The closest hit: `(scene triangle, hit)`.
pub(super) struct ClosestQuery<'a>(pub(super) SceneRay<'a>);

/// The top level of a closest-hit query: each placement met continues in its BVH.
struct ClosestPlacements<'a, 'b> {
    ray: &'b SceneRay<'a>,
    best: Best,
}

impl Visit for ClosestPlacements<'_, '_> {
    const NEAREST_FIRST: bool = true;

    #[inline(always)]
    fn tmax(&self) -> f32 {
        self.best.t
    }

    #[inline(always)]
    fn leaf<K: Kernel>(&mut self, bvh: &WideBvh, leaf: u32) -> bool {
        for (filter, local) in self.ray.placements(bvh, leaf) {
            let mut v = Closest { ray: &local, best: &mut self.best, filter: &filter };
            walk::<K, _>(&filter.blas.bvh, &local, &mut v);
        }
        false
    }
}

impl Query for ClosestQuery<'_> {
    type Out = Option<(u32, RawHit)>;

    #[inline(always)]
    fn run<K: Kernel>(&self) -> Self::Out {
        let r = &self.0;
        let best = match &r.tracer.tlas {
            None => {
                let filter = r.filter(0);
                let ray = r.local(&filter);
                let mut best = Best::new(r.tmax);
                walk::<K, _>(
                    &filter.blas.bvh,
                    &ray,
                    &mut Closest { ray: &ray, best: &mut best, filter: &filter },
                );
                best
            }
            Some(tlas) => {
                let ray = r.world();
                let mut v = ClosestPlacements { ray: r, best: Best::new(r.tmax) };
                walk::<K, _>(tlas, &ray, &mut v);
                v.best
            }
        };
        best.hit.map(|h| (best.id, h))
    }
}

/// Whether anything blocks the ray.
pub(super) struct OcclusionQuery<'a>(pub(super) SceneRay<'a>);

/// The top level of an occlusion query.
struct AnyPlacement<'a, 'b> {
    ray: &'b SceneRay<'a>,
}

impl Visit for AnyPlacement<'_, '_> {
    /// The top level keeps nearest-first order for shadow rays too: a placement met first
    /// is searched first, and its own tree then goes in slot order.
    const NEAREST_FIRST: bool = true;

    #[inline(always)]
    fn tmax(&self) -> f32 {
        self.ray.tmax
    }

    #[inline(always)]
    fn leaf<K: Kernel>(&mut self, bvh: &WideBvh, leaf: u32) -> bool {
        for (filter, local) in self.ray.placements(bvh, leaf) {
            if walk::<K, _>(&filter.blas.bvh, &local, &mut Any { ray: &local, filter: &filter }) {
                return true;
            }
        }
        false
    }
}

impl Query for OcclusionQuery<'_> {
    type Out = bool;

    #[inline(always)]
    fn run<K: Kernel>(&self) -> bool {
        let r = &self.0;
        match &r.tracer.tlas {
            None => {
                let filter = r.filter(0);
                let ray = r.local(&filter);
                walk::<K, _>(&filter.blas.bvh, &ray, &mut Any { ray: &ray, filter: &filter })
            }
            Some(tlas) => {
                let ray = r.world();
                walk::<K, _>(tlas, &ray, &mut AnyPlacement { ray: r })
            }
        }
    }
}
