//! Collapsing obvhs' binary BVH into the [`WideBvh`] layout.
//!
//! The binary tree is built with one primitive per leaf (obvhs' own leaf collapse is
//! skipped), then cut into wide nodes by the surface-area heuristic, optimally over every
//! way of cutting it (the dynamic programme of Ylitie, Karras & Laine 2017, §3.1, \[YKL17\]):
//! for each binary node `n` and slot budget `j ≤ 8`, `cost[n][j]` is the least expected cost
//! of representing `n`'s subtree in at most `j` child slots of one wide node, where a slot is
//! either a leaf (a subtree of at most [`LEAF_PRIMS`] primitives, priced as one pack test,
//! [`PACK_COST`], whether it fills one pack or two: the setting measured in `PACK_BITS`'s
//! docs) or a wide node of its own (one test of eight boxes, [`NODE_COST`], plus its
//! eight slots), each weighted by its box's surface area (the probability that a ray
//! meeting the parent meets it, \[MB90\]). Children are computed before
//! parents; the choices are recomputed from the table while the wide tree is emitted.
//!
//! Measured against the greedy collapse it replaced (open the child with the largest
//! surface area until eight, \[WBB08\] §3) with `lightvol bench --embree`, 300 k rays,
//! AVX2, as lightvol's rays/s over Embree's in the same run, 1 thread: closest hits on the
//! Breakfast Room 0.72× → 0.79×, the occlusion room 0.71× → 0.74×, zdm2 0.92× → 0.94×;
//! the bake mix's closest hits 0.66× → 0.74×, 0.71× → 0.74× and 0.93× → 0.97×. A whole
//! Breakfast Room bake (`lightvol bench --whole-bake --bake-runs 5`, 0.2 m, 256 samples,
//! with the slot-order shadow rays of `traverse`) took 2.54 s against 2.79 s, the same
//! bytes. The table costs eight f32 per binary node while the tree is emitted (about 80 ms
//! of the Breakfast Room's 0.25 s build). (Shadow rays got slower on these trees with
//! nearest-first order and faster than before in slot order: see `traverse`.) A binary
//! leaf with more than
//! [`LEAF_PRIMS`] primitives becomes a node of leaves under its box.

use std::time::Duration;

use glam::Vec3A;
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::builder::{build_bvh2, build_bvh2_from_tris};
use obvhs::triangle::Triangle as ObTriangle;

use super::{EMPTY, LEAF_BIT, LEAF_SIZE, MAX_LEAF_PACKS, Node, PACK_BITS, Tri4, WIDTH, WideBvh};

/// Primitives per leaf at most: a subtree with at most this many becomes one leaf.
const LEAF_PRIMS: usize = LEAF_SIZE * MAX_LEAF_PACKS;

/// Child boxes are widened on each side by this fraction of their largest coordinate
/// magnitude (or extent): 2⁻²⁰, about 16 f32 ulps. The watertight test and the slab test
/// round differently, so a hit's computed distance can lie a few ulps of the coordinates
/// outside the computed slab interval of its box; the margin keeps every box test
/// conservative, so that the traversal finds exactly the hits a loop over all triangles
/// finds (tested against one on 100 000 rays).
pub(crate) const BOX_PAD_REL: f32 = 1.0 / (1 << 20) as f32;

/// obvhs' build parameters with one primitive per binary leaf.
fn binary_params(mut params: BvhBuildParams) -> BvhBuildParams {
    params.max_prims_per_leaf = 1;
    params
}

/// A wide BVH over triangles, with their packs; primitive `i` is `tris[i]`.
pub(crate) fn from_triangles(tris: &[ObTriangle], params: BvhBuildParams) -> WideBvh {
    if tris.is_empty() {
        return empty();
    }
    let b2 = build_bvh2_from_tris(tris, binary_params(params), &mut Duration::default());
    with_packs(collapse(&b2), tris)
}

/// `bvh` (over `tris`) with its triangle packs: pack `k` holds the triangles of
/// `prims[4k .. 4k + 4]`, unused lanes NaN.
pub(super) fn with_packs(mut bvh: WideBvh, tris: &[ObTriangle]) -> WideBvh {
    bvh.packs = bvh
        .prims
        .chunks(LEAF_SIZE)
        .map(|ids| {
            let mut pack = Tri4 { v: [[f32::NAN; LEAF_SIZE]; 9], id: [EMPTY; LEAF_SIZE] };
            for (lane, &id) in ids.iter().enumerate() {
                if id == EMPTY {
                    continue;
                }
                pack.id[lane] = id;
                let t = &tris[id as usize];
                for (i, v) in [t.v0, t.v1, t.v2].into_iter().enumerate() {
                    for axis in 0..3 {
                        pack.v[3 * i + axis][lane] = v[axis];
                    }
                }
            }
            pack
        })
        .collect();
    bvh
}

/// A wide BVH over boxes (its leaves list box indices).
pub(crate) fn from_boxes(boxes: &[Aabb], params: BvhBuildParams) -> WideBvh {
    if boxes.is_empty() {
        return empty();
    }
    collapse(&build_bvh2(boxes, binary_params(params), &mut Duration::default()))
}

fn empty() -> WideBvh {
    WideBvh { root: EMPTY, nodes: Vec::new(), prims: Vec::new(), packs: Vec::new() }
}

/// The box of binary node `i`, widened by [`BOX_PAD_REL`] (rounded outward).
fn padded(b2: &Bvh2, i: usize) -> (Vec3A, Vec3A) {
    let Aabb { min, max } = *b2.nodes[i].aabb();
    let pad = min.abs().max(max.abs()).max(max - min) * BOX_PAD_REL;
    (min - pad, max + pad)
}

/// Each binary node's primitive count, and the table `cost[n][j − 1]`: the least cost of
/// binary node `n`'s subtree in at most `j` slots (module docs). Both are computed children
/// first, in one pass over a pre-order of the tree reversed (u32 indices: the table is the
/// build's peak, and obvhs' indices are u32).
fn tables(b2: &Bvh2) -> (Vec<u32>, Vec<[f32; WIDTH]>) {
    let n = b2.nodes.len();
    let mut order: Vec<u32> = Vec::with_capacity(n);
    let mut stack = vec![0u32];
    while let Some(i) = stack.pop() {
        order.push(i);
        let node = &b2.nodes[i as usize];
        if !node.is_leaf() {
            stack.extend([node.first_index, node.first_index + 1]);
        }
    }
    let mut counts = vec![0u32; n];
    let mut cost = vec![[0f32; WIDTH]; n];
    for &i in order.iter().rev() {
        let i = i as usize;
        let node = &b2.nodes[i];
        counts[i] = if node.is_leaf() {
            node.prim_count
        } else {
            let l = node.first_index as usize;
            counts[l] + counts[l + 1]
        };
        cost[i] = slot_row(b2, &counts, &cost, i);
    }
    (counts, cost)
}

/// The wide tree of a binary tree (module docs).
pub(super) fn collapse(b2: &Bvh2) -> WideBvh {
    let (counts, cost) = tables(b2);
    let mut c = Collapser { b2, counts, cost, out: empty() };
    c.out.root = c.emit(0);
    c.out
}

/// The least cost of the whole tree (module docs): the root in one slot, as the collapse
/// emits it.
#[cfg(test)]
pub(super) fn collapse_cost(b2: &Bvh2) -> f32 {
    let (counts, cost) = tables(b2);
    one_slot_with(b2, &counts, 0, splits(b2, &cost, 0)[WIDTH - 1].0).0
}

/// The cost of one wide node's test of its eight child boxes, in the units of
/// [`PACK_COST`].
pub(crate) const NODE_COST: f32 = 1.0;

/// The cost of one leaf's watertight test of its four triangles, relative to [`NODE_COST`]:
/// the pack test divides and re-checks zero edges where the box test only multiplies.
/// Measured with `lightvol bench --embree` on the Breakfast Room at 0.5, 1, 2 and 4: 2 gave
/// the fastest closest hits (0.5 the slowest, 4 within noise of 2).
pub(crate) const PACK_COST: f32 = 2.0;

/// The best ways for the two children of binary node `i` to fill `j` slots between them,
/// for each `j` (entry `j − 1`): `(cost, k)` with `k` slots to the left child and `j − k`
/// to the right, the lowest `k` among equal costs; infinite cost for `j = 1` and for a
/// binary leaf. All budgets in one pass over the children's rows.
fn splits(b2: &Bvh2, cost: &[[f32; WIDTH]], i: usize) -> [(f32, usize); WIDTH] {
    let mut out = [(f32::INFINITY, 0); WIDTH];
    let node = &b2.nodes[i];
    if node.is_leaf() {
        return out;
    }
    let l = node.first_index as usize;
    let (a, b) = (cost[l], cost[l + 1]);
    for (j, o) in out.iter_mut().enumerate().skip(1) {
        // j + 1 slots: k + 1 to the left, j − k to the right.
        for k in 0..j {
            let c = a[k] + b[j - 1 - k];
            if c < o.0 {
                *o = (c, k + 1);
            }
        }
    }
    out
}

/// Binary node `i` in one slot: `(cost, leaf)`, a leaf where that is no dearer than a wide
/// node of its own, given its children's split over eight slots `split8`.
fn one_slot_with(b2: &Bvh2, counts: &[u32], i: usize, split8: f32) -> (f32, bool) {
    let node = &b2.nodes[i];
    let area = node.aabb().half_area();
    let n = counts[i] as usize;
    let as_leaf = if n <= LEAF_PRIMS { area * PACK_COST } else { f32::INFINITY };
    let as_node = if node.is_leaf() {
        // A big binary leaf: a node of leaves under its box.
        area * (NODE_COST + PACK_COST * n.div_ceil(LEAF_SIZE) as f32)
    } else {
        area * NODE_COST + split8
    };
    if as_leaf <= as_node { (as_leaf, true) } else { (as_node, false) }
}

/// The row `cost[i]` from its children's rows.
fn slot_row(b2: &Bvh2, counts: &[u32], cost: &[[f32; WIDTH]], i: usize) -> [f32; WIDTH] {
    let split = splits(b2, cost, i);
    let mut row = [one_slot_with(b2, counts, i, split[WIDTH - 1].0).0; WIDTH];
    for j in 1..WIDTH {
        row[j] = row[j - 1].min(split[j].0);
    }
    row
}

struct Collapser<'a> {
    b2: &'a Bvh2,
    /// Primitives under each binary node.
    counts: Vec<u32>,
    /// The table of [`tables`].
    cost: Vec<[f32; WIDTH]>,
    out: WideBvh,
}

impl Collapser<'_> {
    /// Emits binary node `i`, in one slot, as a leaf or a wide node (whichever
    /// [`one_slot_with`] chooses, given its children's best split); returns its child reference.
    fn emit(&mut self, i: usize) -> u32 {
        let b2 = self.b2;
        let split = splits(b2, &self.cost, i);
        let (_, leaf) = one_slot_with(b2, &self.counts, i, split[WIDTH - 1].0);
        if leaf {
            let prims = self.subtree_prims(i);
            return self.leaf(&prims);
        }
        if b2.nodes[i].is_leaf() {
            let prims = self.subtree_prims(i);
            let b = padded(b2, i);
            return self.prims_node(&prims, b);
        }
        let mut kids = Vec::with_capacity(WIDTH);
        self.slots(i, WIDTH, split[WIDTH - 1].1, &mut kids);
        let index = self.out.nodes.len();
        self.out.nodes.push(Node::empty());
        let mut node = Node::empty();
        for (lane, &k) in kids.iter().enumerate() {
            node.child[lane] = self.emit(k);
            set_box(&mut node, lane, padded(b2, k));
        }
        self.out.nodes[index] = node;
        index as u32
    }

    /// The binary nodes that fill the `j` slots of wide node `i` (an internal binary node
    /// that is not a leaf), `k` of them to its left child ([`splits`]): its children's
    /// subtrees cut by the table, left to right.
    fn slots(&self, i: usize, j: usize, k: usize, out: &mut Vec<usize>) {
        let l = self.b2.nodes[i].first_index as usize;
        self.fill(l, k, out);
        self.fill(l + 1, j - k, out);
    }

    /// The binary nodes that fill at most `j` slots with subtree `i`: itself where one slot
    /// costs no more than the best split over `j` slots, else its children's cuts. The
    /// split's cost only falls as `j` grows (each child's row is a least cost over
    /// budgets), so the table's `cost[i][j − 1]` is the one-slot cost `cost[i][0]` exactly
    /// when keeping `i` whole is no dearer.
    fn fill(&self, i: usize, j: usize, out: &mut Vec<usize>) {
        let row = &self.cost[i];
        if j < 2 || row[j - 1] >= row[0] {
            out.push(i);
        } else {
            self.slots(i, j, splits(self.b2, &self.cost, i)[j - 1].1, out);
        }
    }

    /// The primitives under binary node `i`, left to right.
    fn subtree_prims(&self, i: usize) -> Vec<u32> {
        let b2 = self.b2;
        let mut prims = Vec::new();
        let mut stack = vec![i];
        while let Some(k) = stack.pop() {
            let node = &b2.nodes[k];
            if node.is_leaf() {
                let a = node.first_index as usize;
                prims.extend_from_slice(&b2.primitive_indices[a..a + node.prim_count as usize]);
            } else {
                let l = node.first_index as usize;
                stack.extend([l + 1, l]);
            }
        }
        prims
    }

    /// One leaf of at most [`LEAF_PRIMS`] primitives, in whole packs.
    fn leaf(&mut self, prims: &[u32]) -> u32 {
        let out = &mut self.out;
        let first = out.prims.len() / LEAF_SIZE;
        let packs = prims.len().div_ceil(LEAF_SIZE);
        out.prims.extend_from_slice(prims);
        out.prims.resize((first + packs) * LEAF_SIZE, EMPTY);
        LEAF_BIT | (first << PACK_BITS) as u32 | (packs - 1) as u32
    }

    /// A node of leaves holding `prims` (more than one leaf's worth), every child under the
    /// box `b`.
    fn prims_node(&mut self, prims: &[u32], b: (Vec3A, Vec3A)) -> u32 {
        let per_child = prims.len().div_ceil(WIDTH).max(LEAF_PRIMS);
        let index = self.out.nodes.len();
        self.out.nodes.push(Node::empty());
        let mut node = Node::empty();
        for (lane, chunk) in prims.chunks(per_child).enumerate() {
            node.child[lane] =
                if chunk.len() <= LEAF_PRIMS { self.leaf(chunk) } else { self.prims_node(chunk, b) };
            set_box(&mut node, lane, b);
        }
        self.out.nodes[index] = node;
        index as u32
    }
}

/// Child `lane`'s box.
fn set_box(node: &mut Node, lane: usize, (lo, hi): (Vec3A, Vec3A)) {
    for axis in 0..3 {
        node.planes[2 * axis][lane] = lo[axis];
        node.planes[2 * axis + 1][lane] = hi[axis];
    }
}
