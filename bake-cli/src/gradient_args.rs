//! SH irradiance gradients in the CLI (Oat, *Irradiance Volumes for Games*, GDC 2005 —
//! \[Oat05\], "Spherical Harmonic Irradiance Gradients"): the estimator option of
//! `bake --gradients` and `compare --gradient-estimator`.
//!
//! The estimators, their dispatch and the lookups live in lightvol-sampler
//! (`gradients`, `gradient_estimator`, `eval::entries`) and lightvol-volume (`gradient`).

use clap::ValueEnum;
use lightvol_sampler::gradient_estimator::GradientEstimator;

/// Which estimator computes the per-node gradients (the command-line spelling of
/// lightvol-sampler's `GradientEstimator`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum GradientEstimatorArg {
    /// Oat 2005's central differences: six extra point projections per node at 1/16 of a
    /// cell (common random numbers); costs 6 × samples extra directions per node.
    Central,
    /// Petrov-Galerkin estimate from the bake's own kept samples (trilinear basis gradients
    /// as test functions, restricted to the domain of interest): no extra rays; needs
    /// `prefilter` or `doi`.
    Basis,
}

impl From<GradientEstimatorArg> for GradientEstimator {
    fn from(a: GradientEstimatorArg) -> Self {
        match a {
            GradientEstimatorArg::Central => Self::Central,
            GradientEstimatorArg::Basis => Self::Basis,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The command-line names are the sampler's names, variant for variant.
    #[test]
    fn estimator_names_match_the_sampler() {
        for a in GradientEstimatorArg::value_variants() {
            let name = a.to_possible_value().expect("named").get_name().to_owned();
            assert_eq!(GradientEstimator::from(*a).name(), name);
        }
    }
}
