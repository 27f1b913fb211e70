//! Exact, order-free sums: fixed-point integers for the bake's Eq. 6 sums.
//!
//! Floating-point addition is not associative, so a bake split over shards or threads and
//! summed in another grouping differs from the whole bake in the last bits. The
//! [`Accumulator`](crate::Accumulator) therefore rounds every term once to a multiple of
//! 2^-[`FRAC_BITS`] and adds integers: integer addition is associative and commutative, so
//! every grouping — any shard count, shard order or thread count — gives the same bits.
//!
//! **Range.** Terms are rounded to the nearest multiple of 2^-64 ≈ 5.4e-20 (absolute).
//! A term of magnitude [`MAX_TERM`] (2^48 ≈ 2.8e14) or more, or a non-finite term, cannot be
//! represented and poisons its sum (it reads back as NaN, which the finalizer zeroes and
//! counts, as it does for a NaN radiance). Sums are exact while their true value stays
//! below 2^63 ≈ 9.2e18 in magnitude (i128 has 127 value bits, 64 of them fractional), which
//! holds for at least 2^15 terms of the largest size and for any number of terms whose sum
//! stays below 2^63 — a bake's sums are sample counts times radiances, far below it.
//! Additions wrap modulo 2^128, which is itself associative, so intermediate overflow in
//! any order cannot change a final sum that is in range.

/// Fractional bits of the fixed-point sums.
pub const FRAC_BITS: i32 = 64;

/// Terms at or beyond this magnitude (2^48) are not representable (see the module docs).
pub const MAX_TERM: f64 = 281_474_976_710_656.0;

/// 2^FRAC_BITS as f64 (exact: a power of two).
const SCALE: f64 = 18_446_744_073_709_551_616.0;

/// A term in fixed point: the nearest multiple of 2^-64 (ties away from zero), or `None`
/// when it is not finite or not below [`MAX_TERM`].
///
/// Read from the bits of `y = x · 2^64` (exact: a power-of-two scale) with integer
/// operations: `y = m · 2^e` with the 53-bit significand `m`, so the integer is `m << e`
/// for `e ≥ 0` and `(m + 2^(-e-1)) >> -e` (half away from zero, on the magnitude)
/// otherwise. Baseline x86-64 has no instruction for f64 `round` nor for an f64 to i128
/// conversion, so [`to_fixed_reference`]'s two library calls cost a bake a few percent;
/// the two agree on every input (tests).
#[must_use]
#[inline]
pub fn to_fixed(x: f64) -> Option<i128> {
    if !(x.abs() < MAX_TERM) {
        return None;
    }
    let bits = (x * SCALE).to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    if biased == 0 {
        // ±0 or subnormal: below 2^-1022, rounds to 0.
        return Some(0);
    }
    let m = (bits & ((1 << 52) - 1)) | (1 << 52);
    // y = m · 2^e; |y| < 2^112 (MAX_TERM · 2^64), so e ≤ 59 and m << e fits an i128.
    let e = biased - 1075;
    let magnitude = if e >= 0 {
        i128::from(m) << e
    } else if e >= -53 {
        // ((m >> (s - 1)) + 1) >> 1 = (m + 2^(s-1)) >> s for s = -e in 1..=53.
        i128::from(((m >> (-e - 1)) + 1) >> 1)
    } else {
        // |y| < 2^53 · 2^-54 = 1/2.
        0
    };
    Some(if bits >> 63 == 0 { magnitude } else { -magnitude })
}

/// [`to_fixed`] in floating point: `round(x · 2^64)` converted to i128 (exact for
/// |x · 2^64| < 2^124), the reference the integer form is tested against.
#[must_use]
pub fn to_fixed_reference(x: f64) -> Option<i128> {
    if x.abs() < MAX_TERM { Some((x * SCALE).round() as i128) } else { None }
}

/// A fixed-point sum as f64 (correctly rounded to nearest).
#[must_use]
#[inline]
pub fn from_fixed(v: i128) -> f64 {
    v as f64 / SCALE
}

/// An array of fixed-point sums with their poison flags (17 bytes per sum).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FixedSums {
    value: Vec<i128>,
    poisoned: Vec<bool>,
}

impl FixedSums {
    /// `n` zero sums.
    #[must_use]
    pub fn zeros(n: usize) -> Self {
        Self { value: vec![0; n], poisoned: vec![false; n] }
    }

    /// From raw values (no sum poisoned).
    #[must_use]
    pub fn from_raw(value: Vec<i128>) -> Self {
        let poisoned = vec![false; value.len()];
        Self { value, poisoned }
    }

    /// Number of sums.
    #[must_use]
    pub fn len(&self) -> usize {
        self.value.len()
    }

    /// True when there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.value.is_empty()
    }

    /// Appends `n` zero sums.
    pub fn extend_zeros(&mut self, n: usize) {
        self.value.resize(self.value.len() + n, 0);
        self.poisoned.resize(self.poisoned.len() + n, false);
    }

    /// Adds term `x` to sum `i`.
    ///
    /// # Panics
    /// If `i` is out of range.
    #[inline]
    pub fn add(&mut self, i: usize, x: f64) {
        match to_fixed(x) {
            Some(v) => self.value[i] = self.value[i].wrapping_add(v),
            None => self.poisoned[i] = true,
        }
    }

    /// Adds another array element-wise (exact).
    ///
    /// # Panics
    /// If the lengths differ.
    pub fn merge(&mut self, o: &FixedSums) {
        assert_eq!(self.len(), o.len(), "fixed-sum arrays of different lengths");
        for (a, b) in self.value.iter_mut().zip(&o.value) {
            *a = a.wrapping_add(*b);
        }
        for (a, b) in self.poisoned.iter_mut().zip(&o.poisoned) {
            *a |= *b;
        }
    }

    /// Adds a raw fixed-point value to sum `i` (exact).
    ///
    /// # Panics
    /// If `i` is out of range.
    #[inline]
    pub fn add_raw(&mut self, i: usize, v: i128) {
        self.value[i] = self.value[i].wrapping_add(v);
    }

    /// Adds sum `j` of `src` to sum `i` (exact; a poisoned `src` sum poisons sum `i`).
    ///
    /// # Panics
    /// If `i` or `j` is out of range.
    #[inline]
    pub fn add_sum(&mut self, i: usize, src: &FixedSums, j: usize) {
        self.value[i] = self.value[i].wrapping_add(src.value[j]);
        self.poisoned[i] |= src.poisoned[j];
    }

    /// Sum `i` as f64 (NaN when poisoned).
    #[must_use]
    #[inline]
    pub fn get(&self, i: usize) -> f64 {
        if self.poisoned[i] { f64::NAN } else { from_fixed(self.value[i]) }
    }

    /// Every sum as f64 (NaN where poisoned).
    #[must_use]
    pub fn to_f64(&self) -> Vec<f64> {
        (0..self.len()).map(|i| self.get(i)).collect()
    }

    /// The raw values (units of 2^-64).
    #[must_use]
    pub fn raw(&self) -> &[i128] {
        &self.value
    }

    /// The first poisoned sum, if any.
    #[must_use]
    pub fn first_poisoned(&self) -> Option<usize> {
        self.poisoned.iter().position(|&p| p)
    }

    /// The sums at `indices`, in that order (for sparse subsets).
    #[must_use]
    pub fn gather(&self, indices: impl Iterator<Item = usize>) -> Self {
        let mut out = Self::default();
        for i in indices {
            out.value.push(self.value[i]);
            out.poisoned.push(self.poisoned[i]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The integer rounding equals the floating-point reference: on ties at every
    /// scale (`(k + ½) · 2^-64 · 2^j`), around the subnormal, half-unit and largest terms,
    /// and on values drawn over the whole exponent range of both signs.
    #[test]
    fn integer_rounding_equals_the_float_reference() {
        let check = |x: f64| assert_eq!(to_fixed(x), to_fixed_reference(x), "{x:e} ({:#x})", x.to_bits());
        for special in [0.0, -0.0, f64::MIN_POSITIVE, 5e-324, 2f64.powi(-65), 2f64.powi(-64), MAX_TERM] {
            for x in [
                special,
                -special,
                f64::from_bits(special.to_bits() + 1),
                f64::from_bits(special.to_bits().max(1) - 1),
            ] {
                check(x);
            }
        }
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e300] {
            check(x);
        }
        for j in -70..48 {
            for k in [0u64, 1, 2, 3, 7, (1 << 52) - 1, 1 << 52] {
                let tie = (k as f64 + 0.5) * 2f64.powi(j - 64);
                for x in [tie, -tie, f64::from_bits(tie.to_bits() + 1), f64::from_bits(tie.to_bits() - 1)] {
                    check(x);
                }
            }
        }
        let mut rng = lightvol_sh::lowdisc::SplitMix64::new(7);
        for _ in 0..200_000 {
            let e = rng.range(-80.0, 50.0).floor() as i32;
            let x = rng.range(1.0, 2.0) * 2f64.powi(e);
            check(x);
            check(-x);
        }
    }

    /// The constants are the powers of two they claim to be.
    #[test]
    fn constants_are_powers_of_two() {
        assert_eq!(SCALE, 2f64.powi(FRAC_BITS));
        assert_eq!(MAX_TERM, 2f64.powi(48));
    }

    /// Round trip: dyadic values are exact; others are within half a unit (2^-65).
    #[test]
    fn round_trip_and_rounding() {
        for x in [0.0, 1.0, -0.5, 3.25, 1e-19 * 0.0, 2f64.powi(47)] {
            assert_eq!(from_fixed(to_fixed(x).unwrap()), x);
        }
        for x in [0.1, -1.0 / 3.0, std::f64::consts::PI, 1e-12] {
            let e = (from_fixed(to_fixed(x).unwrap()) - x).abs();
            assert!(e <= 2f64.powi(-65) + x.abs() * f64::EPSILON, "{x}: {e}");
        }
        assert_eq!(to_fixed(f64::NAN), None);
        assert_eq!(to_fixed(MAX_TERM), None);
        assert_eq!(to_fixed(-f64::INFINITY), None);
    }

    /// Any grouping and order of the same terms gives the same bits, where f64 sums differ.
    #[test]
    fn sums_are_order_free() {
        let terms: Vec<f64> =
            (0..1000).map(|i| ((i as f64) * 0.618_033_988_75).sin() * 10f64.powi(i % 7 - 3)).collect();
        let mut fwd = FixedSums::zeros(1);
        terms.iter().for_each(|&t| fwd.add(0, t));
        let mut rev = FixedSums::zeros(1);
        terms.iter().rev().for_each(|&t| rev.add(0, t));
        let (mut a, mut b) = (FixedSums::zeros(1), FixedSums::zeros(1));
        for (i, &t) in terms.iter().enumerate() {
            if i % 3 == 0 { a.add(0, t) } else { b.add(0, t) }
        }
        b.merge(&a);
        assert_eq!(fwd, rev);
        assert_eq!(fwd, b);
        let f64_fwd: f64 = terms.iter().sum();
        let f64_rev: f64 = terms.iter().rev().sum();
        assert_ne!(f64_fwd, f64_rev, "the f64 sums should differ for this test to mean anything");
        assert!((fwd.get(0) - f64_fwd).abs() < 1e-12);
        let mut p = FixedSums::zeros(1);
        p.add(0, f64::NAN);
        p.add(0, 1.0);
        assert!(p.get(0).is_nan());
        assert_eq!(p.first_poisoned(), Some(0));
    }

    /// Wrapping intermediate overflow does not change an in-range final sum.
    #[test]
    fn wrapping_is_harmless_for_in_range_results() {
        let big = 2f64.powi(47);
        let mut s = FixedSums::zeros(1);
        for _ in 0..(1 << 17) {
            s.add(0, big); // 2^17 · 2^47 · 2^64 = 2^128: wraps
        }
        for _ in 0..(1 << 17) {
            s.add(0, -big);
        }
        s.add(0, 0.25);
        assert_eq!(s.get(0), 0.25);
    }
}
