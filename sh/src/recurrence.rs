//! The constants of the normalised three-term recurrence of the real SH basis (no
//! Condon-Shortley phase), in closed form, f64: the one source of the constants that the
//! generated straight-line code (`tests/sourcegen.rs`), the proxies' lane evaluation and
//! the GPU shaders round to f32.
//!
//! `Q_l^m = a_lm · z · Q_{l-1}^m + b_lm · Q_{l-2}^m`, started from `Q_m^m`;
//! `y_lm = Q_l^|m| · Re((x + i y)^|m|)` for `m > 0`, `Im` for `m < 0`, `y_l0 = Q_l^0`.
//!
//! [`crate::eval::eval_recurrence`] is the arbitrary-order twin: it builds `Q_m^m` by the
//! ratio `Q_m^m / Q_{m-1}^{m-1} = sqrt((2m+1)/(2m))` (times `sqrt 2` leaving `m = 0`) so that
//! no factorial overflows, and is tested against these closed forms.

/// Largest `m` for which [`q_diag`]'s integer factorials are exact in u64 (`(2m)!` with
/// `m = 10` is `20! < 2^64`).
pub const MAX_CLOSED_FORM_M: u64 = 10;

/// `(2m-1)!!` as an exact integer (`1` for `m = 0`).
fn double_factorial_odd(m: u64) -> u64 {
    (1..=m).map(|k| 2 * k - 1).product()
}

fn factorial(n: u64) -> u64 {
    (1..=n).product()
}

/// `Q_m^m = sqrt((2 - δ_m0)(2m+1)/(4π) · ((2m-1)!!)² / (2m)!)`.
///
/// # Panics
/// If `m > MAX_CLOSED_FORM_M` (the factorials would overflow).
#[must_use]
pub fn q_diag(m: u64) -> f64 {
    assert!(m <= MAX_CLOSED_FORM_M, "Q_m^m in closed form for m <= {MAX_CLOSED_FORM_M}");
    let dfact = double_factorial_odd(m) as f64;
    let fact = factorial(2 * m) as f64;
    let two = if m == 0 { 1.0 } else { 2.0 };
    (two * (2 * m + 1) as f64 / (4.0 * std::f64::consts::PI) * dfact * dfact / fact).sqrt()
}

/// `a_lm = sqrt((4l² - 1) / (l² - m²))`, for `l > m`.
#[must_use]
pub fn a_coef(l: u64, m: u64) -> f64 {
    (((4 * l * l - 1) as f64) / ((l * l - m * m) as f64)).sqrt()
}

/// `b_lm = -sqrt((2l+1)(l-1-m)(l-1+m) / ((2l-3)(l-m)(l+m)))`, for `l ≥ m + 2`.
#[must_use]
pub fn b_coef(l: u64, m: u64) -> f64 {
    let num = ((2 * l + 1) * (l - 1 - m) * (l - 1 + m)) as f64;
    let den = ((2 * l - 3) * (l - m) * (l + m)) as f64;
    -(num / den).sqrt()
}

/// The constants of the first `B` bands, each computed in f64 by [`q_diag`], [`a_coef`] and
/// [`b_coef`] and rounded once to f32, as every f32 port of the recurrence reads them (the
/// proxies' lane evaluation, the GPU evaluator's shader tables). Indexed `[l][m]`; zero where
/// the recurrence has no constant (`a` for `l <= m`, `b` for `l < m + 2`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecurrenceF32<const B: usize> {
    /// `Q_m^m`, indexed by `m`.
    pub diag: [f32; B],
    /// `a_lm`, indexed `[l][m]`.
    pub a: [[f32; B]; B],
    /// `b_lm`, indexed `[l][m]`.
    pub b: [[f32; B]; B],
}

impl<const B: usize> RecurrenceF32<B> {
    /// The constants.
    ///
    /// # Panics
    /// If `B` exceeds [`MAX_CLOSED_FORM_M`] + 1 bands.
    #[must_use]
    pub fn new() -> Self {
        let mut r = Self { diag: [0.0; B], a: [[0.0; B]; B], b: [[0.0; B]; B] };
        for m in 0..B {
            r.diag[m] = q_diag(m as u64) as f32;
            for l in m + 1..B {
                r.a[l][m] = a_coef(l as u64, m as u64) as f32;
                if l >= m + 2 {
                    r.b[l][m] = b_coef(l as u64, m as u64) as f32;
                }
            }
        }
        r
    }
}

impl<const B: usize> Default for RecurrenceF32<B> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The f32 table holds the f64 closed forms rounded once, and zeros where the
    /// recurrence has no constant. Three entries derived another way, from the polynomials
    /// `Y_00 = 1/sqrt(4π)`, `Y_10 = sqrt(3/4π) z`, `Y_20 = sqrt(5/16π) (3z² - 1)`: `Q_0^0 =
    /// 1/sqrt(4π)`; `a_10 = Y_10 / (z Y_00) = sqrt 3`; the constant term of `Y_20` is
    /// `b_20 Y_00`, so `b_20 = -sqrt(5/16π) · sqrt(4π) = -sqrt 5 / 2`.
    #[test]
    fn f32_table_rounds_the_closed_forms_once() {
        let r = RecurrenceF32::<4>::new();
        assert_eq!(r.diag[0], (1.0 / (4.0 * PI).sqrt()) as f32);
        assert_eq!(r.a[1][0], 3f64.sqrt() as f32);
        assert_eq!(r.b[2][0], (-(5f64.sqrt()) / 2.0) as f32);
        for l in 0..4 {
            for m in 0..4 {
                let a = if l > m { a_coef(l as u64, m as u64) as f32 } else { 0.0 };
                let b = if l >= m + 2 { b_coef(l as u64, m as u64) as f32 } else { 0.0 };
                assert_eq!((r.a[l][m], r.b[l][m]), (a, b), "l = {l}, m = {m}");
            }
        }
    }
    use std::f64::consts::PI;

    /// Rounding of a few f64 operations on O(1) values.
    const TOL: f64 = 1e-14;

    /// Derived another way: `Q_0^0 = 1/sqrt(4π)`, `Q_1^1 = sqrt(3/(4π))`,
    /// `Q_2^2 = sqrt(15/(16π))` (the printed normalisations of `y_00`, `y_11`, `y_22`), and
    /// the ratio form of `eval_recurrence` for every `m`.
    #[test]
    fn diagonal_matches_known_normalisations_and_the_ratio_form() {
        assert!((q_diag(0) - (1.0 / (4.0 * PI)).sqrt()).abs() < TOL);
        assert!((q_diag(1) - (3.0 / (4.0 * PI)).sqrt()).abs() < TOL);
        assert!((q_diag(2) - (15.0 / (16.0 * PI)).sqrt()).abs() < TOL);
        let mut q = (0.25 / PI).sqrt();
        for m in 1..=MAX_CLOSED_FORM_M {
            let mf = m as f64;
            q *= ((2.0 * mf + 1.0) / (2.0 * mf)).sqrt() * if m == 1 { 2f64.sqrt() } else { 1.0 };
            assert!((q_diag(m) - q).abs() < TOL * q, "m = {m}");
        }
    }

    /// `Q_1^0 = a_10 z Q_0^0` must be `sqrt(3/(4π)) z`, and `Q_2^0 = a_20 z Q_1^0 + b_20 Q_0^0`
    /// must be `sqrt(5/(16π)) (3z² - 1)`: the recurrence reproduces the printed `y_10`, `y_20`.
    #[test]
    fn recurrence_reproduces_y10_and_y20() {
        for z in [-0.9, -0.3, 0.0, 0.4, 1.0] {
            let q10 = a_coef(1, 0) * z * q_diag(0);
            assert!((q10 - (3.0 / (4.0 * PI)).sqrt() * z).abs() < TOL);
            let q20 = a_coef(2, 0) * z * q10 + b_coef(2, 0) * q_diag(0);
            assert!((q20 - (5.0 / (16.0 * PI)).sqrt() * (3.0 * z * z - 1.0)).abs() < TOL);
        }
    }
}
