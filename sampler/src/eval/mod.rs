//! # Evaluation: methods against a path-traced reference
//!
//! The measurement of Kontkanen & Laine 2006, *Sampling Precomputed Volumetric Lighting*
//! (\[KL06\] §8, Fig. 6): bake every method at the same sample budget, read each volume on a
//! horizontal *plate* of points (normal up), and compare with path-traced irradiance at the
//! same points. Points that see back faces lie outside the domain of interest and are left
//! out; the metrics show leaking as points that come out too dark, above all next to
//! surfaces. Beyond the paper's three bakes, the entries include \[Oat05\]'s gradient
//! lookups and adaptive octree (Oat, *Irradiance Volumes for Games*, GDC 2005) and the leak
//! fixes of engines ([`crate::baselines`]), and two studies measure error against memory
//! and against grid resolution. Through cameras, the comparison also renders the scene as a
//! person sees it, shaded by each entry's volume and by path tracing, and measures each
//! view against the path-traced one ([`views`]).
//!
//! ## Modules
//!
//! | module | concept |
//! | --- | --- |
//! | [`plate`] | the plate: layout, back-face classification, near-surface flags, reference |
//! | [`metrics`] | `rel_rmse`, `bias`, `too_dark`, `too_dark_near`, `too_bright` (\[KL06\] Fig. 6) |
//! | [`entries`] | what can be compared ([`Entry`]), entry names, \[Oat05\]'s memory accounting |
//! | [`runs`] | baking and measuring one entry ([`MethodRun`]) in a shared [`BakeContext`] |
//! | [`compare`](mod@compare) | the whole comparison: [`CompareConfig`] → [`Comparison`] |
//! | [`sweep`] | error against memory ([`memory_sweep`]) and against resolution ([`resolution_sweep`]) |
//! | [`views`] | the comparison through cameras: path-traced and per-entry views, their metrics ([`ComparedView`]) |
//! | [`baked`] | what an entry baked, read anywhere through its lookup ([`RunVolume`]) |
//! | [`report`] | the comparison as `report.json`, panels, views, `plate.exr` and an HTML page, in memory ([`report::compare_files`]) |
//! | [`observer`] | progress reports to the caller ([`Observer`], [`Silent`]) |
//! | [`error`] | [`EvalError`] |
//!
//! ## Guide
//!
//! ```
//! use lightvol_sampler::builtin;
//! use lightvol_sampler::eval::{CompareConfig, NamedEntry, PlateConfig, Silent, compare};
//!
//! // The maze at its recommended grid, a small plate at its recommended height.
//! let maze = builtin::maze();
//! let plate = PlateConfig {
//!     height: maze.plate_heights[0],
//!     res: 12,
//!     reference_samples: 16,
//!     classify_dirs: 64,
//! };
//! let mut config = CompareConfig::new(maze.grid.clone(), plate);
//! config.samples = 8;
//! config.methods = ["point", "doi", "doi+hermite"]
//!     .iter()
//!     .map(|s| NamedEntry::parse(s))
//!     .collect::<Result<_, _>>()?;
//! // Bakes the three entries (the Hermite lookup on a doi bake with gradients), with no
//! // progress reports.
//! let result = compare(&maze.scene, &config, &Silent)?;
//! let [point, doi, hermite] = [0, 1, 2].map(|i| &result.methods[i]);
//! assert!(doi.metrics.rel_rmse < point.metrics.rel_rmse);
//! assert_eq!(hermite.memory_bytes, 4 * point.memory_bytes); // [Oat05]: gradients quadruple the floats
//! // doi's volume also carries its node reach: six f32 per node.
//! assert_eq!(doi.memory_bytes, point.memory_bytes + 24 * maze.grid.node_count());
//! # Ok::<(), lightvol_sampler::eval::EvalError>(())
//! ```
//!
//! Everything is deterministic: for one configuration the numbers are bit-identical across
//! runs and thread counts (the bakes are, see [`crate::bake`](mod@crate::bake); the plate's
//! streams derive from the seed; every sum is taken in a fixed order). Only the wall times
//! (`seconds`) vary.
//!
//! Nothing here writes files: [`report`] turns a [`Comparison`] into the bytes of its
//! reports and images, the caller writes them and turns an [`Observer`] into progress bars.

pub mod baked;
pub mod compare;
pub mod entries;
pub mod error;
pub mod metrics;
pub mod observer;
pub mod plate;
pub mod report;
pub mod runs;
pub mod sweep;
pub mod table;
pub mod views;

pub use baked::RunVolume;
pub use compare::{CompareConfig, Comparison, compare};
pub use entries::{Entry, NamedEntry, parse_entry, uniform_memory_bytes};
pub use error::EvalError;
pub use metrics::{Metrics, PlatePoint};
pub use observer::{Observer, Silent};
pub use plate::{Plate, PlateConfig, default_plate_height};
pub use runs::{BakeContext, GradientCache, GradientVolume, MethodRun, RunDetail};
pub use sweep::{ResolutionSeries, SweepConfig, SweepPoint, SweepReport, memory_sweep, resolution_sweep};
pub use views::{ComparedView, MethodView, ViewCamera, ViewsConfig, compare_views, view_metrics};
