//! One volume bake as a request: the method (a grid method, Kontkanen & Laine 2006 Eq. 4-6
//! and Algorithm 2, or an engine baseline, [`crate::baselines`]) with its settings, the rules
//! that say which settings go together ([`BakeRequest::validate`]), and the run of a uniform
//! bake, whole or one shard, with its node fit and gradients ([`bake_uniform`]).
//!
//! `lightvol bake` builds a [`BakeRequest`] from its options and calls these; the octree
//! bake ([`crate::adaptive`]) and the baselines' own runs take the request's settings.

use lightvol_core::samples::Samples;
use lightvol_volume::{
    BakeMetadata, BakeRecord, EngineLookup, FillReport, FitRecord, GridSpec, IrradianceVolume, NoiseRecord,
    TargetRecord, VolumeGradients,
};

use crate::adaptive::AdaptiveSettings;
use crate::adaptive_shard::base_label;
use crate::gradient_bake::ShardGradients;
use crate::gradient_estimator::{GradientBakeError, GradientEstimator, bake_with_estimator};
use crate::method::BakeMethod;
use crate::method::Baseline;
use crate::node_fit::{FitReport, bake_with_mass, finalize_least_squares, solve_least_squares};
use crate::noise::NoiseTarget;
use crate::provenance;
use crate::target::{TargetReport, TargetSettings, fit_for_lookup, own_samples_mask};
use crate::{BakeError, BakeOutput, BakeSettings, Method};
use lightvol_core::progress::BakeControl;
use lightvol_scene::{Scene, Transport, TransportSettings, UpAxis};

pub use crate::node_fit::Fit;

/// Which per-node SH gradients (Oat 2005) a bake also estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GradientChoice {
    /// The method's own estimator ([`GradientEstimator::default_for`]).
    MethodDefault,
    /// This estimator.
    Estimator(GradientEstimator),
}

/// The octree part of a request (Oat 2005, "Adaptive Octree Subdivision").
#[derive(Clone, Debug, PartialEq)]
pub struct AdaptiveRequest {
    /// Levels, heuristics and culling.
    pub settings: AdaptiveSettings,
    /// With a shard: the refinement level it bakes (`None` or 0: the base grid).
    pub level: Option<u32>,
    /// Whether shard files of earlier levels are given (to bake a level from, or to
    /// assemble).
    pub from_shards: bool,
}

/// A whole volume bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeRequest {
    /// A grid method or an engine baseline.
    pub method: BakeMethod,
    /// Samples per cell (prefilter, doi-paper), per node (doi-node) or directions per node
    /// (point, doi, the baselines).
    pub samples: Samples,
    /// SH coefficients per channel (4, 9 or 16).
    pub coeffs: usize,
    /// Seed of every random stream.
    pub seed: u64,
    /// Path length and which light counts directly.
    pub transport: TransportSettings,
    /// How node values come from the sums (point sampling always averages).
    pub fit: Fit,
    /// Gradients to estimate, if any.
    pub gradients: Option<GradientChoice>,
    /// Shard `(k, n)` of a sharded bake; `None` bakes the whole volume.
    pub shard: Option<(u32, u32)>,
    /// Keep the exact sums of an unsharded bake (for a later `merge`).
    pub keep_accumulator: bool,
    /// An octree bake instead of a uniform one.
    pub adaptive: Option<AdaptiveRequest>,
    /// Node values chosen for this engine lookup ([`crate::target`]; `None`: the plain
    /// bake; [`EngineLookup::Lightvol`]: for lightvol's own, the plain bake smoothed where
    /// it is noisy).
    pub target: Option<TargetSettings>,
    /// Sample each unit until its estimate converges ([`crate::noise`]).
    pub noise: Option<NoiseTarget>,
    /// Bake lighting scenarios ([`crate::scenarios`]): each a whole bake under its own
    /// lights, into one file.
    pub scenarios: bool,
    /// Also keep one volume per light group, from the same paths: the transport given to
    /// [`bake_uniform`] must carry the groups
    /// ([`Transport::with_groups`](lightvol_scene::transport::Transport::with_groups)).
    pub light_groups: bool,
}

impl BakeRequest {
    /// A whole uniform bake of `method` with `samples`, 9 coefficients, seed 1, unbiased
    /// paths, the average fit, no gradients.
    #[must_use]
    pub fn new(method: BakeMethod, samples: Samples) -> Self {
        Self {
            method,
            samples,
            coeffs: 9,
            seed: 1,
            transport: TransportSettings::default(),
            fit: Fit::Average,
            gradients: None,
            shard: None,
            keep_accumulator: false,
            adaptive: None,
            target: None,
            noise: None,
            light_groups: false,
            scenarios: false,
        }
    }

    /// The bake records the node reach ([`crate::reach`]): a uniform `doi` bake (the
    /// octree keeps none). Its memory estimate counts it
    /// ([`crate::scene_setup::NODE_REACH_BYTES`]).
    #[must_use]
    pub fn records_node_reach(&self) -> bool {
        self.method == BakeMethod::Grid(Method::Doi) && self.adaptive.is_none()
    }

    /// The method's name (`point`, `doi`, `point+apv`, ...).
    #[must_use]
    pub fn method_name(&self) -> &'static str {
        self.method.name()
    }

    /// The grid method the samples are taken with (point sampling for the baselines).
    #[must_use]
    pub fn grid_method(&self) -> Method {
        match self.method {
            BakeMethod::Grid(m) => m,
            BakeMethod::Baseline(_) => Method::Point,
        }
    }

    /// The fit the bake uses: [`Self::fit`], except that point sampling always averages.
    #[must_use]
    pub fn effective_fit(&self) -> Fit {
        if self.grid_method() == Method::Point { Fit::Average } else { self.fit }
    }

    /// The gradient estimator the bake uses, if any.
    #[must_use]
    pub fn estimator(&self) -> Option<GradientEstimator> {
        self.gradients.map(|g| match g {
            GradientChoice::MethodDefault => GradientEstimator::default_for(self.grid_method()),
            GradientChoice::Estimator(e) => e,
        })
    }

    /// The engine lookup the node values are chosen for, with the smoothing before the fit
    /// only where the bake estimates each node's error (`doi`). Lightvol's own lookup is a
    /// target only with that smoothing (it fits nothing): without it the bake is plain.
    #[must_use]
    pub fn effective_target(&self) -> Option<TargetSettings> {
        let doi = self.method == BakeMethod::Grid(Method::Doi);
        self.target
            .map(|t| TargetSettings { smoothing: t.smoothing.filter(|_| doi), ..t })
            .filter(|t| t.lookup != EngineLookup::Lightvol || t.smoothing.is_some())
    }

    /// The method label in reports and file metadata: the method's name, with the fit when it
    /// is not the average and the target lookup when there is one.
    #[must_use]
    pub fn label(&self) -> String {
        let mut label = match self.effective_fit() {
            Fit::Average => self.method_name().to_owned(),
            fit => format!("{} fit={fit}", self.method_name()),
        };
        if let Some(n) = self.noise {
            label.push_str(&format!(" noise={}:{}", n.relative_error, n.max_samples));
        }
        if let Some(t) = self.effective_target() {
            label.push_str(&format!(" target={}", t.lookup));
        }
        label
    }

    /// The typed record of the method and settings that every file of this bake carries
    /// ([`BakeRecord`]).
    #[must_use]
    pub fn record(&self) -> BakeRecord {
        BakeRecord {
            method: self.method_name().to_owned(),
            samples_per_unit: self.samples.get(),
            coeffs: self.coeffs,
            fit: match self.effective_fit() {
                Fit::Average => FitRecord::Average,
                Fit::LeastSquares { lambda } => FitRecord::LeastSquares { lambda },
            },
            gradients: self.estimator().map(|e| e.name().to_owned()),
            bounces: self.transport.bounces,
            russian_roulette: self.transport.russian_roulette,
            direct_light: self.transport.direct.name().to_owned(),
            octree: self.adaptive.as_ref().map(|a| a.settings.clone()),
            target: self.effective_target().map(|t| TargetRecord {
                lookup: t.lookup.name().to_owned(),
                lambda: t.lambda,
                smoothing: t.smoothing,
            }),
            noise: self
                .noise
                .map(|n| NoiseRecord { relative_error: n.relative_error, max_samples: n.max_samples.get() }),
        }
    }

    /// The method label of this bake's files: [`Self::label`], except that the level-0
    /// shards of an octree bake carry [`base_label`] of it, so that a plain merge refuses
    /// them and the octree's assembly recognises them.
    #[must_use]
    pub fn file_label(&self) -> String {
        match (&self.adaptive, self.shard) {
            (Some(AdaptiveRequest { level: None | Some(0), .. }), Some(_)) => base_label(&self.label()),
            _ => self.label(),
        }
    }

    /// The settings key of this bake on `grid` over `scene` ([`provenance::bake_key`] of
    /// [`Self::label`]: every level and shard of one bake shares it).
    #[must_use]
    pub fn key(&self, scene: &Scene, grid: &GridSpec) -> String {
        let adaptive = self.adaptive.as_ref().map(|a| a.settings.clone());
        provenance::bake_key(
            scene,
            grid,
            &self.label(),
            self.samples,
            self.coeffs,
            &self.transport,
            adaptive.as_ref(),
        )
    }

    /// The metadata of a file of this bake from `scene` (in the file frame `frame`), keyed
    /// by `key` ([`Self::key`]), whose bake traced `sampling_rays` sampling rays
    /// ([`provenance::bake_metadata`] under [`Self::file_label`], for the request's shard or
    /// the whole volume), with the typed record of its settings ([`Self::record`]).
    #[must_use]
    pub fn metadata(&self, scene: &Scene, frame: UpAxis, key: &str, sampling_rays: u64) -> BakeMetadata {
        BakeMetadata {
            settings: Some(self.record()),
            ..provenance::bake_metadata(
                scene,
                frame,
                key,
                &self.file_label(),
                sampling_rays,
                self.seed,
                self.shard.unwrap_or((0, 1)),
            )
        }
    }

    /// Whether the bake writes its exact sums (a shard, or `keep_accumulator`).
    #[must_use]
    pub fn writes_accumulator(&self) -> bool {
        self.shard.is_some() || self.keep_accumulator
    }

    /// The sampler's settings of this request.
    #[must_use]
    pub fn settings(&self) -> BakeSettings {
        BakeSettings {
            method: self.grid_method(),
            samples: self.samples,
            coeffs: self.coeffs,
            seed: self.seed,
            shard: self.shard.unwrap_or((0, 1)),
            noise: self.noise,
            ..BakeSettings::default()
        }
    }

    /// Checks that the settings go together, before any scene is read.
    ///
    /// # Errors
    /// The first [`RequestError`] in the order: samples, then the baselines', octree's,
    /// fit's and gradients' rules.
    pub fn validate(&self) -> Result<(), RequestError> {
        if let Some(t) = self.effective_target() {
            // lightvol's own target only smooths, which a merge of the shards' sums repeats
            // from the per-node errors they carry; an engine's fit traces rays in the scene,
            // which a merge does not have.
            let engine = t.lookup != EngineLookup::Lightvol;
            let refused = [
                (
                    matches!(self.method, BakeMethod::Baseline(_)),
                    "an engine baseline (a fix for its own lookup)",
                ),
                (self.adaptive.is_some(), "an octree bake"),
                (
                    engine && self.shard.is_some(),
                    "a shard for an engine's lookup (the fit traces rays over the whole volume, which a merge cannot; bake whole or with --checkpoint, or shard with --target lightvol)",
                ),
                (
                    engine && self.keep_accumulator,
                    "keeping the accumulator for an engine's lookup (a merge of it cannot trace the fit's rays)",
                ),
                (self.gradients.is_some(), "gradients"),
            ];
            if let Some((_, with)) = refused.into_iter().find(|(set, _)| *set) {
                return Err(RequestError::Target(with));
            }
        }
        if self.noise.is_some() {
            let refused = [
                (matches!(self.method, BakeMethod::Baseline(_)), "an engine baseline"),
                (self.adaptive.is_some(), "an octree bake"),
                (self.gradients.is_some(), "gradients"),
            ];
            if let Some((_, with)) = refused.into_iter().find(|(set, _)| *set) {
                return Err(RequestError::Noise(with));
            }
        }
        if self.light_groups {
            let fit = self.effective_fit();
            let refused = [
                (matches!(self.method, BakeMethod::Baseline(_)), "an engine baseline"),
                (self.adaptive.is_some(), "an octree bake"),
                (self.gradients.is_some(), "gradients"),
                (fit != Fit::Average, "a fit other than the average"),
                (self.effective_target().is_some(), "--target"),
            ];
            if let Some((_, with)) = refused.into_iter().find(|(set, _)| *set) {
                return Err(RequestError::LightGroups(with));
            }
        }
        if self.scenarios {
            let fit = self.effective_fit();
            let refused = [
                (matches!(self.method, BakeMethod::Baseline(_)), "an engine baseline"),
                (self.adaptive.is_some(), "an octree bake"),
                (self.gradients.is_some(), "gradients"),
                (self.light_groups, "light groups or a sky transfer"),
                (
                    self.writes_accumulator()
                        && (fit != Fit::Average || self.effective_target().is_some() || self.noise.is_some()),
                    "shards or a kept accumulator with a fit other than the average, --target or --noise",
                ),
            ];
            if let Some((_, with)) = refused.into_iter().find(|(set, _)| *set) {
                return Err(RequestError::Scenarios(with));
            }
        }
        if let BakeMethod::Baseline(baseline) = self.method {
            let refused = [
                (self.adaptive.is_some(), Conflict::Adaptive),
                (self.shard.is_some(), Conflict::Shard),
                (self.keep_accumulator, Conflict::KeepAccumulator),
                (self.gradients.is_some(), Conflict::Gradients),
            ];
            if let Some((_, with)) = refused.into_iter().find(|(set, _)| *set) {
                return Err(RequestError::Baseline { baseline, with });
            }
        }
        if let Some(a) = &self.adaptive {
            if self.keep_accumulator {
                return Err(RequestError::Adaptive(Conflict::KeepAccumulator));
            }
            if self.gradients.is_some() {
                return Err(RequestError::Adaptive(Conflict::Gradients));
            }
            if self.fit != Fit::Average {
                return Err(RequestError::Adaptive(Conflict::Fit(self.fit)));
            }
            match (self.shard, a.level, a.from_shards) {
                (None, Some(_), _) => return Err(RequestError::LevelNeedsShard),
                (Some(_), Some(0) | None, true) => return Err(RequestError::BaseLevelFromShards),
                (Some(_), Some(l), false) if l > 0 => return Err(RequestError::LevelNeedsShards(l)),
                _ => {}
            }
            return Ok(());
        }
        let method = self.grid_method();
        let fit = self.effective_fit();
        if matches!(method, Method::DoiNode | Method::Doi) && fit != Fit::Average {
            return Err(RequestError::FitNeedsCells { fit, method });
        }
        if fit != Fit::Average && self.gradients.is_some() {
            return Err(RequestError::FitWithGradients(fit));
        }
        if self.estimator().is_some_and(|e| !e.supports(method)) {
            return Err(RequestError::BasisNeedsCells(method));
        }
        Ok(())
    }
}

/// A setting that another refuses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Conflict {
    /// An octree bake.
    Adaptive,
    /// A shard.
    Shard,
    /// Keeping the accumulator.
    KeepAccumulator,
    /// Gradients.
    Gradients,
    /// A fit other than the average.
    Fit(Fit),
}

impl std::fmt::Display for Conflict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Adaptive => f.write_str("an octree bake"),
            Self::Shard => f.write_str("shards"),
            Self::KeepAccumulator => f.write_str("keeping the accumulator"),
            Self::Gradients => f.write_str("gradients"),
            Self::Fit(fit) => write!(f, "the {fit} fit"),
        }
    }
}

/// Settings that do not go together.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum RequestError {
    /// An engine baseline bakes a whole uniform grid.
    #[error("{with} cannot be combined with {} (the engine baselines bake a whole uniform grid)", baseline.name())]
    Baseline {
        /// The baseline.
        baseline: Baseline,
        /// What it refuses.
        with: Conflict,
    },
    /// The octree refuses this.
    #[error("an octree bake cannot be combined with {0}")]
    Adaptive(Conflict),
    /// A refinement level is baked as a shard.
    #[error("an octree refinement level is baked as a shard")]
    LevelNeedsShard,
    /// Level 0 needs the scene only.
    #[error("level 0 is baked from the scene alone, not from shard files")]
    BaseLevelFromShards,
    /// A level above 0 needs the levels below.
    #[error("level {0} needs the shard files of the levels below it")]
    LevelNeedsShards(u32),
    /// A fit other than the average needs cell samples.
    #[error("the {fit} fit needs cell samples (prefilter or doi-paper); {} samples per node", method.name())]
    FitNeedsCells {
        /// The fit.
        fit: Fit,
        /// The method.
        method: Method,
    },
    /// The gradient estimators assume the average fit.
    #[error("the {0} fit cannot be combined with gradients (the gradient estimators assume the average)")]
    FitWithGradients(Fit),
    /// A baseline or octree request given to the uniform bake, which bakes neither.
    #[error("{0} has its own bake run, not the uniform one")]
    NotUniform(&'static str),
    /// A noise target with a setting it cannot go with.
    #[error("--noise cannot be combined with {0}")]
    Noise(&'static str),
    /// A target lookup with a setting it cannot go with.
    #[error("--target cannot be combined with {0}")]
    Target(&'static str),
    /// Light groups with a setting they cannot go with (yet).
    #[error("light groups (--light-groups, --sky-transfer) cannot be combined with {0}")]
    LightGroups(&'static str),
    /// Lighting scenarios with a setting they cannot go with (yet).
    #[error("--scenario cannot be combined with {0}")]
    Scenarios(&'static str),
    /// Light groups asked for, but the transport splits by none.
    #[error("light groups were asked for, but the transport carries none (Transport::with_groups)")]
    NoLightGroups,
    /// The basis estimator needs cell samples.
    #[error("basis gradients need cell samples (prefilter or doi-paper), not {}", .0.name())]
    BasisNeedsCells(Method),
}

/// Per-node gradients of a bake and what they cost.
pub struct GradientsOutcome {
    /// The gradients (world units, `[node][coeff][rgb][xyz]`).
    pub gradients: VolumeGradients,
    /// Which estimator.
    pub estimator: GradientEstimator,
    /// Nodes with a singular basis-gradient system (zero gradient).
    pub singular_nodes: usize,
    /// Directions traced beyond the bake.
    pub extra_directions: u64,
    /// Wall time beyond the bake, in seconds.
    pub seconds: f64,
}

/// A finished uniform bake.
pub struct UniformBake {
    /// The exact sums and statistics; the sums carry the fit's or the gradients' auxiliary
    /// sums when the request writes its accumulator ([`BakeRequest::writes_accumulator`]),
    /// so that a merge of shards fits and differentiates over the whole set.
    pub output: BakeOutput,
    /// The volume (Eq. 6, or the least-squares fit), with metadata.
    pub volume: IrradianceVolume,
    /// Zero-weight nodes filled from neighbours.
    pub fill: FillReport,
    /// The gradients, when asked for.
    pub gradients: Option<GradientsOutcome>,
    /// The least-squares fit's weight λ and solve, when that is the fit.
    pub least_squares: Option<(f64, FitReport)>,
    /// The fit for a target lookup, when asked for ([`crate::target`]); its rays are
    /// counted in the output's query rays.
    pub target: Option<TargetReport>,
    /// The volume split by light group, when asked for ([`BakeRequest::light_groups`]): the
    /// whole bake is [`Self::volume`].
    pub groups: Option<lightvol_volume::GroupedVolume>,
}

/// Why a bake failed.
#[derive(Debug, thiserror::Error)]
pub enum UniformBakeError {
    /// The settings do not go together.
    #[error(transparent)]
    Request(#[from] RequestError),
    /// The bake itself.
    #[error("baking")]
    Bake(#[source] BakeError),
    /// The bake with gradients.
    #[error(transparent)]
    Gradients(#[from] GradientBakeError),
    /// The least-squares node fit.
    #[error("least-squares node fit")]
    LeastSquares(#[source] BakeError),
    /// The fit for a target lookup.
    #[error("fit for the target lookup")]
    Target(#[source] BakeError),
}

/// Where the baked scene's coordinates are shown, and the key of its settings
/// ([`crate::provenance::bake_key`]); goes into the volume's metadata.
#[derive(Clone, Copy, Debug)]
pub struct Provenance<'a> {
    /// The scene file's frame.
    pub frame: UpAxis,
    /// The settings key.
    pub key: &'a str,
}

/// Bakes the uniform volume of a grid-method `request` on `grid` (whole or one shard) with
/// its fit and gradients, and finalizes it with metadata from `provenance`.
///
/// # Errors
/// [`UniformBakeError`]: a request that does not validate or is a baseline or octree bake
/// ([`RequestError`]), or a failed bake, gradient step or fit.
pub fn bake_uniform(
    transport: &Transport<'_>,
    scene: &Scene,
    grid: &GridSpec,
    request: &BakeRequest,
    provenance: Provenance<'_>,
    control: &BakeControl<'_>,
) -> Result<UniformBake, UniformBakeError> {
    request.validate()?;
    if let BakeMethod::Baseline(baseline) = request.method {
        return Err(RequestError::NotUniform(baseline.name()).into());
    }
    if request.light_groups && transport.groups().is_none() {
        return Err(RequestError::NoLightGroups.into());
    }
    if request.adaptive.is_some() {
        return Err(RequestError::NotUniform("an octree bake").into());
    }
    let settings = request.settings();
    let fit = request.effective_fit();
    enum Extra {
        None,
        Mass(crate::node_fit::MassMatrix),
        Gradients(GradientsOutcome, Box<ShardGradients>),
    }
    let (mut output, extra) = match (request.estimator(), fit) {
        (Some(est), _) => {
            let g = bake_with_estimator(transport, grid, &settings, est, control)?;
            let outcome = GradientsOutcome {
                gradients: g.gradients,
                estimator: g.estimator,
                singular_nodes: g.singular_nodes,
                extra_directions: g.extra_directions,
                seconds: g.seconds,
            };
            (g.output, Extra::Gradients(outcome, Box::new(g.sums)))
        }
        (None, Fit::Average) => {
            (crate::bake(transport, grid, &settings, control).map_err(UniformBakeError::Bake)?, Extra::None)
        }
        (None, Fit::LeastSquares { .. }) => {
            let (out, mass) =
                bake_with_mass(transport, grid, &settings, control).map_err(UniformBakeError::Bake)?;
            (out, Extra::Mass(mass))
        }
    };
    let meta = request.metadata(scene, provenance.frame, provenance.key, output.stats.rays.sampling);
    if request.writes_accumulator() {
        // Auxiliary sums do not change what the accumulator finalizes to.
        match &extra {
            Extra::Mass(mass) => mass.attach_to(&mut output.accumulator),
            Extra::Gradients(_, sums) => sums.attach_to(&mut output.accumulator),
            // `doi`'s per-node errors, for the merged set's smoothing (`merge::finish_merged`).
            Extra::None if request.effective_target().is_some() => {
                output.keep_node_errors(grid, settings.shard)
            }
            Extra::None => {}
        }
    }
    let (volume, fill, gradients, least_squares) = match extra {
        Extra::None => {
            let (v, fill) = output.accumulator.finalize();
            (v.with_metadata(meta), fill, None, None)
        }
        Extra::Gradients(g, _) => {
            let (v, fill) = output.accumulator.finalize();
            (v.with_metadata(meta), fill, Some(g), None)
        }
        Extra::Mass(mass) => {
            let Fit::LeastSquares { lambda } = fit else {
                unreachable!("mass matrices are only baked for lsq")
            };
            let (values, solve) = solve_least_squares(&mass, &output.accumulator, lambda)
                .map_err(UniformBakeError::LeastSquares)?;
            let (v, fill) = finalize_least_squares(&output.accumulator, values);
            (v.with_metadata(meta), fill, None, Some((lambda, solve)))
        }
    };
    let (volume, target) = match request.effective_target() {
        // A shard's volume is part of the whole: the merge smooths the merged set.
        None => (volume, None),
        Some(_) if request.shard.is_some() => (volume, None),
        Some(t) => {
            // APV's lookup renormalises over valid nodes: those with samples of their own.
            let valid = own_samples_mask(&output.accumulator);
            // `doi`'s per-node errors, for the smoothing before the fit.
            let node_error = (output.node_error.len() == valid.len()).then_some(output.node_error.as_slice());
            // The fitted volume keeps the bake's metadata.
            let (fitted, report) = fit_for_lookup(transport, &volume, &t, Some(valid), node_error)
                .map_err(UniformBakeError::Target)?;
            output.stats.rays.query += report.rays;
            (fitted, Some(report))
        }
    };
    let groups = match output.accumulator.finalize_grouped(&volume).filter(|_| request.light_groups) {
        Some(g) => Some(g.map_err(|e| UniformBakeError::Bake(BakeError::Volume(e.to_string())))?),
        None => None,
    };
    Ok(UniformBake { output, volume, fill, gradients, least_squares, target, groups })
}

#[cfg(test)]
#[path = "request_tests.rs"]
mod tests;
