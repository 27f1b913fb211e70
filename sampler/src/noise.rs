//! Baking until converged (`bake --noise`): each unit (a node, or a cell) is sampled in
//! rounds of doubling sample counts until the relative standard error of its estimate
//! falls below a target, or a cap is reached.
//!
//! A unit's estimate of its constant SH coefficient is the mean of its samples' values
//! (Kontkanen & Laine 2006 Eq. 4; Eq. 6 weights them, which the unweighted mean
//! approximates per unit); the values are the luminance of each sample's radiance over its
//! density. The standard error of that mean is `s / √n` with `s` the samples' standard
//! deviation, and the relative error divides it by the mean. Round `r` bakes the unit
//! afresh with `n₀ · 2^r` samples (the same per-sample streams, so every round's first
//! samples are the previous round's), and the last round is kept: what a unit receives
//! depends only on its own samples, so a bake is bit-identical for any thread or shard
//! count. Earlier rounds' rays are counted with the unit's, so the total stays honest
//! (at most twice the final round's).

use lightvol_core::samples::Samples;
use lightvol_scene::envmap::luminance;

/// Sample until the relative standard error of a unit's estimate is at most
/// `relative_error`, doubling from the bake's samples up to `max_samples`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseTarget {
    /// The relative standard error to reach (e.g. 0.01).
    pub relative_error: f64,
    /// The most samples a unit gets.
    pub max_samples: Samples,
}

/// Default cap of `--noise`: sixteen thousand samples per unit.
pub const DEFAULT_MAX_SAMPLES: u32 = 16_384;

/// The value of one sample (module docs): the luminance of its terms' radiance over
/// density, summed.
#[must_use]
pub(crate) fn sample_value(terms: &[[f64; 3]]) -> f64 {
    let mut sum = [0.0; 3];
    for t in terms {
        for ch in 0..3 {
            sum[ch] += t[ch];
        }
    }
    luminance(sum)
}

/// Relative standard error of the mean of `values` (module docs): `None` for fewer than
/// two values; 0 when every value is 0 (a unit that sees only black); infinite when they
/// are not all 0 but their mean is not positive.
pub(crate) fn relative_error_of(values: &[f64]) -> Option<f64> {
    let n = values.len();
    if n < 2 {
        return None;
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1) as f64;
    if var == 0.0 && mean == 0.0 {
        return Some(0.0);
    }
    if !(mean > 0.0) {
        return Some(f64::INFINITY);
    }
    Some((var / n as f64).sqrt() / mean)
}

/// Whether a unit whose samples have `values` meets `target`: its relative error is known
/// and at most the target's. A unit with fewer than two samples (outside the domain,
/// filled from its neighbours) has nothing more to gain.
pub(crate) fn converged(values: &[f64], target: &NoiseTarget) -> bool {
    relative_error_of(values).is_none_or(|e| e <= target.relative_error)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed form on a two-valued sample: values 0 and 2 in equal numbers have mean
    /// 1 and sample variance n/(n-1), so the relative standard error is 1/√(n-1).
    #[test]
    fn relative_error_of_a_two_valued_sample() {
        for n in [2usize, 8, 64, 1000] {
            let v: Vec<f64> = (0..n).map(|i| if i % 2 == 0 { 0.0 } else { 2.0 }).collect();
            let want = 1.0 / ((n - 1) as f64).sqrt();
            let got = relative_error_of(&v).unwrap();
            // Sums of n small integers are exact; the square root rounds once.
            assert!((got - want).abs() < 1e-15 * want.max(1.0), "{n}: {got} against {want}");
        }
        assert_eq!(relative_error_of(&[1.0]), None);
        assert_eq!(relative_error_of(&[0.0; 5]), Some(0.0));
        assert_eq!(relative_error_of(&[3.0; 5]), Some(0.0));
        assert_eq!(relative_error_of(&[-1.0, 1.0, -1.0]), Some(f64::INFINITY));
    }

    /// Quadrupling the samples of the same distribution halves the error.
    #[test]
    fn four_times_the_samples_halve_the_error() {
        let sample = |n: usize| -> Vec<f64> { (0..n).map(|i| [1.0, 3.0, 2.0, 6.0][i % 4]).collect() };
        let (a, b) = (relative_error_of(&sample(400)).unwrap(), relative_error_of(&sample(1600)).unwrap());
        // The sample variances differ by n/(n-1) factors: 1e-3 relative at n = 400.
        assert!((a / b - 2.0).abs() < 2e-3, "{a} {b}");
    }
}
