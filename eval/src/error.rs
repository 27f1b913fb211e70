//! What can go wrong in an evaluation.

use lightvol_volume::VolumeError;

use lightvol_sampler::error::BakeError;
use lightvol_sampler::gradient_estimator::GradientBakeError;
use lightvol_view::ViewError;

/// An evaluation error. Invalid settings are reported by [`CompareConfig::validate`]
/// (and [`compare`], which calls it) before any ray is traced; the other variants come
/// from the bakes.
///
/// [`CompareConfig::validate`]: crate::CompareConfig::validate
/// [`compare`]: crate::compare()
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A `BASE+relit` entry without the sky to bake it under.
    #[error(
        "BASE+relit and BASE+skyocc entries need --relight-from (the sky they are baked under before they are relit)"
    )]
    NoRelightFrom,
    /// A relit entry's groups or relighting failed.
    #[error("relighting: {0}")]
    Relight(String),
    /// An entry names no bake method (the message of [`Method`](lightvol_sampler::Method)'s parser).
    #[error("{0}")]
    UnknownMethod(String),
    /// An entry names no gradient lookup.
    #[error("unknown gradient lookup '{0}' (taylor, gtrilinear, hermite)")]
    UnknownLookup(String),
    /// `bound+NAME` names no engine lookup.
    #[error("unknown engine lookup '{0}' in bound+ (three, bevy, trilinear, apv, lightvol)")]
    UnknownEngineLookup(String),
    /// `adaptiveL` with `L` outside `1..=max` (`entries::ADAPTIVE_LEVELS_MAX`).
    #[error("'{name}': adaptiveL needs a finest level L from 1 to {max}")]
    AdaptiveLevel {
        /// The entry as given.
        name: String,
        /// The finest level accepted.
        max: u32,
    },
    /// `BASE+average|lsq[:λ]` with an invalid fit.
    #[error("'{entry}': {message}")]
    Fit {
        /// The entry.
        entry: String,
        /// What the fit's parser said.
        message: String,
    },
    /// No entry to compare.
    #[error("no method to compare")]
    NoMethods,
    /// A memory sweep without scales.
    #[error("the memory sweep needs at least one scale")]
    NoSweepScales,
    /// A memory-sweep scale outside `(0, max]` (or NaN; `sweep::MAX_SWEEP_SCALE`).
    #[error("sweep scale {scale} is not in (0, {max}]")]
    SweepScale {
        /// The scale given.
        scale: f64,
        /// The largest scale accepted.
        max: f64,
    },
    /// The grid has a placement transform; the plate is horizontal in the grid's frame.
    #[error("compare needs an axis-aligned grid (no placement transform)")]
    PlacedGrid,
    /// An engine's lookup asked of an entry that is not a uniform grid.
    #[error(
        "--lookup {lookup} reads uniform grids; entry {entry} is not one (leave out gradient and adaptive entries)"
    )]
    EngineLookupNeedsGrid {
        /// The way of reading (`ReadAs::name`).
        lookup: String,
        /// The entry's name.
        entry: String,
    },
    /// The plate height is NaN or infinite.
    #[error("plate height {0} is not finite")]
    PlateHeightNotFinite(f64),
    /// The plate lies outside the grid.
    #[error("plate height {height} is outside the grid's z range [{min}, {max}]")]
    PlateOutsideGrid {
        /// The plate height.
        height: f64,
        /// The grid's lowest z.
        min: f64,
        /// The grid's highest z.
        max: f64,
    },
    /// Fewer than 2 plate points along the longer side, or more than the most a plate may
    /// have (`max`).
    #[error("plate resolution {res} is outside 2..={max}")]
    PlateResolution {
        /// The resolution asked for.
        res: u32,
        /// The most accepted.
        max: u32,
    },
    /// No plate point is inside the domain of interest: nothing to measure.
    #[error("no plate point at height {0} sees the scene from inside the domain of interest")]
    NoValidPoints(f64),
    /// A gradient entry on a `point` bake with the basis estimator, which needs cell samples.
    #[error(
        "'{entry}': the basis gradient estimator needs cell samples (prefilter or doi); use the central estimator with point sampling"
    )]
    BasisNeedsCells {
        /// The entry.
        entry: String,
    },
    /// Zero worker threads.
    #[error("worker threads must be at least 1")]
    ZeroThreads,
    /// The thread pool could not be built.
    #[error("creating the thread pool")]
    ThreadPool(#[source] rayon::ThreadPoolBuildError),
    /// A bake failed.
    #[error("{step}")]
    Bake {
        /// `baking` or `adaptive bake`.
        step: &'static str,
        /// Why.
        #[source]
        source: BakeError,
    },
    /// A bake with gradients failed.
    #[error(transparent)]
    Gradient(#[from] GradientBakeError),
    /// A grid or a gradient lookup was rejected by lightvol-volume.
    #[error(transparent)]
    Volume(#[from] VolumeError),
    /// A view's camera, image size or sample count is invalid, or its rendering failed.
    #[error(transparent)]
    View(#[from] ViewError),
    /// A view without a label.
    #[error("every view needs a label")]
    ViewLabel,
    /// Two views with one label.
    #[error("two views are labelled '{0}'")]
    DuplicateView(String),
    /// No pixel of a view sees a surface inside the grid: there is nothing to measure in it.
    #[error("view '{0}' sees no surface inside the grid")]
    ViewSeesNothing(String),
    /// The path-traced view is black over the pixels measured: a relative error is
    /// undefined there.
    #[error(
        "the path-traced view '{0}' is black where it is measured (is the camera inside a closed solid?)"
    )]
    BlackView(String),
}

impl EvalError {
    /// A closure wrapping a bake error with the step that failed.
    pub(crate) fn at(step: &'static str) -> impl FnOnce(BakeError) -> Self {
        move |source| Self::Bake { step, source }
    }
}
