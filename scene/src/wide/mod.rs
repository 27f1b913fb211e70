//! The tracer's wide BVH: an 8-wide tree laid out for CPU SIMD, collapsed from obvhs'
//! binary BVH, with leaves of up to eight triangles stored four side by side.
//!
//! obvhs builds the binary tree (PLOC, reinsertion, optional pre-splits); `build`
//! collapses it into nodes of eight children whose boxes are stored as uncompressed f32
//! planes in structure-of-arrays form (`lo_x[8] hi_x[8] lo_y[8] …`), so that one ray tests
//! all eight at once (\[WBB08\] §3; the layout of Embree's BVH8, \[WWB14\] §4, and of
//! tinybvh's `BVH8_CPU`). A child subtree of at most eight primitives becomes one
//! leaf; a triangle leaf is one or two `Tri4` packs, each four triangles' vertices side by
//! side, so that the watertight test ([`crate::watertight`], \[WBW13\]) runs on four at once.
//!
//! Traversal (`traverse`) is written once over a `kernel::Kernel`, the box test of
//! eight children and the triangle test of one pack, and instantiated for each kernel the
//! machine can run ([`Isa`], chosen at run time in `dispatch`). Every kernel returns the
//! same hits bit for bit: the triangle arithmetic is the scalar reference's, operation for
//! operation (no fused multiply-adds), the box tests are conservative (\[Ize13\]), and the closest hit
//! is the least `(t, triangle)` pair, so neither traversal order nor kernel can change it.

pub(crate) mod build;
pub(crate) mod dispatch;
pub(crate) mod kernel;
#[cfg(target_arch = "x86_64")]
mod simd;
pub(crate) mod traverse;

#[cfg(test)]
mod tests;

pub use dispatch::{ISA_ENV, Isa};

/// Children per node.
pub(crate) const WIDTH: usize = 8;

/// Primitives per leaf pack: a child subtree with at most this many becomes a leaf.
pub(crate) const LEAF_SIZE: usize = 4;

/// An unused child slot, or an empty tree.
pub(crate) const EMPTY: u32 = u32::MAX;

/// Set in a child reference that names a leaf: the rest is the leaf's first pack `k` and,
/// in the low [`PACK_BITS`] bits, its number of packs less one (the leaf holds the
/// primitives `prims[4k ..]`, and in a triangle tree the packs `packs[k ..]`).
pub(crate) const LEAF_BIT: u32 = 1 << 31;

/// Bits of a leaf reference that count its packs: 1, leaves of one or two packs (subtrees
/// of up to eight triangles). Against one pack per leaf (`lightvol bench --embree`, 300 k
/// rays, AVX2, 1 thread, the two builds alternating, best of 5), lightvol's rays/s rose on
/// 11 of 12 cells: closest hits +9.1%, +5.4% and +1.8% on the Breakfast Room, the occlusion
/// room and zdm2, the bake mix's closest hits +4.9%, +2.4% and +2.4%, its shadow rays
/// +1.6%, +3.0% and +3.0%, uniform shadow rays −0.7%, +0.3% and +4.6%. The trees have
/// fewer nodes (the Breakfast Room 9,399 against 17,088), and 3.0-3.2 triangles a pack on
/// the vendored scenes. (Testing both packs of a leaf at once in eight AVX2 lanes was
/// slower on shadow rays, 7-9%, and no faster on closest hits.)
pub(crate) const PACK_BITS: u32 = 1;

/// Packs per leaf at most.
pub(crate) const MAX_LEAF_PACKS: usize = 1 << PACK_BITS;

/// The set bits of a lane mask, lowest first: the lanes a box or triangle test reported.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lanes(pub(crate) u32);

impl Iterator for Lanes {
    type Item = usize;

    #[inline(always)]
    fn next(&mut self) -> Option<usize> {
        if self.0 == 0 {
            return None;
        }
        let lane = self.0.trailing_zeros() as usize;
        self.0 &= self.0 - 1;
        Some(lane)
    }
}

/// One node: the boxes of eight children as planes (`planes[2·axis]` the low side,
/// `planes[2·axis + 1]` the high side; an unused slot has the empty box `+∞ … −∞`, which no
/// ray meets) and the child references (a node index, `LEAF_BIT | leaf`, or [`EMPTY`]).
#[repr(C, align(32))]
#[derive(Clone, Debug)]
pub(crate) struct Node {
    pub(crate) planes: [[f32; WIDTH]; 6],
    pub(crate) child: [u32; WIDTH],
}

impl Node {
    /// A node with no children.
    fn empty() -> Self {
        let mut planes = [[f32::INFINITY; WIDTH]; 6];
        for axis in 0..3 {
            planes[2 * axis + 1] = [f32::NEG_INFINITY; WIDTH];
        }
        Self { planes, child: [EMPTY; WIDTH] }
    }
}

/// Four triangles side by side: `v[3·i + axis][lane]` is coordinate `axis` of vertex `i`
/// of the triangle in `lane`. Unused lanes hold NaN vertices and the id [`EMPTY`].
#[repr(C, align(16))]
#[derive(Clone, Debug)]
pub(crate) struct Tri4 {
    pub(crate) v: [[f32; LEAF_SIZE]; 9],
    pub(crate) id: [u32; LEAF_SIZE],
}

impl Tri4 {
    /// The lanes that hold a triangle, as bits.
    #[inline(always)]
    pub(crate) fn valid(&self) -> u32 {
        let mut m = 0;
        for (lane, &id) in self.id.iter().enumerate() {
            if id != EMPTY {
                m |= 1 << lane;
            }
        }
        m
    }

    /// The vertices of the triangle in `lane`.
    #[inline(always)]
    pub(crate) fn triangle(&self, lane: usize) -> [[f32; 3]; 3] {
        std::array::from_fn(|i| std::array::from_fn(|axis| self.v[3 * i + axis][lane]))
    }
}

/// A wide BVH over triangles (with [`Tri4`] packs) or over boxes (the top level over
/// placements, whose leaves list placement indices). Every leaf is one or two packs of up to
/// [`LEAF_SIZE`] primitives each ([`PACK_BITS`]), named by its first pack's index and
/// count in the child reference itself, so that a leaf costs no lookup beyond its packs.
#[derive(Clone, Debug)]
pub(crate) struct WideBvh {
    /// The root reference: node 0, a single leaf, or [`EMPTY`] for no primitives.
    pub(crate) root: u32,
    pub(crate) nodes: Vec<Node>,
    /// Primitive indices, [`LEAF_SIZE`] per leaf; unused slots hold [`EMPTY`].
    pub(crate) prims: Vec<u32>,
    /// Triangle trees only: pack `k` holds the triangles of `prims[4k .. 4k + 4]`.
    pub(crate) packs: Vec<Tri4>,
}

impl WideBvh {
    /// The first pack and the pack count of leaf `leaf` (a child reference less
    /// [`LEAF_BIT`]).
    #[inline(always)]
    fn leaf_range(leaf: u32) -> (usize, usize) {
        ((leaf >> PACK_BITS) as usize, (leaf & ((1u32 << PACK_BITS) - 1)) as usize + 1)
    }

    /// The packs of leaf `leaf` (triangle trees).
    #[inline(always)]
    pub(crate) fn leaf_packs(&self, leaf: u32) -> &[Tri4] {
        let (first, n) = Self::leaf_range(leaf);
        &self.packs[first..first + n]
    }

    /// The primitives of leaf `leaf`, unused slots ([`EMPTY`]) included.
    #[inline(always)]
    pub(crate) fn leaf_prims(&self, leaf: u32) -> &[u32] {
        let (first, n) = Self::leaf_range(leaf);
        &self.prims[first * LEAF_SIZE..(first + n) * LEAF_SIZE]
    }

    /// Every leaf (as its reference less [`LEAF_BIT`]).
    #[cfg(test)]
    pub(crate) fn leaves(&self) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = vec![self.root];
        while let Some(r) = stack.pop() {
            if r == EMPTY {
                continue;
            }
            if r & LEAF_BIT != 0 {
                out.push(r & !LEAF_BIT);
            } else {
                stack.extend(self.nodes[r as usize].child);
            }
        }
        out
    }

    /// Bytes the tree occupies (nodes, primitive slots and packs).
    pub(crate) fn bytes(&self) -> usize {
        self.nodes.len() * size_of::<Node>() + self.prims.len() * 4 + self.packs.len() * size_of::<Tri4>()
    }
}
