//! SH exponentiation and logarithm (Ren et al. 2006, "Real-time Soft Shadows in Dynamic
//! Scenes using Spherical Harmonic Exponentiation", as used by Sloan et al. 2007,
//! \[SGNS07\] Eq. 4).
//!
//! With the truncated SH product `f * g` ([`crate::gaunt::product`]), the SH exponential is
//! the series `exp(f) = 1 + f + f*f/2! + …`. Since `f * g = M_f g` with the symmetric product
//! matrix `M_f`, the series is `exp(M_f) 1`, where `1` is the constant function (coefficient
//! `sqrt(4π)` at index 0). This module provides:
//!
//! - [`exp_reference`]: `exp(M_f) 1` through the eigen-decomposition of `M_f`;
//! - [`log_reference`]: the `f` with `exp_reference(f) = g`, started from `log(M_g) 1` (the
//!   eigen-decomposition again) and refined by Newton steps on the exact exponential;
//! - DC isolation: `exp(f) = exp(f_0 / sqrt(4π)) · exp(f̂)`, with `f̂` = `f` without its DC
//!   term (exact, because the constant function commutes with everything);
//! - [`OlTable`]: Ren's optimal linear approximation `exp(f̂) ≈ a(‖f̂‖) 1 + b(‖f̂‖) f̂`, with
//!   `a` and `b` tabulated against `‖f̂‖` by least-squares fits to the reference over the log
//!   visibility of sphere blockers (single caps and pairs);
//! - [`exp_hyb`]: Ren's HYB, scaling and squaring: halve `f̂` until its norm is small, apply
//!   OL, then square back with SH products; [`hyb_start`] and [`exp_hyb_with`] are its two
//!   halves, for callers with their own squaring (the f32 kernels of lightvol-proxies).

use std::f64::consts::PI;

use crate::coeffs::Sh;
use crate::gaunt::{product, product_matrix};
use crate::linalg::{cholesky_solve, symmetric_eigen};
use crate::lowdisc::SplitMix64;
use crate::real::Real;
use crate::sampling::sample_uniform_sphere;
use crate::zonal::Zh;

/// The SH vector of the constant function 1.
#[must_use]
pub fn unit<const N: usize>() -> Sh<f64, N> {
    let mut u = Sh::ZERO;
    u.0[0] = (4.0 * PI).sqrt();
    u
}

/// `h(M_f) 1` for a scalar function `h` of the eigenvalues.
fn matrix_function<const N: usize>(f: &Sh<f64, N>, h: impl Fn(f64) -> f64) -> Sh<f64, N> {
    let m = product_matrix(f);
    let (lambda, v) = symmetric_eigen(&m, N);
    let s = (4.0 * PI).sqrt();
    let mut out = [0.0; N];
    for k in 0..N {
        out[k] = s * (0..N).map(|j| v[k * N + j] * h(lambda[j]) * v[j]).sum::<f64>();
    }
    Sh(out)
}

/// The reference SH exponential `exp(M_f) 1` (Ren et al. 2006 §4), by eigen-decomposition.
#[must_use]
pub fn exp_reference<const N: usize>(f: &Sh<f64, N>) -> Sh<f64, N> {
    matrix_function(f, f64::exp)
}

/// Smallest eigenvalue (relative to the largest) that [`log_reference`] takes the logarithm
/// of: strong blockers truncated to few bands have non-positive eigenvalues, whose log does
/// not exist. They are raised to this floor before the Newton refinement. 1e-2 (rather than
/// 1e-6) keeps the logs of big blockers to moderate norms, which HYB then exponentiates with
/// 5-10x less error (measured in `tests/shexp.rs`); blockers with an exact log are unaffected.
pub const LOG_EIGEN_FLOOR: f64 = 1e-2;

/// The reference SH logarithm: the `f` with `exp_reference(f) = g`.
///
/// Starts from `log(M_g) 1` (eigenvalues floored at [`LOG_EIGEN_FLOOR`] times the largest) and
/// applies Newton steps `f ← f + M_{exp f}⁻¹ (g - exp f)` until the residual stops falling.
/// Returns the logarithm and the final residual norm `‖exp(f) - g‖`, which is 0 to rounding
/// whenever an exact logarithm exists.
#[must_use]
pub fn log_reference<const N: usize>(g: &Sh<f64, N>) -> (Sh<f64, N>, f64) {
    let m = product_matrix(g);
    let (lambda, _) = symmetric_eigen(&m, N);
    let top = lambda.iter().fold(0.0f64, |a, &b| a.max(b.abs())).max(f64::MIN_POSITIVE);
    let mut f = matrix_function(g, |l| l.max(LOG_EIGEN_FLOOR * top).ln());
    let mut residual = (exp_reference(&f) - *g).norm();
    for _ in 0..50 {
        let e = exp_reference(&f);
        let r = *g - e;
        let me = product_matrix(&e);
        let Some(step) = cholesky_solve(&me, &r.0, N) else { break };
        let mut candidate = f;
        for i in 0..N {
            candidate.0[i] += step[i];
        }
        let cr = (exp_reference(&candidate) - *g).norm();
        // Stop when the residual stops falling (or turns NaN).
        if cr.is_nan() || cr >= residual {
            break;
        }
        f = candidate;
        residual = cr;
        if residual < 1e-14 {
            break;
        }
    }
    (f, residual)
}

/// Splits `f` into its DC factor `exp(f_0 / sqrt(4π))` and `f̂` (DC removed).
#[must_use]
pub fn split_dc<const N: usize>(f: &Sh<f64, N>) -> (f64, Sh<f64, N>) {
    let mut hat = *f;
    hat.0[0] = 0.0;
    ((f.0[0] / (4.0 * PI).sqrt()).exp(), hat)
}

/// Ren's optimal linear (OL) approximation of the exponential of a DC-free vector:
/// `exp(f̂) ≈ a(‖f̂‖) 1 + b(‖f̂‖) f̂`, with `a`, `b` tabulated on a uniform grid of `‖f̂‖`.
#[derive(Clone, Debug)]
pub struct OlTable<const N: usize> {
    max_norm: f64,
    a: Vec<f64>,
    b: Vec<f64>,
}

/// Norm scale of the OL table's bins: bins are uniform in `ln(1 + ‖f̂‖ / OL_NORM_SCALE)`,
/// fine near 0 (where HYB works) and coarse for the large norms of big blockers.
const OL_NORM_SCALE: f64 = 0.05;

impl<const N: usize> OlTable<N> {
    /// Fits the table to the reference exponential over sphere-blocker log visibilities:
    /// single caps of half-angle up to 90° and pairs of caps at random (seeded) directions,
    /// each also scaled by `2^-k` (`k = 1..=10`, the arguments HYB feeds to OL), in `bins`
    /// bins. Each bin's `(a, b)` minimises `Σ ‖a 1 + b f̂ - exp(f̂)‖²` over the training vectors
    /// in it; empty bins interpolate, and the table starts from the exact limit `(1, 1)` at
    /// `‖f̂‖ = 0`.
    #[must_use]
    pub fn fit_sphere_blockers(bins: usize, seed: u64) -> Self {
        let mut training = sphere_blocker_logs::<N>(seed);
        let base = training.clone();
        for k in 1..=10 {
            training.extend(base.iter().map(|f| *f * (0.5f64).powi(k)));
        }
        let max_norm = training.iter().map(|f| f.norm()).fold(0.0, f64::max) * 1.0001;
        let u = unit::<N>();
        let mut table = Self { max_norm, a: vec![f64::NAN; bins], b: vec![f64::NAN; bins] };
        // Normal equations per bin: [[u·u, u·f], [u·f, f·f]] (a, b) = (u·e, f·e).
        let mut sums = vec![[0.0f64; 5]; bins];
        for f in &training {
            let bin = table.bin_coordinate(f.norm()) as usize;
            let e = exp_reference(f);
            let s = &mut sums[bin.min(bins - 1)];
            s[0] += u.dot(&u);
            s[1] += u.dot(f);
            s[2] += f.dot(f);
            s[3] += u.dot(&e);
            s[4] += f.dot(&e);
        }
        for (i, s) in sums.iter().enumerate() {
            if s[0] > 0.0
                && let Some(x) = cholesky_solve(&[s[0], s[1], s[1], s[2]], &[s[3], s[4]], 2)
            {
                table.a[i] = x[0];
                table.b[i] = x[1];
            }
        }
        fill_gaps(&mut table.a);
        fill_gaps(&mut table.b);
        table
    }

    /// Continuous bin coordinate of a norm, in `[0, bins]`.
    fn bin_coordinate(&self, norm: f64) -> f64 {
        let t = (1.0 + norm / OL_NORM_SCALE).ln() / (1.0 + self.max_norm / OL_NORM_SCALE).ln();
        t * self.a.len() as f64
    }

    /// `(a, b)` at a norm, by linear interpolation between bin centres, from the exact limit
    /// `(1, 1)` at norm 0, clamped at the top.
    #[must_use]
    pub fn coefficients(&self, norm: f64) -> (f64, f64) {
        let n = self.a.len();
        let x = self.bin_coordinate(norm) - 0.5;
        if x < 0.0 {
            // Between norm 0 (a = b = 1 exactly) and the first bin centre.
            let t = (x + 0.5) / 0.5;
            return (1.0 + t * (self.a[0] - 1.0), 1.0 + t * (self.b[0] - 1.0));
        }
        let x = x.min((n - 1) as f64);
        let i = (x as usize).min(n.saturating_sub(2));
        let t = x - i as f64;
        let j = (i + 1).min(n - 1);
        (self.a[i] + t * (self.a[j] - self.a[i]), self.b[i] + t * (self.b[j] - self.b[i]))
    }

    /// Largest norm covered by the fit.
    #[must_use]
    pub fn max_norm(&self) -> f64 {
        self.max_norm
    }

    /// OL exponential of a full vector (with DC isolation).
    #[must_use]
    pub fn exp(&self, f: &Sh<f64, N>) -> Sh<f64, N> {
        let (dc, hat) = split_dc(f);
        let (a, b) = self.coefficients(hat.norm());
        (unit::<N>() * a + hat * b) * dc
    }
}

fn fill_gaps(v: &mut [f64]) {
    let known: Vec<usize> = (0..v.len()).filter(|&i| v[i].is_finite()).collect();
    if known.is_empty() {
        v.iter_mut().for_each(|x| *x = 0.0);
        return;
    }
    for i in 0..v.len() {
        if v[i].is_finite() {
            continue;
        }
        let lo = known.iter().rev().find(|&&k| k < i).copied();
        let hi = known.iter().find(|&&k| k > i).copied();
        v[i] = match (lo, hi) {
            (Some(l), Some(h)) => v[l] + (v[h] - v[l]) * (i - l) as f64 / (h - l) as f64,
            (Some(l), None) => v[l],
            (None, Some(h)) => v[h],
            (None, None) => 0.0,
        };
    }
}

/// Log visibilities (DC removed) of sphere blockers: single caps of half-angle 1°..90° and
/// 200 pairs of caps at seeded random directions, for fitting [`OlTable`].
fn sphere_blocker_logs<const N: usize>(seed: u64) -> Vec<Sh<f64, N>> {
    let mut out = Vec::new();
    let cap_log = |alpha: f64, axis: [f64; 3]| -> Sh<f64, N> {
        let vis = unit::<N>() - cap_sh::<N>(alpha, axis);
        log_reference(&vis).0
    };
    for k in 1..=90 {
        let alpha = f64::from(k).to_radians();
        out.push(split_dc(&cap_log(alpha, [0.0, 0.0, 1.0])).1);
    }
    let mut rng = SplitMix64::new(seed);
    for _ in 0..200 {
        let a1 = rng.range(2.0, 60.0).to_radians();
        let a2 = rng.range(2.0, 60.0).to_radians();
        let d1 = sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
        let d2 = sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
        out.push(split_dc(&(cap_log(a1, d1) + cap_log(a2, d2))).1);
    }
    out
}

/// SH of the indicator of a cap of half-angle `alpha` around `axis` (for `N` = 1..=36).
fn cap_sh<const N: usize>(alpha: f64, axis: [f64; 3]) -> Sh<f64, N> {
    match N {
        1 => Zh::<f64, 1>::cap(alpha).rotate_to::<1>(axis).resize(),
        4 => Zh::<f64, 2>::cap(alpha).rotate_to::<4>(axis).resize(),
        9 => Zh::<f64, 3>::cap(alpha).rotate_to::<9>(axis).resize(),
        16 => Zh::<f64, 4>::cap(alpha).rotate_to::<16>(axis).resize(),
        25 => Zh::<f64, 5>::cap(alpha).rotate_to::<25>(axis).resize(),
        36 => Zh::<f64, 6>::cap(alpha).rotate_to::<36>(axis).resize(),
        _ => panic!("cap_sh supports 1, 4, 9, 16, 25 or 36 coefficients"),
    }
}

/// Visibility `1 - cap` of a sphere blocker of angular radius `alpha` seen along `axis`,
/// projected to `N` coefficients.
#[must_use]
pub fn sphere_visibility<const N: usize>(alpha: f64, axis: [f64; 3]) -> Sh<f64, N> {
    unit::<N>() - cap_sh::<N>(alpha, axis)
}

/// Norm below which [`exp_hyb`] applies OL directly. OL's error grows with the square of the
/// norm and each squaring doubles it; 0.1 was the better of 0.1 and 0.25 on sphere blockers
/// (`tests/shexp.rs` prints the table).
pub const HYB_NORM_THRESHOLD: f64 = 0.1;

/// HYB up to its squarings, for one vector `f` (Ren et al. 2006 §5, as in \[SGNS07\] Eq. 4):
/// DC isolation `f = f_0 / sqrt(4π) · 1 + f̂`, the number `k` of squarings, and OL of the
/// scaled-down `f̂ / 2^k`. Then `exp(f) = dc · ol^(2^k)` with `k` SH squarings of `ol`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HybStart<T, const N: usize> {
    /// `a 1 + b f̂ / 2^k`, OL's `exp(f̂ / 2^k)` with `(a, b)` at the norm `‖f̂‖ / 2^k`.
    pub ol: [T; N],
    /// `k`, the smallest number of squarings (at most 30) with `‖f̂‖ / 2^k <= threshold`.
    pub squarings: u32,
    /// The DC factor `exp(f_0 / sqrt(4π))`.
    pub dc: T,
}

/// The start of Ren's HYB for `f` (see [`HybStart`]), in `T`'s precision: `‖f̂‖`, `ol` and
/// the DC factor are computed in `T`, the norm comparisons and the OL coefficients in f64.
/// [`exp_hyb_with`] finishes it; callers that batch many vectors square the starts in
/// lockstep themselves.
#[must_use]
pub fn hyb_start<T: Real, const N: usize>(table: &OlTable<N>, f: &[T; N], threshold: f64) -> HybStart<T, N> {
    let sqrt_4pi = (4.0 * PI).sqrt();
    let mut hat = *f;
    hat[0] = T::ZERO;
    let norm = Sh(hat).norm();
    let mut k = 0u32;
    while norm.to_f64() / f64::from(1u32 << k) > threshold && k < 30 {
        k += 1;
    }
    // A power of two: scaling by it is exact, so `norm * s` is the norm of `f̂ / 2^k`.
    let s = T::from_f64(1.0 / f64::from(1u32 << k));
    let (a, b) = table.coefficients((norm * s).to_f64());
    let b = T::from_f64(b);
    let mut ol = hat.map(|v| v * s * b);
    ol[0] = T::from_f64(a * sqrt_4pi);
    HybStart { ol, squarings: k, dc: (f[0] / T::from_f64(sqrt_4pi)).exp() }
}

/// Ren's HYB exponential with a given SH squaring `square(g) = g * g`: [`hyb_start`], then
/// `k` squarings, then the DC factor. [`exp_hyb`] squares with [`product`]; a caller with a
/// faster squaring of its own (lightvol-proxies' f32 kernels, a packed symmetric schedule)
/// passes it here, so the algorithm exists once.
#[must_use]
pub fn exp_hyb_with<T: Real, const N: usize>(
    table: &OlTable<N>,
    f: &[T; N],
    threshold: f64,
    mut square: impl FnMut(&[T; N]) -> [T; N],
) -> [T; N] {
    let HybStart { ol: mut g, squarings, dc } = hyb_start(table, f, threshold);
    for _ in 0..squarings {
        g = square(&g);
    }
    g.map(|v| v * dc)
}

/// Ren's HYB exponential: DC isolation, then `exp(f̂) = exp(f̂ / 2^k)^(2^k)` with OL for the
/// small exponential and `k` SH squarings ([`product`]), `k` chosen so that
/// `‖f̂‖ / 2^k <= threshold`. The f64 instance is the reference; the f32 instance is its twin
/// (`tests/shexp.rs` compares them).
#[must_use]
pub fn exp_hyb<T: Real, const N: usize>(table: &OlTable<N>, f: &Sh<T, N>, threshold: f64) -> Sh<T, N> {
    Sh(exp_hyb_with(table, &f.0, threshold, |g| product(&Sh(*g), &Sh(*g)).0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_of_constant_and_zero() {
        let zero = Sh::<f64, 9>::ZERO;
        let e = exp_reference(&zero);
        assert!((e - unit::<9>()).norm() < 1e-14);
        // exp(c · 1) = e^c · 1.
        let c = unit::<9>() * 0.7;
        assert!((exp_reference(&c) - unit::<9>() * 0.7f64.exp()).norm() < 1e-13);
        // DC isolation is exact.
        let mut f = Sh::<f64, 9>([0.3, 0.1, -0.2, 0.05, 0.0, 0.1, -0.1, 0.02, 0.0]);
        let (dc, hat) = split_dc(&f);
        assert!((exp_reference(&f) - exp_reference(&hat) * dc).norm() < 1e-13);
        f.0[0] = 0.0;
        assert_eq!(hat, f);
    }

    /// The eigen route equals the power series `Σ f^k / k!` with SH products.
    #[test]
    fn exp_matches_series() {
        let f = Sh::<f64, 16>(core::array::from_fn(|i| 0.3 * ((i as f64) * 1.3).sin()));
        let mut term = unit::<16>();
        let mut sum = term;
        for k in 1..40 {
            term = product(&term, &f) * (1.0 / f64::from(k));
            sum += term;
        }
        assert!((exp_reference(&f) - sum).norm() < 1e-12);
    }
}
