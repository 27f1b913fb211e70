//! Makhotkin's hemispherical harmonics (Makhotkin 1996), from shifted Jacobi polynomials.
//!
//! Definition: with `t = 2 cos θ - 1`, `n = l - |m|`,
//!
//! ```text
//! M_l^m = N_l^m sqrt(cos θ) (1 - t²)^{|m|/2} P_n^{(|m|, |m|+1)}(t) · {cos(mφ), 1, sin(|m|φ)}
//! ```
//!
//! for `m > 0`, `m = 0`, `m < 0`. The factor `sqrt(cos θ)` turns orthogonality of
//! `P_n^{(α, β)}` under the weight `(1-t)^α (1+t)^β` into orthogonality under `dω` on the
//! hemisphere: `cos θ (1-t²)^m dz = ¼ (1-t)^m (1+t)^{m+1} dt`, hence `β = α + 1`. The
//! normalisation follows from the Jacobi norm
//! `h_n = 2^{α+β+1} (n+α)! (n+β)! / ((2n+α+β+1) (n+α+β)! n!)`:
//! `N = 1 / sqrt(c_φ h_n / 4)`, `c_φ = 2π` for `m = 0`, `π` otherwise. For `l <= 2` these
//! are exactly the unsimplified forms of \[Ish11\] Eq. 1.33-1.45 (checked in the tests); the
//! thesis and this crate ship 4 and 9 functions, and higher orders are the same family.
//!
//! Corrections to \[Ish11\] §1.8.4 (each checked in this module's tests):
//! - Eq. 1.33: the Cartesian form is `sqrt(z)/sqrt(π)`, not `z/sqrt(π)`.
//! - Eq. 1.42: `4(2 cos θ - 2) = 8(z - 1)`, not `16(z - 1)`:
//!   `M_2^0 = sqrt(3/π) sqrt(z) (10z² - 12z + 3)`; the square root covers only `3/π`.
//! - Eq. 1.34/1.36 and 1.37/1.45 attach `cos` to negative and `sin` to positive `m`; this
//!   crate uses the lightvol-sh convention (`m < 0` ↔ sine) for every basis, so the thesis's
//!   `M_1^-1` is `M_1^1` here and vice versa (same for `m = ±2`).

use std::f64::consts::PI;

use crate::basis::{HemiBasis, forward_eval};
use crate::program::Program;
use crate::sep::{Poly, PolyEval, Radial, SepFn, Separable, Var, factorial};

/// Makhotkin's basis with `bands` bands (`bands²` functions; 4 = 2 bands, 9 = 3 bands).
#[derive(Clone, Debug)]
pub struct Makhotkin {
    bands: usize,
    fam: Separable,
}

fn binomial(n: u32, k: u32) -> f64 {
    if k > n { 0.0 } else { factorial(n) / (factorial(k) * factorial(n - k)) }
}

/// `P_n^{(α, β)}(t)` as a polynomial in `t`, by the explicit sum
/// `Σ_s C(n+α, n-s) C(n+β, s) ((t-1)/2)^s ((t+1)/2)^{n-s}`.
fn jacobi_poly(n: u32, a: u32, b: u32) -> Poly {
    let minus = Poly::linear(-0.5, 0.5);
    let plus = Poly::linear(0.5, 0.5);
    let mut sum = Poly::constant(0.0);
    for s in 0..=n {
        let mut term = Poly::constant(binomial(n + a, n - s) * binomial(n + b, s));
        for _ in 0..s {
            term = term.mul(&minus);
        }
        for _ in 0..(n - s) {
            term = term.mul(&plus);
        }
        sum = sum.add(&term);
    }
    sum
}

/// `P_n^{(α, β)}(t)` by the three-term recurrence (Abramowitz & Stegun 22.7.1), for tests.
fn jacobi_recurrence(n: u32, a: f64, b: f64, t: f64) -> f64 {
    let mut p0 = 1.0;
    if n == 0 {
        return p0;
    }
    let mut p1 = 0.5 * ((a + b + 2.0) * t + (a - b));
    for k in 2..=n {
        let k = f64::from(k);
        let c = 2.0 * k + a + b;
        let a1 = 2.0 * k * (k + a + b) * (c - 2.0);
        let a2 = (c - 1.0) * (a * a - b * b);
        let a3 = (c - 2.0) * (c - 1.0) * c;
        let a4 = 2.0 * (k + a - 1.0) * (k + b - 1.0) * c;
        let p2 = ((a2 + a3 * t) * p1 - a4 * p0) / a1;
        p0 = p1;
        p1 = p2;
    }
    p1
}

/// `N_l^m` (module docs).
fn norm(l: u32, m: u32) -> f64 {
    let n = l - m;
    let (a, b) = (m, m + 1);
    let h = 2f64.powi((a + b + 1) as i32) * factorial(n + a) * factorial(n + b)
        / (f64::from(2 * n + a + b + 1) * factorial(n + a + b) * factorial(n));
    let c_phi = if m == 0 { 2.0 * PI } else { PI };
    1.0 / (c_phi * h / 4.0).sqrt()
}

impl Makhotkin {
    /// Makhotkin's basis with `bands` bands.
    ///
    /// # Panics
    /// If `bands == 0` or `bands > 10`.
    #[must_use]
    pub fn new(bands: usize) -> Self {
        assert!((1..=10).contains(&bands), "Makhotkin bands must be in 1..=10");
        let mut fns = Vec::with_capacity(bands * bands);
        for l in 0..bands as u32 {
            for m in -(l as i32)..=(l as i32) {
                let am = m.unsigned_abs();
                // (1 - t²)^{m/2} = 2^m (z(1-z))^{m/2}.
                let scale = norm(l, am) * f64::from(1u32 << am);
                fns.push(SepFn { scale, poly: jacobi_poly(l - am, am, am + 1), m });
            }
        }
        Self { bands, fam: Separable::new(Var::TwoZMinusOne, Radial::SqrtZOverOnePlusZ, true, fns) }
    }

    /// Band count.
    #[must_use]
    pub fn bands(&self) -> usize {
        self.bands
    }

    fn eval<T: PolyEval>(&self, dir: [T; 3], out: &mut [T]) {
        self.fam.eval(dir, out);
    }

    /// Slow evaluation from angles with the Jacobi recurrence, for tests.
    #[must_use]
    pub fn reference(&self, dir: [f64; 3]) -> Vec<f64> {
        let phi = dir[1].atan2(dir[0]);
        let t = 2.0 * dir[2] - 1.0;
        let mut out = Vec::with_capacity(self.bands * self.bands);
        for l in 0..self.bands as u32 {
            for m in -(l as i32)..=(l as i32) {
                let am = m.unsigned_abs();
                let amf = f64::from(am);
                let radial = dir[2].max(0.0).sqrt()
                    * (1.0 - t * t).max(0.0).powf(amf / 2.0)
                    * jacobi_recurrence(l - am, amf, amf + 1.0, t)
                    * norm(l, am);
                out.push(match m {
                    0 => radial,
                    _ if m > 0 => radial * (amf * phi).cos(),
                    _ => radial * (amf * phi).sin(),
                });
            }
        }
        out
    }
}

impl HemiBasis for Makhotkin {
    fn name(&self) -> &'static str {
        "makhotkin"
    }
    fn label(&self) -> &'static str {
        "Makhotkin"
    }
    fn len(&self) -> usize {
        self.fam.len()
    }
    fn orthonormal(&self) -> bool {
        true
    }
    fn order(&self) -> usize {
        self.bands
    }
    fn program(&self) -> Program {
        self.fam.program()
    }
    forward_eval!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::{TEST_DIRS, assert_orthonormal};

    /// Separable Cartesian form vs. angle form: rounding of acos/atan2/cos/powf.
    const FORM_TOL: f64 = 1e-12;

    #[test]
    fn orthonormal_on_hemisphere() {
        for bands in 1..=6 {
            assert_orthonormal(&Makhotkin::new(bands));
        }
    }

    #[test]
    fn jacobi_sum_matches_recurrence() {
        for n in 0..6 {
            for (a, b) in [(0, 1), (1, 2), (2, 3), (3, 4)] {
                let p = jacobi_poly(n, a, b);
                for &t in &[-1.0, -0.4, 0.1, 0.9, 1.0] {
                    let r = jacobi_recurrence(n, f64::from(a), f64::from(b), t);
                    assert!((p.eval(t) - r).abs() < FORM_TOL * (1.0 + r.abs()), "n={n} a={a}");
                }
            }
        }
    }

    #[test]
    fn fast_matches_reference() {
        let h = Makhotkin::new(5);
        let mut v = vec![0.0; 25];
        for &d in TEST_DIRS {
            h.eval_f64(d, &mut v);
            let r = h.reference(d);
            for i in 0..25 {
                assert!((v[i] - r[i]).abs() < FORM_TOL, "i={i} at {d:?}: {} vs {}", v[i], r[i]);
            }
        }
    }

    /// The corrected Cartesian forms of \[Ish11\] Eq. 1.33-1.45 (module docs).
    #[test]
    fn corrected_thesis_closed_forms() {
        let h = Makhotkin::new(3);
        let mut v = vec![0.0; 9];
        for &[x, y, z] in TEST_DIRS {
            h.eval_f64([x, y, z], &mut v);
            let (sz, q) = (z.sqrt(), 1.0 / (1.0 + z).sqrt());
            let (a, b) = ((3.0 / PI).sqrt(), (15.0 / PI).sqrt());
            let want = [
                sz / PI.sqrt(),
                2.0 * a * y * z * q,
                sz * (6.0 * z - 4.0) / (2.0 * PI).sqrt(),
                2.0 * a * x * z * q,
                4.0 * b * x * y * z * sz / (1.0 + z),
                a * y * z * (10.0 * z - 6.0) * q,
                a * sz * (1.0 + 8.0 * (z - 1.0) + 10.0 * (z - 1.0) * (z - 1.0)),
                a * x * z * (10.0 * z - 6.0) * q,
                2.0 * b * z * sz * (x * x - y * y) / (1.0 + z),
            ];
            for i in 0..9 {
                assert!((v[i] - want[i]).abs() < FORM_TOL, "M[{i}] at {:?}", [x, y, z]);
            }
        }
    }
}
