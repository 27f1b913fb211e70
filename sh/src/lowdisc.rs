//! Deterministic random and low-discrepancy sources shared by every lightvol crate.
//!
//! - [`Halton`]: the Halton sequence with Owen scrambling per dimension and per stream
//!   (pbrt-v4's `OwenScrambledRadicalInverse`). Scrambling keeps the sequence's
//!   stratification (every elementary interval of base `b` gets its share of points) while
//!   decorrelating streams, e.g. the grid cells of a bake (Kontkanen & Laine 2006 §6 use
//!   Halton points per cell).
//! - [`SplitMix64`]: a tiny seeded generator for tests and for deriving per-item seeds.
//! - [`mix_bits`] / [`hash2`]: integer hashing for "one seed per (cell, sample)" schemes, so
//!   that results never depend on thread scheduling.
//!
//! Nothing here reads a clock or OS entropy.

/// A 64-bit finaliser (the one pbrt-v4 and MurmurHash3 use as `MixBits`): a bijection with
/// good avalanche, used to turn structured integers into well-spread seeds.
#[must_use]
#[inline]
pub const fn mix_bits(mut v: u64) -> u64 {
    v ^= v >> 31;
    v = v.wrapping_mul(0x7fb5_d329_728e_a185);
    v ^= v >> 27;
    v = v.wrapping_mul(0x81da_def4_bc2d_d44d);
    v ^= v >> 33;
    v
}

/// Hash of two integers, e.g. `(seed, cell index)`.
#[must_use]
#[inline]
pub const fn hash2(a: u64, b: u64) -> u64 {
    mix_bits(a ^ mix_bits(b.wrapping_add(0x9e37_79b9_7f4a_7c15)))
}

/// The first `count` primes, by a sieve (no hand-typed table).
#[must_use]
pub fn primes(count: usize) -> Vec<u64> {
    let mut out = Vec::with_capacity(count);
    let mut candidate = 2u64;
    while out.len() < count {
        if out.iter().take_while(|&&p| p * p <= candidate).all(|&p| !candidate.is_multiple_of(p)) {
            out.push(candidate);
        }
        candidate += 1;
    }
    out
}

/// Kensler's hashed permutation: element `i` of a pseudo-random permutation of `0..l` chosen
/// by `p` (Kensler 2013, "Correlated Multi-Jittered Sampling", as in pbrt-v4).
#[must_use]
#[inline]
pub fn permutation_element(mut i: u32, l: u32, p: u32) -> u32 {
    let mut w = l - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
        i ^= p;
        i = i.wrapping_mul(0xe170_893d);
        i ^= p >> 16;
        i ^= (i & w) >> 4;
        i ^= p >> 8;
        i = i.wrapping_mul(0x0929_eb3f);
        i ^= p >> 23;
        i ^= (i & w) >> 1;
        i = i.wrapping_mul(1 | (p >> 27));
        i = i.wrapping_mul(0x6935_fa69);
        i ^= (i & w) >> 11;
        i = i.wrapping_mul(0x74dc_b303);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0x9e50_1cc3);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0xc860_a3df);
        i &= w;
        i ^= i >> 5;
        if i < l {
            break;
        }
    }
    (i.wrapping_add(p)) % l
}

/// Plain (unscrambled) radical inverse of `a` in base `base`: the van der Corput sequence.
#[must_use]
pub fn radical_inverse(base: u64, mut a: u64) -> f64 {
    let inv = 1.0 / base as f64;
    let mut inv_n = 1.0;
    let mut reversed = 0u64;
    while a > 0 {
        let next = a / base;
        reversed = reversed * base + (a - next * base);
        inv_n *= inv;
        a = next;
    }
    (reversed as f64 * inv_n).min(ONE_MINUS_EPSILON)
}

/// Largest f64 below 1.
pub const ONE_MINUS_EPSILON: f64 = 1.0 - f64::EPSILON / 2.0;

/// Owen-scrambled radical inverse: each digit is permuted by a permutation that depends on
/// the hash and on the whole prefix of more significant digits, continued until f64
/// precision is exhausted so that leading zero digits are scrambled too.
///
/// The prefix is identified by its value *and its length*. pbrt-v4's version hashes the
/// value alone, so the prefixes "0", "00", "000", … share one permutation: whenever the
/// first zero digit maps to 0 (probability 1/base) every later one does too, and point 0
/// lands exactly on 0. Hashing the length as well gives every tree node its own
/// permutation, as nested uniform scrambling requires.
#[must_use]
pub fn owen_scrambled_radical_inverse(base: u64, mut a: u64, hash: u32) -> f64 {
    let inv = 1.0 / base as f64;
    let mut inv_n = 1.0;
    let mut reversed = 0u64;
    let mut depth = 0u64;
    while 1.0 - (base - 1) as f64 * inv_n < 1.0 {
        let next = a / base;
        let digit = (a - next * base) as u32;
        let digit_hash = hash2(u64::from(hash) | (depth << 32), reversed) as u32;
        depth += 1;
        let digit = permutation_element(digit, base as u32, digit_hash);
        reversed = reversed * base + u64::from(digit);
        inv_n *= inv;
        a = next;
    }
    (reversed as f64 * inv_n).min(ONE_MINUS_EPSILON)
}

/// The Owen-scrambled Halton sequence: dimension `d` uses the `d`-th prime as its base.
///
/// Each [`Halton`] value is one *stream*; different seeds give independent scramblings of the
/// same well-stratified point set.
///
/// ```
/// use lightvol_sh::lowdisc::Halton;
/// let h = Halton::new(7, 2);
/// let p = h.point::<2>(5);
/// assert!(p.iter().all(|&v| (0.0..1.0).contains(&v)));
/// assert_eq!(p, Halton::new(7, 2).point::<2>(5)); // deterministic
/// ```
#[derive(Clone, Debug)]
pub struct Halton {
    seed: u64,
    bases: Vec<u64>,
    hashes: Vec<u32>,
}

impl Halton {
    /// A stream with `dims` dimensions scrambled by `seed`.
    #[must_use]
    pub fn new(seed: u64, dims: usize) -> Self {
        let bases = primes(dims);
        let hashes = (0..dims as u64).map(|d| hash2(seed, d) as u32).collect();
        Self { seed, bases, hashes }
    }

    /// The same dimensions, rescrambled for another stream (e.g. another grid cell).
    #[must_use]
    pub fn with_stream(&self, stream: u64) -> Self {
        Self::new(hash2(self.seed, stream), self.bases.len())
    }

    /// Number of dimensions.
    #[must_use]
    pub fn dims(&self) -> usize {
        self.bases.len()
    }

    /// Coordinate `dim` of point `index`, in `[0, 1)`.
    ///
    /// # Panics
    /// If `dim >= self.dims()`.
    #[must_use]
    #[inline]
    pub fn sample(&self, index: u64, dim: usize) -> f64 {
        owen_scrambled_radical_inverse(self.bases[dim], index, self.hashes[dim])
    }

    /// The first `D` coordinates of point `index`.
    ///
    /// # Panics
    /// If `D > self.dims()`.
    #[must_use]
    pub fn point<const D: usize>(&self, index: u64) -> [f64; D] {
        core::array::from_fn(|d| self.sample(index, d))
    }
}

/// SplitMix64 (Steele, Lea & Flood 2014): a seeded 64-bit generator for tests and seeding.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator with the given seed.
    #[must_use]
    pub const fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// Next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[lo, hi)`.
    #[inline]
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primes_are_primes() {
        assert_eq!(primes(10), vec![2, 3, 5, 7, 11, 13, 17, 19, 23, 29]);
    }

    #[test]
    fn van_der_corput_base_2() {
        let v: Vec<f64> = (0..5).map(|i| radical_inverse(2, i)).collect();
        assert_eq!(v, vec![0.0, 0.5, 0.25, 0.75, 0.125]);
    }

    #[test]
    fn permutation_is_a_permutation() {
        for l in [2u32, 3, 5, 7, 13] {
            for p in [0u32, 1, 0xdead_beef] {
                let mut seen: Vec<u32> = (0..l).map(|i| permutation_element(i, l, p)).collect();
                seen.sort_unstable();
                assert_eq!(seen, (0..l).collect::<Vec<_>>());
            }
        }
    }

    /// Owen scrambling keeps the (0, 1)-sequence property per dimension: the first `b^k`
    /// points put exactly one point in each interval `[j/b^k, (j+1)/b^k)`.
    #[test]
    fn scrambled_halton_is_stratified() {
        for seed in [0u64, 1, 12345] {
            let h = Halton::new(seed, 3);
            for (dim, &base) in [2u64, 3, 5].iter().enumerate() {
                for k in 1..=4u32 {
                    let n = base.pow(k);
                    let mut counts = vec![0u32; n as usize];
                    for i in 0..n {
                        let v = h.sample(i, dim);
                        counts[(v * n as f64) as usize] += 1;
                    }
                    assert!(counts.iter().all(|&c| c == 1), "seed {seed} base {base} k {k}");
                }
            }
        }
    }

    /// Point 0 of a scrambled stream is uniform over [0, 1): it must not sit exactly on 0
    /// (pbrt-v4's prefix hash puts it there with probability 1/base).
    #[test]
    fn first_point_is_not_pinned_to_zero() {
        let mut zeros = 0;
        let mut mean = 0.0;
        let n = 4000;
        for seed in 0..n {
            let h = Halton::new(seed, 3);
            for d in 0..3 {
                let v = h.sample(0, d);
                zeros += usize::from(v == 0.0);
                mean += v;
            }
        }
        assert_eq!(zeros, 0);
        mean /= f64::from(3 * n as u32);
        // Mean of 12000 uniforms: standard error 0.0026; allow 5 sigma.
        assert!((mean - 0.5).abs() < 0.013, "mean of point 0 = {mean}");
    }

    #[test]
    fn streams_differ_and_repeat() {
        let a = Halton::new(1, 2);
        let b = a.with_stream(5);
        assert_ne!(a.point::<2>(3), b.point::<2>(3));
        assert_eq!(b.point::<2>(3), Halton::new(1, 2).with_stream(5).point::<2>(3));
    }

    #[test]
    fn splitmix_mean() {
        let mut r = SplitMix64::new(42);
        let n = 100_000;
        let mean: f64 = (0..n).map(|_| r.next_f64()).sum::<f64>() / n as f64;
        // Standard error of the mean of U(0,1) is sqrt(1/12/n) ≈ 9e-4; allow 5 sigma.
        assert!((mean - 0.5).abs() < 5.0 * (1.0 / 12.0 / n as f64).sqrt());
    }
}
