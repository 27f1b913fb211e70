//! What a bake reports: the figures of a uniform bake ([`crate::request::bake_uniform`]),
//! an engine baseline ([`crate::baselines::bake_baseline`]) or an octree bake
//! ([`crate::adaptive::bake_adaptive`]), made from the library's outputs, with the scene's
//! size and the memory estimate the bake was checked against. `lightvol bake --json` prints
//! them.
//!
//! What only the caller measured (the ray tracer's build time, the whole run's time, the
//! file it wrote) it passes in as [`RunFigures`].

use lightvol_scene::RayCounts;
use lightvol_volume::frame::FileGrid;
use lightvol_volume::{AdaptiveVolume, GridSpec};
use serde::Serialize;

use crate::adaptive::AdaptiveStats;
use crate::baselines::BaselineBake;
use crate::gradient_estimator::GradientEstimator;
use crate::request::{BakeRequest, UniformBake};
use crate::scene_setup::LoadedScene;
use crate::stats::mrays_per_second;

/// What the caller of a bake measured around it.
#[derive(Clone, Debug, PartialEq)]
pub struct RunFigures {
    /// Seconds the ray tracer took to build.
    pub bvh_seconds: f64,
    /// Seconds of the whole run: load, ray tracer, bake and write.
    pub total_seconds: f64,
    /// The volume file written, as shown to users.
    pub output: String,
}

/// The report of a uniform bake or an engine baseline.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BakeReport {
    /// The scene's label ([`LoadedScene::label`]).
    pub scene: String,
    /// The method label ([`BakeRequest::label`]).
    pub method: String,
    /// The grid, in the scene file's frame.
    pub grid: FileGrid,
    /// Samples per cell or node.
    pub samples: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Rays by kind.
    pub rays: RayCounts,
    /// Cells where Algorithm 2 found back faces.
    pub cells_with_back_faces: u64,
    /// Candidate samples.
    pub candidates: u64,
    /// Samples kept.
    pub samples_kept: u64,
    /// Samples rejected as outside the domain of interest.
    pub samples_rejected: u64,
    /// Nodes with zero weight (a baseline's: the nodes its validity test rejected).
    pub zero_weight_nodes: usize,
    /// Zero-weight (or invalid) nodes filled from their neighbours.
    pub filled_nodes: usize,
    /// Rays of the node reach (`doi`; [`crate::reach`]), counted among `rays.query` too.
    pub reach_rays: u64,
    /// Sampling wall time, in seconds.
    pub seconds: f64,
    /// Seconds the ray tracer took to build.
    pub bvh_seconds: f64,
    /// Million rays per second over the sampling wall time.
    pub mrays_per_second: f64,
    /// The scene's size, the memory estimate against the peak, and the whole run's time.
    #[serde(flatten)]
    pub scale: BakeScale,
    /// The volume file written.
    pub output: String,
    /// The gradients, when baked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gradients: Option<GradientsReport>,
    /// What an engine baseline did, when the method is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baseline: Option<BaselineReport>,
    /// The samples a bake until converged spent, when it had a noise target.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseReport>,
    /// How noisy the nodes' estimates came out (`doi`, the method that keeps each node's
    /// error estimate, [`crate::bake::BakeOutput::node_error`]; a shard's nodes in a shard).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub node_noise: Option<NodeNoiseReport>,
    /// The light groups, when the bake was split by them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub light_groups: Option<LightGroupsReport>,
}

/// A bake split by light group ([`lightvol_volume::light_groups`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LightGroupsReport {
    /// The groups' names, in the file's order.
    pub groups: Vec<String>,
    /// Bytes the groups add to the file's coefficients (f32).
    pub bytes: usize,
    /// [`Self::bytes`] per grid node.
    pub bytes_per_node: usize,
    /// Bytes the groups add to the bake's working memory per node
    /// ([`crate::scene_setup::light_group_bytes`]).
    pub working_bytes_per_node: u64,
    /// The largest difference between the groups' sum and the whole bake, relative to the
    /// largest coefficient ([`lightvol_volume::GroupedVolume::sum_error`]).
    pub sum_error: f64,
}

/// What a bake until converged (`--noise`, [`crate::noise`]) spent.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NoiseReport {
    /// The relative error aimed at.
    pub relative_error: f64,
    /// The cap on samples per unit.
    pub max_samples: u32,
    /// Units (nodes, or cells) baked.
    pub units: u64,
    /// Samples of the units' final rounds, summed (the rays of earlier rounds are in the
    /// report's ray counts).
    pub final_samples: u64,
    /// Units that reached the cap before the target.
    pub capped_units: u64,
}

/// The spread of the nodes' estimated relative errors ([`crate::noise`]'s prefix estimate
/// of each node's mean over its kept samples): what a bake at a fixed sample count reached,
/// to judge it by, or to choose a `--noise` target from.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NodeNoiseReport {
    /// Nodes with an estimate (samples of their own, enough of them and some light).
    pub nodes: usize,
    /// The median estimate.
    pub median: f64,
    /// The 90th percentile: nine nodes in ten are at most this noisy.
    pub p90: f64,
    /// The largest estimate.
    pub max: f64,
}

impl NodeNoiseReport {
    /// The spread of `node_error` (NaN where a node has no estimate); `None` when no node
    /// has one. Percentiles are nearest-rank (`⌈p n⌉`-th smallest).
    #[must_use]
    pub fn of(node_error: &[f32]) -> Option<Self> {
        let mut e: Vec<f64> = node_error.iter().filter(|x| x.is_finite()).map(|&x| f64::from(x)).collect();
        e.sort_by(f64::total_cmp);
        let rank = |p: f64| e[((p * e.len() as f64).ceil() as usize).clamp(1, e.len()) - 1];
        (!e.is_empty()).then(|| Self {
            nodes: e.len(),
            median: rank(0.5),
            p90: rank(0.9),
            max: e[e.len() - 1],
        })
    }
}

/// Size and cost figures of a bake (flattened into [`BakeReport`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BakeScale {
    /// Triangles the scene places (every instance counted).
    pub triangles: u64,
    /// Triangles stored (each instanced mesh once).
    pub unique_triangles: u64,
    /// Mesh instances.
    pub instances: u64,
    /// The memory estimate a bake's grid is checked against: scene, ray tracer and grid
    /// ([`LoadedScene::bake_memory_bytes`]).
    pub estimated_memory_bytes: u64,
    /// This process's peak resident memory (Linux), when the figures were made.
    pub peak_memory_bytes: Option<u64>,
    /// Wall time of the whole run (the caller's [`RunFigures::total_seconds`]).
    pub total_seconds: f64,
}

/// The gradient step of a bake.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GradientsReport {
    /// The estimator.
    pub estimator: GradientEstimator,
    /// Nodes with a singular basis-gradient system (zero gradient).
    pub singular_nodes: usize,
    /// Directions traced beyond the bake.
    pub extra_directions: u64,
    /// Wall time beyond the bake, in seconds.
    pub seconds: f64,
    /// Bytes of gradient data (f32).
    pub memory_bytes: usize,
}

/// What an engine baseline did to its probes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct BaselineReport {
    /// Nodes its validity test rejected.
    pub invalid_nodes: usize,
    /// Nodes sampled elsewhere than at the node (virtual offset, relocation).
    pub moved_nodes: usize,
    /// Whether the volume carries the validity mask (`point+apv`).
    pub validity_mask: bool,
}

impl BakeScale {
    /// The figures of a bake of `loaded` on `grid` under `request`, with this process's
    /// peak resident memory now (make them once the volume is written) and the run's
    /// `total_seconds`.
    #[must_use]
    pub fn measure(loaded: &LoadedScene, grid: &GridSpec, request: &BakeRequest, total_seconds: f64) -> Self {
        let estimate =
            loaded.bake_memory_bytes(grid.res().map(u64::from), request.coeffs, request.records_node_reach());
        Self {
            triangles: loaded.scene.triangle_count() as u64,
            unique_triangles: loaded.scene.unique_triangle_count() as u64,
            instances: loaded.scene.instances.len() as u64,
            estimated_memory_bytes: u64::try_from(estimate).unwrap_or(u64::MAX),
            peak_memory_bytes: lightvol_scene::estimate::peak_resident_bytes(),
            total_seconds,
        }
    }
}

impl BakeReport {
    /// The report of the uniform bake `bake` of `loaded` on `grid` under `request`, with
    /// what the caller measured (`run`).
    #[must_use]
    pub fn uniform(
        loaded: &LoadedScene,
        grid: &GridSpec,
        request: &BakeRequest,
        bake: &UniformBake,
        run: RunFigures,
    ) -> Self {
        let s = &bake.output.stats;
        let mut report = Self {
            cells_with_back_faces: s.cells_with_back_faces,
            candidates: s.candidates,
            samples_kept: s.samples_kept,
            samples_rejected: s.samples_rejected,
            zero_weight_nodes: bake.volume.weights().iter().filter(|&&w| w == 0.0).count(),
            filled_nodes: bake.fill.filled,
            reach_rays: s.reach_rays,
            mrays_per_second: s.mrays_per_second(),
            node_noise: NodeNoiseReport::of(&bake.output.node_error),
            noise: request.noise.map(|n| NoiseReport {
                relative_error: n.relative_error,
                max_samples: n.max_samples.get(),
                units: s.units,
                final_samples: s.final_samples,
                capped_units: s.capped_units,
            }),
            gradients: bake.gradients.as_ref().map(|g| GradientsReport {
                estimator: g.estimator,
                singular_nodes: g.singular_nodes,
                extra_directions: g.extra_directions,
                seconds: g.seconds,
                memory_bytes: g.gradients.memory_bytes(),
            }),
            light_groups: bake.groups.as_ref().map(|g| {
                let nodes = grid.node_count().max(1);
                LightGroupsReport {
                    groups: g.names().to_vec(),
                    bytes: g.layer_bytes(),
                    bytes_per_node: g.layer_bytes() / nodes,
                    working_bytes_per_node: u64::try_from(crate::scene_setup::light_group_bytes(
                        [1, 1, 1],
                        request.coeffs,
                        g.names().len(),
                    ))
                    .unwrap_or(u64::MAX),
                    sum_error: g.sum_error(),
                }
            }),
            ..Self::common(loaded, grid, request, s.rays, s.wall_time.as_secs_f64(), run)
        };
        if let Some(g) = &bake.groups {
            let extra = crate::scene_setup::light_group_bytes(
                grid.res().map(u64::from),
                request.coeffs,
                g.names().len(),
            );
            let total = u128::from(report.scale.estimated_memory_bytes).saturating_add(extra);
            report.scale.estimated_memory_bytes = u64::try_from(total).unwrap_or(u64::MAX);
        }
        report
    }

    /// The report of the engine baseline `bake` of `loaded` on `grid` under `request`, with
    /// what the caller measured (`run`).
    #[must_use]
    pub fn baseline(
        loaded: &LoadedScene,
        grid: &GridSpec,
        request: &BakeRequest,
        bake: &BaselineBake,
        run: RunFigures,
    ) -> Self {
        let seconds = bake.wall_time.as_secs_f64();
        let invalid = bake.invalid_nodes();
        Self {
            zero_weight_nodes: invalid,
            filled_nodes: bake.filled,
            mrays_per_second: mrays_per_second(&bake.rays, seconds),
            baseline: Some(BaselineReport {
                invalid_nodes: invalid,
                moved_nodes: bake.moved_nodes(grid),
                validity_mask: bake.volume.validity().is_some(),
            }),
            ..Self::common(loaded, grid, request, bake.rays, seconds, run)
        }
    }

    /// The fields every bake fills alike; the sampler's counters zero.
    fn common(
        loaded: &LoadedScene,
        grid: &GridSpec,
        request: &BakeRequest,
        rays: RayCounts,
        seconds: f64,
        run: RunFigures,
    ) -> Self {
        Self {
            scene: loaded.label.clone(),
            method: request.label(),
            grid: FileGrid::of(grid, loaded.frame),
            samples: request.samples.get(),
            seed: request.seed,
            rays,
            cells_with_back_faces: 0,
            candidates: 0,
            samples_kept: 0,
            samples_rejected: 0,
            zero_weight_nodes: 0,
            filled_nodes: 0,
            reach_rays: 0,
            seconds,
            bvh_seconds: run.bvh_seconds,
            mrays_per_second: 0.0,
            scale: BakeScale::measure(loaded, grid, request, run.total_seconds),
            output: run.output,
            gradients: None,
            baseline: None,
            noise: None,
            node_noise: None,
            light_groups: None,
        }
    }
}

/// The report of an octree bake.
///
/// `lightvol bake --adaptive --json` prints it through [`serde_json::to_value`] (see
/// [`Self::to_json`]): without serde_json's `preserve_order` feature a JSON value's objects
/// keep their keys sorted, so the keys come out in alphabetical order at every level, the
/// grid's (`bounds`, `frame`, `res`) included. The fields are declared in that order too.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AdaptiveReport {
    /// Always `true`: an octree.
    pub adaptive: bool,
    /// Seconds the ray tracer took to build.
    pub bvh_seconds: f64,
    /// Rays of the depth heuristic.
    pub depth_rays: u64,
    /// The level-0 grid, in the scene file's frame.
    pub grid: FileGrid,
    /// The method label ([`BakeRequest::label`]).
    pub method: String,
    /// The octree's description (lightvol-volume's `info::octree_json`).
    pub octree: serde_json::Value,
    /// The volume file written.
    pub output: String,
    /// All rays (bakes and heuristics).
    pub rays: RayCounts,
    /// Samples per cell or node.
    pub samples: u32,
    /// The scene's label ([`LoadedScene::label`]).
    pub scene: String,
    /// Wall time of the whole bake, in seconds.
    pub seconds: f64,
    /// Seed of every random stream.
    pub seed: u64,
    /// Cells each heuristic asked to split.
    pub split_votes: SplitVotes,
}

/// Cells each subdivision heuristic asked to split (a cell may count under several).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct SplitVotes {
    /// The depth heuristic.
    pub depth: usize,
    /// The geometry heuristic.
    pub geometry: usize,
    /// The gradient heuristic.
    pub gradient: usize,
}

impl AdaptiveReport {
    /// The report of the octree `volume` that a bake of `loaded` on the level-0 grid `grid`
    /// under `request` made, with its `stats`, the ray tracer's build time `bvh_seconds`
    /// and the file written, `output`.
    #[must_use]
    pub fn new(
        loaded: &LoadedScene,
        grid: &GridSpec,
        request: &BakeRequest,
        volume: &AdaptiveVolume,
        stats: &AdaptiveStats,
        bvh_seconds: f64,
        output: String,
    ) -> Self {
        let [gradient, geometry, depth] = stats.split_votes;
        Self {
            adaptive: true,
            bvh_seconds,
            depth_rays: stats.depth_rays,
            grid: FileGrid::of(grid, loaded.frame),
            method: request.label(),
            octree: lightvol_volume::info::octree_json(volume),
            output,
            rays: stats.rays,
            samples: request.samples.get(),
            scene: loaded.label.clone(),
            seconds: stats.wall_time.as_secs_f64(),
            seed: request.seed,
            split_votes: SplitVotes { depth, geometry, gradient },
        }
    }

    /// The report as the JSON value that is printed: keys in alphabetical order at every
    /// level.
    ///
    /// # Errors
    /// serde_json's, which this report's fields do not raise (it has no map with keys
    /// other than strings).
    pub fn to_json(&self) -> Result<serde_json::Value, serde_json::Error> {
        serde_json::to_value(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adaptive::{AdaptiveSettings, bake_adaptive};
    use crate::baselines::bake_baseline;
    use crate::method::{BakeMethod, Baseline, Method};
    use crate::request::{AdaptiveRequest, Provenance, bake_uniform};
    use crate::scene_setup::{LightOverrides, SceneSource, load};
    use lightvol_core::progress::BakeControl;
    use lightvol_core::samples::samples;
    use lightvol_scene::{Tracer, Transport, UpAxis};

    fn maze() -> (LoadedScene, GridSpec) {
        let loaded =
            load(&SceneSource::Builtin("maze".into()), u128::MAX, &LightOverrides::default()).unwrap();
        let (lo, hi) = loaded.grid.as_ref().unwrap().bounds();
        let grid = GridSpec::new(lo, hi, [4, 4, 3]).unwrap();
        (loaded, grid)
    }

    fn run() -> RunFigures {
        RunFigures { bvh_seconds: 0.25, total_seconds: 1.5, output: "out/v.exr".into() }
    }

    /// 48 nodes of 27 coefficients: 29 sums of 17 bytes, 28 f64 estimates and 28 f32
    /// values each ([`crate::scene_setup::bake_memory_bytes`]), plus the scene.
    fn estimate(loaded: &LoadedScene) -> u64 {
        48 * (29 * 17 + 28 * 8 + 28 * 4) + loaded.memory.total()
    }

    #[test]
    fn a_uniform_bake_reports_its_sampler_and_scale() {
        let (loaded, grid) = maze();
        let tracer = Tracer::new(&loaded.scene);
        let t = Transport::new(&loaded.scene, &tracer, Default::default());
        let request =
            BakeRequest { seed: 3, ..BakeRequest::new(BakeMethod::Grid(Method::DoiPaper), samples(4)) };
        let p = Provenance { frame: loaded.frame, key: "k" };
        let bake = bake_uniform(&t, &loaded.scene, &grid, &request, p, &BakeControl::default()).unwrap();
        let r = BakeReport::uniform(&loaded, &grid, &request, &bake, run());
        let s = &bake.output.stats;
        assert_eq!(
            (r.scene.as_str(), r.method.as_str(), r.samples, r.seed),
            ("builtin:maze", "doi-paper", 4, 3)
        );
        assert_eq!(
            r.grid,
            FileGrid { res: [4, 4, 3], bounds: [grid.bounds().0, grid.bounds().1], frame: UpAxis::Z }
        );
        assert_eq!(r.rays, s.rays);
        // 18 cells of 4 candidates each, every candidate kept or rejected.
        assert_eq!(r.candidates, 18 * 4);
        assert_eq!(r.samples_kept + r.samples_rejected, r.candidates);
        assert_eq!(
            (r.candidates, r.samples_kept, r.samples_rejected),
            (s.candidates, s.samples_kept, s.samples_rejected)
        );
        assert_eq!(r.cells_with_back_faces, s.cells_with_back_faces);
        let zero = bake.volume.weights().iter().filter(|w| **w == 0.0).count();
        assert_eq!((r.zero_weight_nodes, r.filled_nodes), (zero, bake.fill.filled));
        assert_eq!(r.seconds, s.wall_time.as_secs_f64());
        assert_eq!(r.mrays_per_second, r.rays.total() as f64 / r.seconds / 1e6);
        assert_eq!((r.bvh_seconds, r.output.as_str()), (0.25, "out/v.exr"));
        let tris = loaded.scene.triangle_count() as u64;
        assert!(tris > 0);
        assert_eq!((r.scale.triangles, r.scale.unique_triangles, r.scale.instances), (tris, tris, 0));
        assert_eq!(r.scale.estimated_memory_bytes, estimate(&loaded));
        assert_eq!(r.scale.total_seconds, 1.5);
        assert!(r.gradients.is_none() && r.baseline.is_none() && r.node_noise.is_none());
        // The scale is flattened between the throughput and the output; absent parts are left out.
        let json = serde_json::to_string(&r).unwrap();
        let at = |k: &str| json.find(&format!("\"{k}\":")).unwrap_or_else(|| panic!("{k} in {json}"));
        assert!(at("mrays_per_second") < at("triangles") && at("total_seconds") < at("output"), "{json}");
        assert!(!json.contains("\"gradients\"") && !json.contains("\"baseline\""), "{json}");
    }

    /// Nearest-rank percentiles over the nodes with an estimate; NaN and infinite ones are
    /// left out, and a bake without any has no report.
    #[test]
    fn node_noise_is_the_spread_of_the_estimates() {
        let mut e: Vec<f32> = (1..=10).rev().map(|i| i as f32 / 100.0).collect();
        e.extend([f32::NAN, f32::INFINITY, f32::NAN]);
        let r = NodeNoiseReport::of(&e).unwrap();
        assert_eq!(r.nodes, 10);
        assert_eq!((r.median, r.p90, r.max), (f64::from(0.05f32), f64::from(0.09f32), f64::from(0.1f32)));
        let one = NodeNoiseReport::of(&[0.25]).unwrap();
        assert_eq!((one.nodes, one.median, one.p90, one.max), (1, 0.25, 0.25, 0.25));
        assert!(NodeNoiseReport::of(&[f32::NAN; 4]).is_none());
        assert!(NodeNoiseReport::of(&[]).is_none());
    }

    /// A `doi` bake reports its nodes' noise (the other methods keep no per-node estimate).
    #[test]
    fn a_doi_bake_reports_its_nodes_noise() {
        let (loaded, grid) = maze();
        let tracer = Tracer::new(&loaded.scene);
        let t = Transport::new(&loaded.scene, &tracer, Default::default());
        let request = BakeRequest::new(BakeMethod::Grid(Method::Doi), samples(64));
        let p = Provenance { frame: loaded.frame, key: "k" };
        let bake = bake_uniform(&t, &loaded.scene, &grid, &request, p, &BakeControl::default()).unwrap();
        let r = BakeReport::uniform(&loaded, &grid, &request, &bake, run());
        let n = r.node_noise.clone().expect("a doi bake estimates its nodes' errors");
        assert_eq!(Some(n.clone()), NodeNoiseReport::of(&bake.output.node_error));
        assert!(n.nodes > 0 && n.nodes <= grid.node_count(), "{n:?}");
        assert!(0.0 <= n.median && n.median <= n.p90 && n.p90 <= n.max, "{n:?}");
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["node_noise"]["nodes"], n.nodes);
    }

    #[test]
    fn a_baseline_reports_its_probes() {
        let (loaded, grid) = maze();
        let tracer = Tracer::new(&loaded.scene);
        let t = Transport::new(&loaded.scene, &tracer, Default::default());
        let request = BakeRequest::new(BakeMethod::Baseline(Baseline::Apv), samples(4));
        let bake = bake_baseline(&t, &grid, &request.settings(), Baseline::Apv).unwrap();
        let r = BakeReport::baseline(&loaded, &grid, &request, &bake, run());
        let invalid = bake.valid.iter().filter(|v| !**v).count();
        assert_eq!(
            (r.method.as_str(), r.zero_weight_nodes, r.filled_nodes),
            ("point+apv", invalid, bake.filled)
        );
        let b = r.baseline.as_ref().unwrap();
        assert_eq!(
            (b.invalid_nodes, b.moved_nodes, b.validity_mask),
            (invalid, bake.moved_nodes(&grid), true)
        );
        assert_eq!((r.candidates, r.samples_kept, r.cells_with_back_faces), (0, 0, 0));
        assert_eq!(r.rays, bake.rays);
        assert!(r.rays.query >= 48 * 64, "{:?}", r.rays);
        assert_eq!(r.seconds, bake.wall_time.as_secs_f64());
        assert_eq!(r.mrays_per_second, r.rays.total() as f64 / r.seconds / 1e6);
        assert_eq!(r.scale.estimated_memory_bytes, estimate(&loaded));
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["baseline"]["invalid_nodes"], invalid);
    }

    #[test]
    fn an_octree_report_prints_its_keys_in_order() {
        let (loaded, grid) = maze();
        let tracer = Tracer::new(&loaded.scene);
        let t = Transport::new(&loaded.scene, &tracer, Default::default());
        let settings = AdaptiveSettings { max_level: 1, ..AdaptiveSettings::default() };
        let request = BakeRequest {
            adaptive: Some(AdaptiveRequest { settings: settings.clone(), level: None, from_shards: false }),
            ..BakeRequest::new(BakeMethod::Grid(Method::Doi), samples(4))
        };
        let (vol, stats) =
            bake_adaptive(&t, &grid, &request.settings(), &settings, &BakeControl::default()).unwrap();
        let r = AdaptiveReport::new(&loaded, &grid, &request, &vol, &stats, 0.25, "o.exr".into());
        let [gradient, geometry, depth] = stats.split_votes;
        assert_eq!(r.split_votes, SplitVotes { depth, geometry, gradient });
        assert_eq!(
            (r.rays, r.depth_rays, r.samples, r.method.as_str()),
            (stats.rays, stats.depth_rays, 4, "doi")
        );
        assert_eq!(r.octree["max_level"], 1);
        let json = r.to_json().unwrap();
        let keys = |v: &serde_json::Value| v.as_object().unwrap().keys().cloned().collect::<Vec<_>>();
        let top = [
            "adaptive",
            "bvh_seconds",
            "depth_rays",
            "grid",
            "method",
            "octree",
            "output",
            "rays",
            "samples",
            "scene",
            "seconds",
            "seed",
            "split_votes",
        ];
        assert_eq!(keys(&json), top);
        assert_eq!(keys(&json["grid"]), ["bounds", "frame", "res"]);
        assert_eq!(keys(&json["rays"]), ["bounce", "query", "sampling", "shadow", "total"]);
        assert_eq!(keys(&json["split_votes"]), ["depth", "geometry", "gradient"]);
        assert_eq!(json["grid"]["res"], serde_json::json!([4, 4, 3]));
    }
}
