//! Real Gaunt coefficients `G_ijk = ∫ y_i y_j y_k dω` and SH products.
//!
//! The coefficients are computed in closed form, not by quadrature:
//!
//! 1. Wigner 3j symbols by Racah's formula, with exact integer factorials (every factorial
//!    needed for up to 6 bands fits in f64 exactly);
//! 2. complex Gaunt coefficients
//!    `∫ Y_{l1}^{m1} Y_{l2}^{m2} Y_{l3}^{m3} dω = sqrt((2l1+1)(2l2+1)(2l3+1)/4π)
//!    (l1 l2 l3; 0 0 0)(l1 l2 l3; m1 m2 m3)`;
//! 3. the real basis expressed through the complex one (Condon-Shortley complex `Y`):
//!    `y_l0 = Y_l^0`, `y_lm = ((-1)^m Y_l^m + Y_l^{-m}) / sqrt2`,
//!    `y_l,-m = ((-1)^m Y_l^m - Y_l^{-m}) / (i sqrt2)` for `m > 0`.
//!
//! The tests compare the result with exact quadrature of the triple products and check the
//! number of non-zero coefficients against theory (10, 83, 353, 1158 for 2-5 bands).
//!
//! With the table, the truncated product `h = f g` is `h_k = Σ_ij G_ijk f_i g_j`, and the
//! product matrix of `f` is `(M_f)_kj = Σ_i G_ijk f_i`, so that `h = M_f g`.

use std::sync::OnceLock;

use crate::coeffs::Sh;
use crate::index::sh_lm;
use crate::real::Real;

/// Most bands for which Gaunt tables are built (orders up to 6, l <= 5; wider tables work but
/// are not cached).
pub const MAX_CACHED_BANDS: usize = 6;

/// Coefficients whose magnitude is below this are structural zeros that picked up rounding
/// (the non-zero ones are all above 1e-3 for l <= 5).
const ZERO_THRESHOLD: f64 = 1e-13;

fn factorial(n: i64) -> f64 {
    (1..=n).map(|k| k as f64).product()
}

/// Wigner 3j symbol `(j1 j2 j3; m1 m2 m3)` for integer arguments, by Racah's formula.
#[must_use]
pub fn wigner_3j(j1: i64, j2: i64, j3: i64, m1: i64, m2: i64, m3: i64) -> f64 {
    if m1 + m2 + m3 != 0
        || m1.abs() > j1
        || m2.abs() > j2
        || m3.abs() > j3
        || j3 < (j1 - j2).abs()
        || j3 > j1 + j2
    {
        return 0.0;
    }
    let delta = factorial(j1 + j2 - j3) * factorial(j1 - j2 + j3) * factorial(-j1 + j2 + j3)
        / factorial(j1 + j2 + j3 + 1);
    let pre = (delta
        * factorial(j1 + m1)
        * factorial(j1 - m1)
        * factorial(j2 + m2)
        * factorial(j2 - m2)
        * factorial(j3 + m3)
        * factorial(j3 - m3))
    .sqrt();
    let kmin = 0.max(j2 - j3 - m1).max(j1 - j3 + m2);
    let kmax = (j1 + j2 - j3).min(j1 - m1).min(j2 + m2);
    let mut sum = 0.0;
    for k in kmin..=kmax {
        let den = factorial(k)
            * factorial(j3 - j2 + k + m1)
            * factorial(j3 - j1 + k - m2)
            * factorial(j1 + j2 - j3 - k)
            * factorial(j1 - k - m1)
            * factorial(j2 - k + m2);
        sum += if k % 2 == 0 { 1.0 } else { -1.0 } / den;
    }
    let sign = if (j1 - j2 - m3).rem_euclid(2) == 0 { 1.0 } else { -1.0 };
    sign * pre * sum
}

/// `∫ Y_{l1}^{m1} Y_{l2}^{m2} Y_{l3}^{m3} dω` for complex, Condon-Shortley `Y` (no conjugates).
#[must_use]
pub fn complex_gaunt(l1: i64, m1: i64, l2: i64, m2: i64, l3: i64, m3: i64) -> f64 {
    let w0 = wigner_3j(l1, l2, l3, 0, 0, 0);
    if w0 == 0.0 {
        return 0.0;
    }
    let norm = (((2 * l1 + 1) * (2 * l2 + 1) * (2 * l3 + 1)) as f64 / (4.0 * std::f64::consts::PI)).sqrt();
    norm * w0 * wigner_3j(l1, l2, l3, m1, m2, m3)
}

/// The real function `y_lm` as `Σ (coefficient, μ) Y_l^μ`, coefficients complex `(re, im)`.
fn real_in_complex(m: i64) -> Vec<((f64, f64), i64)> {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let sign = if m.abs() % 2 == 0 { 1.0 } else { -1.0 };
    match m.signum() {
        0 => vec![((1.0, 0.0), 0)],
        1 => vec![((sign * s, 0.0), m), ((s, 0.0), -m)],
        // 1/(i√2) = -i/√2.
        _ => vec![((0.0, -sign * s), -m), ((0.0, s), m)],
    }
}

/// One real Gaunt coefficient `∫ y_i y_j y_k dω` (flat indices), from complex Gaunt values.
#[must_use]
pub fn real_gaunt(i: usize, j: usize, k: usize) -> f64 {
    let (l1, m1) = sh_lm(i);
    let (l2, m2) = sh_lm(j);
    let (l3, m3) = sh_lm(k);
    let (l1, l2, l3) = (i64::from(l1), i64::from(l2), i64::from(l3));
    if (l1 + l2 + l3) % 2 == 1 || l3 < (l1 - l2).abs() || l3 > l1 + l2 {
        return 0.0;
    }
    let (mut re, mut im) = (0.0, 0.0);
    for ((a, b), mu1) in real_in_complex(i64::from(m1)) {
        for ((c, d), mu2) in real_in_complex(i64::from(m2)) {
            for ((e, f), mu3) in real_in_complex(i64::from(m3)) {
                let g = complex_gaunt(l1, mu1, l2, mu2, l3, mu3);
                if g == 0.0 {
                    continue;
                }
                // (a + ib)(c + id)(e + if)
                let (pr, pi) = (a * c - b * d, a * d + b * c);
                re += g * (pr * e - pi * f);
                im += g * (pr * f + pi * e);
            }
        }
    }
    debug_assert!(im.abs() < 1e-12, "real Gaunt must be real, got imaginary part {im}");
    re
}

/// One non-zero entry `G_ijk` of a sparse Gaunt table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GauntEntry {
    /// Index of the first factor.
    pub i: u16,
    /// Index of the second factor.
    pub j: u16,
    /// Index of the result.
    pub k: u16,
    /// `∫ y_i y_j y_k dω`.
    pub value: f64,
}

/// All non-zero real Gaunt coefficients with `i, j, k < bands²`, sorted by `(k, i, j)`.
#[derive(Clone, Debug)]
pub struct GauntTable {
    bands: usize,
    entries: Vec<GauntEntry>,
}

impl GauntTable {
    /// Builds the table in closed form (milliseconds for 6 bands).
    #[must_use]
    pub fn new(bands: usize) -> Self {
        let n = bands * bands;
        let mut entries = Vec::new();
        for k in 0..n {
            for i in 0..n {
                for j in 0..n {
                    let v = real_gaunt(i, j, k);
                    if v.abs() > ZERO_THRESHOLD {
                        entries.push(GauntEntry { i: i as u16, j: j as u16, k: k as u16, value: v });
                    }
                }
            }
        }
        Self { bands, entries }
    }

    /// The process-wide table for `bands <= MAX_CACHED_BANDS`, built on first use.
    ///
    /// # Panics
    /// If `bands > MAX_CACHED_BANDS` or `bands == 0`.
    #[must_use]
    pub fn cached(bands: usize) -> &'static GauntTable {
        static TABLES: [OnceLock<GauntTable>; MAX_CACHED_BANDS] =
            [const { OnceLock::new() }; MAX_CACHED_BANDS];
        assert!((1..=MAX_CACHED_BANDS).contains(&bands), "cached Gaunt tables cover 1..=6 bands");
        TABLES[bands - 1].get_or_init(|| GauntTable::new(bands))
    }

    /// Number of bands.
    #[must_use]
    pub fn bands(&self) -> usize {
        self.bands
    }

    /// The non-zero entries.
    #[must_use]
    pub fn entries(&self) -> &[GauntEntry] {
        &self.entries
    }
}

/// Truncated SH product `h = f g` (both band-limited to `N` coefficients, result truncated to
/// `N`). `N` must be at most 36.
#[must_use]
pub fn product<T: Real, const N: usize>(f: &Sh<T, N>, g: &Sh<T, N>) -> Sh<T, N> {
    let table = GauntTable::cached(N.isqrt());
    let mut out = [T::ZERO; N];
    for e in table.entries() {
        out[e.k as usize] += T::from_f64(e.value) * f.0[e.i as usize] * g.0[e.j as usize];
    }
    Sh(out)
}

/// The product matrix `M_f` (row-major `N × N`, `(M_f)_kj = Σ_i G_ijk f_i`), so that
/// `product(f, g) = M_f g`. Symmetric, since `G` is symmetric in its indices.
#[must_use]
pub fn product_matrix<const N: usize>(f: &Sh<f64, N>) -> Vec<f64> {
    let table = GauntTable::cached(N.isqrt());
    let mut m = vec![0.0; N * N];
    for e in table.entries() {
        m[e.k as usize * N + e.j as usize] += e.value * f.0[e.i as usize];
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wigner_3j_known_values() {
        // (1 1 0; 0 0 0) = -1/sqrt3, (1 1 2; 0 0 0) = sqrt(2/15), (2 2 2; 0 0 0) = -sqrt(2/35).
        assert!((wigner_3j(1, 1, 0, 0, 0, 0) + 1.0 / 3f64.sqrt()).abs() < 1e-15);
        assert!((wigner_3j(1, 1, 2, 0, 0, 0) - (2.0f64 / 15.0).sqrt()).abs() < 1e-15);
        assert!((wigner_3j(2, 2, 2, 0, 0, 0) + (2.0f64 / 35.0).sqrt()).abs() < 1e-15);
        // Orthogonality: Σ_{m1 m2} (j1 j2 j3; m1 m2 m3)² = 1/(2 j3 + 1), here j3 = 4, m3 = 1.
        let mut total = 0.0;
        for m1 in -2..=2i64 {
            for m2 in -3..=3i64 {
                if m1 + m2 == -1 {
                    total += wigner_3j(2, 3, 4, m1, m2, 1).powi(2);
                }
            }
        }
        assert!((total - 1.0 / 9.0).abs() < 1e-15);
    }
}
