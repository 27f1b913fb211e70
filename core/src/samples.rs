//! Sample counts: how many samples a unit of work takes (per node, per cell, per texel, per
//! pixel, per plate point). A count of zero would make every estimate 0/0, so the type
//! cannot hold it: [`Samples`] is checked once where a count enters (a command-line option,
//! a file) and trusted everywhere after.
//!
//! A count of *rays* (what a bake traced in all, recorded in its files and reports) is a
//! plain `u64`: it is a measurement, not a setting, and zero is a valid one.

use std::num::NonZeroU32;

/// Samples per unit of work (at least one).
pub type Samples = NonZeroU32;

/// `n` samples.
///
/// # Panics
/// When `n` is 0; in a `const` context that is a compile error, so
/// `const S: Samples = samples(256);` checks its literal at build time.
#[must_use]
pub const fn samples(n: u32) -> Samples {
    match NonZeroU32::new(n) {
        Some(s) => s,
        None => panic!("a sample count is at least 1"),
    }
}

/// Parses a sample count: a decimal integer of at least 1.
///
/// # Errors
/// A one-line message for text that is no integer, or is 0.
pub fn parse_samples(s: &str) -> Result<Samples, String> {
    let n: u32 = s.trim().parse().map_err(|e| format!("{e}"))?;
    NonZeroU32::new(n).ok_or_else(|| "must be at least 1".to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_of_zero_are_refused() {
        const S: Samples = samples(256);
        assert_eq!(S.get(), 256);
        assert_eq!(parse_samples("64"), Ok(samples(64)));
        assert_eq!(parse_samples("0"), Err("must be at least 1".to_owned()));
        assert!(parse_samples("-3").is_err() && parse_samples("x").is_err());
        assert!(std::panic::catch_unwind(|| samples(0)).is_err());
    }
}
