//! The x86-64 SIMD kernels (SSE2 and AVX2) and the AVX2 entry point: the one module of
//! this crate with `unsafe` code (see the crate README).
//!
//! Each kernel computes exactly the scalar kernel's arithmetic, lane by lane: the same
//! operations in the same order, no fused multiply-add (Rust never contracts `a·b + c`),
//! and the watertight test's f64 re-evaluation of zero edge functions done by the scalar
//! reference itself for those lanes. So the hits are bit-identical across kernels.
#![allow(unsafe_code)]

use std::arch::x86_64::*;

use super::kernel::{FAR_SCALE, Kernel, Query, RayK, TriLanes};
use super::{Lanes, Node, Tri4, WIDTH};
use crate::watertight::intersect_raw;

/// True when the CPU runs AVX2 and FMA (detected once by the standard library, cached).
pub(crate) fn avx2_detected() -> bool {
    is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
}

/// Runs `q` with the AVX2 kernel, or `None` where the CPU lacks AVX2 or FMA.
#[inline]
pub(crate) fn run_avx2<Q: Query>(q: &Q) -> Option<Q::Out> {
    if !avx2_detected() {
        return None;
    }
    // SAFETY: `run_avx2_inner` only needs the CPU features its `target_feature` names,
    // which were just detected.
    Some(unsafe { run_avx2_inner(q) })
}

/// `q` compiled with AVX2 and FMA enabled: the query and both kernels inline into it.
#[target_feature(enable = "avx2,fma")]
unsafe fn run_avx2_inner<Q: Query>(q: &Q) -> Q::Out {
    q.run::<Avx2>()
}

/// The 4-wide SSE2 kernel (part of every x86-64 CPU).
pub(crate) struct Sse2;

/// The 8-wide AVX2 kernel (boxes 8 at once; triangles as [`Sse2`], VEX-encoded).
pub(crate) struct Avx2;

/// The near and far slab distances `(plane − o)·(1/d)` of axis `$a` for the lanes from
/// `4·$half` (written as a macro, not a closure: a closure is compiled without the entry
/// point's target features, so the AVX intrinsics in it would not inline).
macro_rules! slab {
    ($node:expr, $ray:expr, $a:expr, $half:expr, $load:ident, $set1:ident, $sub:ident, $mul:ident) => {{
        let o = $set1($ray.origin[$a]);
        let inv = $set1($ray.inv[$a]);
        let s = $ray.sign[$a];
        let near = $load($node.planes[2 * $a + s].as_ptr().add(4 * $half));
        let far = $load($node.planes[2 * $a + 1 - s].as_ptr().add(4 * $half));
        ($mul($sub(near, o), inv), $mul($sub(far, o), inv))
    }};
}

impl Kernel for Sse2 {
    #[inline(always)]
    fn boxes(node: &Node, ray: &RayK, tmax: f32, tnear: &mut [f32; WIDTH]) -> u32 {
        let mut mask = 0;
        for half in 0..2 {
            // SAFETY: SSE2 is part of x86-64. `Node` is 32-byte aligned and each plane row
            // is 8 f32 (32 bytes), so `row + 4·half` is 16-byte aligned and 4 lanes long;
            // `tnear[4·half..]` holds 4 f32.
            unsafe {
                let (nx, fx) = slab!(node, ray, 0, half, _mm_load_ps, _mm_set1_ps, _mm_sub_ps, _mm_mul_ps);
                let (ny, fy) = slab!(node, ray, 1, half, _mm_load_ps, _mm_set1_ps, _mm_sub_ps, _mm_mul_ps);
                let (nz, fz) = slab!(node, ray, 2, half, _mm_load_ps, _mm_set1_ps, _mm_sub_ps, _mm_mul_ps);
                let tn = _mm_max_ps(_mm_max_ps(nx, ny), _mm_max_ps(nz, _mm_set1_ps(ray.tmin)));
                let tf = _mm_min_ps(
                    _mm_mul_ps(_mm_min_ps(_mm_min_ps(fx, fy), fz), _mm_set1_ps(FAR_SCALE)),
                    _mm_set1_ps(tmax),
                );
                _mm_storeu_ps(tnear.as_mut_ptr().add(4 * half), tn);
                mask |= (_mm_movemask_ps(_mm_cmple_ps(tn, tf)) as u32) << (4 * half);
            }
        }
        mask
    }

    #[inline(always)]
    fn tris(pack: &Tri4, valid: u32, ray: &RayK, tmax: f32, out: &mut TriLanes) -> u32 {
        tris_sse(pack, valid, ray, tmax, out)
    }
}

impl Kernel for Avx2 {
    #[inline(always)]
    fn boxes(node: &Node, ray: &RayK, tmax: f32, tnear: &mut [f32; WIDTH]) -> u32 {
        // SAFETY: only compiled into `run_avx2_inner`, which runs after AVX2 was detected.
        // `Node` is 32-byte aligned and each plane row is 8 f32, so each row is one aligned
        // 256-bit load; `tnear` holds 8 f32.
        unsafe {
            let (nx, fx) =
                slab!(node, ray, 0, 0, _mm256_load_ps, _mm256_set1_ps, _mm256_sub_ps, _mm256_mul_ps);
            let (ny, fy) =
                slab!(node, ray, 1, 0, _mm256_load_ps, _mm256_set1_ps, _mm256_sub_ps, _mm256_mul_ps);
            let (nz, fz) =
                slab!(node, ray, 2, 0, _mm256_load_ps, _mm256_set1_ps, _mm256_sub_ps, _mm256_mul_ps);
            let tn = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, _mm256_set1_ps(ray.tmin)));
            let tf = _mm256_min_ps(
                _mm256_mul_ps(_mm256_min_ps(_mm256_min_ps(fx, fy), fz), _mm256_set1_ps(FAR_SCALE)),
                _mm256_set1_ps(tmax),
            );
            _mm256_storeu_ps(tnear.as_mut_ptr(), tn);
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, tf)) as u32
        }
    }

    #[inline(always)]
    fn tris(pack: &Tri4, valid: u32, ray: &RayK, tmax: f32, out: &mut TriLanes) -> u32 {
        tris_sse(pack, valid, ray, tmax, out)
    }
}

/// The watertight test of four triangles at once ([`crate::watertight::intersect_raw`]
/// lane by lane).
#[inline(always)]
fn tris_sse(pack: &Tri4, valid: u32, ray: &RayK, tmax: f32, out: &mut TriLanes) -> u32 {
    let sh = &ray.shear;
    let [kx, ky, kz] = sh.k;
    // SAFETY: SSE2 is part of x86-64. `Tri4` is 16-byte aligned and each row is 4 f32, so
    // every load is aligned; each `out` row holds 4 f32.
    let (mut mask, zero_edges) = unsafe {
        let (ox, oy, oz) =
            (_mm_set1_ps(sh.origin[kx]), _mm_set1_ps(sh.origin[ky]), _mm_set1_ps(sh.origin[kz]));
        let (sx, sy, sz) = (_mm_set1_ps(sh.s[0]), _mm_set1_ps(sh.s[1]), _mm_set1_ps(sh.s[2]));
        // Vertex i relative to the origin and sheared: (x, y, z).
        macro_rules! vertex {
            ($i:expr) => {{
                let ax = _mm_sub_ps(_mm_load_ps(pack.v[3 * $i + kx].as_ptr()), ox);
                let ay = _mm_sub_ps(_mm_load_ps(pack.v[3 * $i + ky].as_ptr()), oy);
                let az = _mm_sub_ps(_mm_load_ps(pack.v[3 * $i + kz].as_ptr()), oz);
                (_mm_sub_ps(ax, _mm_mul_ps(sx, az)), _mm_sub_ps(ay, _mm_mul_ps(sy, az)), az)
            }};
        }
        let (a, b, c) = (vertex!(0), vertex!(1), vertex!(2));
        // edge(p, q) = q.x·p.y − q.y·p.x
        let u = _mm_sub_ps(_mm_mul_ps(c.0, b.1), _mm_mul_ps(c.1, b.0));
        let v = _mm_sub_ps(_mm_mul_ps(a.0, c.1), _mm_mul_ps(a.1, c.0));
        let w = _mm_sub_ps(_mm_mul_ps(b.0, a.1), _mm_mul_ps(b.1, a.0));
        let zero = _mm_setzero_ps();
        let zero_edges = _mm_movemask_ps(_mm_or_ps(
            _mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)),
            _mm_cmpeq_ps(w, zero),
        )) as u32;
        let neg = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)), _mm_cmplt_ps(w, zero));
        let pos = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u, zero), _mm_cmpgt_ps(v, zero)), _mm_cmpgt_ps(w, zero));
        let det = _mm_add_ps(_mm_add_ps(u, v), w);
        let scaled = _mm_add_ps(
            _mm_add_ps(_mm_mul_ps(u, _mm_mul_ps(sz, a.2)), _mm_mul_ps(v, _mm_mul_ps(sz, b.2))),
            _mm_mul_ps(w, _mm_mul_ps(sz, c.2)),
        );
        let t = _mm_div_ps(scaled, det);
        let in_range = _mm_and_ps(_mm_cmpge_ps(t, _mm_set1_ps(ray.tmin)), _mm_cmple_ps(t, _mm_set1_ps(tmax)));
        let ok = _mm_andnot_ps(_mm_and_ps(neg, pos), _mm_and_ps(_mm_cmpneq_ps(det, zero), in_range));
        _mm_storeu_ps(out.t.as_mut_ptr(), t);
        _mm_storeu_ps(out.uvw[0].as_mut_ptr(), u);
        _mm_storeu_ps(out.uvw[1].as_mut_ptr(), v);
        _mm_storeu_ps(out.uvw[2].as_mut_ptr(), w);
        _mm_storeu_ps(out.det.as_mut_ptr(), det);
        (_mm_movemask_ps(ok) as u32, zero_edges & valid)
    };
    mask &= valid & !zero_edges;
    // Lanes with an edge function exactly 0: the scalar reference re-evaluates it in f64.
    for lane in Lanes(zero_edges) {
        if let Some(h) = intersect_raw(sh, &pack.triangle(lane), ray.tmin, tmax) {
            out.set(lane, &h);
            mask |= 1 << lane;
        }
    }
    mask
}
