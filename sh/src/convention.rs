//! Conversion between this crate's convention and the Condon-Shortley one.
//!
//! lightvol uses real SH *without* the Condon-Shortley phase: `y_1,-1 ∝ +y`, `y_10 ∝ z`,
//! `y_11 ∝ +x` (as in Ramamoorthi & Hanrahan 2001, \[KL06\] Table 1 and
//! \[Ish11\] Eq. 1.9-1.17). Google's `spherical-harmonics` library, Sloan's papers and D3DX
//! include the phase `(-1)^m`, which flips the sign of every coefficient with odd `|m|`
//! (e.g. their `y_11 = -sqrt(3/4π) x`). The map is its own inverse.

use crate::index::sh_lm;
use crate::real::Real;

/// Sign `(-1)^|m|` relating coefficient `i` in the two conventions.
#[must_use]
#[inline]
pub const fn condon_shortley_sign(index: usize) -> i32 {
    if sh_lm(index).1.unsigned_abs() % 2 == 1 { -1 } else { 1 }
}

/// Converts coefficients (in place) from this crate's convention to Condon-Shortley.
pub fn to_condon_shortley<T: Real>(coeffs: &mut [T]) {
    for (i, c) in coeffs.iter_mut().enumerate() {
        if condon_shortley_sign(i) < 0 {
            *c = -*c;
        }
    }
}

/// Converts coefficients (in place) from Condon-Shortley to this crate's convention.
pub fn from_condon_shortley<T: Real>(coeffs: &mut [T]) {
    to_condon_shortley(coeffs);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::eval_basis;

    /// Google's `spherical-harmonics` hard-coded band-1 and band-2 functions (with CS phase):
    /// y_1,-1 = -c y, y_11 = -c x, y_2,-1 = -c' yz, y_21 = -c' xz. Converting our basis values
    /// must produce exactly those signs.
    #[test]
    fn matches_google_signs() {
        let d = [0.48_f64, 0.6, 0.64];
        let mut y: [f64; 9] = eval_basis(d);
        to_condon_shortley(&mut y);
        let c1 = (3.0 / (4.0 * std::f64::consts::PI)).sqrt();
        let c2 = 0.5 * (15.0 / std::f64::consts::PI).sqrt();
        assert!((y[1] + c1 * d[1]).abs() < 1e-15);
        assert!((y[2] - c1 * d[2]).abs() < 1e-15);
        assert!((y[3] + c1 * d[0]).abs() < 1e-15);
        assert!((y[4] - c2 * d[0] * d[1]).abs() < 1e-15);
        assert!((y[5] + c2 * d[1] * d[2]).abs() < 1e-15);
        assert!((y[7] + c2 * d[0] * d[2]).abs() < 1e-15);
        from_condon_shortley(&mut y);
        assert_eq!(y, eval_basis::<f64, 9>(d));
    }
}
