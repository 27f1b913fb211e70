//! The leakage metrics of an evaluation plate (Kontkanen & Laine 2006 — \[KL06\] — §7-8,
//! Fig. 6), computed over the *valid* plate points (points that see no back faces, i.e.
//! inside the domain of interest).
//!
//! With `E` the method's irradiance and `T` the path-traced reference (luminance):
//! - `rel_rmse = sqrt(mean((E - T)²)) / mean(T)` (`lightvol_core::metric`, the one
//!   definition);
//! - `bias = mean(E - T) / mean(T)`;
//! - `too_dark` = share of points with `E < 0.8 T`;
//! - `too_bright` = share with `E > 1.25 T`;
//! - `too_dark_near` = `too_dark` over valid points whose nearest surface is closer than
//!   half the largest cell edge.

use serde::Serialize;

/// Ratio `E / T` below which a point counts as too dark.
pub const TOO_DARK: f64 = 0.8;
/// Ratio `E / T` above which a point counts as too bright.
pub const TOO_BRIGHT: f64 = 1.25;

/// One plate point's inputs to the metrics.
#[derive(Clone, Copy, Debug)]
pub struct PlatePoint {
    /// The method's irradiance (luminance).
    pub estimate: f64,
    /// The reference irradiance (luminance).
    pub truth: f64,
    /// The point sees no back faces.
    pub valid: bool,
    /// The nearest surface is closer than half the largest cell edge.
    pub near: bool,
}

/// The metrics of one estimate on one plate (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Metrics {
    /// `sqrt(mean((E - T)²)) / mean(T)` over valid points.
    pub rel_rmse: f64,
    /// `mean(E - T) / mean(T)` over valid points.
    pub bias: f64,
    /// Share of valid points with `E < 0.8 T`.
    pub too_dark: f64,
    /// Share of valid near-surface points with `E < 0.8 T`.
    pub too_dark_near: f64,
    /// Share of valid points with `E > 1.25 T`.
    pub too_bright: f64,
    /// Number of valid points.
    pub valid_points: usize,
    /// Number of valid near-surface points.
    pub near_points: usize,
}

/// Computes [`Metrics`] over `points` (sums in a fixed order: deterministic). With no valid
/// point every metric is 0; a share over no near point is 0.
#[must_use]
pub fn compute(points: &[PlatePoint]) -> Metrics {
    let (mut n, mut sum_t, mut sum_d, mut sum_d2, mut dark, mut bright, mut near, mut dark_near) =
        (0usize, 0.0, 0.0, 0.0, 0usize, 0usize, 0usize, 0usize);
    for p in points.iter().filter(|p| p.valid) {
        n += 1;
        sum_t += p.truth;
        let d = p.estimate - p.truth;
        sum_d += d;
        sum_d2 += d * d;
        let is_dark = p.estimate < TOO_DARK * p.truth;
        dark += usize::from(is_dark);
        bright += usize::from(p.estimate > TOO_BRIGHT * p.truth);
        if p.near {
            near += 1;
            dark_near += usize::from(is_dark);
        }
    }
    if n == 0 {
        return Metrics::default();
    }
    let nf = n as f64;
    let mean_t = sum_t / nf;
    let share = |k: usize, of: usize| if of == 0 { 0.0 } else { k as f64 / of as f64 };
    Metrics {
        rel_rmse: lightvol_core::metric::rel_rmse_of_sums(sum_d2, sum_t, n),
        bias: sum_d / nf / mean_t,
        too_dark: share(dark, n),
        too_dark_near: share(dark_near, near),
        too_bright: share(bright, n),
        valid_points: n,
        near_points: near,
    }
}

/// One (series, resolution) point of the error-against-memory study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepPoint {
    /// `uniform`, `uniform+taylor`, `uniform+gtrilinear`, `uniform+hermite`, `doi`,
    /// `adaptive`, `adaptive1`, `bricks`.
    pub series: String,
    /// Grid nodes per axis (the octree's finest level).
    pub res: [u32; 3],
    /// Stored nodes (a brick export's probes).
    pub nodes: usize,
    /// Run-time bytes (\[Oat05\]'s accounting; a brick export's atlas and indirection).
    pub memory_bytes: usize,
    /// Relative RMSE on the plate's valid points.
    pub rel_rmse: f64,
    /// Relative bias.
    pub bias: f64,
    /// Share of valid near-surface points with `E < 0.8 T`.
    pub too_dark_near: f64,
    /// Rays of the bake (and gradient step).
    pub rays: u64,
    /// Bake seconds (and gradient step).
    pub seconds: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(estimate: f64, truth: f64, valid: bool, near: bool) -> PlatePoint {
        PlatePoint { estimate, truth, valid, near }
    }

    #[test]
    fn hand_computed_example() {
        // Valid: (1,1) exact, (0.5,1) too dark & near, (2,1) too bright; invalid ignored.
        let pts = [
            p(1.0, 1.0, true, false),
            p(0.5, 1.0, true, true),
            p(2.0, 1.0, true, false),
            p(9.0, 1.0, false, true),
        ];
        let m = compute(&pts);
        assert_eq!(m.valid_points, 3);
        assert_eq!(m.near_points, 1);
        assert!((m.rel_rmse - ((0.25 + 1.0) / 3.0f64).sqrt()).abs() < 1e-15);
        assert!((m.bias - 0.5 / 3.0).abs() < 1e-15);
        assert!((m.too_dark - 1.0 / 3.0).abs() < 1e-15);
        assert!((m.too_bright - 1.0 / 3.0).abs() < 1e-15);
        assert_eq!(m.too_dark_near, 1.0);
        // Thresholds are strict: exactly 0.8 T is not too dark, exactly 1.25 T not too bright.
        let edge = compute(&[p(0.8, 1.0, true, true), p(1.25, 1.0, true, true)]);
        assert_eq!((edge.too_dark, edge.too_bright), (0.0, 0.0));
        assert_eq!(compute(&[]), Metrics::default());
    }
}
