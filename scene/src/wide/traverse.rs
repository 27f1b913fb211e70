//! Traversal of a [`WideBvh`], written once over a [`Kernel`].
//!
//! A stack of `(child, entry distance)` pairs. For closest hits a node's children that the
//! ray meets are visited nearest first (sorted by their box entry distance, the nearest
//! taken at once and the others pushed), and a popped entry whose box starts beyond the
//! best hit so far is skipped. Occlusion, which stops at the first hit, visits them in
//! slot order, the order of the collapse's cut of the binary tree (`build`), and skips the
//! sort. On the collapsed trees of `build`, with sun shadow rays (`lightvol bench
//! --embree`, 300 k rays, AVX2, 1 thread, lightvol's rays/s over Embree's), sorting gave
//! 0.71-0.76× on the Breakfast Room and slot order 0.87×; against the earlier trees
//! traversed nearest first (0.79×), slot order on the new trees gives the Breakfast Room
//! 0.84×, the occlusion room 0.88× (was 0.74×) and zdm2 0.86× (was 0.77×), and the bake
//! mix's shadow rays 0.82×, 0.84× and 0.85× (were 0.71×, 0.63× and 0.76×). (The sort is work at
//! every node, and a shadow ray needs any occluder, not the nearest.) The closest hit is the least
//! `(t, id)` pair over every triangle the ray meets, and an occlusion query's answer is
//! whether any accepted hit exists, so the order of visits cannot change either.

use super::kernel::{Kernel, RayK, TriLanes};
use super::{EMPTY, LEAF_BIT, Lanes, WIDTH, WideBvh};
use crate::watertight::RawHit;

/// Stack entries kept inline; deeper traversals spill to the heap. The inline array is
/// zeroed for every ray, so it is kept small: at 64 entries (512 bytes) the zeroing was a
/// call to `memset` per ray, at 32 it is a few vector stores. Of a Breakfast Room bake's
/// 12 M traversals at 0.2 m and 256 samples, 134 spilled at 32 entries (429,209 at 16).
const INLINE_STACK: usize = 32;

#[cfg(test)]
thread_local! {
    /// Entries this thread pushed past the inline array (tests: that a traversal spilled).
    pub(crate) static SPILLED: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// The traversal stack.
struct Stack {
    items: [(u32, f32); INLINE_STACK],
    len: usize,
    spill: Vec<(u32, f32)>,
}

impl Stack {
    #[inline(always)]
    fn new() -> Self {
        Self { items: [(0, 0.0); INLINE_STACK], len: 0, spill: Vec::new() }
    }

    #[inline(always)]
    fn push(&mut self, e: (u32, f32)) {
        if self.len < INLINE_STACK {
            self.items[self.len] = e;
            self.len += 1;
        } else {
            #[cfg(test)]
            SPILLED.set(SPILLED.get() + 1);
            self.spill.push(e);
        }
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        if let Some(e) = self.spill.pop() {
            return Some(e);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some(self.items[self.len])
    }
}

/// What a traversal does at a leaf.
pub(crate) trait Visit {
    /// Whether a node's hit children are visited nearest first (closest hits) or in slot
    /// order (occlusion; module docs).
    const NEAREST_FIRST: bool;

    /// The far end of the ray now: the best hit so far for closest hits.
    fn tmax(&self) -> f32;

    /// Visits leaf `leaf` of `bvh`; true stops the traversal.
    fn leaf<K: Kernel>(&mut self, bvh: &WideBvh, leaf: u32) -> bool;
}

/// Walks `bvh` with `ray`, nearest child first; true when a leaf stopped it.
#[inline(always)]
pub(crate) fn walk<K: Kernel, V: Visit>(bvh: &WideBvh, ray: &RayK, v: &mut V) -> bool {
    if bvh.root == EMPTY {
        return false;
    }
    let mut stack = Stack::new();
    let mut tnear = [0f32; WIDTH];
    // Filled anew at each node (only `hits[..n]` is read); declared once per ray.
    let mut hits = [(0u32, 0f32); WIDTH];
    let mut next = Some((bvh.root, ray.tmin));
    loop {
        let (r, entry) = match next.take() {
            Some(e) => e,
            None => match stack.pop() {
                Some(e) => e,
                None => return false,
            },
        };
        let tmax = v.tmax();
        if entry > tmax {
            continue;
        }
        if r & LEAF_BIT != 0 {
            if v.leaf::<K>(bvh, r & !LEAF_BIT) {
                return true;
            }
            continue;
        }
        let node = &bvh.nodes[r as usize];
        let mask = K::boxes(node, ray, tmax, &mut tnear);
        // Hit children, sorted by entry distance, nearest first (insertion sort of ≤ 8),
        // or in slot order, in `hits[..n]`.
        let mut n = 0;
        for lane in Lanes(mask) {
            let e = (node.child[lane], tnear[lane]);
            let mut k = n;
            if V::NEAREST_FIRST {
                while k > 0 && hits[k - 1].1 > e.1 {
                    hits[k] = hits[k - 1];
                    k -= 1;
                }
            }
            hits[k] = e;
            n += 1;
        }
        if n == 0 {
            continue;
        }
        for &e in hits[1..n].iter().rev() {
            stack.push(e);
        }
        next = Some(hits[0]);
    }
}

/// How triangle hits are identified and filtered.
pub(crate) trait Filter {
    /// The id that breaks ties between hits at the same distance (the scene index).
    fn id(&self, prim: u32) -> u32;

    /// False for a candidate hit that is no surface (alpha).
    fn accept(&self, prim: u32, hit: &RawHit) -> bool;
}

/// The best hit so far.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Best {
    /// Its distance (the ray's `tmax` before any hit).
    pub(crate) t: f32,
    /// Its tie-breaking id ([`EMPTY`] before any hit).
    pub(crate) id: u32,
    /// The hit itself.
    pub(crate) hit: Option<RawHit>,
}

impl Best {
    /// No hit yet, on a ray ending at `tmax`.
    #[inline(always)]
    pub(crate) fn new(tmax: f32) -> Self {
        Self { t: tmax, id: EMPTY, hit: None }
    }

    /// Takes `hit` with `id` when it is the lesser `(t, id)` pair and `accept` agrees.
    #[inline(always)]
    pub(crate) fn offer(&mut self, id: u32, hit: RawHit, accept: impl FnOnce() -> bool) {
        if (hit.t < self.t || (hit.t == self.t && id < self.id)) && accept() {
            *self = Self { t: hit.t, id, hit: Some(hit) };
        }
    }
}

/// Closest hit over a triangle tree.
pub(crate) struct Closest<'a, F> {
    pub(crate) ray: &'a RayK,
    pub(crate) best: &'a mut Best,
    pub(crate) filter: &'a F,
}

impl<F: Filter> Visit for Closest<'_, F> {
    const NEAREST_FIRST: bool = true;

    #[inline(always)]
    fn tmax(&self) -> f32 {
        self.best.t
    }

    #[inline(always)]
    fn leaf<K: Kernel>(&mut self, bvh: &WideBvh, leaf: u32) -> bool {
        let mut lanes = TriLanes::default();
        for pack in bvh.leaf_packs(leaf) {
            let mask = K::tris(pack, pack.valid(), self.ray, self.best.t, &mut lanes);
            for lane in Lanes(mask) {
                let prim = pack.id[lane];
                let hit = lanes.hit(lane);
                let filter = self.filter;
                self.best.offer(filter.id(prim), hit, || filter.accept(prim, &hit));
            }
        }
        false
    }
}

/// Any hit over a triangle tree (shadow rays).
pub(crate) struct Any<'a, F> {
    pub(crate) ray: &'a RayK,
    pub(crate) filter: &'a F,
}

impl<F: Filter> Visit for Any<'_, F> {
    const NEAREST_FIRST: bool = false;

    #[inline(always)]
    fn tmax(&self) -> f32 {
        self.ray.tmax
    }

    #[inline(always)]
    fn leaf<K: Kernel>(&mut self, bvh: &WideBvh, leaf: u32) -> bool {
        let mut lanes = TriLanes::default();
        for pack in bvh.leaf_packs(leaf) {
            let mask = K::tris(pack, pack.valid(), self.ray, self.ray.tmax, &mut lanes);
            for lane in Lanes(mask) {
                if self.filter.accept(pack.id[lane], &lanes.hit(lane)) {
                    return true;
                }
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::{INLINE_STACK, Stack};

    /// Entries come back last in, first out across the inline array and its spill.
    #[test]
    fn stack_is_lifo_across_the_spill() {
        let mut s = Stack::new();
        let n = 3 * INLINE_STACK + 5;
        for i in 0..n {
            s.push((i as u32, i as f32 * 0.5));
        }
        for i in (0..n).rev() {
            assert_eq!(s.pop(), Some((i as u32, i as f32 * 0.5)));
        }
        assert_eq!(s.pop(), None);
        // Refilled after emptying: the inline part is used again.
        s.push((7, 1.0));
        assert_eq!(s.pop(), Some((7, 1.0)));
        assert_eq!(s.pop(), None);
    }
}
