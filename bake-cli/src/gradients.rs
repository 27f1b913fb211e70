//! SH irradiance gradients in the CLI (Oat, *Irradiance Volumes for Games*, GDC 2005 —
//! \[Oat05\], "Spherical Harmonic Irradiance Gradients"): which estimator bakes them
//! (`bake --gradients`), which lookup uses them (`compare --methods doi+taylor,...`), and
//! \[Oat05\]'s memory accounting as `info` prints it.
//!
//! The estimators and lookups themselves live in lightvol-sampler (`gradients`) and
//! lightvol-volume (`gradient`); this module only chooses between them.

use anyhow::{Context, bail};
use clap::ValueEnum;
use lightvol_sampler::gradients::{
    ShardGradients, bake_with_gradients, central_difference_data, default_offset,
};
use lightvol_sampler::{BakeControl, BakeOutput, BakeSettings, Method, Tracer, Transport, TransportSettings};
use lightvol_volume::gradient::{GradientLookup, floats_per_sample};
use lightvol_volume::{GridSpec, IrradianceVolume, VolumeGradients};
use serde::Serialize;

use crate::cmd_bake::progress_bar;

/// Which estimator computes the per-node gradients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
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
        if method == Method::Point { Self::Central } else { Self::Basis }
    }

    /// Name as on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Central => "central",
            Self::Basis => "basis",
        }
    }
}

/// A volume, its gradients and what computing them cost.
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
    /// Wall time of the gradient step beyond the bake.
    pub seconds: f64,
    /// What a shard file carries for `merge`: the basis estimator's exact sums, or the
    /// central differences of the shard's nodes.
    pub sums: ShardGradients,
}

/// Bakes `grid` with `settings` and computes the gradients by `estimator`; the volume is
/// `output.accumulator.finalize()` (the caller finalizes and attaches metadata).
///
/// A sharded bake (`settings.shard`) computes the central differences of its own range of
/// nodes ([`lightvol_sampler::shard::shard_range`]); its `gradients` are zero elsewhere.
///
/// # Errors
/// `basis` with `point` sampling, and the bake's own errors.
#[allow(clippy::too_many_arguments)] // reason: mirrors cmd_bake::run_bake plus the estimator
pub fn bake_with(
    scene: &lightvol_sampler::Scene,
    tracer: &Tracer,
    grid: &GridSpec,
    settings: &BakeSettings,
    ts: TransportSettings,
    estimator: GradientEstimator,
    quiet: bool,
    label: &str,
) -> anyhow::Result<GradientBake> {
    if estimator == GradientEstimator::Basis && settings.method == Method::Point {
        bail!(
            "--gradients basis needs cell samples (--method prefilter or doi); use --gradients central with point sampling"
        );
    }
    let transport = Transport::new(scene, tracer, ts);
    let pb = progress_bar(quiet, 0, label);
    let report = |p: lightvol_sampler::Progress| {
        pb.set_length(p.total as u64);
        pb.set_position(p.done as u64);
    };
    let control = BakeControl { progress: Some(&report), cancel: None };
    let result = match estimator {
        GradientEstimator::Basis => {
            let (output, acc) =
                bake_with_gradients(&transport, grid, settings, &control).context("baking with gradients")?;
            pb.finish_and_clear();
            let t0 = std::time::Instant::now();
            let (vol, _) = output.accumulator.finalize();
            let (gradients, rep) = acc.finish(&vol).context("solving the basis-gradient systems")?;
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
            let output = lightvol_sampler::bake(&transport, grid, settings, &control).context("baking")?;
            pb.finish_and_clear();
            let t0 = std::time::Instant::now();
            let (vol, _) = output.accumulator.finalize();
            let nodes = lightvol_sampler::shard::shard_range(grid.node_count(), settings.shard);
            let count = nodes.len() as u64;
            let data = central_difference_data(&transport, grid, settings, default_offset(grid), nodes)
                .context("central-difference gradients")?;
            let gradients =
                VolumeGradients::new(&vol, data.clone()).context("central-difference gradients")?;
            GradientBake {
                output,
                gradients,
                estimator,
                singular_nodes: 0,
                extra_directions: 6 * u64::from(settings.samples) * count,
                seconds: t0.elapsed().as_secs_f64(),
                sums: ShardGradients::Central(data),
            }
        }
    };
    Ok(result)
}

/// Parses a lookup name: `taylor` (\[Oat05\]'s first-order Taylor expansion from the nearest
/// node), `gtrilinear` (each corner extrapolated, then trilinear) or `hermite` (tricubic
/// Hermite from values and gradients).
pub fn parse_lookup(s: &str) -> anyhow::Result<GradientLookup> {
    match s {
        "taylor" => Ok(GradientLookup::Taylor),
        "gtrilinear" => Ok(GradientLookup::GradientTrilinear),
        "hermite" => Ok(GradientLookup::Hermite),
        _ => bail!("unknown gradient lookup '{s}' (taylor, gtrilinear, hermite)"),
    }
}

/// The name [`parse_lookup`] reads.
#[must_use]
pub fn lookup_name(l: GradientLookup) -> &'static str {
    match l {
        GradientLookup::Taylor => "taylor",
        GradientLookup::GradientTrilinear => "gtrilinear",
        GradientLookup::Hermite => "hermite",
    }
}

/// Runtime bytes of a uniform volume in \[Oat05\]'s accounting ("GPU Memory Requirements"): the
/// RGB SH floats of every node ([`floats_per_sample`]), with or without gradients, f32.
/// The bake weights are not counted (a renderer does not read them).
#[must_use]
pub fn uniform_memory_bytes(vol: &IrradianceVolume, gradients: bool) -> usize {
    vol.spec().node_count() * floats_per_sample(vol.bands(), gradients) * 4
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

    #[test]
    fn lookup_names_round_trip() {
        for l in [GradientLookup::Taylor, GradientLookup::GradientTrilinear, GradientLookup::Hermite] {
            assert_eq!(parse_lookup(lookup_name(l)).unwrap(), l);
        }
        assert!(parse_lookup("cubic").is_err());
    }
}
