//! Tests of the least-squares node fit.

use lightvol_core::samples::samples;

use super::*;
use lightvol_scene::builtin::city;
use lightvol_scene::bvh::Tracer;
use lightvol_scene::transport::TransportSettings;
use lightvol_sh::lowdisc::Halton;

/// Conjugate gradients stop at a relative residual of 1e-9 (`CG_TOLERANCE`); the recovered
/// node values of a well-conditioned system then agree to a few times that.
const SOLVE_TOL: f64 = 1e-7;

fn grid() -> GridSpec {
    GridSpec::new([0.0; 3], [4.0, 3.0, 2.0], [5, 4, 3]).unwrap()
}

/// Feeds `n` Halton points (restricted by `inside`) of the scalar field `f` into an
/// accumulator (4 coefficients, the field in coefficient 0 of every channel) and a mass
/// matrix, exactly as the bake does.
fn feed(
    grid: &GridSpec,
    n: u64,
    inside: impl Fn([f64; 3]) -> bool,
    f: impl Fn([f64; 3]) -> f64,
) -> (Accumulator, MassMatrix) {
    let mut acc = Accumulator::new(grid.clone(), 4).unwrap();
    let mut mass = MassMatrix::new(grid);
    let h = Halton::new(3, 3);
    let (lo, hi) = grid.bounds();
    for s in 0..n {
        let u: [f64; 3] = h.point(s);
        let p = [0, 1, 2].map(|a| lo[a] + (hi[a] - lo[a]) * u[a]);
        if !inside(p) {
            continue;
        }
        let (nodes, w) = grid.trilinear(p);
        let v = f(p);
        for c in 0..8 {
            if w[c] > 0.0 {
                acc.add(nodes[c], w[c], [v; 3], &[1.0, 0.0, 0.0, 0.0]);
            }
        }
        mass.add_sample(&nodes, &w);
    }
    (acc, mass)
}

/// `Σ_i c_i b_i(p)` for channel 0 of coefficient 0.
fn reconstruct(grid: &GridSpec, values: &[f64], p: [f64; 3]) -> f64 {
    let (nodes, w) = grid.trilinear(p);
    (0..8).map(|c| w[c] * values[nodes[c] * 12]).sum()
}

/// The mass matrix of uniform samples over the grid converges to `∫ b_i b_j`. Checked through
/// ratios that do not depend on the sample count: for an interior node
/// `M_ii / m_i = (2/3)³` (per axis `∫ b² / ∫ b = (2h/3) / h`), a face neighbour has
/// `M_ij / M_ii = 1/4` (one axis `(h/6) / (2h/3)`), and a corner neighbour `(1/4)³`.
#[test]
fn mass_matrix_matches_the_analytic_integrals() {
    let g = grid();
    let (_, mass) = feed(&g, 200_000, |_| true, |_| 1.0);
    let node = g.node_index(2, 1, 1);
    let row = mass.row(node);
    let diag = row[offset_slot([0, 0, 0])];
    // QMC integration error with 2e5 points of a piecewise polynomial with kinks.
    const QMC_TOL: f64 = 2e-3;
    assert!(
        (diag / mass.row_sum(node) - (2.0f64 / 3.0).powi(3)).abs() < QMC_TOL,
        "{}",
        diag / mass.row_sum(node)
    );
    assert!((row[offset_slot([1, 0, 0])] / diag - 0.25).abs() < QMC_TOL);
    assert!((row[offset_slot([1, 1, 1])] / diag - 0.25f64.powi(3)).abs() < QMC_TOL);
    // Symmetry: M_ij = M_ji.
    let nb = g.node_index(3, 1, 1);
    assert!((row[offset_slot([1, 0, 0])] - mass.row(nb)[offset_slot([-1, 0, 0])]).abs() < 1e-9 * diag);
}

/// With λ = 0 the fit reproduces any field that is trilinear on the grid, also when the
/// domain is cut (here by a slanted plane): `r = M c*` then holds exactly for the sampled
/// sums, so `c = c*` up to the solver tolerance, while Eq. 6 is off wherever the field is
/// not linear across a node's support.
#[test]
fn lambda_zero_reproduces_trilinear_fields() {
    let g = grid();
    let truth: Vec<f64> = (0..g.node_count())
        .map(|n| {
            let [i, j, k] = g.node_coords(n);
            (f64::from(i * 7 + j * 3 + k * 5) * 0.37).sin() + 2.0
        })
        .collect();
    let field = |p: [f64; 3]| reconstruct(&g, &truth.iter().flat_map(|&v| [v; 12]).collect::<Vec<_>>(), p);
    let inside = |p: [f64; 3]| p[0] + 0.5 * p[1] + p[2] > 0.7;
    let (acc, mass) = feed(&g, 40_000, inside, field);
    let (values, report) = solve_least_squares(&mass, &acc, 0.0).unwrap();
    assert!(report.max_relative_residual <= CG_TOLERANCE, "{report:?}");
    let mut worst_avg = 0.0f64;
    for n in 0..g.node_count() {
        if acc.denominator()[n] > 0.0 {
            for ch in 0..3 {
                assert!(
                    (values[n * 12 + ch] - truth[n]).abs() < SOLVE_TOL,
                    "node {n}: {} vs {}",
                    values[n * 12],
                    truth[n]
                );
            }
            worst_avg = worst_avg.max((acc.node_estimate(n).unwrap()[0] - truth[n]).abs());
        }
    }
    assert!(worst_avg > 0.05, "Eq. 6 should blur this field ({worst_avg})");
}

/// Large λ gives back Eq. 6 (the system tends to `λ diag(m) c = λ r`).
#[test]
fn large_lambda_tends_to_the_average() {
    let g = grid();
    let (acc, mass) = feed(&g, 20_000, |p| p[2] > 0.3, |p| (3.0 * p[0]).sin() + p[1]);
    let (values, _) = solve_least_squares(&mass, &acc, 1e6).unwrap();
    for n in 0..g.node_count() {
        if let Some(avg) = acc.node_estimate(n) {
            // Deviation O(1/λ) relative to the field's range (~3).
            assert!((values[n * 12] - avg[0]).abs() < 1e-4, "{} vs {}", values[n * 12], avg[0]);
        }
    }
}

/// The point of the fit: on a field with a feature narrower than two cells, the
/// least-squares reconstruction has a smaller error over the domain than Eq. 6.
#[test]
fn least_squares_beats_the_average_on_a_narrow_feature() {
    let g = grid();
    let f = |p: [f64; 3]| if (p[0] - 2.2).abs() < 0.6 && (p[1] - 1.4).abs() < 0.6 { 10.0 } else { 1.0 };
    let (acc, mass) = feed(&g, 60_000, |_| true, f);
    let (lsq, _) = solve_least_squares(&mass, &acc, DEFAULT_LAMBDA).unwrap();
    let avg: Vec<f64> = (0..g.node_count()).flat_map(|n| acc.node_estimate(n).unwrap()).collect();
    let h = Halton::new(9, 3);
    let (mut e_lsq, mut e_avg) = (0.0, 0.0);
    for s in 0..20_000 {
        let u: [f64; 3] = h.point(s);
        let p = [4.0 * u[0], 3.0 * u[1], 2.0 * u[2]];
        e_lsq += (reconstruct(&g, &lsq, p) - f(p)).powi(2);
        e_avg += (reconstruct(&g, &avg, p) - f(p)).powi(2);
    }
    assert!(e_lsq < 0.8 * e_avg, "lsq {e_lsq} avg {e_avg}");
}

/// A whole bake with the least-squares fit is bit-identical for 1 and 2 threads, and
/// differs from the Eq. 6 volume (else the option would do nothing).
#[test]
fn fitted_bake_is_deterministic() {
    let c = city();
    let tracer = Tracer::new(&c.scene);
    let t = Transport::new(&c.scene, &tracer, TransportSettings::default());
    let grid = GridSpec::new([-14.0, -14.0, -1.0], [14.0, 14.0, 11.0], [7, 7, 4]).unwrap();
    let s = BakeSettings {
        method: Method::DoiPaper,
        samples: samples(24),
        seed: 5,
        chunk: 7,
        ..Default::default()
    };
    let run = |threads: usize, fit: Fit| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| bake_fitted(&t, &grid, &s, &BakeControl::default(), fit).unwrap())
    };
    let (one, _, rep) = run(1, Fit::default());
    let (two, _, _) = run(2, Fit::default());
    assert_eq!(one.data(), two.data());
    assert_eq!(one.weights(), two.weights());
    let rep = rep.unwrap();
    assert!(rep.max_relative_residual <= CG_TOLERANCE && rep.active_nodes > 0, "{rep:?}");
    let (avg, _, none) = run(2, Fit::Average);
    assert!(none.is_none());
    assert_ne!(avg.data(), one.data());
}

/// A NaN radiance sample (a broken scene) must neither panic nor spread through the solve:
/// its node is left out of the system and zeroed and counted as `finalize` does for Eq. 6;
/// every other node stays finite.
#[test]
fn a_nan_sample_is_zeroed_not_spread() {
    let g = grid();
    let (mut acc, mass) = feed(&g, 20_000, |_| true, |p| 1.0 + p[0]);
    let bad = g.node_index(2, 1, 1);
    acc.add(bad, 0.5, [f64::NAN, 1.0, 1.0], &[1.0, 0.0, 0.0, 0.0]);
    let (values, report) = solve_least_squares(&mass, &acc, DEFAULT_LAMBDA).unwrap();
    assert_eq!(report.active_nodes, g.node_count() - 1);
    assert!(values.iter().all(|v| v.is_finite()));
    let (volume, fill) = finalize_least_squares(&acc, values);
    let (_, average_fill) = acc.finalize();
    assert_eq!(fill.non_finite_zeroed, average_fill.non_finite_zeroed);
    assert!(fill.non_finite_zeroed >= 1);
    assert_eq!(volume.node(bad)[0], 0.0);
    assert!(volume.data().iter().all(|v| v.is_finite()));
}

#[test]
fn fit_names_parse() {
    assert_eq!("average".parse::<Fit>(), Ok(Fit::Average));
    assert_eq!("lsq".parse::<Fit>(), Ok(Fit::LeastSquares { lambda: DEFAULT_LAMBDA }));
    assert_eq!("lsq:0.5".parse::<Fit>(), Ok(Fit::LeastSquares { lambda: 0.5 }));
    assert!("lsq:-1".parse::<Fit>().is_err());
    assert!("lsq:nan".parse::<Fit>().is_err());
    assert!("blur".parse::<Fit>().is_err());
    for f in [Fit::Average, Fit::default(), Fit::LeastSquares { lambda: 0.1 }] {
        assert_eq!(f.to_string().parse::<Fit>(), Ok(f));
    }
}
