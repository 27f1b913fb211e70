//! Baking until converged (`bake --noise`): each unit (a node, or a cell) is sampled in
//! rounds of growing sample counts until the estimated relative error of its estimate
//! falls below a target, or a cap is reached.
//!
//! A unit's estimate of its constant SH coefficient is the mean of its samples' values
//! (Kontkanen & Laine 2006 Eq. 4; Eq. 6 weights them, which the unweighted mean
//! approximates per unit); the values are the luminance of each sample's radiance over its
//! density.
//!
//! **The error estimate.** A unit's first directions are a scrambled Halton sequence
//! ([`lightvol_scene::qmc`]), so its mean converges faster than the independent-sample
//! standard error `s/√n` says: on the Breakfast Room that formula asks for the cap in every
//! unit at a 1% target. The sequence is extensible, and every prefix of it is itself a
//! stratified estimate, so the estimate compares prefixes (the way extensible quasi-Monte
//! Carlo rules are usually stopped, e.g. Owen, *Monte Carlo theory, methods and examples*,
//! §17): with `m_k` the mean of the first `k` values,
//!
//! `ê_n = max(|m_n − m_{n/2}|, ½ |m_n − m_{n/4}|) / m_n`.
//!
//! `|m_n − m_{n/2}|` estimates the error of `m_{n/2}`, which is at least `m_n`'s; `|m_n − m_{n/4}|`
//! estimates `m_{n/4}`'s, which is at least twice `m_n`'s at the Monte Carlo rate `n^-½`
//! and more at any faster one. Taking the larger of the two guards against one difference
//! that happens to cross zero (test
//! `the_prefix_estimate_is_calibrated_like_a_standard_error`).
//!
//! **Rounds.** Round 0 has the bake's samples; each round after it has at least twice as
//! many, more when the estimate is far from the target (`next_samples`), and the last
//! round is kept. The other methods bake each round afresh with the same per-sample streams
//! (so a round's first samples are the previous round's); `doi` classifies a node once,
//! with the cap's directions, and each round extends the one before (the bake's
//! `sample_unit`). What a unit receives depends only on its own samples, so a bake
//! is bit-identical for any thread or shard count. Earlier rounds' rays are counted with
//! the unit's, so the total stays honest.

use lightvol_core::metric::prefix_error;
use lightvol_core::samples::Samples;
use lightvol_scene::envmap::luminance;
use lightvol_volume::Accumulator;
use lightvol_volume::fixed::FixedSums;

/// Sample until the estimated relative error of a unit's estimate is at most
/// `relative_error`, growing from the bake's samples up to `max_samples`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseTarget {
    /// The relative error to reach (e.g. 0.01).
    pub relative_error: f64,
    /// The most samples a unit gets.
    pub max_samples: Samples,
}

/// Default cap of `--noise`: sixteen thousand samples per unit.
pub const DEFAULT_MAX_SAMPLES: u32 = 16_384;

/// The fewest kept samples the prefix estimate uses: its shortest prefix (a quarter) then
/// holds 4. A unit with fewer kept samples (outside the domain and filled, or nearly every
/// direction rejected) is left as it is.
pub const MIN_VALUES: usize = 16;

/// The rate the round planner assumes the error falls at, `n^-RATE`: between the Monte
/// Carlo rate ½ (the bounces) and the stratified first hits' rate near 1.
const PLANNING_RATE: f64 = 0.75;

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

/// The estimated relative error of the mean of `values`, a unit's samples in stream order
/// (module docs, `ê_n`): `None` for fewer than [`MIN_VALUES`]; 0 when the prefixes agree
/// exactly (a unit that sees only black, or one constant); infinite when they differ but
/// the mean is not positive.
pub(crate) fn relative_error_of(values: &[f64]) -> Option<f64> {
    let n = values.len();
    if n < MIN_VALUES {
        return None;
    }
    let mean = |k: usize| values[..k].iter().sum::<f64>() / k as f64;
    let (m, half, quarter) = (mean(n), mean(n / 2), mean(n / 4));
    let e = prefix_error(m, half, quarter);
    if e == 0.0 {
        return Some(0.0);
    }
    if !(m > 0.0) {
        return Some(f64::INFINITY);
    }
    Some(e / m)
}

/// The estimated relative error of a unit whose samples have `values` where it misses
/// `target`, `None` where it meets it: its error is known and at most the target's, or it
/// has fewer than [`MIN_VALUES`] kept samples, which the estimate cannot judge.
pub(crate) fn unmet_error(values: &[f64], target: &NoiseTarget) -> Option<f64> {
    relative_error_of(values).filter(|&e| !(e <= target.relative_error))
}

/// Whether a unit whose samples have `values` meets `target` ([`unmet_error`]).
#[cfg(test)]
pub(crate) fn converged(values: &[f64], target: &NoiseTarget) -> bool {
    unmet_error(values, target).is_none()
}

/// The next round's samples after a round of `n` whose estimated relative error is
/// `error` (above the target): the power of two that the error's fall at
/// `n^-PLANNING_RATE` says reaches the target, at least `2n`, at most the cap.
pub(crate) fn next_samples(n: u32, error: f64, target: &NoiseTarget) -> u32 {
    let cap = target.max_samples.get();
    let want = f64::from(n) * (error / target.relative_error).powf(1.0 / PLANNING_RATE);
    let doubled = n.saturating_mul(2);
    if !(want < f64::from(cap)) {
        return cap.max(n);
    }
    // `want` < cap ≤ u32::MAX, so the cast is exact after the ceiling.
    (want.ceil() as u32).next_power_of_two().max(doubled).min(cap).max(n)
}

/// Name of a `doi` bake's per-node error estimates ([`crate::bake::BakeOutput::node_error`])
/// among an accumulator's auxiliary sums: what a shard file, a kept accumulator or a
/// checkpoint carries so that the merged set can be smoothed under its noise
/// ([`crate::denoise`]) as the whole bake is.
pub const NODE_ERROR_AUX: &str = "doi-node-error";

/// Stores `errors`, the estimates of the nodes from `first` on (NaN where a node has none),
/// in `acc`'s auxiliary sums under [`NODE_ERROR_AUX`]. Each node's entry is its estimate's
/// f32 bits plus one (0: no estimate). Only the shard that samples a node writes its
/// entry, so adding the shards' sums as integers gives every node its own estimate back,
/// bit for bit ([`node_errors_of`]).
///
/// # Panics
/// If `first + errors.len()` exceeds the grid's node count (a shard's node range always
/// lies inside it).
pub fn attach_node_errors(acc: &mut Accumulator, first: usize, errors: &[f32]) {
    let mut raw = vec![0i128; acc.spec().node_count()];
    for (slot, e) in raw[first..first + errors.len()].iter_mut().zip(errors) {
        if e.is_finite() {
            *slot = i128::from(e.to_bits()) + 1;
        }
    }
    acc.set_aux(NODE_ERROR_AUX, FixedSums::from_raw(raw));
}

/// The per-node error estimates [`attach_node_errors`] stored in `acc` (merged or not), NaN
/// where a node has none; `None` when `acc` carries none.
#[must_use]
pub fn node_errors_of(acc: &Accumulator) -> Option<Vec<f32>> {
    let (name, sums) = acc.aux()?;
    if name != NODE_ERROR_AUX || sums.len() != acc.spec().node_count() {
        return None;
    }
    let decode = |v: i128| u32::try_from(v - 1).ok().map_or(f32::NAN, f32::from_bits);
    Some(sums.raw().iter().map(|&v| decode(v)).collect())
}

#[cfg(test)]
#[path = "noise_tests.rs"]
mod tests;
