//! Tests of the brick volume: its probes against the octree, the fast lookup against the
//! reference, continuity across level changes (and what stitching mends), the budget, the
//! stream cells and the checks of `from_parts`.

use super::build::build;
use super::*;
use crate::adaptive::AdaptiveVolume;
use crate::adaptive::tests::step_volume;
use lightvol_sh::lowdisc::SplitMix64;

/// Half-float rounding of a probe: relative 2^-11 (f16 has an 11-bit significand).
const HALF_REL: f64 = 1.0 / 2048.0;

fn largest_value(v: &AdaptiveVolume) -> f64 {
    // The field is bounded by the base level plus every surplus.
    let mut m = v.base().data().iter().fold(0.0f64, |m, x| m.max(f64::from(x.abs())));
    for l in 1..=v.params().max_level {
        m += v.level_nodes(l).flat_map(|(_, d)| d.iter()).fold(0.0f64, |m, x| m.max(f64::from(x.abs())));
    }
    m
}

fn random_points(v: &BrickVolume, n: usize, seed: u64) -> Vec<[f64; 3]> {
    let (lo, hi) = v.spec().bounds();
    let mut rng = SplitMix64::new(seed);
    (0..n).map(|_| std::array::from_fn(|a| lo[a] + rng.next_f64() * (hi[a] - lo[a]))).collect()
}

#[test]
fn refines_where_the_octree_stores_finer_nodes() {
    let oct = step_volume();
    let (b, report) =
        bricks_from_octree(&oct, &BrickParams { cells: 2, max_probe_bytes: None, merge_tolerance: 0.0 })
            .unwrap();
    assert_eq!(b.finest_level(), oct.max_level());
    let per = b.bricks_per_level();
    assert!(
        per[per.len() - 1] > 0 && per.iter().filter(|&&n| n > 0).count() >= 2,
        "bricks per level {per:?}"
    );
    assert_eq!(report.bricks(), b.bricks().len());
    // Every stored node of a level above a brick's lies outside that brick's closed box.
    for br in b.bricks() {
        for m in br.level + 1..=b.finest_level() {
            let size = 2u32 << (m - br.level);
            for (c, _) in oct.level_nodes(m) {
                let inside = (0..3).all(|a| c[a] >= br.coords[a] * size && c[a] <= (br.coords[a] + 1) * size);
                assert!(!inside, "brick {br:?} holds a level-{m} node {c:?}");
            }
        }
    }
}

#[test]
fn interior_probes_are_the_octree_prefiltered_at_their_level() {
    let oct = step_volume();
    let (b, _) = bricks_from_octree(&oct, &BrickParams::default()).unwrap();
    let k = b.coeffs() * 3;
    let p = b.brick_probes();
    let res0 = oct.base().spec().res();
    let mut checked = 0;
    for (i, br) in b.bricks().iter().enumerate() {
        let d = b.brick_data(i);
        for z in 1..p - 1 {
            for y in 1..p - 1 {
                for x in 1..p - 1 {
                    let q = [x, y, z];
                    let u0: [f64; 3] = std::array::from_fn(|a| {
                        (f64::from(br.coords[a] * b.brick_cells() + q[a]) / f64::from(1u32 << br.level))
                            .min(f64::from(res0[a] - 1))
                    });
                    let mut want = vec![0.0; k];
                    oct.sum_levels_f64(u0, br.level + 1, &mut want);
                    let at = (x + p * (y + p * z)) as usize * k;
                    for (got, w) in d[at..at + k].iter().zip(&want) {
                        assert_eq!(got.to_bits(), half::f16::from_f64(*w).to_f32().to_bits());
                    }
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 100);
}

#[test]
fn fast_lookup_matches_the_reference() {
    let oct = step_volume();
    let (b, _) = bricks_from_octree(&oct, &BrickParams::default()).unwrap();
    // f32 rounding of the cell coordinate (a few ε₃₂ of the largest coordinate, moving a
    // weight by as much) times the Lipschitz constant, plus the eight products' rounding.
    let m = largest_value(&oct);
    let tol = 64.0 * f64::from(f32::EPSILON) * m * 64.0;
    let mut out = vec![0.0f32; b.coeffs() * 3];
    for p in random_points(&b, 4000, 7) {
        b.coeffs_at(p.map(|x| x as f32), &mut out);
        let r = b.coeffs_at_reference(p);
        for (a, e) in out.iter().zip(&r) {
            assert!((f64::from(*a) - e).abs() <= tol, "at {p:?}: {a} vs {e} (tolerance {tol})");
        }
    }
}

/// Pairs of points at ±eps across every brick face, on a lattice of each face.
fn face_pairs(b: &BrickVolume, eps: f64) -> Vec<([f64; 3], [f64; 3])> {
    let g = b.spec();
    let (lo, hi) = g.bounds();
    let res0 = g.res();
    let unit: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]) / f64::from(res0[a] - 1));
    let mut out = Vec::new();
    for br in b.bricks() {
        let size = f64::from(b.brick_cells()) / f64::from(1u32 << br.level);
        let o: [f64; 3] = std::array::from_fn(|a| f64::from(br.coords[a]) * size);
        for axis in 0..3 {
            let side = o[axis] + size;
            if side >= f64::from(res0[axis] - 1) {
                continue;
            }
            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
            for s in 0..7 {
                for t in 0..7 {
                    let mut u = [0.0; 3];
                    u[axis] = side;
                    u[a1] = (o[a1] + (0.05 + 0.15 * f64::from(s)) * size).min(f64::from(res0[a1] - 1));
                    u[a2] = (o[a2] + (0.05 + 0.15 * f64::from(t)) * size).min(f64::from(res0[a2] - 1));
                    let w = |d: f64| -> [f64; 3] {
                        std::array::from_fn(|a| lo[a] + (u[a] + if a == axis { d } else { 0.0 }) * unit[a])
                    };
                    out.push((w(-eps), w(eps)));
                }
            }
        }
    }
    out
}

fn largest_jump(b: &BrickVolume, pairs: &[([f64; 3], [f64; 3])]) -> f64 {
    pairs
        .iter()
        .map(|(p, q)| {
            let (a, c) = (b.coeffs_at_reference(*p), b.coeffs_at_reference(*q));
            a.iter().zip(&c).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
        })
        .fold(0.0, f64::max)
}

#[test]
fn stitching_keeps_the_field_continuous_across_level_changes() {
    // Refinement alone keeps level changes where the octree has no finer node on the
    // shared face; the budget's merges put coarse bricks beside fine ones that have.
    let oct = step_volume();
    let free = BrickParams { cells: 2, max_probe_bytes: None, merge_tolerance: 0.0 };
    let full = bricks_from_octree(&oct, &free).unwrap().0.probe_bytes();
    let params = BrickParams { max_probe_bytes: Some(full * 2 / 3), ..free };
    let (b, report) = bricks_from_octree(&oct, &params).unwrap();
    assert!(report.merges > 0);
    let (raw, _) = build(&oct, &params, false).unwrap();
    assert!(report.stitched_probes > 0);
    let eps = 1e-7;
    let pairs = face_pairs(&b, eps);
    assert!(pairs.len() > 100);
    // Continuous: a jump no larger than the slope over 2·eps (the steepest brick slope is
    // below 2·max|v| per finest cell) plus the half-float rounding of a stitched probe.
    let m = largest_value(&oct);
    let bound = 2.0 * m * f64::from(1u32 << b.finest_level()) * 2.0 * eps + HALF_REL * m;
    let jump = largest_jump(&b, &pairs);
    assert!(jump <= bound, "largest jump {jump} > {bound}");
    // Without stitching the same faces jump (the T-junctions of the octree).
    let raw_jump = largest_jump(&raw, &face_pairs(&raw, eps));
    assert!(raw_jump > 10.0 * bound, "unstitched jump {raw_jump}");
}

#[test]
fn a_budget_merges_the_least_useful_bricks_and_says_so() {
    let oct = step_volume();
    let free = BrickParams { cells: 2, max_probe_bytes: None, merge_tolerance: 0.0 };
    let (full, r0) = bricks_from_octree(&oct, &free).unwrap();
    assert_eq!(r0.dropped_bricks, 0);
    let half = full.probe_bytes() / 2;
    let (b, r) = bricks_from_octree(&oct, &BrickParams { max_probe_bytes: Some(half), ..free }).unwrap();
    assert!(b.probe_bytes() <= half);
    assert!(r.merges > 0 && r.dropped_bricks == r0.bricks() - b.bricks().len());
    assert!(r.largest_dropped_error > 0.0);
    let line = r.summary();
    assert!(!line.contains('\n') && line.contains("the budget dropped"), "{line}");
    // The fewer bricks, the further from the octree (measured on random points).
    let pts = random_points(&full, 3000, 11);
    let err = |v: &BrickVolume| -> f64 {
        pts.iter()
            .map(|p| {
                let (a, c) = (v.coeffs_at_reference(*p), oct.coeffs_at_reference(*p));
                a.iter().zip(&c).map(|(x, y)| (x - y).powi(2)).sum::<f64>()
            })
            .sum::<f64>()
    };
    let quarter = full.probe_bytes() / 4;
    let (q, _) = bricks_from_octree(&oct, &BrickParams { max_probe_bytes: Some(quarter), ..free }).unwrap();
    assert!(err(&full) < err(&b) && err(&b) < err(&q), "{} {} {}", err(&full), err(&b), err(&q));
    // A budget below the coarsest bricks is refused in one line.
    let e =
        bricks_from_octree(&oct, &BrickParams { max_probe_bytes: Some(10), ..free }).unwrap_err().to_string();
    assert!(e.contains("below") && e.contains("MiB") && !e.contains('\n'), "{e}");
}

#[test]
fn stream_cells_hold_each_brick_once_under_its_level_zero_brick() {
    let oct = step_volume();
    let (b, _) =
        bricks_from_octree(&oct, &BrickParams { cells: 2, max_probe_bytes: None, merge_tolerance: 0.0 })
            .unwrap();
    let cells = b.stream_cells();
    let n0 = bricks_per_axis(b.spec(), 2, b.finest_level(), 0);
    assert_eq!(cells.len(), n0.iter().map(|&n| n as usize).product::<usize>());
    let mut next = 0;
    for c in &cells {
        assert_eq!(c.first, next);
        next += c.count;
        for br in &b.bricks()[c.first as usize..(c.first + c.count) as usize] {
            assert_eq!(br.coords.map(|x| x >> br.level), c.coords);
        }
    }
    assert_eq!(next as usize, b.bricks().len());
}

#[test]
fn from_parts_rejects_gaps_overlaps_and_bad_sizes() {
    let oct = step_volume();
    let (b, _) = bricks_from_octree(&oct, &BrickParams::default()).unwrap();
    let parts = |bricks: Vec<Brick>, data: Vec<f32>, cells: u32| {
        BrickVolume::from_parts(
            b.spec().clone(),
            b.coeffs(),
            cells,
            b.finest_level(),
            bricks,
            data,
            b.metadata().clone(),
        )
    };
    assert_eq!(parts(b.bricks().to_vec(), b.data.clone(), 4).unwrap(), b);
    let per = b.brick_values();
    // A missing brick leaves texels uncovered.
    let e = parts(b.bricks()[1..].to_vec(), b.data[per..].to_vec(), 4).unwrap_err().to_string();
    assert!(e.contains("covered by no brick"), "{e}");
    // A repeated brick overlaps.
    let mut twice = b.bricks().to_vec();
    twice.push(b.bricks()[0]);
    let mut data = b.data.clone();
    data.extend_from_slice(&b.data[..per]);
    assert!(parts(twice, data, 4).unwrap_err().to_string().contains("overlap"));
    assert!(parts(b.bricks().to_vec(), b.data.clone(), 9).is_err());
    assert!(parts(b.bricks().to_vec(), b.data[1..].to_vec(), 4).is_err());
    let mut nan = b.data.clone();
    nan[3] = f32::NAN;
    assert!(parts(b.bricks().to_vec(), nan, 4).is_err());
}

#[test]
fn the_merge_tolerance_merges_only_smooth_bricks() {
    let oct = step_volume();
    let exact = BrickParams { cells: 2, max_probe_bytes: None, merge_tolerance: 0.0 };
    let (all, r0) = bricks_from_octree(&oct, &exact).unwrap();
    assert_eq!(r0.smooth_merges, 0);
    let (some, r) = bricks_from_octree(&oct, &BrickParams { merge_tolerance: 0.05, ..exact }).unwrap();
    assert!(r.smooth_merges > 0 && some.bricks().len() < all.bricks().len());
    assert_eq!(r.bricks_wanted, some.bricks().len());
    assert_eq!((r.dropped_bricks, r.merges), (0, 0));
    // Each merged group lost at most the tolerance (its largest surplus measure over the
    // children's probes, relative to the value scale): away from the step, the irradiance
    // along +z moves by less than that times the value scale times the largest
    // |Y_j(n)|-weighted sum, √(coeffs/4π) · √coeffs.
    let limit = 0.05 * oct.value_scale() * (4.0 / (4.0 * std::f64::consts::PI)).sqrt() * 2.0 + 1e-2;
    let mut worst = 0.0f64;
    for p in random_points(&all, 2000, 5) {
        let (a, b) =
            (all.irradiance_reference(p, [0.0, 0.0, 1.0]), some.irradiance_reference(p, [0.0, 0.0, 1.0]));
        worst = worst.max((0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f64::max) / std::f64::consts::PI);
    }
    assert!(worst <= limit, "{worst} > {limit}");
}
