//! The relative RMSE, lightvol's one error measure against a reference:
//!
//! `rel_rmse = sqrt(mean((E - T)²)) / mean(T)`
//!
//! over `n` pairs of an estimate `E` and its reference `T` (plate points, pixels, or
//! pixel channels). Dividing by the *mean* reference, not each point's, keeps dark points
//! from dominating, and makes the value the RMSE in units of the scene's average level.

/// Running sums of [`rel_rmse`]: pairs can be added one at a time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RelRmse {
    n: usize,
    sum_truth: f64,
    sum_sq_diff: f64,
}

impl RelRmse {
    /// Adds one pair.
    pub fn add(&mut self, estimate: f64, truth: f64) {
        let d = estimate - truth;
        self.n += 1;
        self.sum_truth += truth;
        self.sum_sq_diff += d * d;
    }

    /// Pairs added.
    #[must_use]
    pub fn count(&self) -> usize {
        self.n
    }

    /// The relative RMSE of the pairs added (module docs); 0 for none.
    #[must_use]
    pub fn value(&self) -> f64 {
        rel_rmse_of_sums(self.sum_sq_diff, self.sum_truth, self.n)
    }
}

/// The relative RMSE from its sums: `Σ (E - T)²`, `Σ T` over `n` pairs (module docs); 0 for
/// `n = 0`. The one place the formula is written.
#[must_use]
pub fn rel_rmse_of_sums(sum_sq_diff: f64, sum_truth: f64, n: usize) -> f64 {
    if n == 0 {
        return 0.0;
    }
    let nf = n as f64;
    (sum_sq_diff / nf).sqrt() / (sum_truth / nf)
}

/// The relative RMSE that differences `errors` (each `E − T`, e.g. a reference's own
/// estimated error at each point) amount to over references of mean `mean_truth`
/// ([`rel_rmse_of_sums`]); `None` for no errors or a mean that is not positive.
#[must_use]
pub fn rel_rmse_of_errors(errors: &[f64], mean_truth: f64) -> Option<f64> {
    let n = errors.len();
    (n > 0 && mean_truth > 0.0)
        .then(|| rel_rmse_of_sums(errors.iter().map(|e| e * e).sum(), mean_truth * n as f64, n))
}

/// The estimated error of the mean `m_n` of an extensible quasi-Monte Carlo rule from the
/// means of its prefixes, `m_{n/2}` of the first half and `m_{n/4}` of the first quarter of
/// the same samples: `max(|m_n − m_{n/2}|, ½ |m_n − m_{n/4}|)` (Owen, *Monte Carlo theory,
/// methods and examples*, §17; lightvol-sampler's `noise` module says why each term). The
/// one place the formula is written: `bake --noise` stops on it, and `compare` reports
/// its reference's noise with it.
#[must_use]
pub fn prefix_error(full: f64, half: f64, quarter: f64) -> f64 {
    (full - half).abs().max(0.5 * (full - quarter).abs())
}

/// The relative RMSE of `(estimate, truth)` pairs (module docs).
#[must_use]
pub fn rel_rmse(pairs: impl IntoIterator<Item = (f64, f64)>) -> f64 {
    let mut r = RelRmse::default();
    for (e, t) in pairs {
        r.add(e, t);
    }
    r.value()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// By hand: truths 1, 2, 3 (mean 2), estimates 1.5, 2, 2 (errors 0.5, 0, -1):
    /// `sqrt((0.25 + 0 + 1) / 3) / 2 = sqrt(5/12) / 2 ≈ 0.3227`.
    #[test]
    fn hand_computed_case() {
        let r = rel_rmse([(1.5, 1.0), (2.0, 2.0), (2.0, 3.0)]);
        assert!((r - (5.0f64 / 12.0).sqrt() / 2.0).abs() < 1e-15, "{r}");
        assert!((r - 0.322_748_6).abs() < 1e-7);
        assert_eq!(rel_rmse([(4.0, 4.0); 3]), 0.0);
        assert_eq!(rel_rmse(std::iter::empty()), 0.0);
        // The same case from its errors alone and the mean truth.
        let e = rel_rmse_of_errors(&[0.5, 0.0, -1.0], 2.0).unwrap();
        assert!((e - r).abs() < 1e-15, "{e} against {r}");
        assert_eq!(rel_rmse_of_errors(&[], 2.0), None);
        assert_eq!(rel_rmse_of_errors(&[0.5], 0.0), None);
    }

    /// It is scale-free: scaling estimates and truths together leaves it unchanged, and a
    /// uniform 10% excess gives 0.1.
    #[test]
    fn scale_free() {
        let pairs: Vec<(f64, f64)> = (1..20).map(|i| (f64::from(i) * 1.1, f64::from(i))).collect();
        let a = rel_rmse(pairs.iter().copied());
        let b = rel_rmse(pairs.iter().map(|&(e, t)| (e * 8.0, t * 8.0)));
        assert!((a - b).abs() < 1e-15);
        let flat = rel_rmse([(1.1, 1.0); 5]);
        assert!((flat - 0.1).abs() < 1e-12, "{flat}");
    }
}
