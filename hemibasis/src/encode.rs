//! Storage encoding of coefficient maps (\[Ish11\] §2.2.3, Listings 2.1-2.2).
//!
//! The lightmap-like coefficient ([`HemiBasis::dc_index`], the constant term) is stored
//! through a transfer curve ([`DcTransfer`]): the thesis's gamma 2.2, `v = c^(1/2.2)`
//! ([`DcTransfer::Gamma22`], the default), or the piecewise sRGB curve of IEC 61966-2-1
//! ([`DcTransfer::Srgb`], which the hardware decodes exactly when the texture has an `_SRGB`
//! format; gamma 2.2 only approximates it, so an `_SRGB` texture must hold sRGB-encoded
//! values, as `lightvol bake-surface` writes). Every other coefficient is range-compressed
//! linearly like a normal map, `v = (c + r) / (2r)` with the compression range `r` (default
//! 0.75), decoded by `c = 2r v - r` (Listing 2.2's `2*0.75*tex - 0.75`). Stored values are clamped to `[0, 1]`; with 8-bit textures they are
//! also quantised to `k/255`.
//!
//! Correction to \[Ish11\] Listing 2.1: its compression line `modHc[] + 0.75/(2*0.75)` lost
//! its parentheses; the inverse of Listing 2.2's decode is `(modHc[] + 0.75) / (2*0.75)`.
//!
//! [`encoding_error`] measures what the round trip costs in irradiance, integrated exactly
//! over the hemisphere with the basis's Gram matrix.

use crate::basis::HemiBasis;

/// How the constant (lightmap) coefficient is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DcTransfer {
    /// `v = c^(1/2.2)`, the thesis's choice.
    #[default]
    Gamma22,
    /// The piecewise sRGB curve of IEC 61966-2-1 (what GPU sRGB formats decode exactly).
    Srgb,
    /// Range-compressed like the other coefficients.
    Linear,
}

impl DcTransfer {
    /// Linear value in `[0, 1]` → stored value.
    #[must_use]
    pub fn encode(self, c: f64) -> f64 {
        let c = c.clamp(0.0, 1.0);
        match self {
            Self::Gamma22 => c.powf(1.0 / 2.2),
            Self::Srgb => lightvol_core::color::srgb_encode(c),
            Self::Linear => c,
        }
    }

    /// Stored value → linear value.
    #[must_use]
    pub fn decode(self, v: f64) -> f64 {
        match self {
            Self::Gamma22 => v.max(0.0).powf(2.2),
            Self::Srgb => lightvol_core::color::srgb_decode(v),
            Self::Linear => v,
        }
    }
}

/// The encoding parameters (\[Ish11\] §2.2.3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Encoding {
    /// Range-compression factor `r`: non-DC coefficients in `[-r, r]` map to `[0, 1]`.
    pub range: f64,
    /// Transfer of the DC coefficient. With [`DcTransfer::Linear`] the DC coefficient is
    /// range-compressed too.
    pub dc: DcTransfer,
    /// Quantise stored values to 8 bits (`round(255 v) / 255`).
    pub quantize_8bit: bool,
}

impl Default for Encoding {
    /// The thesis's setting: gamma 2.2 DC, range 0.75, 8-bit textures.
    fn default() -> Self {
        Self { range: 0.75, dc: DcTransfer::Gamma22, quantize_8bit: true }
    }
}

/// Counts of values that did not fit the encodable range.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClampStats {
    /// DC values outside `[0, 1]` (negative irradiance or brighter than 1).
    pub dc_clamped: usize,
    /// Other values outside `[-range, range]`.
    pub ac_clamped: usize,
}

impl Encoding {
    fn is_dc(&self, basis: &dyn HemiBasis, i: usize) -> bool {
        self.dc != DcTransfer::Linear && basis.dc_index() == Some(i)
    }

    fn quantize(&self, v: f64) -> f64 {
        if self.quantize_8bit { (v * 255.0).round() / 255.0 } else { v }
    }

    /// Encodes RGB coefficients (coefficient-major) into stored values in `[0, 1]`.
    #[must_use]
    pub fn encode(&self, basis: &dyn HemiBasis, coeffs: &[[f64; 3]]) -> (Vec<[f64; 3]>, ClampStats) {
        let mut stats = ClampStats::default();
        let out = coeffs
            .iter()
            .enumerate()
            .map(|(i, c)| {
                c.map(|c| {
                    if self.is_dc(basis, i) {
                        if !(0.0..=1.0).contains(&c) {
                            stats.dc_clamped += 1;
                        }
                        self.quantize(self.dc.encode(c))
                    } else {
                        if c.abs() > self.range {
                            stats.ac_clamped += 1;
                        }
                        self.quantize(((c + self.range) / (2.0 * self.range)).clamp(0.0, 1.0))
                    }
                })
            })
            .collect();
        (out, stats)
    }

    /// Decodes stored values back to coefficients (Listing 2.2).
    #[must_use]
    pub fn decode(&self, basis: &dyn HemiBasis, stored: &[[f64; 3]]) -> Vec<[f64; 3]> {
        stored
            .iter()
            .enumerate()
            .map(|(i, v)| {
                v.map(|v| {
                    if self.is_dc(basis, i) { self.dc.decode(v) } else { 2.0 * self.range * v - self.range }
                })
            })
            .collect()
    }

    /// Encodes to 8-bit texels (`round(255 v)`), regardless of [`Self::quantize_8bit`].
    #[must_use]
    pub fn encode_u8(&self, basis: &dyn HemiBasis, coeffs: &[[f64; 3]]) -> (Vec<[u8; 3]>, ClampStats) {
        let (v, stats) = Encoding { quantize_8bit: false, ..*self }.encode(basis, coeffs);
        (v.iter().map(|c| c.map(|v| (v * 255.0).round() as u8)).collect(), stats)
    }

    /// Decodes 8-bit texels.
    #[must_use]
    pub fn decode_u8(&self, basis: &dyn HemiBasis, texels: &[[u8; 3]]) -> Vec<[f64; 3]> {
        let v: Vec<[f64; 3]> = texels.iter().map(|t| t.map(|b| f64::from(b) / 255.0)).collect();
        self.decode(basis, &v)
    }
}

/// The irradiance error an encoding round trip introduces for one set of coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncodingError {
    /// Per channel, `sqrt(∫_H (E' - E)² dω / 2π)`: the RMS irradiance error over the
    /// hemisphere (exact, `Δcᵀ G Δc`).
    pub rms: [f64; 3],
    /// Largest `|c' - c|` over all coefficients and channels.
    pub max_coeff_error: f64,
    /// Values that had to be clamped.
    pub clamped: ClampStats,
}

/// Encodes and decodes `coeffs` with `enc` and reports the error (\[Ish11\] §2.2.3).
#[must_use]
pub fn encoding_error(basis: &dyn HemiBasis, coeffs: &[[f64; 3]], enc: &Encoding) -> EncodingError {
    let (stored, clamped) = enc.encode(basis, coeffs);
    let back = enc.decode(basis, &stored);
    let g = basis.gram();
    let mut rms = [0.0; 3];
    let mut max_coeff_error: f64 = 0.0;
    for ch in 0..3 {
        let d: Vec<f64> = back.iter().zip(coeffs).map(|(b, c)| b[ch] - c[ch]).collect();
        max_coeff_error = d.iter().fold(max_coeff_error, |m, v| m.max(v.abs()));
        let gd = g.mul_vec(&d);
        let e2: f64 = d.iter().zip(&gd).map(|(a, b)| a * b).sum();
        rms[ch] = (e2.max(0.0) / (2.0 * std::f64::consts::PI)).sqrt();
    }
    EncodingError { rms, max_coeff_error, clamped }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ShBasis;

    /// f64 round trip without quantisation: pow/rounding only.
    const ROUND_TRIP_TOL: f64 = 1e-12;

    #[test]
    fn transfers_round_trip() {
        for t in [DcTransfer::Gamma22, DcTransfer::Srgb, DcTransfer::Linear] {
            for &c in &[0.0, 0.001, 0.002, 0.01, 0.2, 0.5, 1.0] {
                assert!((t.decode(t.encode(c)) - c).abs() < ROUND_TRIP_TOL, "{t:?} {c}");
            }
        }
        // The sRGB transfer is lightvol-core's (its own tests check the curve); 1 stays 1.
        assert!(DcTransfer::Srgb.encode(1.0) > 0.999_999);
    }

    #[test]
    fn unquantised_round_trip_is_exact_in_range_and_clamps_outside() {
        let b = ShBasis::new(2);
        let enc = Encoding { quantize_8bit: false, ..Encoding::default() };
        let c = [[0.5, 0.1, 0.9], [0.7, -0.7, 0.0], [0.3, -0.2, 0.1], [-0.5, 0.5, 0.74]];
        let e = encoding_error(&b, &c, &enc);
        assert!(e.max_coeff_error < ROUND_TRIP_TOL);
        assert_eq!(e.clamped, ClampStats::default());
        let bad = [[-0.1, 0.1, 1.5], [0.8, -0.7, 0.0], [0.3, -0.2, 0.1], [-0.5, 0.5, 0.74]];
        let e = encoding_error(&b, &bad, &enc);
        assert_eq!(e.clamped, ClampStats { dc_clamped: 2, ac_clamped: 1 });
        // DC -0.1 → 0 and 1.5 → 1; AC 0.8 → 0.75.
        assert!((e.max_coeff_error - 0.5).abs() < ROUND_TRIP_TOL);
    }

    /// Half-Life 2 has no lightmap coefficient: all three are range-compressed.
    #[cfg(feature = "hl2")]
    #[test]
    fn hl2_range_compresses_everything() {
        let enc = Encoding { quantize_8bit: false, ..Encoding::default() };
        let (stored, stats) = enc.encode(&crate::Hl2, &[[-0.5, 0.0, 0.75]; 3]);
        assert_eq!(stats, ClampStats::default());
        for v in &stored {
            assert!((v[0] - 1.0 / 6.0).abs() < ROUND_TRIP_TOL);
            assert!((v[1] - 0.5).abs() < ROUND_TRIP_TOL);
            assert!((v[2] - 1.0).abs() < ROUND_TRIP_TOL);
        }
    }

    #[test]
    fn eight_bit_error_is_bounded_by_half_a_step() {
        let b = ShBasis::new(3);
        let enc = Encoding::default();
        let mut c: Vec<[f64; 3]> =
            (0..9).map(|i| [0.05 * i as f64 + 0.3, -0.3, 0.123 * (i as f64 - 4.0) / 4.0]).collect();
        c[0] = [0.3, 0.6, 0.45];
        let e = encoding_error(&b, &c, &enc);
        // AC step is 2r/255; half of it bounds the AC error. The DC error through the gamma
        // curve near c ≈ 0.3-0.7 is below (half a step) × d(c)/dv ≤ 0.5/255 × 2.2.
        let bound = (0.5 / 255.0 * 2.2f64).max(0.75 / 255.0);
        assert!(e.max_coeff_error <= bound, "{}", e.max_coeff_error);
        assert!(e.max_coeff_error > 0.0);
        let (texels, _) = enc.encode_u8(&b, &c);
        let back = enc.decode_u8(&b, &texels);
        let (stored, _) = enc.encode(&b, &c);
        let back2 = enc.decode(&b, &stored);
        for (a, b) in back.iter().zip(&back2) {
            for ch in 0..3 {
                assert!((a[ch] - b[ch]).abs() < ROUND_TRIP_TOL);
            }
        }
    }
}
