//! Zonal harmonics (ZH): functions symmetric about the z axis, one coefficient per band.
//!
//! A ZH `g(s) = Σ_l g_l y_l0(s)` can be
//! - rotated to any axis `z'` (Sloan et al. 2007, \[SGNS07\] Eq. 8):
//!   `rot(g, z')_lm = sqrt(4π/(2l+1)) g_l y_lm(z')`;
//! - used as a convolution kernel (\[SGNS07\] Eq. 7):
//!   `(f * g)_lm = sqrt(4π/(2l+1)) f_lm g_l`.
//!
//! Analytic ZH of the clamped cosine `max(0, cos θ)` and of a spherical cap are provided in
//! closed form; tests derive both by quadrature.

use std::f64::consts::PI;

use crate::coeffs::Sh;
use crate::eval::eval_basis;
use crate::index::sh_lm;
use crate::irradiance::cosine_lobe_factor;
use crate::real::Real;
use crate::reference::legendre_p;

/// A zonal harmonic with `B` bands: `g(s) = Σ_l g_l y_l0(s)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Zh<T, const B: usize>(pub [T; B]);

/// `sqrt(4π / (2l + 1))`, the factor of \[SGNS07\] Eq. 7-8.
#[must_use]
#[inline]
pub fn zh_scale(l: u32) -> f64 {
    (4.0 * PI / f64::from(2 * l + 1)).sqrt()
}

impl<T: Real, const B: usize> Zh<T, B> {
    /// Rotates the ZH so that its axis points along the unit vector `axis` (\[SGNS07\] Eq. 8).
    /// `N` must be `B²` (checked at compile time).
    #[must_use]
    #[inline]
    pub fn rotate_to<const N: usize>(&self, axis: [T; 3]) -> Sh<T, N> {
        const { assert!(N == B * B, "rotate_to needs N = B * B") };
        let mut y = eval_basis::<T, N>(axis);
        for (i, v) in y.iter_mut().enumerate() {
            let l = sh_lm(i).0;
            *v *= self.0[l as usize] * T::from_f64(zh_scale(l));
        }
        Sh(y)
    }

    /// Convolves `f` with this kernel (\[SGNS07\] Eq. 7). Bands of `f` beyond `B` are zeroed.
    #[must_use]
    pub fn convolve<const N: usize>(&self, f: &Sh<T, N>) -> Sh<T, N> {
        let mut out = *f;
        for (i, v) in out.0.iter_mut().enumerate() {
            let l = sh_lm(i).0 as usize;
            let g = if l < B { self.0[l] * T::from_f64(zh_scale(l as u32)) } else { T::ZERO };
            *v *= g;
        }
        out
    }

    /// The ZH as a full SH vector along `+z` (`N = B²`).
    #[must_use]
    pub fn to_sh<const N: usize>(&self) -> Sh<T, N> {
        const { assert!(N == B * B, "to_sh needs N = B * B") };
        let mut out = [T::ZERO; N];
        for l in 0..B {
            out[l * (l + 1)] = self.0[l];
        }
        Sh(out)
    }

    /// Value at polar angle `θ` given `cos θ`.
    #[must_use]
    pub fn eval_cos(&self, cos_theta: f64) -> f64 {
        (0..B)
            .map(|l| {
                let norm = (f64::from(2 * l as u32 + 1) / (4.0 * PI)).sqrt();
                self.0[l].to_f64() * norm * legendre_p(l as u32, 0, cos_theta)
            })
            .sum()
    }
}

impl<const B: usize> Zh<f64, B> {
    /// ZH of the clamped cosine `max(0, cos θ)`: `g_l = A_l / sqrt(4π/(2l+1))`
    /// (so `sqrt(π)/2`, `sqrt(π/3)`, `sqrt(5π)/8`, 0, …).
    #[must_use]
    pub fn clamped_cosine() -> Self {
        Self(core::array::from_fn(|l| cosine_lobe_factor(l as u32) / zh_scale(l as u32)))
    }

    /// ZH of the indicator of a spherical cap of angular radius `alpha` around `+z`:
    /// `g_l = 2π sqrt((2l+1)/4π) ∫_{cos α}^1 P_l(t) dt`, with
    /// `∫_c^1 P_l = (P_{l-1}(c) - P_{l+1}(c)) / (2l+1)` for `l >= 1` and `1 - c` for `l = 0`.
    #[must_use]
    pub fn cap(alpha: f64) -> Self {
        let c = alpha.cos();
        Self(core::array::from_fn(|l| {
            let l = l as u32;
            let integral = if l == 0 {
                1.0 - c
            } else {
                (legendre_p(l - 1, 0, c) - legendre_p(l + 1, 0, c)) / f64::from(2 * l + 1)
            };
            2.0 * PI * (f64::from(2 * l + 1) / (4.0 * PI)).sqrt() * integral
        }))
    }

    /// Projects an axially symmetric function `f(cos θ)` by Gauss-Legendre quadrature with
    /// `n` nodes: exact when `f` is a polynomial of degree `<= 2n - B` in `cos θ`.
    #[must_use]
    pub fn project(f: impl Fn(f64) -> f64, n: usize) -> Self {
        let (t, w) = crate::quadrature::gauss_legendre(n);
        Self(core::array::from_fn(|l| {
            let norm = (f64::from(2 * l as u32 + 1) / (4.0 * PI)).sqrt();
            2.0 * PI
                * t.iter().zip(&w).map(|(&t, &w)| w * f(t) * norm * legendre_p(l as u32, 0, t)).sum::<f64>()
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::gauss_legendre;

    /// Exact quadrature of polynomial integrands; f64 rounding only.
    const EXACT: f64 = 1e-13;

    #[test]
    fn clamped_cosine_by_quadrature() {
        // max(0, t) is a polynomial (t) on [0, 1]: Gauss-Legendre mapped to [0, 1] is exact.
        let (t, w) = gauss_legendre(16);
        let z = Zh::<f64, 12>::clamped_cosine();
        for l in 0..12u32 {
            let norm = (f64::from(2 * l + 1) / (4.0 * PI)).sqrt();
            let q: f64 = t
                .iter()
                .zip(&w)
                .map(|(&t, &w)| {
                    let u = 0.5 * (t + 1.0);
                    0.5 * w * u * norm * legendre_p(l, 0, u)
                })
                .sum::<f64>()
                * 2.0
                * PI;
            assert!((z.0[l as usize] - q).abs() < EXACT, "l={l}: {} vs {q}", z.0[l as usize]);
        }
        assert!((z.0[0] - PI.sqrt() / 2.0).abs() < EXACT);
        assert!((z.0[1] - (PI / 3.0).sqrt()).abs() < EXACT);
        assert!((z.0[2] - (5.0 * PI).sqrt() / 8.0).abs() < EXACT);
    }

    #[test]
    fn cap_by_quadrature() {
        for alpha in [0.1, 0.7, 1.5, 2.5] {
            let c: f64 = f64::cos(alpha);
            let (t, w) = gauss_legendre(20);
            let z = Zh::<f64, 8>::cap(alpha);
            for l in 0..8u32 {
                let norm = (f64::from(2 * l + 1) / (4.0 * PI)).sqrt();
                // ∫_c^1 P_l(t) dt by GL mapped to [c, 1]: exact for a polynomial.
                let q: f64 = t
                    .iter()
                    .zip(&w)
                    .map(|(&t, &w)| {
                        let u = c + (1.0 - c) * 0.5 * (t + 1.0);
                        0.5 * (1.0 - c) * w * legendre_p(l, 0, u)
                    })
                    .sum::<f64>()
                    * 2.0
                    * PI
                    * norm;
                assert!((z.0[l as usize] - q).abs() < EXACT);
            }
            // DC term: solid angle / sqrt(4π).
            assert!((z.0[0] - 2.0 * PI * (1.0 - c) / (4.0 * PI).sqrt()).abs() < EXACT);
        }
    }

    #[test]
    fn rotation_to_z_is_identity_and_convolution_matches_irradiance() {
        let z = Zh::<f64, 3>::clamped_cosine();
        let r: Sh<f64, 9> = z.rotate_to([0.0, 0.0, 1.0]);
        let t = z.to_sh::<9>();
        for i in 0..9 {
            // rotate_to multiplies by sqrt(4π/(2l+1)) · y_l0(+z) = 1 up to rounding.
            assert!((r.0[i] - t.0[i]).abs() < EXACT);
        }
        // Convolving with the clamped cosine multiplies band l by A_l.
        let f = Sh::<f64, 9>([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
        let g = z.convolve(&f);
        for i in 0..9 {
            let l = sh_lm(i).0;
            assert!((g.0[i] - cosine_lobe_factor(l) * f.0[i]).abs() < EXACT);
        }
    }
}
