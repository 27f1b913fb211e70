//! The low-discrepancy streams of the bake: lightvol-sh's Owen-scrambled Halton sequence,
//! one stream per cell (or node, or plate point), plus a per-stream Cranley-Patterson
//! rotation.
//!
//! The rotation works around a weakness of `lightvol_sh::lowdisc::owen_scrambled_radical_inverse`
//! (as of this writing): the digit permutation's hash depends on the permuted prefix but not
//! on the digit's position, so while the permuted prefix is all zeros every digit uses the
//! same permutation. Index 0 then lands exactly on 0, 1/2 (base 3), ... for a large share
//! of streams (measured: 1312 exact zeros in 40000 coordinates of the first 8 points of
//! 1000 five-dimensional streams), which put sample origins exactly on cell faces. A
//! random toroidal shift per stream and dimension removes those special values and keeps
//! the sequence's equidistribution. TODO(sh): move the fix into lightvol-sh.

use lightvol_sh::lowdisc::{Halton, SplitMix64, hash2};

/// A `D`-dimensional scrambled and rotated Halton stream.
#[derive(Clone, Debug)]
pub struct Qmc<const D: usize> {
    halton: Halton,
    shift: [f64; D],
}

impl<const D: usize> Qmc<D> {
    /// Stream `stream` under `seed`.
    #[must_use]
    pub fn new(seed: u64, stream: u64) -> Self {
        let key = hash2(seed, stream);
        let mut rng = SplitMix64::new(hash2(key, 0x5348_4946_54));
        Self { halton: Halton::new(key, D), shift: std::array::from_fn(|_| rng.next_f64()) }
    }

    /// Point `i`, every coordinate in [0, 1).
    #[must_use]
    #[inline]
    pub fn point(&self, i: u64) -> [f64; D] {
        std::array::from_fn(|d| {
            let v = self.halton.sample(i, d) + self.shift[d];
            let v = if v >= 1.0 { v - 1.0 } else { v };
            // v - 1 can round to exactly 1 - 2^-53 + ...; keep strictly below 1.
            v.min(lightvol_sh::lowdisc::ONE_MINUS_EPSILON)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No coordinate of the first points of many streams is exactly 0 or 1/2 (the values
    /// the unrotated sequence produces at index 0), and the streams are stratified: each of
    /// 16 equal bins of dimension 0 gets 1/16 of 1024 points up to the rotation's boundary
    /// effect (at most one point moves per bin edge).
    #[test]
    fn no_special_values_and_still_stratified() {
        for s in 0..200 {
            let q = Qmc::<5>::new(1, s);
            for i in 0..4 {
                assert!(q.point(i).iter().all(|&v| v != 0.0 && v != 0.5 && (0.0..1.0).contains(&v)));
            }
        }
        let q = Qmc::<2>::new(3, 7);
        let mut bins = [0u32; 16];
        for i in 0..1024 {
            bins[(q.point(i)[0] * 16.0) as usize] += 1;
        }
        assert!(bins.iter().all(|&b| (63..=65).contains(&b)), "{bins:?}");
    }
}
