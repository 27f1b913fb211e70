//! Collapsing obvhs' binary BVH into the [`WideBvh`] layout.
//!
//! The binary tree is built with one primitive per leaf (obvhs' own leaf collapse is
//! skipped). Each wide node starts from a binary node's two children and repeatedly opens
//! the child with the largest surface area until it has [`WIDTH`] children or none can be
//! opened (the greedy collapse of \[WBB08\] §3); a child whose subtree
//! holds at most [`LEAF_PRIMS`] primitives is never opened and becomes one leaf. (The
//! binary leaves hold one primitive each; a binary leaf with more than [`LEAF_SIZE`] would
//! become a node of leaves under its box.)

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

struct Collapser<'a> {
    b2: &'a Bvh2,
    /// Primitives under each binary node.
    counts: Vec<u32>,
    out: WideBvh,
}

/// The wide tree of a binary tree (module docs).
pub(super) fn collapse(b2: &Bvh2) -> WideBvh {
    let n = b2.nodes.len();
    // Subtree primitive counts, children before parents (a pre-order, reversed).
    let mut order = Vec::with_capacity(n);
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        order.push(i);
        let node = &b2.nodes[i];
        if !node.is_leaf() {
            let l = node.first_index as usize;
            stack.extend([l, l + 1]);
        }
    }
    let mut counts = vec![0u32; n];
    for &i in order.iter().rev() {
        let node = &b2.nodes[i];
        counts[i] = if node.is_leaf() {
            node.prim_count
        } else {
            let l = node.first_index as usize;
            counts[l] + counts[l + 1]
        };
    }
    let mut c = Collapser { b2, counts, out: empty() };
    c.out.root = c.emit(0);
    c.out
}

impl Collapser<'_> {
    /// Emits binary node `i` as a wide node or a leaf; returns its child reference.
    fn emit(&mut self, i: usize) -> u32 {
        let b2 = self.b2;
        if self.counts[i] as usize <= LEAF_PRIMS {
            let prims = self.subtree_prims(i);
            return self.leaf(&prims);
        }
        if b2.nodes[i].is_leaf() {
            let prims = self.subtree_prims(i);
            let b = padded(b2, i);
            return self.prims_node(&prims, b);
        }
        let l = b2.nodes[i].first_index as usize;
        let mut kids: Vec<usize> = vec![l, l + 1];
        while kids.len() < WIDTH {
            let open = kids
                .iter()
                .enumerate()
                .filter(|&(_, &k)| !b2.nodes[k].is_leaf() && self.counts[k] as usize > LEAF_PRIMS)
                .max_by(|a, b| {
                    let area = |k: usize| b2.nodes[k].aabb().half_area();
                    area(*a.1).total_cmp(&area(*b.1)).then(b.0.cmp(&a.0))
                })
                .map(|(slot, _)| slot);
            let Some(slot) = open else { break };
            let first = b2.nodes[kids[slot]].first_index as usize;
            kids[slot] = first;
            kids.push(first + 1);
        }
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
