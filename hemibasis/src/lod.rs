//! Level of detail for the modified H-basis (\[Ish11\] Listing 2.2, §3.2).
//!
//! The modified H-basis is built so that its first function alone is a lightmap: every
//! function but `H1 = 1/sqrt(2π)` vanishes at the unperturbed normal `n = (0, 0, 1)`
//! (`H2 ∝ y`, `H3 ∝ 1 - z`, `H4 ∝ x`, `H5 ∝ xy`, `H6 ∝ x² - y²`). Listing 2.2 therefore
//! stops the sum after 1 (lowest LOD, "light mapping"), 4 (linear band) or 6 (full)
//! coefficients. Because `H5` and `H6` are orthogonal on the hemisphere to `H1 … H4` (the
//! Gram matrix is block diagonal, see [`crate::hbasis`]), the 4-coefficient level is also
//! exactly the least-squares 4-coefficient fit: the levels are nested truncations.
//!
//! What the lowest level equals: the full evaluation at the geometric normal, for any
//! coefficients. It equals the true irradiance at the geometric normal (the plain
//! lightmap value) whenever the irradiance is linear in `n` (radiance of at most 2 SH
//! bands); for a 3-band SH irradiance converted with Listing 2.1 it is
//! `E(0,0,1) - sqrt(5)/(8 sqrt(π)) E_20`, the least-squares fit's error at the pole (test
//! `lightmap_level_of_sh9_pipeline_has_closed_form_offset`).

use crate::HemiBasis;
use crate::encode::Encoding;
use crate::hbasis::HBasis;

/// How many modified H-basis coefficients to evaluate (\[Ish11\] Listing 2.2's stop points).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Lod {
    /// `H1` only: a plain lightmap (the normal map has no effect).
    Lightmap,
    /// `H1 … H4`: the linear band ("middle LOD").
    Linear,
    /// `H1 … H6`: full evaluation.
    Full,
}

impl Lod {
    /// All levels, lowest first.
    pub const ALL: [Lod; 3] = [Lod::Lightmap, Lod::Linear, Lod::Full];

    /// Number of coefficients the level evaluates (1, 4 or 6).
    #[must_use]
    #[inline]
    pub const fn coefficients(self) -> usize {
        match self {
            Lod::Lightmap => 1,
            Lod::Linear => 4,
            Lod::Full => 6,
        }
    }

    /// The level that evaluates `count` coefficients (1, 4 or 6).
    #[must_use]
    pub const fn from_coefficients(count: usize) -> Option<Lod> {
        match count {
            1 => Some(Lod::Lightmap),
            4 => Some(Lod::Linear),
            6 => Some(Lod::Full),
            _ => None,
        }
    }
}

/// Evaluates modified H-basis RGB coefficients (4 or 6 of them, coefficient-major) at the
/// tangent-space normal `n`, summing only the first [`Lod::coefficients`] terms (\[Ish11\]
/// Listing 2.2 with decoded coefficients).
///
/// # Panics
/// If `coeffs` has fewer coefficients than the level needs.
#[must_use]
pub fn eval_modified_h(coeffs: &[[f64; 3]], n: [f64; 3], lod: Lod) -> [f64; 3] {
    let k = lod.coefficients();
    assert!(coeffs.len() >= k, "level {lod:?} needs {k} coefficients, got {}", coeffs.len());
    let mut b = [0.0; 6];
    HBasis::modified(6).expect("6 is a valid size").eval_f64(n, &mut b);
    let mut out = [0.0; 3];
    for (bj, c) in b.iter().zip(coeffs).take(k) {
        for ch in 0..3 {
            out[ch] += bj * c[ch];
        }
    }
    out
}

/// \[Ish11\] Listing 2.2 as written: decodes stored texel values (`tex2D` results in
/// `[0, 1]`, coefficient-major RGB) with `enc` and evaluates the first
/// [`Lod::coefficients`] terms at `n`. Only the coefficients the level reads are decoded,
/// as a shader that stops early samples only those textures.
///
/// # Panics
/// If `stored` has fewer coefficients than the level needs.
#[must_use]
pub fn eval_listing_2_2(stored: &[[f64; 3]], n: [f64; 3], lod: Lod, enc: &Encoding) -> [f64; 3] {
    let k = lod.coefficients();
    assert!(stored.len() >= k, "level {lod:?} needs {k} coefficients, got {}", stored.len());
    let basis = HBasis::modified(6).expect("6 is a valid size");
    let decoded = enc.decode(&basis, &stored[..k]);
    eval_modified_h(&decoded, n, lod)
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use lightvol_sh::irradiance::normalized_cosine_lobe_factor;

    use super::*;
    use crate::ShBasis;
    use crate::render::Sky;
    use crate::test_util::TEST_DIRS;

    /// Sums of six products of O(1) numbers: rounding only.
    const SUM_TOL: f64 = 1e-12;

    fn sample_coeffs() -> Vec<[f64; 3]> {
        (0..6).map(|j| [0.3 - 0.1 * j as f64, 0.05 * j as f64, 0.6 * (j as f64 * 0.7).sin()]).collect()
    }

    #[test]
    fn levels_are_nested_truncations_of_the_basis_evaluation() {
        let c = sample_coeffs();
        let h6 = HBasis::modified(6).unwrap();
        let h4 = HBasis::modified(4).unwrap();
        for &n in TEST_DIRS {
            let full = eval_modified_h(&c, n, Lod::Full);
            let want = h6.reconstruct_rgb_f64(&c, n);
            let lin = eval_modified_h(&c, n, Lod::Linear);
            let want_lin = h4.reconstruct_rgb_f64(&c[..4], n);
            // The 4-coefficient level reads only 4 coefficients.
            assert_eq!(eval_modified_h(&c[..4], n, Lod::Linear), lin);
            for ch in 0..3 {
                assert!((full[ch] - want[ch]).abs() < SUM_TOL);
                assert!((lin[ch] - want_lin[ch]).abs() < SUM_TOL);
            }
        }
    }

    /// The 4-coefficient least-squares fit is the truncated 6-coefficient fit (H5, H6 are
    /// orthogonal to H1..H4 on the hemisphere), so the middle level loses nothing against a
    /// dedicated 4-coefficient bake.
    #[test]
    fn four_coefficient_fit_is_the_truncated_six_coefficient_fit() {
        let e = Sky::grazing_sun().irradiance_sh(3);
        let c6 = HBasis::modified(6).unwrap().as_dyn().convert_sh_irradiance_rgb(&e);
        let c4 = HBasis::modified(4).unwrap().as_dyn().convert_sh_irradiance_rgb(&e);
        let scale = e[0][0].abs();
        for j in 0..4 {
            for ch in 0..3 {
                assert!((c6[j][ch] - c4[j][ch]).abs() < SUM_TOL * scale, "j={j}");
            }
        }
    }

    /// The lowest level is the full evaluation at the geometric normal, whatever the normal.
    #[test]
    fn lightmap_level_is_the_full_evaluation_at_the_geometric_normal() {
        let c = sample_coeffs();
        let at_pole = eval_modified_h(&c, [0.0, 0.0, 1.0], Lod::Full);
        // Independently: H1 = 1/sqrt(2π) because ∫_H H1² dω = 2π H1² = 1.
        let h1 = (1.0 / (2.0 * PI)).sqrt();
        for &n in TEST_DIRS {
            let lm = eval_modified_h(&c, n, Lod::Lightmap);
            for ch in 0..3 {
                assert!((lm[ch] - at_pole[ch]).abs() < SUM_TOL);
                assert!((lm[ch] - h1 * c[0][ch]).abs() < SUM_TOL);
            }
        }
    }

    /// A plain lightmap stores the irradiance at the geometric normal. For irradiance linear
    /// in `n` (radiance of at most 2 SH bands) the modified H-basis holds it exactly, so the
    /// lowest level equals the lightmap value `E(0,0,1) = (E_00 y_00 + E_10 y_10(z))`,
    /// computed here straight from the SH constants.
    #[test]
    fn lightmap_level_equals_a_plain_lightmap_for_linear_irradiance() {
        let radiance = [[0.8, 0.5, 0.2], [0.1, -0.2, 0.05], [0.4, 0.3, 0.35], [-0.2, 0.1, 0.0]];
        let e: Vec<[f64; 3]> = radiance
            .iter()
            .enumerate()
            .map(|(j, r)| r.map(|v| v * normalized_cosine_lobe_factor(j.isqrt() as u32)))
            .collect();
        let c = HBasis::modified(6).unwrap().as_dyn().convert_sh_irradiance_rgb(&e);
        let (y00, y10_pole) = (0.5 / PI.sqrt(), (3.0 / (4.0 * PI)).sqrt());
        for &n in TEST_DIRS {
            let lm = eval_modified_h(&c, n, Lod::Lightmap);
            for ch in 0..3 {
                let lightmap = e[0][ch] * y00 + e[2][ch] * y10_pole;
                assert!((lm[ch] - lightmap).abs() < SUM_TOL, "{lm:?} vs {lightmap}");
            }
        }
        // Uniform sky L: irradiance (normalised) is L at every normal; level 1 gives L.
        let uniform = [[2.0 * PI.sqrt(), 2.0 * PI.sqrt(), 2.0 * PI.sqrt()]; 1]; // L = 1
        let c = HBasis::modified(6).unwrap().as_dyn().convert_sh_irradiance_rgb(&uniform);
        let lm = eval_modified_h(&c, [0.6, 0.0, 0.8], Lod::Lightmap);
        assert!(lm.iter().all(|v| (v - 1.0).abs() < SUM_TOL), "{lm:?}");
    }

    /// With a 3-band SH irradiance (Listing 2.1) the lowest level differs from the lightmap
    /// value by the fit's error at the pole. Closed form from Listing 2.1's exact row 0
    /// (`1/sqrt2, sqrt(3/2), 3 sqrt5 / (4 sqrt2)` on `E_00, E_10, E_20`) times `H1`, against
    /// `y_00`, `y_10(pole) = sqrt(3/(4π))`, `y_20(pole) = sqrt(5/(4π))`:
    /// `level1 - E(pole) = (3 sqrt5/(8 sqrtπ) - sqrt5/(2 sqrtπ)) E_20 = -sqrt5/(8 sqrtπ) E_20`.
    #[test]
    fn lightmap_level_of_sh9_pipeline_has_closed_form_offset() {
        let e = Sky::grazing_sun().irradiance_sh(3);
        let c = HBasis::modified(6).unwrap().as_dyn().convert_sh_irradiance_rgb(&e);
        let lm = eval_modified_h(&c, [0.0, 0.0, 1.0], Lod::Lightmap);
        let pole = ShBasis::new(3).reconstruct_rgb_f64(&e, [0.0, 0.0, 1.0]);
        let k = -(5f64.sqrt()) / (8.0 * PI.sqrt());
        for ch in 0..3 {
            let want = pole[ch] + k * e[6][ch];
            assert!((lm[ch] - want).abs() < SUM_TOL * e[0][ch].abs(), "{} vs {want}", lm[ch]);
        }
    }

    /// Listing 2.2 on 8-bit texels agrees with the float evaluation within the encoding's
    /// half-step error: |ΔE| ≤ Σ_j |Δc_j| |H_j(n)|, with |Δc_j| ≤ 0.75/255 for the
    /// range-compressed terms and ≤ 2.2 × 0.5/255 for the gamma-2.2 DC term at c ≥ 0.3
    /// (d(v^2.2)/dv ≤ 2.2); |H_j| ≤ sqrt(15/(2π)) ≤ 1.55.
    #[test]
    fn listing_2_2_on_eight_bit_texels_matches_float_evaluation() {
        let enc = Encoding::default();
        let basis = HBasis::modified(6).unwrap();
        let mut c = sample_coeffs();
        c[0] = [0.35, 0.6, 0.9];
        let (stored, stats) = enc.encode(&basis, &c);
        assert_eq!(stats, crate::encode::ClampStats::default());
        let bound = 1.55 * (2.2 * 0.5 / 255.0 + 5.0 * 0.75 / 255.0);
        for &n in TEST_DIRS {
            for lod in Lod::ALL {
                let a = eval_listing_2_2(&stored, n, lod, &enc);
                let b = eval_modified_h(&c, n, lod);
                for ch in 0..3 {
                    assert!((a[ch] - b[ch]).abs() <= bound, "{lod:?} {a:?} vs {b:?}");
                }
            }
        }
        assert_eq!(Lod::from_coefficients(4), Some(Lod::Linear));
        assert_eq!(Lod::from_coefficients(5), None);
        assert!(Lod::ALL.iter().all(|l| Lod::from_coefficients(l.coefficients()) == Some(*l)));
    }
}
