//! The settings of a bake: its method, samples, SH order, seed, light sampling, shard and
//! chunk size.

use lightvol_core::samples::{Samples, samples};

use crate::method::Method;
use crate::noise::NoiseTarget;

/// Bake settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeSettings {
    /// Estimator.
    pub method: Method,
    /// Candidates per cell (prefilter, doi-paper), per node (doi-node, and doi's support),
    /// or directions per node (point, doi).
    pub samples: Samples,
    /// SH coefficients per channel (4, 9 or 16).
    pub coeffs: usize,
    /// Seed of every random stream.
    pub seed: u64,
    /// One light sample per probe sample (next-event estimation at the probe, MIS).
    pub light_sampling: bool,
    /// Shard `(k, n)`: this bake covers units `k·U/n .. (k+1)·U/n`.
    pub shard: (u32, u32),
    /// Units per parallel chunk (progress and cancellation granularity).
    pub chunk: usize,
    /// Sample each unit in doubling rounds from `samples` until its estimate's relative
    /// standard error reaches this target ([`crate::noise`]); `None`: `samples` exactly.
    pub noise: Option<NoiseTarget>,
}

impl Default for BakeSettings {
    fn default() -> Self {
        Self {
            method: Method::Doi,
            samples: samples(256),
            coeffs: 9,
            seed: 0,
            light_sampling: true,
            shard: (0, 1),
            chunk: 256,
            noise: None,
        }
    }
}
