//! Irradiance from radiance: the clamped-cosine convolution and its three 9-coefficient
//! evaluators.
//!
//! For radiance `L(ω) = Σ L_lm y_lm(ω)`, irradiance at a surface with normal `n` is
//! `E(n) = ∫ L(ω) max(0, n·ω) dω = Σ A_l L_lm y_lm(n)` (Ramamoorthi & Hanrahan 2001,
//! "An Efficient Representation for Irradiance Environment Maps", Eq. 7-9), with
//!
//! - `A_0 = π`, `A_1 = 2π/3`,
//! - `A_l = 0` for odd `l > 1`,
//! - `A_l = 2π (-1)^{l/2-1} / ((l+2)(l-1)) · l! / (2^l ((l/2)!)²)` for even `l`.
//!
//! The same irradiance is available as
//!
//! - [`irradiance`]: the sum above, any order;
//! - [`RhMatrix`]: Ramamoorthi-Hanrahan's 4×4 quadratic form `E(n) = nᵀ M n`, `n = (x, y, z, 1)`
//!   (their Eq. 12);
//! - [`PackedIrradiance`]: the seven `float4` shader constants `cAr … cC` of Oat's "SH
//!   Evaluation With Normal" slide (\[Oat05\], from the DirectX SDK).
//!
//! Tests check that all three agree and that they equal brute-force quadrature.
//!
//! Note on the DirectX SDK's version of the packed constants: it folds in a `1/π` (it
//! returns exit radiance for white albedo, `E/π`) and uses Condon-Shortley signs. The
//! constants here return `E` itself in this crate's convention.

use std::f64::consts::PI;

use crate::coeffs::{Sh, Sh9, ShRgb, ShRgb9};
use crate::eval::eval_basis;
use crate::index::sh_lm;
use crate::real::Real;

/// `A_l`, the clamped-cosine convolution factor of band `l` (RH 2001 Eq. 8-9).
///
/// ```
/// use lightvol_sh::irradiance::cosine_lobe_factor;
/// use std::f64::consts::PI;
/// assert!((cosine_lobe_factor(0) - PI).abs() < 1e-15);
/// assert!((cosine_lobe_factor(2) - PI / 4.0).abs() < 1e-15);
/// assert_eq!(cosine_lobe_factor(3), 0.0);
/// ```
#[must_use]
pub fn cosine_lobe_factor(l: u32) -> f64 {
    match l {
        0 => PI,
        1 => 2.0 * PI / 3.0,
        _ if l % 2 == 1 => 0.0,
        _ => {
            // l! / (2^l ((l/2)!)²) = C(l, l/2) / 2^l = Π_{k=1}^{l/2} (2k-1)/(2k).
            let half = l / 2;
            let central: f64 = (1..=half).map(|k| (2 * k - 1) as f64 / (2 * k) as f64).product();
            let sign = if half % 2 == 1 { 1.0 } else { -1.0 }; // (-1)^{l/2 - 1}
            let lf = f64::from(l);
            2.0 * PI * sign / ((lf + 2.0) * (lf - 1.0)) * central
        }
    }
}

/// `A_l / π`: the factors of the *normalised* clamped cosine `max(0, cos θ)/π`
/// (1, 2/3, 1/4, 0, -1/24, …), which maps radiance to exit radiance of a white diffuse surface.
#[must_use]
pub fn normalized_cosine_lobe_factor(l: u32) -> f64 {
    cosine_lobe_factor(l) / PI
}

/// Convolves radiance with the clamped cosine: the SH of irradiance, `E_lm = A_l L_lm`.
#[must_use]
pub fn radiance_to_irradiance<T: Real, const N: usize>(radiance: &Sh<T, N>) -> Sh<T, N> {
    let mut out = *radiance;
    for i in 0..N {
        out.0[i] *= T::from_f64(cosine_lobe_factor(sh_lm(i).0));
    }
    out
}

/// RGB version of [`radiance_to_irradiance`].
#[must_use]
pub fn radiance_to_irradiance_rgb<T: Real, const N: usize>(radiance: &ShRgb<T, N>) -> ShRgb<T, N> {
    radiance.map(radiance_to_irradiance)
}

/// Irradiance `E(n) = Σ A_l L_lm y_lm(n)` at the unit normal `n`, from radiance SH.
#[must_use]
#[inline]
pub fn irradiance<T: Real, const N: usize>(radiance: &Sh<T, N>, normal: [T; 3]) -> T {
    radiance_to_irradiance(radiance).eval(normal)
}

/// RGB irradiance at the unit normal `n`, from RGB radiance SH.
#[must_use]
#[inline]
pub fn irradiance_rgb<T: Real, const N: usize>(radiance: &ShRgb<T, N>, normal: [T; 3]) -> [T; 3] {
    let y = Sh(eval_basis::<T, N>(normal));
    radiance_to_irradiance_rgb(radiance).dot_scalar(&y)
}

/// Ramamoorthi-Hanrahan's constants (2001, Eq. 12), as exact expressions:
/// `c1 = sqrt(15π)/16`, `c2 = sqrt(3π)/6`, `c3 = 3 sqrt(5π)/16`, `c4 = sqrt(π)/2`,
/// `c5 = sqrt(5π)/16`. (The paper prints them to six digits: 0.429043, 0.511664, 0.743125,
/// 0.886227, 0.247708.) Each is `A_l` times a basis constant; see the tests.
#[must_use]
pub fn rh_constants() -> [f64; 5] {
    [
        (15.0 * PI).sqrt() / 16.0,
        (3.0 * PI).sqrt() / 6.0,
        3.0 * (5.0 * PI).sqrt() / 16.0,
        PI.sqrt() / 2.0,
        (5.0 * PI).sqrt() / 16.0,
    ]
}

/// The symmetric 4×4 matrix `M` with `E(n) = (x, y, z, 1) M (x, y, z, 1)ᵀ`
/// (Ramamoorthi & Hanrahan 2001, Eq. 12), for one colour channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RhMatrix(pub [[f64; 4]; 4]);

impl RhMatrix {
    /// Builds `M` from 9 radiance coefficients (this crate's convention matches RH's: no
    /// Condon-Shortley phase, `y_11 ∝ x`).
    #[must_use]
    pub fn from_radiance(l: &Sh9<f64>) -> Self {
        let [c1, c2, c3, c4, c5] = rh_constants();
        let c = &l.0;
        // Flat indices: 0:L00 1:L1-1 2:L10 3:L11 4:L2-2 5:L2-1 6:L20 7:L21 8:L22.
        Self([
            [c1 * c[8], c1 * c[4], c1 * c[7], c2 * c[3]],
            [c1 * c[4], -c1 * c[8], c1 * c[5], c2 * c[1]],
            [c1 * c[7], c1 * c[5], c3 * c[6], c2 * c[2]],
            [c2 * c[3], c2 * c[1], c2 * c[2], c4 * c[0] - c5 * c[6]],
        ])
    }

    /// `E(n) = nᵀ M n` with `n = (x, y, z, 1)`.
    #[must_use]
    pub fn irradiance(&self, n: [f64; 3]) -> f64 {
        let v = [n[0], n[1], n[2], 1.0];
        let mut e = 0.0;
        for i in 0..4 {
            for j in 0..4 {
                e += v[i] * self.0[i][j] * v[j];
            }
        }
        e
    }
}

/// Oat's packed shader constants (\[Oat05\], "SH Evaluation With Normal"; DirectX SDK):
///
/// ```text
/// x1.r = dot(cAr, n)                    with n = (x, y, z, 1)
/// vB   = n.xyzz * n.yzzx = (xy, yz, z², zx)
/// x2.r = dot(cBr, vB)
/// x3   = cC.rgb * (x² - y²)
/// E    = x1 + x2 + x3
/// ```
///
/// Built here to return irradiance `E` in this crate's convention.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PackedIrradiance {
    /// Linear + constant terms, red: `(x, y, z, 1)` coefficients.
    pub c_ar: [f32; 4],
    /// Linear + constant terms, green.
    pub c_ag: [f32; 4],
    /// Linear + constant terms, blue.
    pub c_ab: [f32; 4],
    /// Four quadratic terms `(xy, yz, z², zx)`, red.
    pub c_br: [f32; 4],
    /// Four quadratic terms, green.
    pub c_bg: [f32; 4],
    /// Four quadratic terms, blue.
    pub c_bb: [f32; 4],
    /// `x² - y²` term for red, green, blue (w unused, 0).
    pub c_c: [f32; 4],
}

impl PackedIrradiance {
    /// Packs RGB radiance SH (9 coefficients per channel).
    #[must_use]
    pub fn from_radiance(radiance: &ShRgb9<f64>) -> Self {
        let [c1, c2, c3, c4, c5] = rh_constants();
        // Expanding nᵀ M n: off-diagonal entries appear twice.
        let ab = |l: &Sh9<f64>| -> ([f32; 4], [f32; 4]) {
            let c = &l.0;
            let a = [2.0 * c2 * c[3], 2.0 * c2 * c[1], 2.0 * c2 * c[2], c4 * c[0] - c5 * c[6]];
            // z² coefficient: c3 L20 (the x² - y² term absorbs the rest of the diagonal).
            let b = [2.0 * c1 * c[4], 2.0 * c1 * c[5], c3 * c[6], 2.0 * c1 * c[7]];
            (a.map(|v| v as f32), b.map(|v| v as f32))
        };
        let (c_ar, c_br) = ab(&radiance.0[0]);
        let (c_ag, c_bg) = ab(&radiance.0[1]);
        let (c_ab, c_bb) = ab(&radiance.0[2]);
        let cc = |l: &Sh9<f64>| (c1 * l.0[8]) as f32;
        let c_c = [cc(&radiance.0[0]), cc(&radiance.0[1]), cc(&radiance.0[2]), 0.0];
        Self { c_ar, c_ag, c_ab, c_br, c_bg, c_bb, c_c }
    }

    /// Evaluates exactly as the shader does, in f32.
    #[must_use]
    pub fn irradiance(&self, n: [f32; 3]) -> [f32; 3] {
        let v = [n[0], n[1], n[2], 1.0];
        let vb = [n[0] * n[1], n[1] * n[2], n[2] * n[2], n[2] * n[0]];
        let vc = n[0] * n[0] - n[1] * n[1];
        let dot = |a: &[f32; 4], b: &[f32; 4]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
        [
            dot(&self.c_ar, &v) + dot(&self.c_br, &vb) + self.c_c[0] * vc,
            dot(&self.c_ag, &v) + dot(&self.c_bg, &vb) + self.c_c[1] * vc,
            dot(&self.c_ab, &v) + dot(&self.c_bb, &vb) + self.c_c[2] * vc,
        ]
    }
}
