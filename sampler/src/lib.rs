#![doc = include_str!("../README.md")]

pub mod adaptive;
pub mod adaptive_regions;
pub mod adaptive_shard;
pub mod bake;
pub mod baselines;
mod cg;
pub mod checkpoint;
pub mod cluster;
pub mod denoise;
pub mod domain;
pub mod error;
pub mod gradient_bake;
pub mod gradient_estimator;
pub mod merge;
pub mod method;
pub mod node_fit;
pub mod noise;
pub mod probe;
pub mod provenance;
pub mod reach;
pub mod relocate;
pub mod report;
pub mod request;
pub mod scenarios;
pub mod scene_setup;
pub mod settings;
pub mod sky_occlusion;
pub mod stats;
pub mod target;
mod unit;

pub use bake::{BakeOutput, bake};
pub use error::BakeError;
pub use method::{BakeMethod, Baseline, Method};
pub use settings::BakeSettings;
pub use stats::BakeStats;

#[cfg(test)]
mod builtin_tests;
