//! The two tests a traversal runs, as a [`Kernel`]: the box test of a node's eight
//! children and the watertight test of a pack of four triangles, with the scalar kernel
//! ([`Scalar`]), the reference every SIMD kernel ([`super::simd`]) matches.

use super::{LEAF_SIZE, Node, Tri4, WIDTH};
use crate::watertight::{RawHit, Shear, intersect_raw};

/// The far distance of a box is scaled up by this before the comparison: `1 + 2γ₃` with
/// `γₙ = nu / (1 − nu)`, `u = 2⁻²⁴`, rounded up to `1 + 4·2⁻²³`. It bounds the rounding
/// of the slab distances `(plane − o)·(1/d)` so that a box the ray touches is never
/// culled (\[Ize13\] §3; derived in a test).
pub(crate) const FAR_SCALE: f32 = 1.0 + 4.0 * f32::EPSILON;

/// Direction components smaller than this in magnitude are replaced by it (with their
/// sign) before inverting, so that the slab distances stay finite and never NaN
/// (`0 · ∞`). A ray then treats a slab it runs parallel to as `10²⁰` times farther than it
/// is, which is exact for boxes the ray's line meets and culls the others.
pub(crate) const TINY_DIR: f32 = 1e-20;

/// A ray prepared for traversal: reciprocal direction, octant and shear.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayK {
    pub(crate) origin: [f32; 3],
    pub(crate) inv: [f32; 3],
    /// 1 where the (clamped) direction is negative: the near plane is then the high side.
    pub(crate) sign: [usize; 3],
    pub(crate) tmin: f32,
    pub(crate) tmax: f32,
    pub(crate) shear: Shear,
}

impl RayK {
    /// The ray `origin + t·dir`, `t ∈ [tmin, tmax]` (`dir` not zero).
    #[inline(always)]
    pub(crate) fn new(origin: [f32; 3], dir: [f32; 3], tmin: f32, tmax: f32) -> Self {
        let clamped = dir.map(|d| if d.abs() < TINY_DIR { TINY_DIR.copysign(d) } else { d });
        let inv = clamped.map(|d| 1.0 / d);
        let sign = inv.map(|i| usize::from(i < 0.0));
        Self { origin, inv, sign, tmin, tmax, shear: Shear::new(origin, dir) }
    }
}

/// A pack's test results, lane by lane: distance, scaled barycentrics and their sum.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct TriLanes {
    pub(crate) t: [f32; LEAF_SIZE],
    pub(crate) uvw: [[f32; LEAF_SIZE]; 3],
    pub(crate) det: [f32; LEAF_SIZE],
}

impl TriLanes {
    /// Lane `lane` as a [`RawHit`].
    #[inline(always)]
    pub(crate) fn hit(&self, lane: usize) -> RawHit {
        RawHit {
            t: self.t[lane],
            uvw: [self.uvw[0][lane], self.uvw[1][lane], self.uvw[2][lane]],
            det: self.det[lane],
        }
    }

    /// Stores `hit` in lane `lane`.
    #[inline(always)]
    pub(crate) fn set(&mut self, lane: usize, hit: &RawHit) {
        self.t[lane] = hit.t;
        self.det[lane] = hit.det;
        for (k, &x) in hit.uvw.iter().enumerate() {
            self.uvw[k][lane] = x;
        }
    }
}

/// The tests a traversal runs.
pub(crate) trait Kernel {
    /// The children of `node` whose boxes the ray meets in `[ray.tmin, tmax]`, as bits,
    /// with each child's entry distance in `tnear`.
    fn boxes(node: &Node, ray: &RayK, tmax: f32, tnear: &mut [f32; WIDTH]) -> u32;

    /// The lanes of `valid` whose triangles the ray meets in `[ray.tmin, tmax]`, as bits,
    /// with their results in `out`: for each such lane exactly
    /// [`intersect_raw`]'s result.
    fn tris(pack: &Tri4, valid: u32, ray: &RayK, tmax: f32, out: &mut TriLanes) -> u32;
}

/// A traversal query, written once over the kernel.
pub(crate) trait Query {
    /// The query's answer.
    type Out;

    /// Runs the query with kernel `K` (to be `#[inline(always)]`, so that it is compiled
    /// inside each kernel's entry point with that kernel's instruction set).
    fn run<K: Kernel>(&self) -> Self::Out;
}

/// The scalar kernel: one child and one triangle at a time.
pub(crate) struct Scalar;

impl Kernel for Scalar {
    #[inline(always)]
    fn boxes(node: &Node, ray: &RayK, tmax: f32, tnear: &mut [f32; WIDTH]) -> u32 {
        let mut mask = 0;
        for (lane, tn_out) in tnear.iter_mut().enumerate() {
            let mut tn = ray.tmin;
            let mut tf = f32::INFINITY;
            for axis in 0..3 {
                let s = ray.sign[axis];
                let near = (node.planes[2 * axis + s][lane] - ray.origin[axis]) * ray.inv[axis];
                let far = (node.planes[2 * axis + 1 - s][lane] - ray.origin[axis]) * ray.inv[axis];
                tn = tn.max(near);
                tf = tf.min(far);
            }
            let tf = (tf * FAR_SCALE).min(tmax);
            *tn_out = tn;
            if tn <= tf {
                mask |= 1 << lane;
            }
        }
        mask
    }

    #[inline(always)]
    fn tris(pack: &Tri4, valid: u32, ray: &RayK, tmax: f32, out: &mut TriLanes) -> u32 {
        let mut mask = 0;
        for lane in 0..LEAF_SIZE {
            if valid & (1 << lane) == 0 {
                continue;
            }
            if let Some(h) = intersect_raw(&ray.shear, &pack.triangle(lane), ray.tmin, tmax) {
                out.set(lane, &h);
                mask |= 1 << lane;
            }
        }
        mask
    }
}
