//! SH irradiance gradients in the CLI (Oat, *Irradiance Volumes for Games*, GDC 2005 —
//! \[Oat05\], "Spherical Harmonic Irradiance Gradients"): the estimator option of
//! `bake --gradients` and `compare --gradient-estimator`, and \[Oat05\]'s memory table as
//! `info` prints it.
//!
//! The estimators, their dispatch and the lookups live in lightvol-sampler
//! (`gradients`, `gradient_estimator`, `eval::entries`) and lightvol-volume (`gradient`).

use clap::ValueEnum;
use lightvol_sampler::gradient_estimator::GradientEstimator;
use lightvol_volume::gradient::floats_per_sample;
use serde::Serialize;

/// Which estimator computes the per-node gradients (the command-line spelling of
/// lightvol-sampler's `GradientEstimator`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GradientEstimatorArg {
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

/// One row of \[Oat05\]'s floats-per-sample table.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct FloatsRow {
    /// SH order (bands).
    pub order: usize,
    /// Floats per sample without gradients (`3 n²`).
    pub floats: usize,
    /// Floats per sample with gradients (`4 · 3 n²`).
    pub floats_with_gradients: usize,
}

/// \[Oat05\]'s "GPU Memory Requirements" rows for orders 3 and 6, and for `extra_order` (the
/// file's), computed from [`floats_per_sample`].
#[must_use]
pub fn floats_table(extra_order: usize) -> Vec<FloatsRow> {
    let mut orders = vec![3, 6];
    if !orders.contains(&extra_order) {
        orders.insert(0, extra_order);
    }
    orders
        .into_iter()
        .map(|n| FloatsRow {
            order: n,
            floats: floats_per_sample(n, false),
            floats_with_gradients: floats_per_sample(n, true),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// \[Oat05\]'s table, from its definition: RGB SH of order n has 3 n² floats, and every
    /// coefficient's gradient adds 3 more per float (4 × in all). Order 3: 27 / 108;
    /// order 6: 108 / 432.
    #[test]
    fn floats_table_matches_the_definition() {
        let t = floats_table(3);
        assert_eq!(t.len(), 2);
        for r in &t {
            let sh = 3 * r.order * r.order;
            assert_eq!(r.floats, sh);
            assert_eq!(r.floats_with_gradients, sh + 3 * sh);
        }
        assert_eq!((t[0].floats, t[0].floats_with_gradients), (27, 108));
        assert_eq!((t[1].floats, t[1].floats_with_gradients), (108, 432));
        assert_eq!(floats_table(2)[0].floats, 12);
    }

    /// The command-line names are the sampler's names, variant for variant.
    #[test]
    fn estimator_names_match_the_sampler() {
        for a in GradientEstimatorArg::value_variants() {
            let name = a.to_possible_value().expect("named").get_name().to_owned();
            assert_eq!(GradientEstimator::from(*a).name(), name);
        }
    }
}
