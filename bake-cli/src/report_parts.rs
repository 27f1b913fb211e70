//! Pieces shared by several verbs' JSON reports.

use serde::Serialize;

/// Rays by kind in reports.
#[derive(Debug, Serialize, Clone, Copy)]
pub(crate) struct RaysJson {
    /// Sampling rays.
    pub(crate) sampling: u64,
    /// Query rays (Algorithm 2).
    pub(crate) query: u64,
    /// Bounce rays.
    pub(crate) bounce: u64,
    /// Shadow rays.
    pub(crate) shadow: u64,
    /// All rays.
    pub(crate) total: u64,
}

impl RaysJson {
    /// Converts counts.
    pub(crate) fn of(r: &lightvol_sampler::RayCounts) -> Self {
        Self { sampling: r.sampling, query: r.query, bounce: r.bounce, shadow: r.shadow, total: r.total() }
    }
}

/// Reference description.
#[derive(Debug, Serialize, Clone)]
pub(crate) struct ReferenceJson {
    /// Samples per point.
    pub(crate) samples: u32,
    /// Mean luminance over valid points.
    pub(crate) mean: f64,
    /// Wall time of the reference.
    pub(crate) seconds: f64,
}
