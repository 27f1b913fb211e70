//! The Half-Life 2 basis (McTaggart 2004, "Half-Life 2 / Valve Source Shading").
//!
//! Three cosine lobes around the orthonormal directions (\[Ish11\] Eq. 1.18-1.20)
//!
//! ```text
//! h1 = (-1/sqrt6, -1/sqrt2, 1/sqrt3),  h2 = (-1/sqrt6, 1/sqrt2, 1/sqrt3),  h3 = (sqrt(2/3), 0, 1/sqrt3)
//! ```
//!
//! with `B_i(n) = sqrt(3/(2π)) n·h_i` (Eq. 1.21). They are orthonormal on the hemisphere
//! because `∫_H n nᵀ dω = (2π/3) I` and the `h_i` are orthonormal; they span the linear
//! functions `{x, y, z}` — there is no constant term, which is why [`HemiBasis::dc_index`] is
//! `None`. The thesis's definitions are correct as printed (checked in the tests).

use lightvol_sh::Real;

use crate::basis::{HemiBasis, forward_eval};
use crate::program::{Expr, Program};

/// The three Half-Life 2 basis directions `h_i` (\[Ish11\] Eq. 1.18-1.20).
#[must_use]
pub fn directions() -> [[f64; 3]; 3] {
    let (s6, s2, s3) = (6f64.sqrt(), 2f64.sqrt(), 3f64.sqrt());
    [
        [-1.0 / s6, -1.0 / s2, 1.0 / s3],
        [-1.0 / s6, 1.0 / s2, 1.0 / s3],
        [(2.0f64 / 3.0).sqrt(), 0.0, 1.0 / s3],
    ]
}

/// The Half-Life 2 basis: 3 functions.
#[derive(Clone, Copy, Debug, Default)]
pub struct Hl2;

/// `1/(2 sqrt π)`, `sqrt(3/(4π))`, `1/sqrt(2π)`, `1/sqrt π`: the entries of
/// `sqrt(3/(2π)) h_i` (products of Eq. 1.18-1.21's constants; tested against them).
const A: f64 = core::f64::consts::FRAC_2_SQRT_PI / 4.0;
const B: f64 = 0.488_602_511_902_919_9;
const C: f64 = core::f64::consts::FRAC_2_SQRT_PI * core::f64::consts::FRAC_1_SQRT_2 / 2.0;
const D: f64 = core::f64::consts::FRAC_2_SQRT_PI / 2.0;

/// The rows `sqrt(3/(2π)) h_i`: `B_i(n) = row_i · n`.
const ROWS: [[f64; 3]; 3] = [[-A, -B, C], [-A, B, C], [D, 0.0, C]];

impl Hl2 {
    fn rows() -> [[f64; 3]; 3] {
        ROWS
    }

    fn eval<T: Real>(&self, dir: [T; 3], out: &mut [T]) {
        for (o, r) in out.iter_mut().zip(ROWS) {
            *o = T::from_f64(r[0]) * dir[0] + T::from_f64(r[1]) * dir[1] + T::from_f64(r[2]) * dir[2];
        }
    }
}

impl HemiBasis for Hl2 {
    fn name(&self) -> &'static str {
        "hl2"
    }
    fn label(&self) -> &'static str {
        "Half-Life 2"
    }
    fn len(&self) -> usize {
        3
    }
    fn orthonormal(&self) -> bool {
        true
    }
    fn order(&self) -> usize {
        1
    }
    fn dc_index(&self) -> Option<usize> {
        None
    }
    fn program(&self) -> Program {
        let mut p = Program::default();
        for r in Self::rows() {
            let mut e = Expr::num(r[0]) * Expr::X + Expr::num(r[2]) * Expr::Z;
            if r[1] != 0.0 {
                e = e + Expr::num(r[1]) * Expr::Y;
            }
            p.outputs.push(e);
        }
        p
    }
    forward_eval!();
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::test_util::assert_orthonormal;

    /// Dot products of unit vectors built from square roots: rounding.
    const DIR_TOL: f64 = 1e-15;

    #[test]
    fn directions_are_orthonormal() {
        let h = directions();
        for i in 0..3 {
            for j in 0..3 {
                let d: f64 = (0..3).map(|k| h[i][k] * h[j][k]).sum();
                assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < DIR_TOL);
            }
        }
    }

    #[test]
    fn row_constants_match_definition() {
        let k = (3.0 / (2.0 * PI)).sqrt();
        for (row, h) in ROWS.iter().zip(directions()) {
            for (r, c) in row.iter().zip(h) {
                assert!((r - k * c).abs() < DIR_TOL, "{r} vs {}", k * c);
            }
        }
        assert!((B - (3.0 / (4.0 * PI)).sqrt()).abs() < DIR_TOL);
    }

    #[test]
    fn orthonormal_on_hemisphere() {
        assert_orthonormal(&Hl2);
    }
}
