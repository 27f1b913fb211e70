//! The H-basis (Habel & Wimmer 2010) and the modified H-basis (\[Ish11\] §1.8.7).
//!
//! H-basis (Habel & Wimmer 2010, "Efficient Irradiance Normal Mapping", I3D; \[Ish11\]
//! Eq. 1.52-1.57), orthonormal on the upper hemisphere:
//!
//! ```text
//! H1 = 1/sqrt(2π)            H2 = sqrt(3/(2π)) y        H3 = sqrt(3/(2π)) (2z - 1)
//! H4 = sqrt(3/(2π)) x        H5 = sqrt(15/(2π)) xy      H6 = ½ sqrt(15/(2π)) (x² - y²)
//! ```
//!
//! The modified H-basis (\[Ish11\] Eq. 1.58) replaces `H3` by `sqrt(3/(2π)) (1 - z)`, so that
//! `H1` alone evaluates the lightmap at the unperturbed normal. It spans the same space as the
//! H-basis but is not orthogonal: its Gram matrix is the identity except
//! `G_13 = G_31 = sqrt(3)/2` (`∫_H (1 - z) dω = π`), and projection uses `G⁻¹`.
//!
//! \[Ish11\] Listing 2.1's SH → modified-H constants all agree with the matrix derived here
//! (test `sh_to_modified_h_matrix_matches_listing_2_1`); in Listing 2.2 `1.54509` is
//! `sqrt(15/(2π)) = 1.5450968…` truncated (correctly rounded: 1.54510).
//!
//! Correction to \[Ish11\] §1.8.6: Eq. 1.53 prints `sqrt(3/(2π) y)`; the root covers only
//! `3/(2π)`. Eq. 1.56's middle form `½ sqrt(15/(2π)) sin 2φ sin²θ` equals `sqrt(15/(2π)) xy`
//! because `sin 2φ sin²θ = 2xy`; both are right.

use std::f64::consts::PI;

use lightvol_sh::Real;

use crate::basis::{HemiBasis, forward_eval};
use crate::program::{Expr, Program};

/// Constants `(1/sqrt(2π), sqrt(3/(2π)), sqrt(15/(2π)))`.
fn consts() -> (f64, f64, f64) {
    (1.0 / (2.0 * PI).sqrt(), (3.0 / (2.0 * PI)).sqrt(), (15.0 / (2.0 * PI)).sqrt())
}

/// The H-basis (`modified == false`) or the modified H-basis, with 4 or 6 functions.
#[derive(Clone, Copy, Debug)]
pub struct HBasis {
    len: usize,
    modified: bool,
}

impl HBasis {
    /// The H-basis with `len` (4 or 6) functions, or `None`.
    #[must_use]
    pub fn new(len: usize) -> Option<Self> {
        matches!(len, 4 | 6).then_some(Self { len, modified: false })
    }

    /// The modified H-basis with `len` (4 or 6) functions, or `None`.
    #[must_use]
    pub fn modified(len: usize) -> Option<Self> {
        matches!(len, 4 | 6).then_some(Self { len, modified: true })
    }

    /// True for the modified H-basis.
    #[must_use]
    pub fn is_modified(&self) -> bool {
        self.modified
    }

    fn eval<T: Real>(&self, dir: [T; 3], out: &mut [T]) {
        let (c1, c3, c15) = consts();
        let [x, y, z] = dir;
        let one = T::ONE;
        out[0] = T::from_f64(c1);
        out[1] = T::from_f64(c3) * y;
        out[2] = T::from_f64(c3) * if self.modified { one - z } else { z + z - one };
        out[3] = T::from_f64(c3) * x;
        if self.len == 6 {
            out[4] = T::from_f64(c15) * x * y;
            out[5] = T::from_f64(0.5 * c15) * (x * x - y * y);
        }
    }

    /// Slow evaluation from angles (\[Ish11\] Eq. 1.52-1.58, middle forms), for tests.
    #[must_use]
    pub fn reference(&self, dir: [f64; 3]) -> Vec<f64> {
        let theta = dir[2].clamp(-1.0, 1.0).acos();
        let phi = dir[1].atan2(dir[0]);
        let (c1, c3, c15) = consts();
        let (st, ct) = (theta.sin(), theta.cos());
        let h3 = if self.modified { c3 * (1.0 - ct) } else { c3 * (2.0 * ct - 1.0) };
        let mut v = vec![c1, c3 * phi.sin() * st, h3, c3 * phi.cos() * st];
        if self.len == 6 {
            v.push(0.5 * c15 * (2.0 * phi).sin() * st * st);
            v.push(0.5 * c15 * (2.0 * phi).cos() * st * st);
        }
        v
    }
}

impl HemiBasis for HBasis {
    fn name(&self) -> &'static str {
        if self.modified { "hbasis_mod" } else { "hbasis" }
    }
    fn label(&self) -> &'static str {
        if self.modified { "Modified H-basis" } else { "H-basis" }
    }
    fn len(&self) -> usize {
        self.len
    }
    fn orthonormal(&self) -> bool {
        !self.modified
    }
    fn order(&self) -> usize {
        2
    }
    fn program(&self) -> Program {
        let (c1, c3, c15) = consts();
        let mut p = Program::default();
        p.outputs.push(Expr::num(c1));
        p.outputs.push(Expr::num(c3) * Expr::Y);
        p.outputs.push(if self.modified {
            Expr::num(c3) * (Expr::num(1.0) - Expr::Z)
        } else {
            Expr::num(c3) * (Expr::num(2.0) * Expr::Z - Expr::num(1.0))
        });
        p.outputs.push(Expr::num(c3) * Expr::X);
        if self.len == 6 {
            p.outputs.push(Expr::num(c15) * Expr::X * Expr::Y);
            p.outputs.push(Expr::num(0.5 * c15) * (Expr::X * Expr::X - Expr::Y * Expr::Y));
        }
        p
    }
    forward_eval!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::{GRAM_TOL, TEST_DIRS, assert_orthonormal, gram_gl};

    /// Polynomial vs. angle form: rounding of acos/atan2/sin/cos.
    const FORM_TOL: f64 = 1e-13;

    #[test]
    fn hbasis_orthonormal_on_hemisphere() {
        assert_orthonormal(&HBasis::new(4).unwrap());
        assert_orthonormal(&HBasis::new(6).unwrap());
    }

    #[test]
    fn modified_gram_matches_analytic() {
        for len in [4, 6] {
            let b = HBasis::modified(len).unwrap();
            let g = gram_gl(&b);
            // Analytic: identity except <H1, H3mod> = (1/sqrt(2π)) sqrt(3/(2π)) π = sqrt(3)/2.
            for i in 0..len {
                for j in 0..len {
                    let want = if i == j {
                        1.0
                    } else if (i, j) == (0, 2) || (i, j) == (2, 0) {
                        3f64.sqrt() / 2.0
                    } else {
                        0.0
                    };
                    assert!((g[i][j] - want).abs() < GRAM_TOL, "G[{i}][{j}] = {}", g[i][j]);
                }
            }
        }
    }

    #[test]
    fn fast_matches_reference() {
        for b in [HBasis::new(6).unwrap(), HBasis::modified(6).unwrap()] {
            let mut v = vec![0.0; 6];
            for &d in TEST_DIRS {
                b.eval_f64(d, &mut v);
                let r = b.reference(d);
                for i in 0..6 {
                    assert!((v[i] - r[i]).abs() < FORM_TOL, "i={i} at {d:?}");
                }
            }
        }
    }

    /// \[Ish11\] Listing 2.1's SH-irradiance → modified-H constants, `(row, sh index, printed)`.
    #[allow(clippy::approx_constant, reason = "the thesis's printed values, compared on purpose")]
    const LISTING_2_1: &[(usize, usize, f64)] = &[
        (0, 0, 0.70711),
        (0, 2, 1.2247),
        (0, 6, 1.1859),
        (1, 1, 0.70711),
        (1, 5, 0.59293),
        (2, 2, -0.70711),
        (2, 6, -1.3693),
        (3, 3, 0.70711),
        (3, 7, 0.59293),
        (4, 4, 0.70711),
        (5, 8, 0.70711),
    ];

    /// Our matrix is exact to rounding of the quadrature and the Cholesky solve.
    const MATRIX_TOL: f64 = 1e-12;

    #[test]
    fn sh_to_modified_h_matrix_matches_listing_2_1() {
        let m = HBasis::modified(6).unwrap().as_dyn().sh_irradiance_matrix(3);
        // Exact values: 1/sqrt2; <y10, ·> gives sqrt(3/2) and -1/sqrt2; <y20, H3> = sqrt15/(4 sqrt2)
        // gives sqrt3 · that and -2 · that; <y2±1, H2|H4> = 3 sqrt5 / (8 sqrt2).
        let r2 = 2f64.sqrt();
        let h3y20 = 15f64.sqrt() / (4.0 * r2);
        let exact = [
            (0, 0, 1.0 / r2),
            (0, 2, 1.5f64.sqrt()),
            (0, 6, 3f64.sqrt() * h3y20),
            (1, 1, 1.0 / r2),
            (1, 5, 3.0 * 5f64.sqrt() / (8.0 * r2)),
            (2, 2, -1.0 / r2),
            (2, 6, -2.0 * h3y20),
            (3, 3, 1.0 / r2),
            (3, 7, 3.0 * 5f64.sqrt() / (8.0 * r2)),
            (4, 4, 1.0 / r2),
            (5, 8, 1.0 / r2),
        ];
        for i in 0..6 {
            for j in 0..9 {
                let want = exact.iter().find(|e| e.0 == i && e.1 == j).map_or(0.0, |e| e.2);
                assert!((m[(i, j)] - want).abs() < MATRIX_TOL, "M[{i}][{j}] = {} vs {want}", m[(i, j)]);
            }
        }
        // Every printed constant agrees with ours to half a unit in its last printed digit.
        for &(i, j, printed) in LISTING_2_1 {
            let decimals = format!("{printed}").split('.').nth(1).map_or(0, str::len) as i32;
            let half_ulp = 0.5 * 10f64.powi(-decimals);
            assert!(
                (m[(i, j)] - printed).abs() <= half_ulp,
                "M[{i}][{j}] = {} vs printed {printed}",
                m[(i, j)]
            );
        }
    }

    /// Listing 2.2's evaluation constants are the basis constants, correctly rounded to five
    /// decimals except `sqrt(15/(2π)) = 1.5450968…`, printed truncated as 1.54509.
    #[test]
    fn listing_2_2_constants() {
        let (c1, c3, c15) = consts();
        for (ours, printed) in [(c1, 0.39894), (c3, 0.69099), (0.5 * c15, 0.77255)] {
            assert!((ours - printed).abs() <= 0.5e-5, "{ours} vs {printed}");
        }
        assert!((c15 - 1.54509).abs() > 0.5e-5 && (c15 - 1.54509) < 1e-5);
        assert!((c15 - 1.54510).abs() <= 0.5e-5);
    }

    #[test]
    fn only_4_and_6() {
        assert!(HBasis::new(5).is_none());
        assert!(HBasis::modified(9).is_none());
    }
}
