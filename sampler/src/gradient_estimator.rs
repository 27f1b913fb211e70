//! Which estimator computes a bake's per-node SH irradiance gradients (Oat, *Irradiance
//! Volumes for Games*, GDC 2005 — \[Oat05\], "Spherical Harmonic Irradiance Gradients"), and
//! one entry point, [`bake_with_estimator`], that bakes a grid and computes its gradients by
//! either.
//!
//! The estimators themselves live in [`crate::gradient_bake`]:
//!
//! - [`GradientEstimator::Central`]: \[Oat05\]'s central differences, six extra point
//!   projections per node at 1/16 of a cell ([`crate::gradient_bake::central_difference_data`]);
//! - [`GradientEstimator::Basis`]: the Petrov-Galerkin estimate from the bake's own kept
//!   samples ([`crate::gradient_bake::bake_with_gradients`]), no extra rays, cell methods only.
//!
//! With either, the bake itself (its Eq. 6 sums and statistics) is bit-identical to a bake
//! without gradients.

use std::time::Instant;

use lightvol_volume::{GridSpec, VolumeGradients};
use serde::Serialize;

use crate::bake::{BakeOutput, bake};
use crate::error::BakeError;
use crate::gradient_bake::{ShardGradients, bake_with_gradients, central_difference_data, default_offset};
use crate::method::Method;
use crate::settings::BakeSettings;
use lightvol_core::progress::BakeControl;
use lightvol_core::shard::shard_range;
use lightvol_scene::transport::Transport;

/// Which estimator computes the per-node gradients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GradientEstimator {
    /// Oat 2005's central differences: six extra point projections per node at 1/16 of a
    /// cell (common random numbers); costs 6 × samples extra directions per node.
    Central,
    /// Petrov-Galerkin estimate from the bake's own kept samples (trilinear basis gradients
    /// as test functions, restricted to the domain of interest): no extra rays; needs
    /// `prefilter` or `doi`.
    Basis,
}

impl GradientEstimator {
    /// The estimator that fits `method` when none is named: `basis` for cell methods (no
    /// extra rays), `central` for `point` (point samples span no volume).
    #[must_use]
    pub fn default_for(method: Method) -> Self {
        if matches!(method, Method::Point | Method::DoiNode | Method::Doi) {
            Self::Central
        } else {
            Self::Basis
        }
    }

    /// Its name: `central` or `basis`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Central => "central",
            Self::Basis => "basis",
        }
    }

    /// Whether it can estimate the gradients of a bake by `method` (the basis estimator
    /// needs cell samples: `prefilter` or `doi`).
    #[must_use]
    pub fn supports(self, method: Method) -> bool {
        !(self == Self::Basis && matches!(method, Method::Point | Method::DoiNode | Method::Doi))
    }
}

/// A bake, its gradients and what computing them cost.
pub struct GradientBake {
    /// The bake's Eq. 6 sums and statistics (identical to a bake without gradients).
    pub output: BakeOutput,
    /// The gradients (world units, `[node][coeff][rgb][xyz]`).
    pub gradients: VolumeGradients,
    /// Which estimator.
    pub estimator: GradientEstimator,
    /// Nodes whose basis-gradient system was singular (zero gradient); 0 for `central`.
    pub singular_nodes: usize,
    /// Directions traced for the gradients beyond the bake (central: 6 per node per
    /// sample; basis: 0).
    pub extra_directions: u64,
    /// Wall time of the gradient step beyond the bake, in seconds.
    pub seconds: f64,
    /// What a shard file carries for a merge: the basis estimator's exact sums, or the
    /// central differences of the shard's nodes.
    pub sums: ShardGradients,
}

/// A failed gradient bake: the step that failed and why.
#[derive(Debug, thiserror::Error)]
#[error("{step}")]
pub struct GradientBakeError {
    /// The step: `baking with gradients`, `solving the basis-gradient systems`, `baking` or
    /// `central-difference gradients`.
    pub step: &'static str,
    /// What went wrong.
    #[source]
    pub source: BakeError,
}

fn at(step: &'static str) -> impl FnOnce(BakeError) -> GradientBakeError {
    move |source| GradientBakeError { step, source }
}

/// Bakes `grid` with `settings` and computes the gradients by `estimator`; the volume is
/// `output.accumulator.finalize()` (the caller finalizes and attaches metadata).
/// `control` reports the progress of the bake (not of the gradient step after it).
///
/// A sharded bake (`settings.shard`) computes the central differences of its own range of
/// nodes ([`shard_range`]); its `gradients` are zero elsewhere.
///
/// # Errors
/// `basis` with `point` sampling ([`GradientEstimator::supports`]), and the bake's own
/// errors, each with the step that failed.
pub fn bake_with_estimator(
    transport: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    estimator: GradientEstimator,
    control: &BakeControl<'_>,
) -> Result<GradientBake, GradientBakeError> {
    Ok(match estimator {
        GradientEstimator::Basis => {
            let (output, acc) = bake_with_gradients(transport, grid, settings, control)
                .map_err(at("baking with gradients"))?;
            let t0 = Instant::now();
            let (vol, _) = output.accumulator.finalize();
            let (gradients, rep) = acc.finish(&vol).map_err(at("solving the basis-gradient systems"))?;
            GradientBake {
                output,
                gradients,
                estimator,
                singular_nodes: rep.singular,
                extra_directions: 0,
                seconds: t0.elapsed().as_secs_f64(),
                sums: ShardGradients::Basis(Box::new(acc)),
            }
        }
        GradientEstimator::Central => {
            let output = bake(transport, grid, settings, control).map_err(at("baking"))?;
            let t0 = Instant::now();
            let (vol, _) = output.accumulator.finalize();
            let nodes = shard_range(grid.node_count(), settings.shard);
            let count = nodes.len() as u64;
            let step = "central-difference gradients";
            let data = central_difference_data(transport, grid, settings, default_offset(grid), nodes)
                .map_err(at(step))?;
            let gradients = VolumeGradients::new(&vol, data.clone())
                .map_err(|e| GradientBakeError { step, source: BakeError::Volume(e.to_string()) })?;
            GradientBake {
                output,
                gradients,
                estimator,
                singular_nodes: 0,
                extra_directions: 6 * u64::from(settings.samples.get()) * count,
                seconds: t0.elapsed().as_secs_f64(),
                sums: ShardGradients::Central(data),
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_core::samples::samples;
    use lightvol_scene::{Tracer, TransportSettings, builtin};

    #[test]
    fn defaults_and_names() {
        assert_eq!(GradientEstimator::default_for(Method::Point), GradientEstimator::Central);
        assert_eq!(GradientEstimator::default_for(Method::DoiPaper), GradientEstimator::Basis);
        assert_eq!(GradientEstimator::default_for(Method::Prefilter), GradientEstimator::Basis);
        assert!(!GradientEstimator::Basis.supports(Method::Point));
        assert!(GradientEstimator::Central.supports(Method::Point));
        assert_eq!(serde_json::to_value(GradientEstimator::Central).unwrap(), "central");
        assert_eq!(GradientEstimator::Basis.name(), "basis");
    }

    /// Both estimators leave the bake itself as a plain bake gives it; central counts its
    /// six extra projections per node and sample, basis traces none.
    #[test]
    fn the_bake_is_unchanged_and_the_cost_counted() {
        let maze = builtin::maze();
        let tracer = Tracer::new(&maze.scene);
        let t = Transport::new(&maze.scene, &tracer, TransportSettings::truncated(1));
        let grid = GridSpec::new([-4.0, -4.0, 0.2], [4.0, 4.0, 2.8], [4, 4, 3]).unwrap();
        let settings =
            BakeSettings { method: Method::DoiPaper, samples: samples(4), ..BakeSettings::default() };
        let plain = bake(&t, &grid, &settings, &BakeControl::default()).unwrap();
        let (plain_vol, _) = plain.accumulator.finalize();
        for est in [GradientEstimator::Basis, GradientEstimator::Central] {
            let g = bake_with_estimator(&t, &grid, &settings, est, &BakeControl::default()).unwrap();
            let (vol, _) = g.output.accumulator.finalize();
            assert_eq!(vol.data(), plain_vol.data(), "{est:?}");
            assert_eq!(g.output.stats.rays.total(), plain.stats.rays.total());
            let want = if est == GradientEstimator::Central { 6 * 4 * 48 } else { 0 };
            assert_eq!(g.extra_directions, want);
        }
        let point = BakeSettings { method: Method::Point, ..settings };
        let err = bake_with_estimator(&t, &grid, &point, GradientEstimator::Basis, &BakeControl::default())
            .err()
            .unwrap();
        assert_eq!(err.step, "baking with gradients");
    }
}
