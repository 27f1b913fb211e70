#![doc = include_str!("../README.md")]

pub mod baked;
pub mod compare;
pub mod convergence;
pub mod demo;
pub mod entries;
pub mod error;
pub mod metrics;
pub mod observer;
pub mod plate;
pub mod reads;
pub mod relight;
pub mod report;
pub mod runs;
pub mod sweep;
pub mod table;
pub mod views;

pub use baked::{GradientVolume, RunVolume};
pub use compare::{CompareConfig, Comparison, compare};
pub use entries::{Entry, NamedEntry, parse_entry, uniform_memory_bytes};
pub use error::EvalError;
pub use metrics::{Metrics, PlatePoint, SweepPoint};
pub use observer::{Observer, Silent};
pub use plate::{Plate, PlateConfig, default_plate_height};
pub use reads::ReadAs;
pub use runs::{BakeContext, GradientCache, MethodRun, RunDetail};
pub use sweep::{ResolutionSeries, SweepConfig, SweepReport, memory_sweep, resolution_sweep};
pub use views::{ComparedView, MethodView, ViewCamera, ViewsConfig, compare_views, view_metrics};
