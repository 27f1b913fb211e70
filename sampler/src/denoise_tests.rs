//! Tests of the noise-weighted smoothing.

use lightvol_sh::lowdisc::hash2;
use lightvol_volume::GridSpec;
use lightvol_volume::reach::NodeReach;

use super::*;

/// Coefficients per node in these tests (order 2: 4 per channel).
const COEFFS: usize = 4;

/// A volume on an `n × n × n` grid (unit cells) whose nodes hold `f(x)` times a fixed
/// coefficient pattern.
fn field(n: u32, f: impl Fn([f64; 3]) -> f64) -> IrradianceVolume {
    let m = f64::from(n - 1);
    let spec = GridSpec::new([0.0; 3], [m; 3], [n; 3]).unwrap();
    IrradianceVolume::from_fn(spec, COEFFS, |x| {
        let a = f(x);
        (0..COEFFS)
            .map(|j| [a / (1 + j) as f64, 0.8 * a / (1 + j) as f64, 1.2 * a / (1 + j) as f64])
            .collect()
    })
    .unwrap()
}

/// Root-mean-square difference of two volumes' values over all nodes.
fn rms_difference(a: &IrradianceVolume, b: &IrradianceVolume) -> f64 {
    let (sum, n) = (0..a.spec().node_count())
        .flat_map(|i| {
            a.node(i).iter().zip(b.node(i)).map(|(x, y)| f64::from(x - y).powi(2)).collect::<Vec<_>>()
        })
        .fold((0.0, 0usize), |(s, n), d| (s + d, n + 1));
    (sum / n as f64).sqrt()
}

/// Relative precision of the f32 node values: the smoothed values are stored as f32, and
/// the solver stops at a relative residual of 1e-7; 1e-6 of a value covers both.
const F32_VALUE_TOLERANCE: f64 = 1e-6;

/// One free node with relative error `e` among kept ones (a 2 × 2 × 2 grid, node 0 free,
/// its three neighbours holding one value `ĉ₂`): its value is the closed-form minimiser of
/// `(c − ĉ₁)²/σ² + 3γ (c − ĉ₂)²`, `(ĉ₁/σ² + 3γ ĉ₂) / (1/σ² + 3γ)`, coefficient by
/// coefficient, and the kept nodes are untouched. The pooled variance is the node's own
/// (no neighbour has a known error); the pooled light of node 0 and of each neighbour is
/// `(m₁ + 3 m₂) / 4` (on this grid every node has three neighbours, and each of node 0's
/// neighbours has node 0 and two nodes of light `m₂` among them), so `γ = 1/(τ (m₁ + 3 m₂)/4)²`.
#[test]
fn one_free_node_gives_the_closed_form() {
    let spec = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
    let vol = IrradianceVolume::from_fn(spec, COEFFS, |x| {
        let a = if x == [0.0; 3] { 2.0 } else { 1.0 };
        (0..COEFFS).map(|j| [a * (1.0 + j as f64), a, 0.5 * a]).collect()
    })
    .unwrap();
    let valid = ValidityMask::new(vec![true; 8]);
    let (e, tau) = (0.2f64, 0.3f64);
    let mut errors = [f32::NAN; 8];
    errors[0] = e as f32;
    let (out, report) = smooth_by_noise(&vol, &valid, &errors, tau).unwrap();
    assert_eq!((report.nodes, report.edges), (1, 3));
    let m1 = light_of(vol.node(0));
    let m2 = light_of(vol.node(1));
    let w = 1.0 / (f64::from(e as f32) * m1).powi(2);
    let g = 1.0 / (tau * 0.25 * (m1 + 3.0 * m2)).powi(2);
    for c in 0..3 * COEFFS {
        let (c1, c2) = (f64::from(vol.node(0)[c]), f64::from(vol.node(1)[c]));
        let want = (w * c1 + 3.0 * g * c2) / (w + 3.0 * g);
        let got = f64::from(out.node(0)[c]);
        assert!(
            (got - want).abs() <= F32_VALUE_TOLERANCE * want.abs(),
            "coefficient {c}: {got} against {want}"
        );
    }
    for node in 1..8 {
        assert_eq!(out.node(node), vol.node(node), "kept node {node}");
    }
}

/// Noise on a smooth field is removed where it was estimated large, and where the whole
/// neighbourhood is estimated exact the nodes keep their values: the smoothed field is at
/// least twice as close to the truth.
#[test]
fn noisy_nodes_move_toward_the_truth_and_exact_ones_stay() {
    let smooth = |x: [f64; 3]| 1.0 + 0.05 * x[0] + 0.03 * x[1] * x[2] / 4.0;
    let truth = field(6, smooth);
    let spec = truth.spec().clone();
    let nodes = spec.node_count();
    // The half x < 2 is estimated exact (error 1e-4); the rest carries ±25% noise, estimated.
    let exact = |node: usize| spec.node_coords(node)[0] < 2;
    let mut noisy = truth.clone();
    let mut errors = vec![0.0f32; nodes];
    for (node, err) in errors.iter_mut().enumerate() {
        let e = if exact(node) { 1e-4 } else { 0.25 };
        let u = (hash2(7, node as u64) >> 11) as f64 / (1u64 << 53) as f64;
        let scale = 1.0 + e * (2.0 * u - 1.0) * 3f64.sqrt();
        let v: Vec<f32> = truth.node(node).iter().map(|&x| (f64::from(x) * scale) as f32).collect();
        noisy.set_node(node, &v).unwrap();
        *err = e as f32;
    }
    let valid = ValidityMask::new(vec![true; nodes]);
    let (out, report) = smooth_by_noise(&noisy, &valid, &errors, 0.3).unwrap();
    assert_eq!(report.nodes, nodes);
    let before = rms_difference(&noisy, &truth);
    let after = rms_difference(&out, &truth);
    assert!(after < 0.5 * before, "rms error {before} -> {after}");
    // x = 0: the node and its whole neighbourhood are estimated exact (pooled ê = 1e-4); it
    // moves by at most ~(ê/τ)² × 6 edges of its neighbours' difference, and those (x = 1)
    // move by at most ~(ê/τ)² times the noisy layer's: 1e-6 relative.
    for node in (0..nodes).filter(|&n| spec.node_coords(n)[0] == 0) {
        for (a, b) in out.node(node).iter().zip(noisy.node(node)) {
            assert!((a - b).abs() <= 2e-6 * b.abs().max(1.0), "node {node}: {b} -> {a}");
        }
    }
}

/// The smoothing keeps the mean of light whose noise is skewed. Monte Carlo estimates of
/// light through small openings are mostly low and now and then far too high, and the
/// estimated error is largest on the lucky nodes. Here each node of a constant field takes
/// the mean of 128 samples that are 0.1 and, with probability 3%, 30.1 (expected mean 1),
/// and its error is the bake's own prefix estimate of them ([`crate::noise`]). Weighted by
/// each node's own estimates, the smoothing pulled the lucky nodes down and trusted the
/// unlucky ones: the mean fell by 13.5% (and the spread of the values went from 0.37 to
/// 0.17). With the pooled estimates it moves by [`SKEW_MEAN_TOLERANCE`] at most, while the
/// spread is more than halved (to 0.09).
#[test]
fn skewed_noise_keeps_its_mean() {
    let n = 10u32;
    let vol = field(n, |_| 1.0);
    let nodes = vol.spec().node_count();
    let mut noisy = vol.clone();
    let mut errors = vec![0.0f32; nodes];
    for node in 0..nodes {
        let values: Vec<f64> =
            (0..128u64).map(|s| if hash2(node as u64, s) % 100 < 3 { 30.1 } else { 0.1 }).collect();
        let m = values.iter().sum::<f64>() / values.len() as f64;
        let v: Vec<f32> = vol.node(node).iter().map(|&x| (f64::from(x) * m) as f32).collect();
        noisy.set_node(node, &v).unwrap();
        errors[node] = crate::noise::relative_error_of(&values).unwrap() as f32;
    }
    let mean = |v: &IrradianceVolume| (0..nodes).map(|i| light_of(v.node(i))).sum::<f64>() / nodes as f64;
    let spread = |v: &IrradianceVolume| {
        let m = mean(v);
        ((0..nodes).map(|i| (light_of(v.node(i)) - m).powi(2)).sum::<f64>() / nodes as f64).sqrt()
    };
    let valid = ValidityMask::new(vec![true; nodes]);
    let (out, _) = smooth_by_noise(&noisy, &valid, &errors, DEFAULT_SMOOTHING).unwrap();
    let (before, after) = (mean(&noisy), mean(&out));
    assert!((after / before - 1.0).abs() < SKEW_MEAN_TOLERANCE, "mean {before} -> {after}");
    assert!(spread(&out) < 0.5 * spread(&noisy), "spread {} -> {}", spread(&noisy), spread(&out));
}

/// How far the mean of [`skewed_noise_keeps_its_mean`]'s smoothed field may move: it moves
/// by 1.6% (the pooled weights still vary between a neighbourhood with a lucky node and
/// one without, and the smoothing keeps the `1/σ̄²`-weighted sum, not the plain one);
/// twice that leaves room for another draw of the samples, and own-error weights (13.5%)
/// fail it by far.
const SKEW_MEAN_TOLERANCE: f64 = 0.03;

/// A wall across the grid (each node beside it reaches only to it) stops the smoothing:
/// a dark and a bright half keep their own light, while without the reach they bleed.
#[test]
fn a_wall_in_the_reach_stops_the_smoothing() {
    let n = 4u32;
    let vol = field(n, |x| if x[0] < 1.5 { 0.1 } else { 1.0 });
    let nodes = vol.spec().node_count();
    let reach: Vec<[f32; 6]> = (0..nodes)
        .map(|i| {
            let x = vol.spec().node_coords(i)[0];
            let mut r = [1.0f32; 6];
            if x == 1 {
                r[0] = 0.5; // +x: the wall half a cell away
            }
            if x == 2 {
                r[1] = 0.5; // -x
            }
            r
        })
        .collect();
    let walled = vol.clone().with_reach(NodeReach::new(reach).unwrap()).unwrap();
    let valid = ValidityMask::new(vec![true; nodes]);
    let errors = vec![0.3f32; nodes];
    let (out, _) = smooth_by_noise(&walled, &valid, &errors, 0.3).unwrap();
    // Each half is constant, so with the wall nothing moves (beyond f32 rounding).
    assert!(rms_difference(&out, &walled) < 1e-7, "{}", rms_difference(&out, &walled));
    let (open, _) = smooth_by_noise(&vol, &valid, &errors, 0.3).unwrap();
    assert!(rms_difference(&open, &vol) > 0.01, "without the reach the halves mix");
}

/// Nodes without samples of their own, with unknown errors or without light keep their
/// values bit for bit; bad settings are refused.
#[test]
fn kept_nodes_and_bad_settings() {
    let vol = field(3, |x| 1.0 + x[0]);
    let nodes = vol.spec().node_count();
    let mut valid = vec![true; nodes];
    valid[4] = false;
    let valid = ValidityMask::new(valid);
    let mut errors = vec![0.5f32; nodes];
    errors[5] = f32::NAN;
    let (out, report) = smooth_by_noise(&vol, &valid, &errors, 0.3).unwrap();
    assert_eq!(report.nodes, nodes - 2);
    assert_eq!(out.node(4), vol.node(4));
    assert_eq!(out.node(5), vol.node(5));
    assert!(rms_difference(&out, &vol) > 0.0);
    for tau in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(smooth_by_noise(&vol, &valid, &errors, tau).is_err(), "τ = {tau}");
    }
    assert!(smooth_by_noise(&vol, &valid, &errors[1..], 0.3).is_err());
}
