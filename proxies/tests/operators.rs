//! The indirect operators ([SGNS07] §5): the analytic order-3 `D` against quadrature, the
//! paper's polynomial fits (Fig. 4) and their stated errors, `M` against an independent
//! geometric quadrature, and Fig. 5's ordering of the operator errors.

use std::f64::consts::PI;

use lightvol_proxies::operators::{
    U_NODES, d_exact, d_exact_with, d_paper_analytic, d_paper_fit, m_exact, m_exact_with, operator_error,
    polynomial_fit, relative_squared_error,
};
use lightvol_proxies::proxy::{SphereProxy, solid_angle};
use lightvol_proxies::reference::intersect;
use lightvol_sh::eval::eval_basis;
use lightvol_sh::quadrature::gauss_legendre;

/// The analytic formula and the quadrature agree to f64 rounding (the formula is evaluated
/// without the `d - ď` cancellation).
const ANALYTIC: f64 = 1e-12;

/// Gauss-Legendre nodes for the continuous L2 errors over `α ∈ [0, 1]` (smooth integrands).
const L2_NODES: usize = 200;

#[test]
fn analytic_order3_d_matches_quadrature() {
    for k in 0..=100 {
        let a = f64::from(k) / 100.0;
        let q = d_exact(a, 3);
        let f = d_paper_analytic(a);
        for l in 0..3 {
            assert!((q[l] - f[l]).abs() < ANALYTIC, "alpha {a}, l {l}: {} vs {}", q[l], f[l]);
        }
    }
    // Quadrature converged: 48 nodes against 96, bands 0-3.
    for a in [0.05, 0.5, 0.99] {
        let (x, y) = (d_exact_with(a, 4, U_NODES), d_exact_with(a, 4, 2 * U_NODES));
        assert!(x.iter().zip(&y).all(|(x, y)| (x - y).abs() < 1e-14));
    }
    // Limits: cosine-weighted hemisphere at α → 0, point sampling at α = 1.
    let d0 = d_exact(1e-7, 3);
    // D_1 has slope -0.25 at 0, so 1e-7 away from the limit it differs by 2.5e-8.
    assert!((d0[1] + 3f64.sqrt() / (3.0 * PI.sqrt())).abs() < 1e-7);
    let d1 = d_exact(1.0, 3);
    assert!((d1[1] + (3.0 / (4.0 * PI)).sqrt()).abs() < 1e-12);
}

/// Fig. 4: the paper's fits against the exact `D`, as continuous relative squared errors
/// over `α ∈ [0, 1]`. Measured: D_1 1.785e-6 (0.000179%, the paper states 0.00016%), D_2
/// 4.789e-6 (0.00048%, the paper states 0.00064%). The printed coefficients are the
/// least-squares fits (our own fits agree to 4e-4), so D_1's stated error is slightly
/// optimistic and D_2's is met.
#[test]
fn paper_polynomial_fits() {
    let e1 = relative_squared_error(|a| d_paper_fit(a)[1], |a| d_exact(a, 3)[1], L2_NODES);
    let e2 = relative_squared_error(|a| d_paper_fit(a)[2], |a| d_exact(a, 3)[2], L2_NODES);
    println!("relative squared error: D1 {e1:.4e} ({:.5}%), D2 {e2:.4e} ({:.5}%)", 100.0 * e1, 100.0 * e2);
    assert!((1.75e-6..1.82e-6).contains(&e1));
    assert!((4.7e-6..4.9e-6).contains(&e2));
    assert!(e1 > 1.6e-6, "the paper's 0.00016% for D_1 is not reached");
    assert!(e2 < 6.4e-6, "the paper's 0.00064% for D_2 is met");
    // D_0 = 1/(2 sqrt π) = 0.282095 (printed 0.28209).
    assert!((d_paper_fit(0.3)[0] - 0.5 / PI.sqrt()).abs() < 1e-5);
    // The printed coefficients are least-squares fits of the exact D.
    let c1 = polynomial_fit(|a| d_exact(a, 3)[1], 2, L2_NODES);
    let c2 = polynomial_fit(|a| d_exact(a, 3)[2], 3, L2_NODES);
    let p1 = [-0.32494, -0.25073, 0.08432];
    let p2 = [0.15950, 0.47398, 0.22502, -0.22230];
    assert!(c1.iter().zip(&p1).all(|(a, b)| (a - b).abs() < 4e-4), "{c1:?}");
    assert!(c2.iter().zip(&p2).all(|(a, b)| (a - b).abs() < 4e-4), "{c2:?}");
}

/// `M` (Eq. 16) against a direct geometric quadrature: rays from the origin over the cap
/// (product Gauss-Legendre in `cos` × uniform azimuth), each intersected with the real sphere;
/// the normal at the hit gives `q̂`. Without the rim substitution this converges slowly, hence
/// the looser tolerance.
#[test]
fn exact_operator_against_ray_quadrature() {
    const GEOMETRIC: f64 = 2e-4;
    for alpha in [0.2, 0.6, 0.95] {
        let m = m_exact::<16>(alpha);
        let sphere = [SphereProxy::new([0.0, 0.0, 1.0], alpha, [1.0; 3])];
        let c = (1.0 - alpha * alpha).sqrt();
        let (x, w) = gauss_legendre(400);
        let nphi = 32;
        let mut b = vec![0.0; 256];
        for (&x, &w) in x.iter().zip(&w) {
            let t = c + (1.0 - c) * 0.5 * (x + 1.0);
            let st = (1.0 - t * t).sqrt();
            for j in 0..nphi {
                let ph = 2.0 * PI * (j as f64 + 0.5) / nphi as f64;
                let s = [st * ph.cos(), st * ph.sin(), t];
                let Some((tt, _)) = intersect(&sphere, [0.0; 3], s) else { continue };
                let q = [(tt * s[0]) / alpha, (tt * s[1]) / alpha, (tt * s[2] - 1.0) / alpha];
                let (ys, yq) = (eval_basis::<f64, 16>(s), eval_basis::<f64, 16>(q));
                let wt = 0.5 * (1.0 - c) * w * 2.0 * PI / nphi as f64;
                for a in 0..16 {
                    for k in 0..16 {
                        b[a * 16 + k] += wt * ys[a] * yq[k];
                    }
                }
            }
        }
        let err = m.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt();
        let norm = m.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(err < GEOMETRIC * norm, "alpha {alpha}: {err:.2e} of {norm:.2e}");
        // Converged in u: 48 against 96 nodes.
        let m2 = m_exact_with::<16>(alpha, 96);
        assert!(m.iter().zip(&m2).all(|(x, y)| (x - y).abs() < 1e-13));
        // D is M's first row normalised by the solid angle: D_l = sqrt(4π) M_{0,l(l+1)} / ω.
        let d = d_exact(alpha, 4);
        for l in 0..4 {
            let from_m = (4.0 * PI).sqrt() * m[l * (l + 1)] / solid_angle(alpha);
            assert!((from_m - d[l]).abs() < 1e-12);
        }
    }
}

/// Fig. 5: the averaged operator is more accurate than point sampling at every size, by an
/// order of magnitude for small proxies; both meet at α = 1, where every ray sees the same
/// point. Measured at order 3: α = 0.1: 1.18e-2 vs 1.02e-3; 0.5: 0.168 vs 0.111;
/// 0.9: 0.242 vs 0.240.
#[test]
fn fig5_operator_errors() {
    for k in 1..100 {
        let a = f64::from(k) / 100.0;
        let e = operator_error::<9>(a);
        assert!(e.averaged < e.point_sampled, "alpha {a}: {e:?}");
        let e16 = operator_error::<16>(a);
        assert!(e16.averaged < e16.point_sampled, "alpha {a}: {e16:?}");
    }
    let e = operator_error::<9>(0.1);
    assert!(e.point_sampled > 10.0 * e.averaged);
    assert!((e.point_sampled - 1.18e-2).abs() < 1e-4 && (e.averaged - 1.02e-3).abs() < 1e-5, "{e:?}");
    let e = operator_error::<9>(1.0);
    assert!((e.point_sampled - e.averaged).abs() < 1e-12);
}
