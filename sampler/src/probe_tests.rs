//! `doi`'s classification converges with the sample count: it changes only at nodes whose
//! back-face shares lie within sampling noise of the thresholds.

use super::*;
use crate::scene_setup::{LightOverrides, SceneSource, load};
use lightvol_scene::LoadOptions;
use lightvol_sh::sampling::fibonacci_sphere;
use rayon::prelude::*;

/// The sample counts compared, from the default to 64 times it.
const COUNTS: [u64; 4] = [256, 1024, 4096, 16_384];

/// Directions of the independent share estimate (a Fibonacci lattice, not the bake's
/// stream): its own error, `sqrt(p(1 − p)/8192)` ≤ 0.0055, is under a fifth of the
/// window below at 256 samples.
const REFERENCE_DIRECTIONS: usize = 8192;

/// How many binomial standard deviations, at the smaller of two sample counts, a share may
/// lie from its threshold for the classification to change between them. Quasi-random
/// directions err less than independent ones, so three deviations of the independent
/// estimate are a bound, not a typical error.
const NOISE_SIGMAS: f64 = 3.0;

/// The share of the back faces a point meets inside its node's trilinear support and
/// beyond it, over a Fibonacci lattice of [`REFERENCE_DIRECTIONS`].
fn shares(tracer: &Tracer, x: DVec3, spacing: [f64; 3]) -> (f64, f64) {
    let test = BackFaceTest::new(spacing, 0);
    let (mut near, mut far) = (0usize, 0usize);
    for d in fibonacci_sphere(REFERENCE_DIRECTIONS) {
        let d = DVec3::from_array(d);
        if let Some(b) = tracer.closest_hit(x, d, 0.0, f64::INFINITY).filter(|h| h.back_face) {
            if test.near(d, b.t) { near += 1 } else { far += 1 }
        }
    }
    let n = REFERENCE_DIRECTIONS as f64;
    (near as f64 / n, far as f64 / n)
}

/// `share` is within [`NOISE_SIGMAS`] binomial deviations of `threshold` at `n` directions.
fn within_noise(share: f64, threshold: f64, n: u64) -> bool {
    let sigma = (threshold * (1.0 - threshold) / n as f64).sqrt();
    (share - threshold).abs() <= NOISE_SIGMAS * sigma
}

/// The Breakfast Room (vendored) on a grid like the CLI's default (the bounds grown by 5%),
/// with 12 cells along the longest axis: 1,170 nodes, among them nodes inside the walls,
/// the floor and the ceiling, in the furniture and beside it.
fn breakfast_room() -> (lightvol_scene::Scene, GridSpec) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/breakfast_room/BreakfastRoom.gltf");
    let source = SceneSource::File { path: path.into(), options: LoadOptions::default() };
    let loaded = load(&source, u128::MAX, &LightOverrides::default()).unwrap();
    let (lo, hi) = loaded.scene.bounds();
    let pad = (hi - lo) * 0.05;
    let (lo, hi) = (lo - pad, hi + pad);
    let res = ((hi - lo) / (hi - lo).max_element() * 12.0).ceil().to_array().map(|c| c as u32 + 1);
    let grid = GridSpec::new(lo.to_array(), hi.to_array(), res).unwrap();
    (loaded.scene, grid)
}

/// A node, its captures and moved-to points at [`COUNTS`], and its near and far shares.
type Row = (usize, [ProbeCapture; 4], [Option<DVec3>; 4], (f64, f64));

/// Where a capture came from, without the relocated point.
fn kind(c: ProbeCapture) -> u8 {
    match c {
        ProbeCapture::AtNode => 0,
        ProbeCapture::Relocated(_) => 1,
        ProbeCapture::Filled => 2,
    }
}

/// From 256 to 16,384 samples a node's classification changes only where its share of near
/// back faces is within noise of [`PROBE_NEAR_BACK_SHARE`] or its share of far ones within
/// noise of [`PROBE_FAR_BACK_SHARE`] (noise at the smaller of the two counts), and a node
/// outside the domain turns from relocated to filled (or back) only where its relocated
/// point's shares are, at the directions it has left. Every node whose shares are clear of
/// the thresholds is classified as the independent shares say, at every count.
#[test]
fn doi_classification_changes_only_near_its_thresholds() {
    let (scene, grid) = breakfast_room();
    let tracer = Tracer::new(&scene);
    let sp = spacing(&grid);
    let rows: Vec<Row> = (0..grid.node_count())
        .into_par_iter()
        .map(|node| {
            let classes = COUNTS.map(|n| classify_node(&tracer, &grid, 1, n, node));
            let captures = classes.each_ref().map(|c| c.capture);
            let moved = classes.each_ref().map(|c| (c.capture != ProbeCapture::AtNode).then_some(c.from));
            let [i, j, k] = grid.node_coords(node);
            let x = DVec3::from_array(grid.node_position_world(i, j, k));
            (node, captures, moved, shares(&tracer, x, sp))
        })
        .collect();
    let (mut changed, mut outside) = (0, 0);
    for (node, captures, moved, (near, far)) in &rows {
        let clear = |n: u64| {
            !within_noise(*near, PROBE_NEAR_BACK_SHARE, n) && !within_noise(*far, PROBE_FAR_BACK_SHARE, n)
        };
        let inside = *near <= PROBE_NEAR_BACK_SHARE && *far <= PROBE_FAR_BACK_SHARE;
        outside += usize::from(!inside);
        for (c, n) in captures.iter().zip(COUNTS) {
            if clear(n) {
                assert_eq!(
                    *c == ProbeCapture::AtNode,
                    inside,
                    "node {node} at {n}: {c:?}, shares {near} {far}"
                );
            }
        }
        for w in 0..COUNTS.len() - 1 {
            let (a, b) = (captures[w], captures[w + 1]);
            if kind(a) == kind(b) {
                continue;
            }
            changed += 1;
            let n = COUNTS[w];
            eprintln!("node {node}: {a:?} at {n}, {b:?} at {}; shares {near:.4} {far:.4}", COUNTS[w + 1]);
            if (a == ProbeCapture::AtNode) != (b == ProbeCapture::AtNode) {
                assert!(
                    !clear(n),
                    "node {node}: {a:?} at {n}, {b:?} at {}; shares {near} {far}",
                    COUNTS[w + 1]
                );
            } else {
                // Relocated and filled: the relocated point's test, at the directions left
                // (at most this many).
                let left = (n as f64 * PROBE_OUTSIDE_SHARE).ceil() as u64;
                let near_noise = |y: DVec3| {
                    let (yn, yf) = shares(&tracer, y, sp);
                    within_noise(yn, PROBE_NEAR_BACK_SHARE, left)
                        || within_noise(yf, PROBE_FAR_BACK_SHARE, left)
                };
                let ys = [moved[w].unwrap(), moved[w + 1].unwrap()];
                let seen: Vec<_> = ys.iter().map(|&y| (y, shares(&tracer, y, sp))).collect();
                assert!(
                    ys.iter().any(|&y| near_noise(y)),
                    "node {node}: {a:?} at {n}, {b:?}; points and shares {seen:?}"
                );
            }
        }
    }
    for (w, n) in COUNTS.iter().enumerate() {
        let mut by_kind = [0usize; 3];
        rows.iter().for_each(|r| by_kind[usize::from(kind(r.1[w]))] += 1);
        eprintln!("{n} samples: at node, relocated, filled {by_kind:?}");
    }
    eprintln!("{outside} of {} nodes outside the domain, {changed} changes", rows.len());
    // The grid has nodes inside the walls, the floor and the furniture; the test must meet
    // them.
    assert!(outside >= 100, "{outside}");
}
