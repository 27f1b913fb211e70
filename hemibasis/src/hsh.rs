//! Hemispherical Harmonics (Gautron, Křivánek, Pattanaik & Bouatouch 2004), any order.
//!
//! Definition (Gautron et al. 2004, Eq. 4-5): the SH construction with `cos θ` replaced by
//! the shifted argument `t = 2 cos θ - 1` and the normalisation doubled for the half domain,
//!
//! ```text
//! H_l^m = √2 K̃_l^m cos(mφ) P_l^m(2 cos θ - 1)      (m > 0)
//! H_l^m = √2 K̃_l^|m| sin(|m|φ) P_l^|m|(2 cos θ - 1) (m < 0)
//! H_l^0 = K̃_l^0 P_l^0(2 cos θ - 1),   K̃_l^m = sqrt((2l+1)(l-|m|)! / (2π (l+|m|)!))
//! ```
//!
//! with the same index order and sign convention as lightvol-sh (no Condon-Shortley phase,
//! `m < 0` ↔ sine). In Cartesian form `(1 - t²)^{m/2} = 2^m (z(1-z))^{m/2}` and
//! `(z(1-z))^{m/2} cos(mφ) = (z/(1+z))^{m/2} Re (x+iy)^m`, which is what [`Hsh`] evaluates
//! (the shared separable form of the private `sep` module).
//!
//! Corrections to \[Ish11\] §1.8.3 (Eq. 1.22-1.32), each checked in this module's tests:
//! - Eq. 1.26: the square root covers only `30/π`: `H_2^-2 = 2 sqrt(30/π) · xyz/(1+z)`
//!   (the OCR'd form puts `xyz/(1+z)` under the root).
//! - Eq. 1.28: likewise `H_2^-1 = sqrt(30/π) · y (2z-1) sqrt(z/(1+z))`.
//! - Eq. 1.30: `H_2^1` has `cos φ`, not `sin φ` (the unsimplified form repeats Eq. 1.27).
//! - Eq. 1.23 vs 1.25 and Eq. 1.26: signs differ between the `θ` and Cartesian forms (mixed
//!   Condon-Shortley phase); here every function uses the phase-free sign, so
//!   `H_1^-1 = +sqrt(6/π) y sqrt(z/(1+z))` and `H_2^-2 = +sqrt(30/π) z(1-z) sin 2φ`.

use std::f64::consts::PI;

use crate::basis::{HemiBasis, forward_eval};
use crate::program::Program;
use crate::sep::{PolyEval, Radial, SepFn, Separable, Var, factorial, legendre_poly};

/// Hemispherical Harmonics with `bands` bands (`bands²` functions; 4 = 2 bands, 9 = 3 bands).
#[derive(Clone, Debug)]
pub struct Hsh {
    bands: usize,
    fam: Separable,
}

/// `K̃_l^m` of Gautron et al. 2004 (the SH factor with `4π` replaced by `2π`).
fn k_tilde(l: u32, m: u32) -> f64 {
    ((2 * l + 1) as f64 * factorial(l - m) / (2.0 * PI * factorial(l + m))).sqrt()
}

impl Hsh {
    /// HSH with `bands` bands.
    ///
    /// # Panics
    /// If `bands == 0` or `bands > 12` (beyond that the monomial form loses f32 accuracy).
    #[must_use]
    pub fn new(bands: usize) -> Self {
        assert!((1..=12).contains(&bands), "HSH bands must be in 1..=12");
        let mut fns = Vec::with_capacity(bands * bands);
        for l in 0..bands as u32 {
            for m in -(l as i32)..=(l as i32) {
                let am = m.unsigned_abs();
                let norm = if m == 0 { 1.0 } else { std::f64::consts::SQRT_2 };
                // (1 - t²)^{m/2} = 2^m (z(1-z))^{m/2}: the 2^m goes into the scale.
                let scale = norm * k_tilde(l, am) * f64::from(1u32 << am);
                fns.push(SepFn { scale, poly: legendre_poly(l, am), m });
            }
        }
        Self { bands, fam: Separable::new(Var::TwoZMinusOne, Radial::SqrtZOverOnePlusZ, false, fns) }
    }

    /// Band count.
    #[must_use]
    pub fn bands(&self) -> usize {
        self.bands
    }

    fn eval<T: PolyEval>(&self, dir: [T; 3], out: &mut [T]) {
        self.fam.eval(dir, out);
    }

    /// Slow textbook evaluation from angles (Gautron et al. 2004, Eq. 4-5), for tests.
    #[must_use]
    pub fn reference(&self, dir: [f64; 3]) -> Vec<f64> {
        let phi = dir[1].atan2(dir[0]);
        let t = 2.0 * dir[2] - 1.0;
        let mut out = Vec::with_capacity(self.bands * self.bands);
        for l in 0..self.bands as u32 {
            for m in -(l as i32)..=(l as i32) {
                let am = m.unsigned_abs();
                let p = lightvol_sh::reference::legendre_p(l, am, t) * k_tilde(l, am);
                out.push(match m {
                    0 => p,
                    _ if m > 0 => std::f64::consts::SQRT_2 * p * (f64::from(m) * phi).cos(),
                    _ => std::f64::consts::SQRT_2 * p * (f64::from(am) * phi).sin(),
                });
            }
        }
        out
    }
}

impl HemiBasis for Hsh {
    fn name(&self) -> &'static str {
        "hsh"
    }
    fn label(&self) -> &'static str {
        "Hemispherical Harmonics"
    }
    fn len(&self) -> usize {
        self.fam.len()
    }
    fn orthonormal(&self) -> bool {
        true
    }
    fn order(&self) -> usize {
        self.bands - 1
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

    /// Separable Cartesian form vs. angle form: rounding of acos/atan2/cos.
    const FORM_TOL: f64 = 1e-12;

    #[test]
    fn orthonormal_on_hemisphere() {
        for bands in 1..=6 {
            assert_orthonormal(&Hsh::new(bands));
        }
    }

    #[test]
    fn fast_matches_reference() {
        let h = Hsh::new(6);
        let mut v = vec![0.0; 36];
        for &d in TEST_DIRS {
            h.eval_f64(d, &mut v);
            let r = h.reference(d);
            for i in 0..36 {
                assert!((v[i] - r[i]).abs() < FORM_TOL, "i={i} at {d:?}: {} vs {}", v[i], r[i]);
            }
        }
    }

    /// The corrected Cartesian forms of \[Ish11\] Eq. 1.22-1.32 (see the module docs).
    #[test]
    fn corrected_thesis_closed_forms() {
        let h = Hsh::new(3);
        let mut v = vec![0.0; 9];
        for &[x, y, z] in TEST_DIRS {
            h.eval_f64([x, y, z], &mut v);
            let q = (z / (1.0 + z)).sqrt();
            let want = [
                1.0 / (2.0 * PI).sqrt(),
                (6.0 / PI).sqrt() * y * q,
                (3.0 / (2.0 * PI)).sqrt() * (2.0 * z - 1.0),
                (6.0 / PI).sqrt() * x * q,
                2.0 * (30.0 / PI).sqrt() * x * y * z / (1.0 + z),
                (30.0 / PI).sqrt() * y * (2.0 * z - 1.0) * q,
                (5.0 / (2.0 * PI)).sqrt() * (6.0 * z * z - 6.0 * z + 1.0),
                (30.0 / PI).sqrt() * x * (2.0 * z - 1.0) * q,
                (30.0 / PI).sqrt() * z * (x * x - y * y) / (1.0 + z),
            ];
            for i in 0..9 {
                assert!((v[i] - want[i]).abs() < FORM_TOL, "H[{i}] at {:?}", [x, y, z]);
            }
        }
    }
}
