//! How a volume was made: the bake metadata every file format carries ([`BakeMetadata`]), the
//! typed record of the bake's settings ([`BakeRecord`], [`FitRecord`]) and the octree
//! settings of an adaptive bake ([`OctreeSettings`], \[Oat05\] "Adaptive Subdivision").
//!
//! Plain data below the volume ([`crate::volume`]) that holds it: the octree settings'
//! checks against the octree's limits live with the octree ([`crate::adaptive`]).

use serde::{Deserialize, Serialize};

use crate::up_axis::UpAxis;

/// The bake method and every setting that shaped a volume, as a typed record: what the
/// free-text [`BakeMetadata::method`] label says, field by field, for programs that read
/// files (a merge finds the least-squares weight here, an engine tool the bounce count).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BakeRecord {
    /// The method: `point`, `prefilter`, `doi`, `doi-paper`, `doi-node` (Kontkanen & Laine
    /// 2006 Eq. 4-6, Algorithm 2) or an engine baseline (`point+apv`, ...).
    pub method: String,
    /// Samples per cell (prefilter, doi-paper), per node (doi-node) or directions per node
    /// (point, doi, the baselines).
    pub samples_per_unit: u32,
    /// SH coefficients per channel.
    pub coeffs: usize,
    /// The node fit.
    pub fit: FitRecord,
    /// The gradient estimator (`central`, `basis`), when gradients were baked (\[Oat05\]).
    pub gradients: Option<String>,
    /// Diffuse bounces traced unconditionally.
    pub bounces: u32,
    /// Whether paths continued under Russian roulette after `bounces` (unbiased).
    pub russian_roulette: bool,
    /// Which light counted when it reached a probe directly (`all`, `sky+indirect`,
    /// `indirect`).
    pub direct_light: String,
    /// The octree settings of an adaptive bake (\[Oat05\], "Subdivision Heuristics").
    pub octree: Option<OctreeSettings>,
    /// The engine lookup the node values were chosen for (`bake --target`), when not
    /// lightvol's own. Absent in files written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<TargetRecord>,
    /// The noise target of a bake sampled until converged (`bake --noise`); absent for a
    /// fixed sample count and in files written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseRecord>,
}

/// A bake sampled until converged: each unit in rounds growing from
/// [`BakeRecord::samples_per_unit`] until its estimate's estimated relative error reached
/// `relative_error`, or it had `max_samples`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NoiseRecord {
    /// The relative error aimed at.
    pub relative_error: f64,
    /// The most samples a unit got.
    pub max_samples: u32,
}

/// The engine lookup a bake's node values were fitted for, and the fit's weight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetRecord {
    /// The lookup's name (`three`, `bevy`, `trilinear`, `apv`; [`crate::EngineLookup::name`]).
    pub lookup: String,
    /// The regularisation weight λ toward the bake's own values.
    pub lambda: f64,
    /// The noise-weighted smoothing's τ applied before the fit (lightvol-sampler's
    /// `denoise`), `None` without one (and in files written before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub smoothing: Option<f64>,
}

/// How node values came from their samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FitRecord {
    /// Kontkanen & Laine Eq. 6: each node the weighted average over its support.
    Average,
    /// Regularised least squares over the domain of interest with weight `lambda`.
    LeastSquares {
        /// The regularisation weight λ.
        lambda: f64,
    },
}

/// How a volume was made, carried through every file format.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BakeMetadata {
    /// Sampling method, e.g. `"point"` (Kontkanen & Laine Eq. 4) or `"domain"` (Eq. 5-6).
    pub method: String,
    /// Sampling rays the bake traced, over all its units (not per unit: that is
    /// [`BakeRecord::samples_per_unit`]); stored under the key `samples` (the EXR attribute
    /// `lightvol.bake.samples`, the JSON of shard files and `info`).
    #[serde(rename = "samples")]
    pub sampling_rays: u64,
    /// Seed of the bake's random (Halton scrambling) streams.
    pub seed: u64,
    /// Index of this shard among `shard_count` (0 for an unsharded bake).
    pub shard_index: u32,
    /// Number of shards the bake was split into (1 for an unsharded bake).
    pub shard_count: u32,
    /// A hash identifying the scene and bake settings (free-form hex string).
    pub scene_hash: String,
    /// The radiometric unit of the coefficients, e.g. `"W sr^-1 m^-2"` or
    /// `"relative"` (default).
    pub units: String,
    /// The frame of the scene file the volume was baked from ([`crate::up_axis`], [`crate::frame`]). The grid
    /// and coefficients stay in lightvol's internal +Z-up frame; coordinates shown to users
    /// and engine exports are converted to this frame. Absent in older files: internal.
    #[serde(default = "internal_frame")]
    pub frame: UpAxis,
    /// The method and settings as a typed record. Absent in files written before it
    /// existed, and in volumes made by hand.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settings: Option<BakeRecord>,
}

fn internal_frame() -> UpAxis {
    UpAxis::INTERNAL
}

impl Default for BakeMetadata {
    fn default() -> Self {
        Self {
            method: "unknown".into(),
            sampling_rays: 0,
            seed: 0,
            shard_index: 0,
            shard_count: 1,
            scene_hash: String::new(),
            units: "relative".into(),
            frame: UpAxis::INTERNAL,
            settings: None,
        }
    }
}

/// Settings of an adaptive bake (\[Oat05\], "Adaptive Subdivision": "Specify a Min and Max
/// level of subdivision", "Allow thresholds to be specified for each subdivision heuristic").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OctreeSettings {
    /// Every cell of the levels below is split.
    pub min_level: u32,
    /// The finest level.
    pub max_level: u32,
    /// Split when the relative change across a cell is at least this (`None`: off).
    pub gradient_threshold: Option<f64>,
    /// Split cells that contain scene geometry.
    pub geometry: bool,
    /// Split when a cell edge exceeds this multiple of a corner's harmonic-mean depth
    /// (`None`: off).
    pub depth_ratio_threshold: Option<f64>,
    /// Rays per node for the harmonic mean.
    pub depth_rays: u32,
    /// Cull nodes whose surplus is within this fraction of the value scale.
    pub cull_tolerance: f64,
    /// Cap on the volume's `memory_bytes` (bytes).
    pub memory_budget: Option<usize>,
    /// Where the user wants more, fewer or no refinement: boxes in lightvol's internal frame
    /// (world units), applied in order after the heuristics ([`OctreeRegion`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub regions: Vec<OctreeRegion>,
}

/// What a placement box asks of an adaptive bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionKind {
    /// A density volume: every cell that overlaps the box is split down to this level
    /// (at most the bake's finest), and the nodes those splits create are never culled.
    Density(u32),
    /// An exclusion volume: cells inside the box are not split (the heuristics are ignored
    /// there; a density volume still applies).
    Exclude,
    /// Where the player can go: when there are walkable boxes, only cells that overlap one
    /// are split (density volumes still apply elsewhere).
    Walkable,
}

/// A placement box of an adaptive bake ([`OctreeSettings::regions`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OctreeRegion {
    /// What the box asks for.
    pub kind: RegionKind,
    /// The box's minimum corner (internal frame, world units).
    pub min: [f64; 3],
    /// The box's maximum corner.
    pub max: [f64; 3],
}

impl Default for OctreeSettings {
    fn default() -> Self {
        Self {
            min_level: 0,
            max_level: 2,
            gradient_threshold: Some(0.25),
            geometry: true,
            depth_ratio_threshold: Some(1.0),
            depth_rays: 32,
            cull_tolerance: 0.01,
            memory_budget: None,
            regions: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The metadata's JSON (the header of shard files, `info --json`) keeps the file format's
    /// key names: the sampling rays are `samples`, as in every file written before.
    #[test]
    fn json_keys_are_the_file_formats() {
        let m = BakeMetadata { sampling_rays: 7168, ..BakeMetadata::default() };
        let v = serde_json::to_value(&m).unwrap();
        assert_eq!(v["samples"], 7168);
        assert!(v.get("sampling_rays").is_none(), "{v}");
        let back: BakeMetadata = serde_json::from_value(v).unwrap();
        assert_eq!(back, m);
    }
}
