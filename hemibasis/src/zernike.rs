//! Koenderink's hemispherical Zernike basis (Koenderink, van Doorn & Stavridi 1996).
//!
//! Definition: the hemisphere is mapped to the unit disk by the equal-area (Lambert
//! azimuthal) map `ρ = sqrt(2) sin(θ/2) = sqrt(1 - cos θ)`, on which `dω = 2 dA`, and the
//! disk-orthonormal Zernike polynomials are divided by `sqrt(2)`:
//!
//! ```text
//! Z_n^m = sqrt(ε_m (n+1) / (2π)) R_n^|m|(ρ) · {cos(mφ), 1, sin(|m|φ)},   ε_0 = 1, ε_m = 2
//! R_n^m(ρ) = Σ_k (-1)^k (n-k)! / (k! ((n+m)/2-k)! ((n-m)/2-k)!) ρ^{n-2k}
//! ```
//!
//! for `n = 0..=order`, `m = -n, -n+2, …, n` (index `n(n+1)/2 + (m+n)/2`): 3 functions up to
//! `n = 1`, 6 up to `n = 2`. In Cartesian form `ρ^m cos(mφ) = Re (x+iy)^m / (1+z)^{m/2}`.
//!
//! Corrections to \[Ish11\] §1.8.5 (each checked in this module's tests):
//! - Eq. 1.48: `Z_1^1 = +sqrt(2/π) x / sqrt(1+z)` (the Cartesian form has a stray minus; the
//!   angle form `(2/sqrt(π)) cos φ sin(θ/2)` is right).
//! - Eq. 1.49: the Cartesian form `-2 sqrt(3/π) xy/(1+z)` keeps the angle form's minus sign;
//!   this crate uses the phase-free sign of every other basis, `Z_2^-2 = +2 sqrt(3/π) xy/(1+z)`.
//!   Likewise `Z_1^-1 = +sqrt(2/π) y / sqrt(1+z)`. Signs do not change the spanned space.

use std::f64::consts::PI;

use crate::basis::{HemiBasis, forward_eval};
use crate::program::Program;
use crate::sep::{Poly, PolyEval, Radial, SepFn, Separable, Var, factorial};

/// Hemispherical Zernike basis up to radial order `order` (`(order+1)(order+2)/2`
/// functions; 3 = order 1, 6 = order 2).
#[derive(Clone, Debug)]
pub struct Zernike {
    order: usize,
    fam: Separable,
}

/// The `(n, m)` pairs in index order.
fn indices(order: usize) -> impl Iterator<Item = (u32, i32)> {
    (0..=order as u32).flat_map(|n| (0..=n).map(move |j| (n, 2 * j as i32 - n as i32)))
}

/// Coefficients of `R_n^m(ρ) / ρ^m` as a polynomial in `v = ρ²`.
fn radial_poly(n: u32, m: u32) -> Poly {
    let kmax = (n - m) / 2;
    let mut c = vec![0.0; kmax as usize + 1];
    for k in 0..=kmax {
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        let a = sign * factorial(n - k)
            / (factorial(k) * factorial((n + m) / 2 - k) * factorial((n - m) / 2 - k));
        // ρ^{n-2k} / ρ^m = v^{(n-m)/2 - k}.
        c[(kmax - k) as usize] = a;
    }
    Poly(c)
}

/// Normalisation `sqrt(ε_m (n+1) / (2π))`.
fn norm(n: u32, m: i32) -> f64 {
    let eps = if m == 0 { 1.0 } else { 2.0 };
    (eps * f64::from(n + 1) / (2.0 * PI)).sqrt()
}

impl Zernike {
    /// Zernike basis up to radial order `order`.
    ///
    /// # Panics
    /// If `order > 12`.
    #[must_use]
    pub fn new(order: usize) -> Self {
        assert!(order <= 12, "Zernike order must be at most 12");
        let fns = indices(order)
            .map(|(n, m)| SepFn { scale: norm(n, m), poly: radial_poly(n, m.unsigned_abs()), m })
            .collect();
        Self { order, fam: Separable::new(Var::OneMinusZ, Radial::InvSqrtOnePlusZ, false, fns) }
    }

    /// The basis with `count` functions (3, 6, 10, …), if `count` is triangular.
    #[must_use]
    pub fn with_count(count: usize) -> Option<Self> {
        (0..=12).find(|o| (o + 1) * (o + 2) / 2 == count).map(Self::new)
    }

    fn eval<T: PolyEval>(&self, dir: [T; 3], out: &mut [T]) {
        self.fam.eval(dir, out);
    }

    /// Slow evaluation from angles (`ρ = sqrt(2) sin(θ/2)`, explicit radial sum in `ρ`).
    #[must_use]
    pub fn reference(&self, dir: [f64; 3]) -> Vec<f64> {
        let theta = dir[2].clamp(-1.0, 1.0).acos();
        let phi = dir[1].atan2(dir[0]);
        let rho = std::f64::consts::SQRT_2 * (0.5 * theta).sin();
        indices(self.order)
            .map(|(n, m)| {
                let am = m.unsigned_abs();
                let mut r = 0.0;
                for k in 0..=(n - am) / 2 {
                    let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                    r += sign * factorial(n - k)
                        / (factorial(k) * factorial((n + am) / 2 - k) * factorial((n - am) / 2 - k))
                        * rho.powi((n - 2 * k) as i32);
                }
                let ang = match m {
                    0 => 1.0,
                    _ if m > 0 => (f64::from(m) * phi).cos(),
                    _ => (f64::from(am) * phi).sin(),
                };
                norm(n, m) * r * ang
            })
            .collect()
    }
}

impl HemiBasis for Zernike {
    fn name(&self) -> &'static str {
        "zernike"
    }
    fn label(&self) -> &'static str {
        "Zernike"
    }
    fn len(&self) -> usize {
        self.fam.len()
    }
    fn orthonormal(&self) -> bool {
        true
    }
    fn order(&self) -> usize {
        self.order
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

    /// Separable Cartesian form vs. angle form: rounding of acos/atan2/sin/powi.
    const FORM_TOL: f64 = 1e-12;

    #[test]
    fn orthonormal_on_hemisphere() {
        for order in 0..=6 {
            assert_orthonormal(&Zernike::new(order));
        }
    }

    #[test]
    fn counts() {
        assert_eq!(Zernike::new(1).len(), 3);
        assert_eq!(Zernike::new(2).len(), 6);
        assert_eq!(Zernike::with_count(6).map(|z| z.order), Some(2));
        assert!(Zernike::with_count(4).is_none());
    }

    #[test]
    fn fast_matches_reference() {
        let h = Zernike::new(6);
        let mut v = vec![0.0; h.len()];
        for &d in TEST_DIRS {
            h.eval_f64(d, &mut v);
            let r = h.reference(d);
            for i in 0..v.len() {
                assert!((v[i] - r[i]).abs() < FORM_TOL, "i={i} at {d:?}: {} vs {}", v[i], r[i]);
            }
        }
    }

    /// The corrected Cartesian forms of \[Ish11\] Eq. 1.46-1.51 (module docs).
    #[test]
    fn corrected_thesis_closed_forms() {
        let h = Zernike::new(2);
        let mut v = vec![0.0; 6];
        for &[x, y, z] in TEST_DIRS {
            h.eval_f64([x, y, z], &mut v);
            let q = 1.0 / (1.0 + z).sqrt();
            let want = [
                1.0 / (2.0 * PI).sqrt(),
                (2.0 / PI).sqrt() * y * q,
                (2.0 / PI).sqrt() * x * q,
                2.0 * (3.0 / PI).sqrt() * x * y / (1.0 + z),
                (3.0 / (2.0 * PI)).sqrt() * (1.0 - 2.0 * z),
                (3.0 / PI).sqrt() * (x * x - y * y) / (1.0 + z),
            ];
            for i in 0..6 {
                assert!((v[i] - want[i]).abs() < FORM_TOL, "Z[{i}] at {:?}", [x, y, z]);
            }
        }
    }
}
