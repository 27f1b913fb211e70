//! The shared-exponent format `E5B9G9R9_UFLOAT_PACK32` (OpenGL `EXT_texture_shared_exponent`,
//! "RGB9_E5"; Vulkan `VK_FORMAT_E5B9G9R9_UFLOAT_PACK32`): three 9-bit mantissas sharing one
//! 5-bit exponent in 32 bits, half the size of RGBA16F. Values are non-negative and at most
//! [`MAX`]; each channel is `m · 2^(e − 15 − 9)`.

/// Mantissa bits.
const N: i32 = 9;
/// Exponent bias.
const B: i32 = 15;
/// Largest exponent.
const E_MAX: i32 = 31;
/// The largest representable value, `(2^9 − 1)/2^9 · 2^(31 − 15)` = 65408.
pub const MAX: f64 = 511.0 / 512.0 * 65536.0;

/// `floor(log2(x))` for a positive finite `x`, exactly (from the f64 exponent bits).
fn floor_log2(x: f64) -> i32 {
    let bits = x.to_bits();
    let e = ((bits >> 52) & 0x7ff) as i32;
    if e == 0 {
        // Subnormal: far below the format's smallest step; any small value works.
        -1100
    } else {
        e - 1023
    }
}

/// Packs an RGB triple by the extension's algorithm (§ "RGB9E5 encoding"): channels are
/// clamped to `[0, MAX]` (negative and NaN to 0), the shared exponent comes from the largest
/// channel, and mantissas are rounded to nearest.
#[must_use]
pub fn pack(rgb: [f64; 3]) -> u32 {
    let c = rgb.map(|v| if v > 0.0 { v.min(MAX) } else { 0.0 });
    let maxc = c[0].max(c[1]).max(c[2]);
    if maxc == 0.0 {
        return 0;
    }
    let mut exp = (-B - 1).max(floor_log2(maxc)) + 1 + B;
    let step = |e: i32| 2f64.powi(e - B - N);
    let maxs = (maxc / step(exp) + 0.5).floor();
    if maxs == f64::from(1 << N) {
        exp += 1;
    }
    debug_assert!((0..=E_MAX).contains(&exp));
    let m = c.map(|v| ((v / step(exp) + 0.5).floor() as u32).min((1 << N) - 1));
    m[0] | (m[1] << 9) | (m[2] << 18) | ((exp as u32) << 27)
}

/// Unpacks a texel.
#[must_use]
pub fn unpack(t: u32) -> [f64; 3] {
    let exp = (t >> 27) as i32;
    let s = 2f64.powi(exp - B - N);
    [t & 0x1ff, (t >> 9) & 0x1ff, (t >> 18) & 0x1ff].map(|m| f64::from(m) * s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Worked values from the definition: 1.0 is mantissa 256 at exponent 16
    /// (`256 · 2^(16−24) = 1`); 65408 is the largest value (all mantissa bits, exponent 31).
    #[test]
    fn known_encodings() {
        assert_eq!(pack([1.0, 0.0, 0.0]), 256 | (16 << 27));
        assert_eq!(unpack(256 | (16 << 27)), [1.0, 0.0, 0.0]);
        assert_eq!(pack([MAX, MAX, MAX]), 0x1ff | (0x1ff << 9) | (0x1ff << 18) | (31 << 27));
        assert_eq!(pack([1e9, -1.0, f64::NAN]), pack([MAX, 0.0, 0.0]));
        assert_eq!(pack([0.0; 3]), 0);
        assert_eq!(MAX, 65408.0);
    }

    /// Round trip: the error of each channel is at most half a step of the shared exponent,
    /// and the largest channel keeps 9 significant bits (relative error ≤ 2^-9).
    #[test]
    fn round_trip_error_is_half_a_step() {
        let mut s = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..20_000 {
            let scale = 2f64.powf(next() * 30.0 - 15.0);
            let v = [next() * scale, next() * scale, next() * scale];
            let t = pack(v);
            let back = unpack(t);
            let step = 2f64.powi((t >> 27) as i32 - B - N);
            let maxc = v[0].max(v[1]).max(v[2]);
            for c in 0..3 {
                assert!((back[c] - v[c]).abs() <= 0.5 * step * (1.0 + 1e-12), "{v:?} -> {back:?}");
            }
            if maxc > 1e-4 {
                let m = back[0].max(back[1]).max(back[2]);
                assert!((m - maxc).abs() <= maxc / 512.0 + 1e-300, "{maxc} -> {m}");
            }
        }
    }
}
