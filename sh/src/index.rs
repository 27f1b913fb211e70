//! Coefficient indexing: `(l, m)` to a flat index `l*(l+1)+m` and back.
//!
//! An SH expansion with `n` *bands* (`l = 0..n`) has `n²` coefficients; graphics
//! literature also calls `n` the *order* ("order-3 SH" = 9 coefficients). In this crate
//! "bands" always means that count, and `l` is the degree of one band.

/// Flat index of the coefficient of degree `l` and order `m` (`-l <= m <= l`): `l*(l+1)+m`.
///
/// ```
/// use lightvol_sh::index::sh_index;
/// assert_eq!(sh_index(0, 0), 0);
/// assert_eq!(sh_index(1, -1), 1);
/// assert_eq!(sh_index(2, 2), 8);
/// ```
#[must_use]
#[inline]
pub const fn sh_index(l: u32, m: i32) -> usize {
    debug_assert!(m.unsigned_abs() <= l);
    ((l * (l + 1)) as i64 + m as i64) as usize
}

/// Inverse of [`sh_index`]: the `(l, m)` of a flat index.
#[must_use]
#[inline]
pub const fn sh_lm(index: usize) -> (u32, i32) {
    let l = index.isqrt() as u32;
    let m = index as i64 - (l * (l + 1)) as i64;
    (l, m as i32)
}

/// Number of coefficients of an expansion with `bands` bands: `bands²`.
#[must_use]
#[inline]
pub const fn num_coeffs(bands: usize) -> usize {
    bands * bands
}

/// Number of bands of an expansion with `n` coefficients, or `None` when `n` is not a
/// perfect square (and so not a whole number of bands).
#[must_use]
#[inline]
pub const fn bands_of(n: usize) -> Option<usize> {
    let b = n.isqrt();
    if b * b == n { Some(b) } else { None }
}

/// The degree `l` of every coefficient index below `n`, as an iterator.
pub fn degrees(n: usize) -> impl Iterator<Item = u32> {
    (0..n).map(|i| sh_lm(i).0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_round_trip() {
        let mut expected = 0;
        for l in 0..20u32 {
            for m in -(l as i32)..=(l as i32) {
                assert_eq!(sh_index(l, m), expected);
                assert_eq!(sh_lm(expected), (l, m));
                expected += 1;
            }
        }
    }

    #[test]
    fn bands() {
        assert_eq!(bands_of(9), Some(3));
        assert_eq!(bands_of(10), None);
        assert_eq!(bands_of(0), Some(0));
        assert_eq!(num_coeffs(6), 36);
    }
}
