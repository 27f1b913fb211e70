//! The slow, obviously-correct reference evaluation of the real SH basis.
//!
//! Textbook form (Ishmukhametov, \[Ish11\] §1.8.1, Eq. 1.6-1.8, without the Condon-Shortley
//! phase that the thesis's rule 2 includes):
//!
//! - spherical coordinates `(x, y, z) = (sin θ cos φ, sin θ sin φ, cos θ)`;
//! - associated Legendre polynomials by the three recurrences
//!   `P_m^m = (2m-1)!! (1-x²)^{m/2}`, `P_{m+1}^m = x (2m+1) P_m^m`,
//!   `(l-m) P_l^m = x (2l-1) P_{l-1}^m - (l+m-1) P_{l-2}^m`;
//! - `y_lm = sqrt2 K_l^m cos(mφ) P_l^m(cos θ)` (m > 0),
//!   `sqrt2 K_l^|m| sin(|m|φ) P_l^|m|(cos θ)` (m < 0), `K_l^0 P_l^0(cos θ)` (m = 0);
//! - `K_l^m = sqrt((2l+1)(l-|m|)! / (4π (l+|m|)!))`.
//!
//! It uses trigonometric functions of the angles, factorials and unnormalised Legendre
//! values: a different route from the generated Cartesian code in [`crate::eval`], which is
//! tested against this one band by band. It is exact to f64 rounding for the orders this
//! crate uses (the factorial ratio stays far inside f64 range up to l ≈ 80).

use std::f64::consts::PI;

use crate::index::sh_index;

/// Unnormalised associated Legendre function `P_l^m(x)` without the Condon-Shortley phase,
/// by the three recurrences of \[Ish11\] §1.8.1.
#[must_use]
pub fn legendre_p(l: u32, m: u32, x: f64) -> f64 {
    assert!(m <= l, "legendre_p needs m <= l");
    // Rule 2: P_m^m = (2m-1)!! (1 - x²)^{m/2}.
    let somx2 = ((1.0 - x) * (1.0 + x)).max(0.0).sqrt();
    let mut pmm = 1.0;
    let mut fact = 1.0;
    for _ in 0..m {
        pmm *= fact * somx2;
        fact += 2.0;
    }
    if l == m {
        return pmm;
    }
    // Rule 3: P_{m+1}^m = x (2m+1) P_m^m.
    let mut pmmp1 = x * (2 * m + 1) as f64 * pmm;
    if l == m + 1 {
        return pmmp1;
    }
    // Rule 1: (l-m) P_l^m = x (2l-1) P_{l-1}^m - (l+m-1) P_{l-2}^m.
    let mut pll = 0.0;
    for ll in (m + 2)..=l {
        pll = ((2 * ll - 1) as f64 * x * pmmp1 - (ll + m - 1) as f64 * pmm) / (ll - m) as f64;
        pmm = pmmp1;
        pmmp1 = pll;
    }
    pll
}

/// `n!` in f64 (exact up to 22!, correctly rounded products beyond).
fn factorial(n: u32) -> f64 {
    (1..=n).map(f64::from).product()
}

/// Normalisation `K_l^m` of \[Ish11\] Eq. 1.8.
#[must_use]
pub fn k_norm(l: u32, m: i32) -> f64 {
    let am = m.unsigned_abs();
    ((2 * l + 1) as f64 * factorial(l - am) / (4.0 * PI * factorial(l + am))).sqrt()
}

/// One real SH basis function `y_lm(θ, φ)` (\[Ish11\] Eq. 1.7, no Condon-Shortley phase).
#[must_use]
pub fn sh_reference_angles(l: u32, m: i32, theta: f64, phi: f64) -> f64 {
    let am = m.unsigned_abs();
    let p = legendre_p(l, am, theta.cos());
    let k = k_norm(l, m);
    match m.signum() {
        1 => std::f64::consts::SQRT_2 * k * (am as f64 * phi).cos() * p,
        -1 => std::f64::consts::SQRT_2 * k * (am as f64 * phi).sin() * p,
        _ => k * p,
    }
}

/// One real SH basis function at a unit direction, through its spherical angles.
#[must_use]
pub fn sh_reference(l: u32, m: i32, dir: [f64; 3]) -> f64 {
    let [x, y, z] = dir;
    let theta = z.clamp(-1.0, 1.0).acos();
    let phi = y.atan2(x);
    sh_reference_angles(l, m, theta, phi)
}

/// All `bands²` basis values at a unit direction, by the reference route.
#[must_use]
pub fn sh_reference_all(bands: usize, dir: [f64; 3]) -> Vec<f64> {
    let mut out = vec![0.0; bands * bands];
    for l in 0..bands as u32 {
        for m in -(l as i32)..=(l as i32) {
            out[sh_index(l, m)] = sh_reference(l, m, dir);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f64 rounding over a handful of operations on O(1) values.
    const TIGHT: f64 = 1e-14;

    #[test]
    fn low_order_closed_forms() {
        // The closed forms of [Ish11] Eq. 1.9-1.17, with the xy typo (1/2 not 1/4 sin 2φ) fixed.
        let d = [0.3_f64, -0.5, 0.0];
        let n = (d[0] * d[0] + d[1] * d[1] + 0.6_f64 * 0.6).sqrt();
        let (x, y, z) = (d[0] / n, d[1] / n, 0.6 / n);
        let dir = [x, y, z];
        let c = |k: f64| k.sqrt() / 2.0;
        assert!((sh_reference(0, 0, dir) - c(1.0 / PI)).abs() < TIGHT);
        assert!((sh_reference(1, -1, dir) - c(3.0 / PI) * y).abs() < TIGHT);
        assert!((sh_reference(1, 0, dir) - c(3.0 / PI) * z).abs() < TIGHT);
        assert!((sh_reference(1, 1, dir) - c(3.0 / PI) * x).abs() < TIGHT);
        assert!((sh_reference(2, -2, dir) - c(15.0 / PI) * x * y).abs() < TIGHT);
        assert!((sh_reference(2, -1, dir) - c(15.0 / PI) * y * z).abs() < TIGHT);
        assert!((sh_reference(2, 0, dir) - c(5.0 / PI) / 2.0 * (3.0 * z * z - 1.0)).abs() < TIGHT);
        assert!((sh_reference(2, 1, dir) - c(15.0 / PI) * z * x).abs() < TIGHT);
        assert!((sh_reference(2, 2, dir) - c(15.0 / PI) / 2.0 * (x * x - y * y)).abs() < TIGHT);
    }

    #[test]
    fn legendre_matches_explicit_polynomials() {
        for &x in &[-0.9_f64, -0.2, 0.0, 0.4, 0.99] {
            let s = (1.0 - x * x).sqrt();
            assert!((legendre_p(2, 0, x) - 0.5 * (3.0 * x * x - 1.0)).abs() < TIGHT);
            assert!((legendre_p(3, 0, x) - 0.5 * (5.0 * x * x * x - 3.0 * x)).abs() < TIGHT);
            assert!((legendre_p(2, 1, x) - 3.0 * x * s).abs() < TIGHT);
            assert!((legendre_p(2, 2, x) - 3.0 * s * s).abs() < TIGHT);
            assert!((legendre_p(3, 3, x) - 15.0 * s * s * s).abs() < TIGHT);
        }
    }
}
