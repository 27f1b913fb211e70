//! Real spherical harmonics used as a hemispherical basis (always compiled).
//!
//! The functions are lightvol-sh's (`y_lm`, flat index `l(l+1)+m`, no Condon-Shortley
//! phase), restricted to `z >= 0`. On the hemisphere they are *not* orthonormal (functions of
//! opposite `z`-parity overlap), so projection and the IMSE fit use the inverse Gram matrix.

use std::f64::consts::PI;

use lightvol_sh::eval::eval_into;

use crate::basis::{HemiBasis, forward_eval};
use crate::program::Program;
use crate::sep::{PolyEval, Radial, SepFn, Separable, Var, factorial, legendre_poly};

/// The first `bands` bands of real SH (`bands²` functions) on the upper hemisphere.
#[derive(Clone, Debug)]
pub struct ShBasis {
    bands: usize,
}

impl ShBasis {
    /// SH with `bands` bands (4 coefficients: 2 bands; 9: 3 bands).
    ///
    /// # Panics
    /// If `bands == 0` or `bands > 16`.
    #[must_use]
    pub fn new(bands: usize) -> Self {
        assert!((1..=16).contains(&bands), "SH bands must be in 1..=16");
        Self { bands }
    }

    /// Band count.
    #[must_use]
    pub fn bands(&self) -> usize {
        self.bands
    }

    fn eval<T: PolyEval>(&self, dir: [T; 3], out: &mut [T]) {
        eval_into(self.bands, dir, out);
    }

    /// SH as a separable family (Sloan's Cartesian form): `y_lm = √2 K_l^m P̄_l^m(z) T_m(x, y)`.
    pub(crate) fn family(bands: usize) -> Separable {
        let mut fns = Vec::with_capacity(bands * bands);
        for l in 0..bands as u32 {
            for m in -(l as i32)..=(l as i32) {
                let am = m.unsigned_abs();
                let k = ((2 * l + 1) as f64 * factorial(l - am) / (4.0 * PI * factorial(l + am))).sqrt();
                let scale = if m == 0 { k } else { std::f64::consts::SQRT_2 * k };
                fns.push(SepFn { scale, poly: legendre_poly(l, am), m });
            }
        }
        Separable::new(Var::Z, Radial::One, false, fns)
    }
}

impl HemiBasis for ShBasis {
    fn name(&self) -> &'static str {
        "sh"
    }
    fn label(&self) -> &'static str {
        "Spherical Harmonics"
    }
    fn len(&self) -> usize {
        self.bands * self.bands
    }
    fn orthonormal(&self) -> bool {
        false
    }
    fn order(&self) -> usize {
        self.bands - 1
    }
    fn program(&self) -> Program {
        Self::family(self.bands).program()
    }
    forward_eval!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::{GRAM_TOL, TEST_DIRS, gram_gl};

    /// Cartesian separable form vs. lightvol-sh's generated code: rounding.
    const FORM_TOL: f64 = 1e-13;

    #[test]
    fn separable_form_matches_lightvol_sh() {
        let fam = ShBasis::family(5);
        let sh = ShBasis::new(5);
        for &d in TEST_DIRS {
            let mut a = vec![0.0; 25];
            let mut b = vec![0.0; 25];
            fam.eval(d, &mut a);
            sh.eval_f64(d, &mut b);
            for i in 0..25 {
                assert!((a[i] - b[i]).abs() < FORM_TOL, "i={i} at {d:?}: {} vs {}", a[i], b[i]);
            }
        }
    }

    /// On the hemisphere, `∫_H y_i² = 1/2` (the square is even in z) and functions of equal
    /// z-parity (`l + m` even or odd) stay orthogonal; opposite parities overlap, which is why
    /// SH needs the inverse Gram matrix here.
    #[test]
    fn hemispherical_gram_structure() {
        let g = gram_gl(&ShBasis::new(4));
        let mut overlap = 0.0f64;
        for i in 0..16 {
            for j in 0..16 {
                let (li, mi) = lightvol_sh::index::sh_lm(i);
                let (lj, mj) = lightvol_sh::index::sh_lm(j);
                let same_parity = (li as i32 + mi - lj as i32 - mj).rem_euclid(2) == 0;
                if i == j {
                    assert!((g[i][j] - 0.5).abs() < GRAM_TOL);
                } else if same_parity {
                    assert!(g[i][j].abs() < GRAM_TOL, "G[{i}][{j}] = {}", g[i][j]);
                } else {
                    overlap = overlap.max(g[i][j].abs());
                }
            }
        }
        // e.g. <y00, y10>_H = sqrt(3)/4.
        assert!((g[0][2] - 3f64.sqrt() / 4.0).abs() < GRAM_TOL);
        assert!(overlap > 0.1);
    }
}
