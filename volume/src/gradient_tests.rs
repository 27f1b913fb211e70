use super::*;
use crate::grid::Placement;
use lightvol_sh::lowdisc::SplitMix64;

/// Exactness tolerance (absolute) for fields of magnitude up to ~20: node values and
/// gradients are stored as f32 (relative rounding 6e-8, so ~1.2e-6 on a value of 20), and a
/// lookup sums at most 8 corners with weights whose absolute values sum to < 1.5 (Hermite's
/// tangent weights are at most 4/27 each); 4e-6 leaves a factor ~2 of headroom.
const EXACT_TOL: f64 = 4e-6;

/// Half-width (grid units) of the step across a face in the continuity walks: small enough
/// that a smooth interpolant moves by < 1e-9 across it.
const FACE_STEP: f64 = 1e-10;

/// Largest allowed jump across a face: f32 data summed in f64 (the two sides use different
/// corner sets whose off-face weights are ~FACE_STEP, times values of magnitude ≤ 10).
const FACE_JUMP_TOL: f64 = 1e-7;

const METHODS: [GradientLookup; 3] =
    [GradientLookup::Taylor, GradientLookup::GradientTrilinear, GradientLookup::Hermite];

/// A rotated (30° about z, 20° about x), anisotropically scaled, translated placement.
fn placement() -> Placement {
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let (c2, s2) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
    // R = Rz · Rx, then scale columns by (1.5, 0.8, 1.2).
    let r = [[c, -s * c2, s * s2], [s, c * c2, -c * s2], [0.0, s2, c2]];
    let sc = [1.5, 0.8, 1.2];
    let t = [0.3, -1.0, 2.0];
    Placement::new(std::array::from_fn(|i| [r[i][0] * sc[0], r[i][1] * sc[1], r[i][2] * sc[2], t[i]]))
        .unwrap()
}

fn spec() -> GridSpec {
    GridSpec::new([-1.0, 0.0, 0.5], [2.0, 2.0, 2.5], [4, 5, 3]).unwrap()
}

/// A linear coefficient field: coefficient m is `a_m + g_m · x` (world x).
struct Linear {
    a: Vec<f64>,
    g: Vec<[f64; 3]>,
}

impl Linear {
    fn new(k: usize, seed: u64) -> Self {
        let mut r = SplitMix64::new(seed);
        let a = (0..k).map(|_| r.range(-1.0, 1.0)).collect();
        let g = (0..k).map(|_| [r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0)]).collect();
        Self { a, g }
    }
    fn value(&self, x: [f64; 3]) -> Vec<f64> {
        self.a.iter().zip(&self.g).map(|(a, g)| a + dot3(*g, x)).collect()
    }
}

fn volume_of(
    spec: GridSpec,
    coeffs: usize,
    f: impl Fn([f64; 3]) -> Vec<f64>,
    g: impl Fn([f64; 3]) -> Vec<[f64; 3]>,
) -> (IrradianceVolume, VolumeGradients) {
    let vol =
        IrradianceVolume::from_fn(spec, coeffs, |x| f(x).chunks(3).map(|c| [c[0], c[1], c[2]]).collect())
            .unwrap();
    let grad = VolumeGradients::from_fn(&vol, g).unwrap();
    (vol, grad)
}

/// Random world points inside the (placed) box.
fn points(spec: &GridSpec, n: usize, seed: u64) -> Vec<[f64; 3]> {
    let (lo, hi) = spec.bounds();
    let mut r = SplitMix64::new(seed);
    (0..n).map(|_| spec.to_world(std::array::from_fn(|a| r.range(lo[a], hi[a])))).collect()
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// Linear fields: all three lookups reproduce fields linear in x, y, z, under
/// a rotated, anisotropically scaled placement (which exercises Hermite's chain rule).
#[test]
fn linear_fields_are_exact() {
    for coeffs in [4, 9] {
        let spec = spec().with_placement(placement());
        let lin = Linear::new(coeffs * 3, 11 + coeffs as u64);
        let (vol, grad) = volume_of(spec.clone(), coeffs, |x| lin.value(x), |_| lin.g.clone());
        for p in points(&spec, 300, 5) {
            let exact = lin.value(p);
            for m in METHODS {
                let got = coeffs_at(&vol, &grad, m, p).unwrap();
                let d = max_diff(&got, &exact);
                assert!(d < EXACT_TOL, "{m:?} coeffs {coeffs} at {p:?}: error {d}");
            }
        }
    }
}

/// An additively separable cubic `p(x) + q(y) + r(z)` per coefficient (grid = world here).
fn separable_cubic(x: [f64; 3], m: usize) -> (f64, [f64; 3]) {
    let c = |a: usize| 0.1 * (1 + ((m * 7 + a * 3) % 5)) as f64;
    let p = |t: f64, a: usize| c(a) * t * t * t - 0.5 * t * t + 0.3 * (m as f64) * t + 1.0;
    let dp = |t: f64, a: usize| 3.0 * c(a) * t * t - t + 0.3 * (m as f64);
    (p(x[0], 0) + p(x[1], 1) + p(x[2], 2), [dp(x[0], 0), dp(x[1], 1), dp(x[2], 2)])
}

/// Separable cubics: Hermite reproduces every additively separable cubic
/// `p(x) + q(y) + r(z)` (hence every cubic in x alone); the first-order lookups do not.
#[test]
fn hermite_is_exact_for_separable_cubics() {
    let spec = spec();
    let k = 9 * 3;
    let f = |x: [f64; 3]| (0..k).map(|m| separable_cubic(x, m).0).collect::<Vec<_>>();
    let g = |x: [f64; 3]| (0..k).map(|m| separable_cubic(x, m).1).collect::<Vec<_>>();
    let (vol, grad) = volume_of(spec.clone(), 9, f, g);
    let mut taylor_err = 0.0f64;
    for p in points(&spec, 300, 9) {
        let got = coeffs_at(&vol, &grad, GradientLookup::Hermite, p).unwrap();
        let d = max_diff(&got, &f(p));
        assert!(d < EXACT_TOL, "Hermite at {p:?}: error {d}");
        taylor_err =
            taylor_err.max(max_diff(&coeffs_at(&vol, &grad, GradientLookup::Taylor, p).unwrap(), &f(p)));
    }
    // The test field is genuinely non-linear: Taylor misses it by far more than rounding.
    assert!(taylor_err > 1e3 * EXACT_TOL, "{taylor_err}");
}

/// The dropped cross term, shown: for `f = x y` (f_xy = 1) Hermite's error is exactly the
/// missing `f_xy` term `(h10(u) + h11(u)) (h10(v) + h11(v)) Δx Δy` (the tangent weights of
/// the four corners of the face sum to that product; f_xy is 1 at every corner).
#[test]
fn hermite_drops_cross_derivatives() {
    let spec = GridSpec::new([0.0; 3], [2.0, 3.0, 1.0], [3, 4, 2]).unwrap(); // cells 1 x 1 x 1
    let f = |x: [f64; 3]| vec![x[0] * x[1]; 12];
    let g = |x: [f64; 3]| vec![[x[1], x[0], 0.0]; 12];
    let (vol, grad) = volume_of(spec, 4, f, g);
    let h1 = |t: f64| (t * t * t - 2.0 * t * t + t) + (t * t * t - t * t);
    for (u, v) in [(0.25, 0.25), (0.1, 0.7), (0.3, 0.8)] {
        let p = [1.0 + u, 1.0 + v, 0.4];
        let got = coeffs_at(&vol, &grad, GradientLookup::Hermite, p).unwrap()[0];
        let missing = h1(u) * h1(v);
        assert!((got + missing - p[0] * p[1]).abs() < EXACT_TOL, "{u} {v}: {got} {missing}");
        assert!(missing.abs() > 1e-3);
    }
}

fn random_field(spec: GridSpec, coeffs: usize, seed: u64) -> (IrradianceVolume, VolumeGradients) {
    let mut r = SplitMix64::new(seed);
    let n = spec.node_count() * coeffs * 3;
    let data: Vec<f32> = (0..n).map(|_| r.range(-5.0, 5.0) as f32).collect();
    let vol = IrradianceVolume::new(spec, coeffs, data, vec![1.0; n / (coeffs * 3)]).unwrap();
    let gd: Vec<f32> = (0..n * 3).map(|_| r.range(-3.0, 3.0) as f32).collect();
    let grad = VolumeGradients::new(&vol, gd).unwrap();
    (vol, grad)
}

/// All three lookups return the node's own value at a node, as plain trilinear does.
#[test]
fn agree_with_trilinear_at_nodes() {
    let spec = spec().with_placement(placement());
    let (vol, grad) = random_field(spec.clone(), 16, 3);
    for node in 0..spec.node_count() {
        let [i, j, k] = spec.node_coords(node);
        let p = spec.node_position_world(i, j, k);
        let tri = vol.coeffs_reference(p);
        for m in METHODS {
            let got = coeffs_at(&vol, &grad, m, p).unwrap();
            // Placement round trips move the point by ~1e-15; gradients ≤ 3·√3 turn that
            // into ≤ 1e-13.
            assert!(max_diff(&got, &tri) < 1e-9, "{m:?} node {node}");
        }
    }
}

/// With zero gradients, gradient-aided trilinear is plain trilinear everywhere.
#[test]
fn zero_gradients_give_trilinear() {
    let spec = spec();
    let (vol, _) = random_field(spec.clone(), 9, 4);
    let grad = VolumeGradients::zeros(&vol);
    for p in points(&spec, 100, 2) {
        let got = coeffs_at(&vol, &grad, GradientLookup::GradientTrilinear, p).unwrap();
        assert!(max_diff(&got, &vol.coeffs_reference(p)) < 1e-12);
    }
}

/// Walks lines across every interior cell face of a random (non-linear) field and finds no
/// jump above FACE_JUMP_TOL for any lookup.
#[test]
fn continuous_across_cell_faces() {
    let spec = spec().with_placement(placement());
    let (vol, grad) = random_field(spec.clone(), 9, 8);
    let (lo, _) = spec.bounds();
    let size = spec.cell_size();
    let res = spec.res();
    let mut r = SplitMix64::new(21);
    let mut walked = 0;
    for axis in 0..3 {
        for face in 1..res[axis] - 1 {
            for _ in 0..6 {
                // A random point on the face plane (grid space), then ± FACE_STEP across it.
                let mut g: [f64; 3] =
                    std::array::from_fn(|a| lo[a] + r.range(0.0, 1.0) * size[a] * f64::from(res[a] - 1));
                g[axis] = lo[axis] + f64::from(face) * size[axis];
                let (mut a, mut b) = (g, g);
                a[axis] -= FACE_STEP;
                b[axis] += FACE_STEP;
                for m in METHODS {
                    let ca = coeffs_at(&vol, &grad, m, spec.to_world(a)).unwrap();
                    let cb = coeffs_at(&vol, &grad, m, spec.to_world(b)).unwrap();
                    let d = max_diff(&ca, &cb);
                    assert!(d < FACE_JUMP_TOL, "{m:?} axis {axis} face {face}: jump {d}");
                }
                walked += 1;
            }
        }
    }
    assert_eq!(walked, 6 * (2 + 3 + 1));
}

/// Taylor from the nearest node is discontinuous half-way between nodes for a non-linear
/// field (the documented limitation): for `f = x³` with nodes at 1 and 2, the tangent of
/// node 1 gives 1 + 3·0.5 = 2.5 at x = 1.5 and that of node 2 gives 8 − 12·0.5 = 2.
#[test]
fn taylor_jumps_at_midplanes() {
    let spec = GridSpec::new([0.0; 3], [3.0, 1.0, 1.0], [4, 2, 2]).unwrap();
    let f = |x: [f64; 3]| vec![x[0] * x[0] * x[0]; 12];
    let g = |x: [f64; 3]| vec![[3.0 * x[0] * x[0], 0.0, 0.0]; 12];
    let (vol, grad) = volume_of(spec, 4, f, g);
    let at = |x: f64| coeffs_at(&vol, &grad, GradientLookup::Taylor, [x, 0.5, 0.5]).unwrap()[0];
    assert!((at(1.5 - 1e-9) - 2.5).abs() < EXACT_TOL);
    assert!((at(1.5 + 1e-9) - 2.0).abs() < EXACT_TOL);
    assert!((at(1.4) - 2.2).abs() < EXACT_TOL);
    assert!((at(1.6) - 3.2).abs() < EXACT_TOL);
}

/// Mismatched gradients are an error, not a panic.
#[test]
fn mismatched_gradients_error() {
    let (vol, _) = random_field(spec(), 9, 1);
    let (other, og) = random_field(spec(), 4, 1);
    assert!(coeffs_at(&vol, &og, GradientLookup::Hermite, [0.0; 3]).is_err());
    assert!(VolumeGradients::new(&other, vec![0.0; 5]).is_err());
    assert!(VolumeGradients::new(&other, vec![f32::NAN; og.data().len()]).is_err());
    assert!(
        irradiance(&vol, &VolumeGradients::zeros(&vol), GradientLookup::Taylor, [0.0; 3], [0.0, 0.0, 1.0])
            .is_ok()
    );
}

/// \[Oat05\]'s memory tables against the formula `3 n² (1 + 3)`: per-sample figures (GPU
/// constant store slide) and the system-memory slide's totals. Reports which agree.
#[test]
fn floats_per_sample_matches_the_printed_memory_tables() {
    // "GPU Memory Requirements": 6th order 108 + 324 = 432; 3rd order 27 + 81 = 108.
    assert_eq!(floats_per_sample(6, false), 108);
    assert_eq!(floats_per_sample(6, true) - floats_per_sample(6, false), 324);
    assert_eq!(floats_per_sample(6, true), 432);
    assert_eq!(floats_per_sample(3, false), 27);
    assert_eq!(floats_per_sample(3, true) - floats_per_sample(3, false), 81);
    assert_eq!(floats_per_sample(3, true), 108);
    // Formula vs an independent count: 3 channels x n² coefficients x (1 value + 3 partials).
    for n in 1..=8 {
        assert_eq!(floats_per_sample(n, true), (0..n).map(|l| 2 * l + 1).sum::<usize>() * 3 * 4);
    }
    // "System Memory Requirements" (f32, 4 bytes a float). In KiB / MiB (1024-based):
    let kib = |b: usize| b as f64 / 1024.0;
    let mib = |b: usize| b as f64 / (1024.0 * 1024.0);
    // Adaptive, 2301 samples: "~970kB" (970.7 KiB) and "~3.8MB" (3.79 MiB) agree.
    assert_eq!(sample_bytes(2301, 3, true), 994_032);
    assert!((kib(sample_bytes(2301, 3, true)) - 970.0).abs() < 1.0);
    assert!((mib(sample_bytes(2301, 6, true)) - 3.8).abs() < 0.05);
    // Uniform, 4913 = 17³ samples: "~2MB" (2.02 MiB) agrees; "~8.2MB" does not: the formula
    // gives 8 489 664 bytes = 8.10 MiB = 8.49 MB, neither rounds to 8.2.
    assert!((mib(sample_bytes(4913, 3, true)) - 2.0).abs() < 0.05);
    assert_eq!(sample_bytes(4913, 6, true), 8_489_664);
    assert!((mib(sample_bytes(4913, 6, true)) - 8.2).abs() > 0.05);
    assert!((sample_bytes(4913, 6, true) as f64 / 1e6 - 8.2).abs() > 0.05);
}

/// Hermite is C¹ across cell faces (documented): one-sided difference quotients of the
/// normal derivative agree on both sides of every interior face, while gradient-aided
/// trilinear's derivative jumps there.
#[test]
fn hermite_is_c1_across_faces() {
    /// Difference-quotient step (grid units): its truncation error is δ·|f''| ≲ 1e-5 · 100.
    const STEP: f64 = 1e-5;
    /// Allowed mismatch of the two one-sided quotients: their truncation errors, 1.5·δ·|f''|
    /// each with |f''| ≲ 100 (values ±5, gradients ±3, cells ≥ 0.5), total ≲ 3e-3; the f64
    /// evaluation noise, 1e-15 / δ, is negligible (the interpolant is exact in the f32 data).
    const DERIV_TOL: f64 = 1e-2;
    let spec = spec();
    let (vol, grad) = random_field(spec.clone(), 4, 12);
    let (lo, _) = spec.bounds();
    let size = spec.cell_size();
    let res = spec.res();
    let mut r = SplitMix64::new(5);
    let (mut hermite_jump, mut trilinear_jump) = (0.0f64, 0.0f64);
    for axis in 0..3 {
        for face in 1..res[axis] - 1 {
            let mut g: [f64; 3] =
                std::array::from_fn(|a| lo[a] + r.range(0.05, 0.95) * size[a] * f64::from(res[a] - 1));
            g[axis] = lo[axis] + f64::from(face) * size[axis];
            let at = |m: GradientLookup, off: f64| {
                let mut p = g;
                p[axis] += off;
                coeffs_at(&vol, &grad, m, p).unwrap()
            };
            for (m, jump) in [
                (GradientLookup::Hermite, &mut hermite_jump),
                (GradientLookup::GradientTrilinear, &mut trilinear_jump),
            ] {
                let (l2, l1, r1, r2) = (at(m, -2.0 * STEP), at(m, -STEP), at(m, STEP), at(m, 2.0 * STEP));
                for c in 0..l1.len() {
                    let dl = (l1[c] - l2[c]) / STEP;
                    let dr = (r2[c] - r1[c]) / STEP;
                    *jump = jump.max((dl - dr).abs());
                }
            }
        }
    }
    assert!(hermite_jump < DERIV_TOL, "{hermite_jump}");
    assert!(trilinear_jump > 0.1, "{trilinear_jump}");
}

/// Gradients round-trip bit-exactly through the native EXR's optional gradient parts; the
/// volume reader ignores them; files without gradients are unchanged and read as `None`.
#[test]
fn exr_gradient_parts_round_trip() {
    use crate::io::exr::{
        ExrOptions, ExrSample, exr_from_bytes, exr_from_bytes_with_gradients, exr_to_bytes,
        exr_to_bytes_with_gradients, read_exr_with_gradients, write_exr_with_gradients,
    };
    let (vol, grad) = random_field(spec().with_placement(placement()), 9, 17);
    for sample in [ExrSample::F32, ExrSample::F16] {
        let opts = ExrOptions { sample, ..Default::default() };
        let plain = exr_to_bytes(&vol, &opts).unwrap();
        // (The exr crate keeps attributes in a hash map, so bytes are compared by length:
        // same parts, same attributes.)
        assert_eq!(exr_to_bytes_with_gradients(&vol, None, &opts).unwrap().len(), plain.len());
        let (v0, g0) = exr_from_bytes_with_gradients(&plain).unwrap();
        assert!(g0.is_none());
        let with = exr_to_bytes_with_gradients(&vol, Some(&grad), &opts).unwrap();
        let (v1, g1) = exr_from_bytes_with_gradients(&with).unwrap();
        assert_eq!(v1, v0);
        assert_eq!(exr_from_bytes(&with).unwrap(), v0);
        // Gradient parts are always f32: bit-exact.
        assert_eq!(g1.as_ref(), Some(&grad));
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("g.lvol.exr");
    write_exr_with_gradients(&path, &vol, &grad, &ExrOptions::default()).unwrap();
    let (v, g) = read_exr_with_gradients(&path).unwrap();
    assert_eq!((v, g), (vol.clone(), Some(grad)));
    let (_, other) = random_field(spec(), 4, 1);
    assert!(exr_to_bytes_with_gradients(&vol, Some(&other), &ExrOptions::default()).is_err());
}

/// A random validity mask (about 70% valid) and node reach (half the directions a full
/// cell, the others a multiple of an eighth below it) for `spec`.
fn random_masks(spec: &GridSpec, seed: u64) -> (crate::ValidityMask, crate::NodeReach) {
    let mut r = SplitMix64::new(seed);
    let n = spec.node_count();
    let valid = (0..n).map(|_| r.next_f64() < 0.7).collect();
    let reach = (0..n)
        .map(|_| {
            std::array::from_fn(|_| if r.next_f64() < 0.5 { 1.0 } else { (r.next_u64() % 8) as f32 / 8.0 })
        })
        .collect();
    (crate::ValidityMask::new(valid), crate::NodeReach::new(reach).unwrap())
}

/// With zero gradients, gradient-aided trilinear on a volume with a validity mask or a node
/// reach is the trilinear lookup of that volume: the same corners left out (coefficients at
/// the point, irradiance with the reach's test point moved along the normal); Hermite, in
/// a cell with a corner left out, is gradient-aided trilinear; Taylor expands about a kept
/// corner.
#[test]
fn masked_lookups_leave_out_the_trilinear_lookups_corners() {
    let spec = spec().with_placement(placement());
    let (vol, grad) = random_field(spec.clone(), 9, 5);
    let zero = VolumeGradients::zeros(&vol);
    let (mask, reach) = random_masks(&spec, 6);
    let mut changed = 0;
    for masked in [vol.clone().with_validity(mask).unwrap(), vol.clone().with_reach(reach).unwrap()] {
        for (q, p) in points(&spec, 300, 7).into_iter().enumerate() {
            let mut r = SplitMix64::new(q as u64);
            let n = lightvol_sh::sampling::sample_uniform_sphere([r.next_f64(), r.next_f64()]);
            let got = coeffs_at(&masked, &zero, GradientLookup::GradientTrilinear, p).unwrap();
            assert!(max_diff(&got, &masked.coeffs_reference(p)) < 1e-12, "point {q}");
            let e = irradiance(&masked, &zero, GradientLookup::GradientTrilinear, p, n).unwrap();
            let want = masked.irradiance_reference(p, n);
            assert!(max_diff(&e, &want) < 1e-12, "point {q}: {e:?} {want:?}");
            let (nodes, b) = masked.reference_weights(p, None);
            let plain = vol.reference_weights(p, None).1;
            if b != plain {
                changed += 1;
                let h = coeffs_at(&masked, &grad, GradientLookup::Hermite, p).unwrap();
                let gt = coeffs_at(&masked, &grad, GradientLookup::GradientTrilinear, p).unwrap();
                assert_eq!(h, gt, "point {q}");
                // Taylor with zero gradients is one kept corner's value.
                let t = coeffs_at(&masked, &zero, GradientLookup::Taylor, p).unwrap();
                let from = (0..8).filter(|&c| b[c] > 0.0).find(|&c| {
                    max_diff(&t, &masked.node(nodes[c]).iter().map(|&v| f64::from(v)).collect::<Vec<_>>())
                        == 0.0
                });
                assert!(from.is_some(), "point {q}: Taylor's corner is not kept");
            }
        }
    }
    assert!(changed > 100, "only {changed} points had a corner left out");
    // An all-valid mask and a full reach change no bit.
    let n = spec.node_count();
    let full = vol
        .clone()
        .with_validity(crate::ValidityMask::new(vec![true; n]))
        .unwrap()
        .with_reach(crate::NodeReach::new(vec![[1.0; 6]; n]).unwrap())
        .unwrap();
    for p in points(&spec, 100, 8) {
        for m in METHODS {
            assert_eq!(
                coeffs_at(&full, &grad, m, p).unwrap(),
                coeffs_at(&vol, &grad, m, p).unwrap(),
                "{m:?}"
            );
        }
    }
}
