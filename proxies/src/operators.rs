//! The indirect-light operators of a canonical proxy (\[SGNS07\] §5): the averaged operator
//! `D(θ)` (Eq. 14), its analytic order-3 form and the paper's polynomial fits, the exact
//! operator `M(θ)` (Eq. 16), and their Frobenius comparison (Fig. 5).
//!
//! Canonical configuration: receiver at the origin, proxy centre at `+z` at distance 1,
//! radius `α = sin θ`. A direction `s` in the proxy's cap (`s_z >= cos θ`) first hits the
//! proxy at `q(s) = s (s_z - sqrt(s_z² - cos²θ))`, whose unit normal is
//! `q̂ = (q - z) / sin θ`.
//!
//! All integrals are over the cap in the variables `u = sqrt(s_z² - cos²θ) ∈ [0, sin θ]`
//! and the azimuth `φ`: `ds = (u / s_z) du dφ`. The substitution removes the square-root
//! singularity at the cap's rim, so Gauss-Legendre in `u` converges geometrically, and the
//! integrand is a trigonometric polynomial of degree `< 2·bands` in `φ`, integrated exactly
//! by a uniform rule with [`PHI_NODES`] nodes.
//!
//! **Normalisation.** `D` is Eq. 14 as printed: `κ = rot(D, d̂) · L̃` is the average over
//! the proxy's visible disk (in solid angle from `p`) of the irradiance `L̃` at the proxy
//! point seen, so a proxy of albedo `ρ` sends radiance `(ρ/π) κ`. The paper's analytic
//! order-3 formula ([`d_paper_analytic`]) is this same `D` (tested to 1e-13). Limits: at
//! `α → 0` the visible part is the hemisphere facing `p`, weighted by its projected area, so
//! `D_l(0) = (A_l/π) y_l0(-z)`; at `α = 1` (receiver on the sphere) every ray meets the sphere
//! at `p`, so `D_l(1) = y_l0(-z)`, the point-sampled value.

use std::f64::consts::PI;

use lightvol_sh::eval::eval_basis;
use lightvol_sh::irradiance::normalized_cosine_lobe_factor;
use lightvol_sh::quadrature::gauss_legendre;
use lightvol_sh::zonal::Zh;

/// Gauss-Legendre nodes in `u` for the cap integrals: the integrands are analytic in `u` on
/// `[0, sin θ]`, and 48 nodes reach f64 rounding (tested against 96 nodes).
pub const U_NODES: usize = 48;

/// Uniform azimuth nodes: exact for the trigonometric polynomials of degree <= 6 (products
/// of two band-3 functions) that appear up to 4 bands.
pub const PHI_NODES: usize = 16;

/// Legendre polynomial `P_l(x)` by the three-term recurrence.
#[must_use]
pub fn legendre(l: usize, x: f64) -> f64 {
    let (mut p0, mut p1) = (1.0, x);
    if l == 0 {
        return 1.0;
    }
    for k in 1..l {
        let kf = k as f64;
        let p2 = ((2.0 * kf + 1.0) * x * p1 - kf * p0) / (kf + 1.0);
        p0 = p1;
        p1 = p2;
    }
    p1
}

/// `y_l0` at a direction with `z = cos θ`.
#[must_use]
pub fn y_l0(l: usize, z: f64) -> f64 {
    ((2 * l + 1) as f64 / (4.0 * PI)).sqrt() * legendre(l, z)
}

/// Quadrature nodes `(s_z, q̂_z, weight)` over the canonical cap for `alpha = sin θ`, with
/// the azimuth already integrated (weight includes the `2π`).
fn cap_nodes(alpha: f64, n: usize) -> Vec<(f64, f64, f64)> {
    let c2 = 1.0 - alpha * alpha;
    let (x, w) = gauss_legendre(n);
    x.iter()
        .zip(&w)
        .map(|(&x, &w)| {
            let u = 0.5 * alpha * (x + 1.0);
            let t = (c2 + u * u).sqrt();
            let qz = t * (t - u);
            let qhat_z = ((qz - 1.0) / alpha).clamp(-1.0, 1.0);
            (t, qhat_z, 2.0 * PI * 0.5 * alpha * w * u / t)
        })
        .collect()
}

/// The averaged operator `D(θ)` of Eq. 14 as a ZH with `bands` bands (<= 8), by quadrature
/// with `n` nodes in `u`. At `alpha = 0` it is the limit `(A_l/π) y_l0(-z)`.
#[must_use]
pub fn d_exact_with(alpha: f64, bands: usize, n: usize) -> Vec<f64> {
    if alpha <= 0.0 {
        return (0..bands).map(|l| normalized_cosine_lobe_factor(l as u32) * y_l0(l, -1.0)).collect();
    }
    let nodes = cap_nodes(alpha, n);
    let omega: f64 = nodes.iter().map(|k| k.2).sum();
    (0..bands).map(|l| nodes.iter().map(|&(_, qz, w)| w * y_l0(l, qz)).sum::<f64>() / omega).collect()
}

/// [`d_exact_with`] at [`U_NODES`] nodes.
#[must_use]
pub fn d_exact(alpha: f64, bands: usize) -> Vec<f64> {
    d_exact_with(alpha, bands, U_NODES)
}

/// The paper's analytic order-3 formula for `D` (printed after Eq. 15), `d = csc θ`,
/// `ď = sqrt(d² - 1)`, rearranged without cancellation (`d - ď = 1/(d + ď)`).
#[must_use]
pub fn d_paper_analytic(alpha: f64) -> [f64; 3] {
    let sp = PI.sqrt();
    if alpha <= 0.0 {
        // d → ∞: D_1 → -sqrt(3)/(3 sqrt π), D_2 → sqrt(5)/(8 sqrt π).
        return [0.5 / sp, -(3f64.sqrt()) / (3.0 * sp), 5f64.sqrt() / (8.0 * sp)];
    }
    let d = 1.0 / alpha;
    let dc = (d * d - 1.0).max(0.0).sqrt();
    // d - ď = 1 / (d + ď), without cancellation for small alpha.
    let dm = 1.0 / (d + dc);
    let d1 = -(3f64.sqrt()) * (2.0 * d * d * dm - dc + 1.0) / (6.0 * sp * d * dm);
    let d2 = 5f64.sqrt() * (6.0 * d.powi(4) * dm - 3.0 * dc * d * d - dc + 4.0) / (20.0 * sp * d * d * dm);
    [0.5 / sp, d1, d2]
}

/// The paper's polynomial fits of `D_0`, `D_1`, `D_2` (Fig. 4), in `α`, as printed.
#[must_use]
pub fn d_paper_fit(alpha: f64) -> [f64; 3] {
    let a = alpha;
    [
        0.28209,
        0.08432 * a * a - 0.25073 * a - 0.32494,
        -0.22230 * a * a * a + 0.22502 * a * a + 0.47398 * a + 0.15950,
    ]
}

/// The exact operator `M(θ)` of Eq. 16 (row-major `N × N`, `N <= 16`): the SH projection of
/// `v_θ(s) L̃(q̂(s))` is `M L̃`. Zero at `alpha = 0`.
#[must_use]
pub fn m_exact<const N: usize>(alpha: f64) -> Vec<f64> {
    m_exact_with::<N>(alpha, U_NODES)
}

/// [`m_exact`] with `n` nodes in `u`.
#[must_use]
pub fn m_exact_with<const N: usize>(alpha: f64, n: usize) -> Vec<f64> {
    let mut m = vec![0.0; N * N];
    if alpha <= 0.0 {
        return m;
    }
    let c2 = 1.0 - alpha * alpha;
    let (x, w) = gauss_legendre(n);
    for (&x, &w) in x.iter().zip(&w) {
        let u = 0.5 * alpha * (x + 1.0);
        let t = (c2 + u * u).sqrt();
        let st = (1.0 - t * t).max(0.0).sqrt();
        let k = t - u; // |q| along s
        let wu = 0.5 * alpha * w * u / t * (2.0 * PI / PHI_NODES as f64);
        for j in 0..PHI_NODES {
            let phi = 2.0 * PI * (j as f64 + 0.5) / PHI_NODES as f64;
            let s = [st * phi.cos(), st * phi.sin(), t];
            let q = [s[0] * k, s[1] * k, s[2] * k];
            let qh = normalize([q[0] / alpha, q[1] / alpha, (q[2] - 1.0) / alpha]);
            let ys = eval_basis::<f64, N>(s);
            let yq = eval_basis::<f64, N>(qh);
            for a in 0..N {
                let f = wu * ys[a];
                for b in 0..N {
                    m[a * N + b] += f * yq[b];
                }
            }
        }
    }
    m
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

/// The three indirect operators of §5 for a canonical proxy as `N × N` matrices acting on
/// `L̃` (row-major): point-sampled (Eq. 13, `V yᵀ(-z)`), averaged (Eq. 15, `V Dᵀ`) and exact
/// (Eq. 16).
#[must_use]
pub fn operators<const N: usize>(alpha: f64) -> [Vec<f64>; 3] {
    let bands = N.isqrt();
    let cap = Zh::<f64, 8>::cap(alpha.clamp(0.0, 1.0).asin()).0;
    let mut v = vec![0.0; N];
    let mut y_down = vec![0.0; N];
    let mut d_sh = vec![0.0; N];
    let d = d_exact(alpha, bands);
    for l in 0..bands {
        v[l * (l + 1)] = cap[l];
        y_down[l * (l + 1)] = y_l0(l, -1.0);
        d_sh[l * (l + 1)] = d[l];
    }
    let outer = |a: &[f64], b: &[f64]| -> Vec<f64> {
        let mut o = vec![0.0; N * N];
        for i in 0..N {
            for j in 0..N {
                o[i * N + j] = a[i] * b[j];
            }
        }
        o
    };
    [outer(&v, &y_down), outer(&v, &d_sh), m_exact::<N>(alpha)]
}

/// One row of Fig. 5: Frobenius norms `‖P - M‖`, `‖A - M‖` and `‖M‖` at `alpha`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct OperatorError {
    /// `α = sin θ`.
    pub alpha: f64,
    /// `‖P - M‖_F`, point-sampled (Eq. 13) against exact (Eq. 16).
    pub point_sampled: f64,
    /// `‖A - M‖_F`, averaged (Eq. 15) against exact.
    pub averaged: f64,
    /// `‖M‖_F`, for relative errors.
    pub exact_norm: f64,
}

/// Fig. 5's operator errors at `alpha`. The Frobenius norm is rotation invariant, so the
/// canonical frame gives the error for every proxy direction; it equals the RMS error over
/// lighting environments with i.i.d. unit-variance coefficients.
#[must_use]
pub fn operator_error<const N: usize>(alpha: f64) -> OperatorError {
    let [p, a, m] = operators::<N>(alpha);
    let fro = |x: &[f64]| x.iter().zip(&m).map(|(x, m)| (x - m) * (x - m)).sum::<f64>().sqrt();
    OperatorError {
        alpha,
        point_sampled: fro(&p),
        averaged: fro(&a),
        exact_norm: m.iter().map(|x| x * x).sum::<f64>().sqrt(),
    }
}

/// Relative squared error `∫₀¹ (f - g)² dα / ∫₀¹ g² dα` by Gauss-Legendre with `n` nodes.
#[must_use]
pub fn relative_squared_error(f: impl Fn(f64) -> f64, g: impl Fn(f64) -> f64, n: usize) -> f64 {
    let (x, w) = gauss_legendre(n);
    let (mut num, mut den) = (0.0, 0.0);
    for (&x, &w) in x.iter().zip(&w) {
        let a = 0.5 * (x + 1.0);
        let (fa, ga) = (f(a), g(a));
        num += w * (fa - ga) * (fa - ga);
        den += w * ga * ga;
    }
    num / den
}

/// Least-squares polynomial fit of degree `deg` to `g` on `[0, 1]` (continuous L2, by
/// Gauss-Legendre with `n` nodes): coefficients from the constant term up.
#[must_use]
pub fn polynomial_fit(g: impl Fn(f64) -> f64, deg: usize, n: usize) -> Vec<f64> {
    let (x, w) = gauss_legendre(n);
    let k = deg + 1;
    let mut ata = vec![0.0; k * k];
    let mut atb = vec![0.0; k];
    for (&x, &w) in x.iter().zip(&w) {
        let a = 0.5 * (x + 1.0);
        let ga = g(a);
        for i in 0..k {
            let pi = a.powi(i as i32);
            atb[i] += w * pi * ga;
            for j in 0..k {
                ata[i * k + j] += w * pi * a.powi(j as i32);
            }
        }
    }
    lightvol_sh::linalg::cholesky_solve(&ata, &atb, k).unwrap_or_else(|| vec![0.0; k])
}
