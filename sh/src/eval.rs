//! Fast evaluation of the real SH basis at a direction.
//!
//! Up to [`MAX_FAST_BANDS`] bands (l <= 7, 64 coefficients) the work is done by generated
//! straight-line code (`src/generated.rs`, written by `tests/sourcegen.rs`); beyond that by
//! the same normalised recurrence run as a loop ([`eval_recurrence`]). Both are tested
//! against the textbook reference in [`crate::reference`].
//!
//! Directions must be unit vectors; the functions are polynomials in `(x, y, z)` and give
//! scaled, meaningless values otherwise.

use crate::index::{bands_of, num_coeffs};
use crate::real::Real;

/// Number of bands covered by the generated straight-line code (l = 0..=7).
pub const MAX_FAST_BANDS: usize = crate::generated::GENERATED_BANDS;

/// Evaluates `bands` bands of the basis at the unit vector `dir` into `out[..bands²]`.
///
/// # Panics
/// If `out` is shorter than `bands²`.
#[inline]
pub fn eval_into<T: Real>(bands: usize, dir: [T; 3], out: &mut [T]) {
    if bands == 0 {
        return;
    }
    let [x, y, z] = dir;
    if bands <= MAX_FAST_BANDS {
        T::eval_sh_fast(bands, x, y, z, out);
    } else {
        eval_recurrence(bands, dir, out);
    }
}

/// The `N = bands²` basis values at `dir` as an array; `N` must be a square no larger than
/// 64 (checked at compile time).
///
/// ```
/// use lightvol_sh::eval::eval_basis;
/// let y: [f64; 4] = eval_basis([0.0, 0.0, 1.0]);
/// // Y_00 = 1/(2 sqrt(pi)), Y_10 = sqrt(3/(4 pi)) z.
/// assert!((y[0] - 0.5 / std::f64::consts::PI.sqrt()).abs() < 1e-15);
/// assert!((y[2] - (3.0 / (4.0 * std::f64::consts::PI)).sqrt()).abs() < 1e-15);
/// ```
#[must_use]
#[inline]
pub fn eval_basis<T: Real, const N: usize>(dir: [T; 3]) -> [T; N] {
    const {
        assert!(
            bands_of(N).is_some() && N <= num_coeffs(MAX_FAST_BANDS),
            "N must be a square number of coefficients up to 64"
        );
    }
    let mut out = [T::ZERO; N];
    T::eval_sh_fast(N.isqrt(), dir[0], dir[1], dir[2], &mut out);
    out
}

/// Evaluates `bands` bands with the normalised three-term recurrence as a loop, for any
/// number of bands. This is the same mathematics as the generated code (see
/// `tests/sourcegen.rs`), with the constants of [`crate::recurrence`] computed on the fly;
/// `Q_m^m` by its ratio form, the twin of [`crate::recurrence::q_diag`], which would
/// overflow its factorials beyond `m = 10`. Its deliberate twin in lightvol-gpu,
/// `lookup::ShRecurrence::eval`, follows the shader's f32 tables and operation order and is
/// tested against this one.
///
/// # Panics
/// If `out` is shorter than `bands²`.
pub fn eval_recurrence<T: Real>(bands: usize, dir: [T; 3], out: &mut [T]) {
    let out = &mut out[..bands * bands];
    let [x, y, z] = dir;
    let inv4pi = T::from_f64(0.25 / std::f64::consts::PI);
    // q_diag tracks Q_m^m; c, s track Re/Im of (x + i y)^m.
    let mut q_diag = inv4pi.sqrt();
    let (mut c, mut s) = (T::ONE, T::ZERO);
    for m in 0..bands {
        if m > 0 {
            // Q_m^m / Q_{m-1}^{m-1} = sqrt((2m+1) / (2m)), times sqrt 2 when leaving m = 0.
            let mf = m as f64;
            let mut ratio = ((2.0 * mf + 1.0) / (2.0 * mf)).sqrt();
            if m == 1 {
                ratio *= std::f64::consts::SQRT_2;
            }
            q_diag *= T::from_f64(ratio);
            let (cn, sn) = (x * c - y * s, x * s + y * c);
            c = cn;
            s = sn;
        }
        let mut q_prev2 = T::ZERO;
        let mut q_prev = q_diag;
        for l in m..bands {
            let q = if l == m {
                q_diag
            } else {
                let (lu, mu) = (l as u64, m as u64);
                let a = crate::recurrence::a_coef(lu, mu);
                let b = if l >= m + 2 { crate::recurrence::b_coef(lu, mu) } else { 0.0 };
                let q = T::from_f64(a) * z * q_prev + T::from_f64(b) * q_prev2;
                q_prev2 = q_prev;
                q_prev = q;
                q
            };
            let base = l * (l + 1);
            if m == 0 {
                out[base] = q;
            } else {
                out[base + m] = q * c;
                out[base - m] = q * s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::sh_reference_all;

    #[test]
    fn recurrence_matches_generated_code() {
        let dir = {
            let v = [0.48_f64, -0.6, 0.64];
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            [v[0] / n, v[1] / n, v[2] / n]
        };
        let mut fast = [0.0; 64];
        let mut rec = [0.0; 64];
        eval_into(8, dir, &mut fast);
        eval_recurrence(8, dir, &mut rec);
        for i in 0..64 {
            // Same operations in the same order up to constant rounding: a few ulps.
            assert!((fast[i] - rec[i]).abs() < 1e-14, "index {i}");
        }
        // Beyond the generated range the recurrence must still agree with the reference.
        let mut big = vec![0.0; 16 * 16];
        eval_into(16, dir, &mut big);
        let refv = sh_reference_all(16, dir);
        for (i, (a, b)) in big.iter().zip(&refv).enumerate() {
            assert!((a - b).abs() < 1e-12, "index {i}: {a} vs {b}");
        }
    }
}
