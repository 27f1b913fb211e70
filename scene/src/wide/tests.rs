use glam::DVec3;
use lightvol_sh::lowdisc::SplitMix64;

use obvhs::triangle::Triangle as ObTriangle;

use super::build::BOX_PAD_REL;
use super::kernel::{FAR_SCALE, Kernel, RayK, Scalar, TINY_DIR};
use super::{Isa, LEAF_SIZE, Node, WIDTH};
use crate::builder::SceneBuilder;
use crate::material::Material;
use crate::{DVec2, Tracer};

/// `count` random triangles: each a centre uniform in the box `±half`, and three vertices
/// at that centre plus offsets uniform in `[lo, hi)³` (each coordinate drawn in f64, then
/// rounded to f32).
fn triangle_soup(
    rng: &mut SplitMix64,
    count: usize,
    half: [f64; 3],
    (lo, hi): (f64, f64),
) -> Vec<ObTriangle> {
    (0..count)
        .map(|_| {
            let c = glam::Vec3A::from_array(half.map(|h| rng.range(-h, h) as f32));
            let mut p = || c + glam::Vec3A::from_array([(); 3].map(|()| rng.range(lo, hi) as f32));
            ObTriangle { v0: p(), v1: p(), v2: p() }
        })
        .collect()
}

/// `FAR_SCALE` is at least `1 + 2γ₃` (Ize 2013), `γₙ = nu/(1 − nu)` with `u = 2⁻²⁴`
/// computed here in f64, and not more than twice that margin.
#[test]
fn far_scale_covers_the_slab_rounding() {
    let u = 2f64.powi(-24);
    let gamma3 = 3.0 * u / (1.0 - 3.0 * u);
    let margin = f64::from(FAR_SCALE) - 1.0;
    assert!(margin >= 2.0 * gamma3, "{margin} < {}", 2.0 * gamma3);
    assert!(margin <= 4.0 * gamma3, "{margin}");
    // The box margin is a few tens of ulps: 2^-20 = 16 · 2^-24.
    assert_eq!(f64::from(BOX_PAD_REL) / u, 16.0);
    // The clamp keeps 1/d finite with room to spare: (1e20)·(3e18) stays below f32::MAX.
    assert!((1.0 / TINY_DIR).is_finite() && (1.0 / TINY_DIR) * 3e18 < f32::MAX);
}

/// Every kernel's box test gives the scalar kernel's mask and entry distances on random
/// boxes and rays, including empty child slots and rays parallel to a slab.
#[test]
fn box_tests_agree_across_kernels() {
    let mut rng = SplitMix64::new(3);
    let mut r = |a: f64, b: f64| rng.range(a, b) as f32;
    let mut hits = 0;
    for case in 0..20_000 {
        let mut node = Node::empty();
        for lane in 0..WIDTH - (case % 3) {
            for axis in 0..3 {
                let (a, b) = (r(-5.0, 5.0), r(-5.0, 5.0));
                node.planes[2 * axis][lane] = a.min(b);
                node.planes[2 * axis + 1][lane] = a.max(b);
            }
            node.child[lane] = lane as u32;
        }
        let o = [r(-8.0, 8.0), r(-8.0, 8.0), r(-8.0, 8.0)];
        let mut d = [r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0)];
        if case % 5 == 0 {
            d[case % 3] = 0.0;
        }
        if d == [0.0; 3] {
            continue;
        }
        let ray = RayK::new(o, d, 0.0, f32::INFINITY);
        let tmax = r(0.0, 20.0);
        let mut want_t = [0f32; WIDTH];
        let want = Scalar::boxes(&node, &ray, tmax, &mut want_t);
        hits += want.count_ones();
        assert_eq!(want & !0xff, 0);
        check_kernels(&node, &ray, tmax, want, &want_t);
    }
    assert!(hits > 3_000, "{hits}");
}

#[cfg(target_arch = "x86_64")]
fn check_kernels(node: &Node, ray: &RayK, tmax: f32, want: u32, want_t: &[f32; WIDTH]) {
    use super::dispatch::run;
    use super::kernel::Query;
    struct BoxQuery<'a>(&'a Node, &'a RayK, f32);
    impl Query for BoxQuery<'_> {
        type Out = (u32, [f32; WIDTH]);
        #[inline(always)]
        fn run<K: Kernel>(&self) -> Self::Out {
            let mut t = [0f32; WIDTH];
            (K::boxes(self.0, self.1, self.2, &mut t), t)
        }
    }
    for isa in Isa::available() {
        let (mask, t) = run(isa, &BoxQuery(node, ray, tmax));
        assert_eq!(mask, want, "{isa}");
        for lane in 0..WIDTH {
            if want & (1 << lane) != 0 {
                assert_eq!(t[lane].to_bits(), want_t[lane].to_bits(), "{isa} lane {lane}");
            }
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn check_kernels(_: &Node, _: &RayK, _: f32, _: u32, _: &[f32; WIDTH]) {}

/// A closed mesh (a subdivided icosahedron, 80 faces) traced through the whole tracer with
/// every kernel: rays from inside aimed at every vertex and at points on every shared edge
/// all hit it (none slips through an edge, and no box test culls the hit).
#[test]
fn no_ray_escapes_a_closed_mesh_through_the_tracer() {
    let (verts, faces) = crate::watertight::tests::closed_mesh();
    let mut b = SceneBuilder::new("ball");
    let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
    let v = |i: usize| DVec3::from(verts[i].map(f64::from));
    for f in &faces {
        b.add_triangle([v(f[0]), v(f[1]), v(f[2])], [DVec2::ZERO; 3], m).unwrap();
    }
    let scene = b.build().unwrap();
    assert_eq!(scene.triangles.len(), 80);
    let mut tr = Tracer::new(&scene);
    let mut targets: Vec<DVec3> = (0..verts.len()).map(v).collect();
    for f in &faces {
        for e in 0..3 {
            let (a, c) = (v(f[e]), v(f[(e + 1) % 3]));
            for s in [0.5, 1e-7, 1.0 - 1e-7, 0.25, 0.75] {
                targets.push(a + (c - a) * s);
            }
        }
    }
    let mut rng = SplitMix64::new(9);
    let origins: Vec<DVec3> = (0..8)
        .map(|_| DVec3::new(rng.range(-0.2, 0.2), rng.range(-0.2, 0.2), rng.range(-0.2, 0.2)))
        .collect();
    let mut rays = 0;
    for isa in Isa::available() {
        tr.set_isa(isa).unwrap();
        for &o in &origins {
            for &t in &targets {
                let d = (t - o).normalize();
                rays += 1;
                assert!(
                    tr.closest_hit(o, d, 0.0, f64::INFINITY).is_some(),
                    "{isa}: escaped at {o} toward {t}"
                );
                assert!(tr.occluded(o, d, 0.0, f64::INFINITY), "{isa}: unoccluded at {o} toward {t}");
            }
        }
    }
    assert!(rays >= 8 * 600, "{rays}");
}

/// Leaves hold at most `MAX_LEAF_PACKS` packs of `LEAF_SIZE` triangles, every triangle sits in one leaf, and the
/// tree is smaller than the binary one it came from.
#[test]
fn collapse_keeps_every_triangle_once() {
    let tris = triangle_soup(&mut SplitMix64::new(4), 5000, [9.0; 3], (0.0, 1.0));
    let bvh = super::build::from_triangles(&tris, obvhs::BvhBuildParams::medium_build());
    let mut seen = vec![0u32; tris.len()];
    for leaf in bvh.leaves() {
        let prims: Vec<u32> = bvh.leaf_prims(leaf).iter().copied().filter(|&p| p != super::EMPTY).collect();
        assert!((1..=LEAF_SIZE * super::MAX_LEAF_PACKS).contains(&prims.len()), "{prims:?}");
        let valid: u32 = bvh.leaf_packs(leaf).iter().map(|p| p.valid().count_ones()).sum();
        assert_eq!(valid as usize, prims.len());
        for p in prims {
            seen[p as usize] += 1;
        }
    }
    assert!(seen.iter().all(|&n| n == 1));
    // At most one node per 8-way split: far fewer nodes than the 2n − 1 of a binary tree.
    assert!(bvh.nodes.len() < tris.len() / 4, "{}", bvh.nodes.len());
}

/// A binary tree whose leaves hold many triangles (obvhs' own SAH leaf collapse, pushed to
/// large leaves) collapses into nodes of four-triangle leaves under each big leaf's box:
/// every triangle sits in exactly one leaf, and the closest hits equal a loop over all
/// triangles on 3,000 rays.
#[test]
fn big_binary_leaves_become_nodes_of_leaves() {
    use super::traverse::{Best, Closest, Filter, walk};
    use crate::watertight::{RawHit, intersect_raw};
    struct All;
    impl Filter for All {
        fn id(&self, prim: u32) -> u32 {
            prim
        }
        fn accept(&self, _: u32, _: &RawHit) -> bool {
            true
        }
    }
    let mut rng = SplitMix64::new(8);
    let tris = triangle_soup(&mut rng, 3000, [9.0; 3], (-1.0, 1.0));
    let mut r = |a: f64, b: f64| rng.range(a, b) as f32;
    let mut params = obvhs::BvhBuildParams::medium_build();
    params.max_prims_per_leaf = 40;
    params.collapse_traversal_cost = 1000.0;
    let b2 = obvhs::bvh2::builder::build_bvh2_from_tris(&tris, params, &mut std::time::Duration::default());
    let biggest = b2.nodes.iter().filter(|n| n.is_leaf()).map(|n| n.prim_count).max().unwrap();
    assert!(biggest as usize > 4 * WIDTH, "the binary leaves must be big for this test: {biggest}");
    let bvh = super::build::with_packs(super::build::collapse(&b2), &tris);
    let mut seen = vec![0u32; tris.len()];
    for leaf in bvh.leaves() {
        for &p in bvh.leaf_prims(leaf).iter().filter(|&&p| p != super::EMPTY) {
            seen[p as usize] += 1;
        }
    }
    assert!(seen.iter().all(|&n| n == 1));
    let verts = |t: &ObTriangle| [t.v0, t.v1, t.v2].map(|v| v.to_array());
    let mut hits = 0;
    for _ in 0..3000 {
        let o = [r(-12.0, 12.0), r(-12.0, 12.0), r(-12.0, 12.0)];
        let d = DVec3::from_array(lightvol_sh::sampling::sample_uniform_sphere([
            f64::from(r(0.0, 1.0)),
            f64::from(r(0.0, 1.0)),
        ]))
        .as_vec3()
        .to_array();
        let ray = RayK::new(o, d, 0.0, f32::MAX);
        let mut got = Best::new(f32::MAX);
        walk::<Scalar, _>(&bvh, &ray, &mut Closest { ray: &ray, best: &mut got, filter: &All });
        let mut want = Best::new(f32::MAX);
        for (i, t) in tris.iter().enumerate() {
            if let Some(h) = intersect_raw(&ray.shear, &verts(t), 0.0, f32::MAX) {
                want.offer(i as u32, h, || true);
            }
        }
        assert_eq!((got.id, got.hit), (want.id, want.hit));
        hits += usize::from(want.hit.is_some());
    }
    assert!(hits > 500, "{hits}");
}

/// The collapse's dynamic programme finds the cheapest cut (module docs of `build`), checked
/// against an exhaustive search that lists every cut of each subtree into at most eight
/// slots explicitly, on small random binary trees; and the tree it emits costs what the
/// programme says, recomputed from the emitted nodes' own boxes.
#[test]
fn collapse_is_the_cheapest_cut() {
    use super::build::{NODE_COST, PACK_COST, collapse, collapse_cost};
    use obvhs::bvh2::Bvh2;
    /// Both sides add the same f32 products in different orders: a few ulps per term.
    const SUM_ORDER_TOLERANCE: f32 = 1e-5;
    /// The emitted boxes are widened by `BOX_PAD_REL` of their largest coordinate (up to
    /// 2⁻²⁰ · 9 on a box 0.2 wide here: 4·10⁻⁵ of its extent per side).
    const PADDING_TOLERANCE: f32 = 1e-3;
    fn area(b2: &Bvh2, i: usize) -> f32 {
        b2.nodes[i].aabb().half_area()
    }
    fn count(b2: &Bvh2, i: usize) -> usize {
        let n = &b2.nodes[i];
        if n.is_leaf() {
            n.prim_count as usize
        } else {
            count(b2, n.first_index as usize) + count(b2, n.first_index as usize + 1)
        }
    }
    /// Every cut of subtree `i` into at most `WIDTH` slots, as lists of binary nodes.
    fn cuts(b2: &Bvh2, i: usize) -> Vec<Vec<usize>> {
        let mut out = vec![vec![i]];
        let n = &b2.nodes[i];
        if !n.is_leaf() {
            let l = n.first_index as usize;
            for a in cuts(b2, l) {
                for b in cuts(b2, l + 1) {
                    if a.len() + b.len() <= WIDTH {
                        out.push([a.clone(), b].concat());
                    }
                }
            }
        }
        out
    }
    /// The least cost of subtree `i` in one slot, by exhaustive search.
    fn one(b2: &Bvh2, i: usize) -> f32 {
        let n = &b2.nodes[i];
        let leaf = if count(b2, i) <= LEAF_SIZE { area(b2, i) * PACK_COST } else { f32::INFINITY };
        if n.is_leaf() {
            return leaf;
        }
        let l = n.first_index as usize;
        let mut node = f32::INFINITY;
        for a in cuts(b2, l) {
            for b in cuts(b2, l + 1) {
                if a.len() + b.len() <= WIDTH {
                    let c: f32 = a.iter().chain(&b).map(|&k| one(b2, k)).sum();
                    node = node.min(area(b2, i) * NODE_COST + c);
                }
            }
        }
        leaf.min(node)
    }
    /// The cost of an emitted (sub)tree from its own boxes.
    fn emitted(bvh: &super::WideBvh, r: u32, box_area: f32) -> f32 {
        if r & super::LEAF_BIT != 0 {
            return box_area * PACK_COST;
        }
        let node = &bvh.nodes[r as usize];
        let mut c = box_area * NODE_COST;
        for lane in 0..WIDTH {
            if node.child[lane] == super::EMPTY {
                continue;
            }
            let e: [f32; 3] =
                std::array::from_fn(|a| node.planes[2 * a + 1][lane] - node.planes[2 * a][lane]);
            c += emitted(bvh, node.child[lane], e[0] * e[1] + e[1] * e[2] + e[2] * e[0]);
        }
        c
    }
    let mut rng = SplitMix64::new(17);
    let mut checked_nodes = 0;
    for trial in 0..40 {
        let n = 5 + trial % 10;
        let spread = if trial % 2 == 0 { 9.0 } else { 2.0 };
        let tris = triangle_soup(&mut rng, n, [spread; 3], (0.0, 0.2));
        let mut params = obvhs::BvhBuildParams::medium_build();
        params.max_prims_per_leaf = 1;
        let b2 =
            obvhs::bvh2::builder::build_bvh2_from_tris(&tris, params, &mut std::time::Duration::default());
        let dp = collapse_cost(&b2);
        let brute = one(&b2, 0);
        assert!((dp - brute).abs() <= SUM_ORDER_TOLERANCE * brute, "{n} triangles: {dp} against {brute}");
        let bvh = collapse(&b2);
        let got = if bvh.root & super::LEAF_BIT != 0 {
            area(&b2, 0) * PACK_COST
        } else {
            emitted(&bvh, bvh.root, area(&b2, 0))
        };
        assert!((got - dp).abs() <= PADDING_TOLERANCE * dp, "{n} triangles: emitted {got}, table {dp}");
        checked_nodes += bvh.nodes.len();
    }
    // Some trees needed more than one wide node (the search covered nested cuts).
    assert!(checked_nodes > 40, "{checked_nodes}");
}

/// A ray that meets the box of every node but no triangle until the last: 40,000 slanted
/// triangles along the x axis whose boxes hold the ray and whose faces pass beside it,
/// then a wall across it. Nearest-first traversal must open every node, so the stack
/// outgrows its inline part and spills to the heap; every kernel still returns the
/// brute-force hit, and occlusion agrees.
#[test]
fn a_traversal_that_spills_its_stack_finds_the_hit() {
    let mut b = SceneBuilder::new("coplanar fan");
    let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
    let n = 40_000;
    let step = 0.001;
    for k in 0..n {
        let x0 = f64::from(k) * step;
        // Seen along x, the triangle (1, 0), (0, 1), (1, 1) in (y, z): above y + z = 1,
        // while the ray passes at (0.1, 0.1), inside the box [0, 1]².
        let tri = [DVec3::new(x0, 1.0, 0.0), DVec3::new(x0, 0.0, 1.0), DVec3::new(x0 + step, 1.0, 1.0)];
        b.add_triangle(tri, [DVec2::ZERO; 3], m).unwrap();
    }
    let wall = f64::from(n) * step + 1.0;
    b.add_triangle(
        [DVec3::new(wall, -1.0, -1.0), DVec3::new(wall, 1.0, -1.0), DVec3::new(wall, 0.0, 2.0)],
        [DVec2::ZERO; 3],
        m,
    )
    .unwrap();
    let scene = b.build().unwrap();
    let (o, d) = (DVec3::new(-1.0, 0.1, 0.1), DVec3::X);
    let mut tracer = Tracer::new(&scene);
    let want = tracer.closest_hit_brute_force(o, d, 0.0, f64::INFINITY).expect("the wall");
    assert_eq!(want.triangle, n);
    for isa in Isa::available() {
        tracer.set_isa(isa).unwrap();
        super::traverse::SPILLED.set(0);
        let got = tracer.closest_hit(o, d, 0.0, f64::INFINITY).expect("the wall");
        assert!(super::traverse::SPILLED.get() > 0, "{isa}: the stack never spilled");
        assert_eq!(
            (got.triangle, got.t.to_bits(), got.bary),
            (want.triangle, want.t.to_bits(), want.bary),
            "{isa}"
        );
        assert!(tracer.occluded(o, d, 0.0, f64::INFINITY), "{isa}");
        assert!(!tracer.occluded(o, d, 0.0, wall - 1.5), "{isa}: only the wall blocks");
    }
}

/// The build runs on rayon's threads (obvhs' `parallel` feature) and gives the same tree,
/// bit for bit, on 1, 2 and 5 threads: 20,000 random triangles, every node's planes and
/// children and every leaf's primitives compared.
#[test]
fn the_tree_is_the_same_on_any_thread_count() {
    let tris = triangle_soup(&mut SplitMix64::new(12), 20_000, [20.0, 5.0, 20.0], (0.0, 1.0));
    let build = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let bvh = pool.install(|| super::build::from_triangles(&tris, obvhs::BvhBuildParams::medium_build()));
        let nodes: Vec<(Vec<u32>, [u32; WIDTH])> = bvh
            .nodes
            .iter()
            .map(|n| (n.planes.iter().flatten().map(|x| x.to_bits()).collect(), n.child))
            .collect();
        (bvh.root, nodes, bvh.prims)
    };
    let one = build(1);
    assert!(one.1.len() > 1_000, "{}", one.1.len());
    for threads in [2, 5] {
        assert!(build(threads) == one, "{threads} threads built another tree");
    }
}
