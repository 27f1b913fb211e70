//! FNV-1a, 64-bit (\[FNV\], Fowler, Noll and Vo: the published offset basis and prime,
//! checked against the published test vectors below). Used for file checksums, scene and lighting
//! fingerprints; it detects accidental change, it is not a cryptographic hash.

/// FNV-1a 64-bit offset basis.
pub const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a 64-bit prime, `2^40 + 2^8 + 0xb3`.
pub const FNV_PRIME: u64 = (1 << 40) + (1 << 8) + 0xb3;

/// Incremental FNV-1a (64-bit), starting from [`FNV_OFFSET`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Self(FNV_OFFSET)
    }
}

impl Fnv1a {
    /// Continues from a hash value `h` (e.g. one returned by [`Self::finish`]).
    #[must_use]
    pub fn from_state(h: u64) -> Self {
        Self(h)
    }

    /// Feeds bytes.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(FNV_PRIME);
        }
    }

    /// Feeds a string prefixed by its length as 8 little-endian bytes (so that `"ab", "c"`
    /// and `"a", "bc"` hash differently).
    pub fn write_str(&mut self, s: &str) {
        self.write(&(s.len() as u64).to_le_bytes());
        self.write(s.as_bytes());
    }

    /// The hash so far.
    #[must_use]
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// FNV-1a of a byte string.
#[must_use]
pub fn fnv1a(bytes: &[u8]) -> u64 {
    fnv1a_from(FNV_OFFSET, bytes)
}

/// FNV-1a of `bytes`, continuing from the hash value `h`.
#[must_use]
pub fn fnv1a_from(h: u64, bytes: &[u8]) -> u64 {
    let mut f = Fnv1a::from_state(h);
    f.write(bytes);
    f.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Published FNV-1a 64 test vectors (Fowler/Noll/Vo): "", "a", "foobar"; the prime as
    /// the published hexadecimal.
    #[test]
    fn published_test_vectors() {
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
        assert_eq!(FNV_PRIME, 0x0000_0100_0000_01b3);
    }

    /// Streaming in pieces equals hashing the concatenation; strings are length-prefixed.
    #[test]
    fn streaming_equals_one_shot() {
        assert_eq!(fnv1a_from(fnv1a(b"foo"), b"bar"), fnv1a(b"foobar"));
        let mut a = Fnv1a::default();
        a.write_str("ab");
        a.write_str("c");
        let mut b = Fnv1a::default();
        b.write_str("a");
        b.write_str("bc");
        assert_ne!(a.finish(), b.finish());
        let mut c = Fnv1a::default();
        c.write(&2u64.to_le_bytes());
        c.write(b"ab");
        let mut d = Fnv1a::default();
        d.write_str("ab");
        assert_eq!(c, d);
    }
}
