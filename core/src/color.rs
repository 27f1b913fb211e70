//! The sRGB transfer function (\[IEC99\], IEC 61966-2-1): the piecewise curve between linear light and
//! sRGB-encoded values in `[0, 1]`, in f64 and f32, and its 8-bit quantisation.
//!
//! The standard's constants: encode `12.92 x` up to `x = 0.0031308`, else
//! `1.055 x^(1/2.4) - 0.055`; decode `y / 12.92` up to `y = 0.04045`, else
//! `((y + 0.055) / 1.055)^2.4`. The tests check that the two thresholds are the same point
//! of the curve and that the pieces meet there.

/// Linear-segment end of the encode, in linear light.
pub const ENCODE_THRESHOLD: f64 = 0.003_130_8;
/// Linear-segment end of the decode, in encoded units (`12.92 ×` [`ENCODE_THRESHOLD`],
/// rounded as the standard prints it).
pub const DECODE_THRESHOLD: f64 = 0.040_45;

macro_rules! transfer {
    ($t:ty, $enc:ident, $dec:ident) => {
        /// sRGB encoding of a linear value in `[0, 1]` (IEC 61966-2-1).
        #[must_use]
        pub fn $enc(x: $t) -> $t {
            if x <= ENCODE_THRESHOLD as $t { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 }
        }

        /// Linear value of an sRGB-encoded value in `[0, 1]` (the hardware sRGB decode).
        #[must_use]
        pub fn $dec(y: $t) -> $t {
            if y <= DECODE_THRESHOLD as $t { y / 12.92 } else { ((y + 0.055) / 1.055).powf(2.4) }
        }
    };
}

transfer!(f64, srgb_encode, srgb_decode);
transfer!(f32, srgb_encode_f32, srgb_decode_f32);

/// A linear value as an 8-bit sRGB code: clamped to `[0, 1]`, encoded, rounded to nearest.
#[must_use]
pub fn srgb8(v: f32) -> u8 {
    (srgb_encode_f32(v.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rounding of the f64 curve near its threshold.
    const CURVE_TOL: f64 = 1e-6;
    /// The pieces meet to within the rounding of the printed four-digit constants: the
    /// standard's curve has a small step at the threshold (about 1e-8 in the decode's units).
    const JOIN_TOL: f64 = 1e-7;
    /// f32 round trip: a few ulps of values up to 1.
    const F32_TOL: f32 = 1e-6;

    #[test]
    fn thresholds_are_one_point_of_the_curve() {
        assert!((12.92 * ENCODE_THRESHOLD - DECODE_THRESHOLD).abs() < 1e-5);
        let t = ENCODE_THRESHOLD;
        assert!((12.92 * t - (1.055 * t.powf(1.0 / 2.4) - 0.055)).abs() < CURVE_TOL);
        let d = DECODE_THRESHOLD;
        assert!((d / 12.92 - ((d + 0.055) / 1.055).powf(2.4)).abs() < JOIN_TOL);
        // The f32 curve compares against the f32 nearest the printed constants.
        assert_eq!(ENCODE_THRESHOLD as f32, 0.003_130_8_f32);
        assert_eq!(DECODE_THRESHOLD as f32, 0.040_45_f32);
    }

    #[test]
    fn decode_inverts_encode() {
        for i in 0..=1000 {
            let x = f64::from(i) / 1000.0;
            assert!((srgb_decode(srgb_encode(x)) - x).abs() < 1e-12, "{x}");
            let xf = x as f32;
            assert!((srgb_decode_f32(srgb_encode_f32(xf)) - xf).abs() < F32_TOL, "{x}");
        }
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-15, "1.055 - 0.055 rounds");
        assert_eq!(srgb_encode(0.0), 0.0);
    }

    /// Known 8-bit codes: 0, 1, and 50% linear light at 188 (0.7354 encoded); values outside
    /// `[0, 1]` clamp.
    #[test]
    fn eight_bit_codes() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert_eq!(srgb8(0.5), 188);
        assert_eq!(srgb8(-1.0), 0);
        assert_eq!(srgb8(7.0), 255);
        assert_eq!(srgb8(f32::NAN), 0);
    }
}
