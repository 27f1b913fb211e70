//! The comparison of Kontkanen & Laine 2006 (\[KL06\] §8, Fig. 6): every entry baked at the
//! same sample budget on one grid and measured on one plate against one path-traced
//! reference, optionally followed by the views through cameras and the error-against-memory
//! study.

use lightvol_core::samples::{Samples, samples};
use lightvol_volume::GridSpec;

use lightvol_volume::volume::check_coeffs;

use crate::entries::{Entry, NamedEntry};
use crate::error::EvalError;
use crate::observer::Observer;
use crate::plate::{Plate, PlateConfig};
use crate::reads::{ReadAs, read_as};
use crate::runs::{
    BakeContext, GradientCache, MethodRun, run_adaptive, run_baseline, run_bound, run_gradient, run_targeted,
    run_uniform,
};
use crate::sweep::{SweepConfig, SweepReport, check_scales, memory_sweep};
use crate::views::{ComparedView, ViewsConfig, check_cameras, compare_views};
use lightvol_sampler::gradient_estimator::GradientEstimator;
use lightvol_sampler::method::Method;
use lightvol_sampler::node_fit::Fit;
use lightvol_scene::bvh::Tracer;
use lightvol_scene::scene::Scene;
use lightvol_scene::transport::{Transport, TransportSettings};

/// Everything a comparison needs besides the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct CompareConfig {
    /// The uniform grid every uniform entry is baked on, and the memory the octree entries
    /// get; axis-aligned (no placement).
    pub grid: GridSpec,
    /// SH coefficients per channel (4, 9 or 16).
    pub coeffs: usize,
    /// The entries, in the order they are baked and reported.
    pub methods: Vec<NamedEntry>,
    /// Samples per cell (prefilter, doi, every octree level) or directions per node (point
    /// and the engine baselines): the same budget for every entry.
    pub samples: Samples,
    /// Seed of every random stream (bakes, plate classification, reference); results are
    /// bit-identical for a seed, whatever the thread count.
    pub seed: u64,
    /// Bake every entry until its units converge ([`lightvol_sampler::noise`]), from
    /// [`samples`](Self::samples); `None`: exactly `samples`.
    pub noise: Option<lightvol_sampler::noise::NoiseTarget>,
    /// Path length and direct light of the bakes and the reference alike.
    pub transport: TransportSettings,
    /// Node fit of the [`Entry::Uniform`] cell-sample entries (`prefilter`, `doi-paper`); the
    /// per-node ones (`point`, `doi`, `doi-node`) take their samples' values.
    pub fit: Fit,
    /// Gradient estimator of the [`Entry::Gradient`] entries (`None`:
    /// [`GradientEstimator::default_for`] the base method).
    pub gradient_estimator: Option<GradientEstimator>,
    /// The evaluation plate.
    pub plate: PlateConfig,
    /// The error-against-memory study over grids scaled from [`grid`](Self::grid), when
    /// wanted.
    pub memory_sweep: Option<SweepConfig>,
    /// The cameras through which every entry is also seen (module
    /// [`views`](crate::views)); none by default.
    pub views: ViewsConfig,
    /// The ways every entry's plate and views are read ([`ReadAs`]): lightvol's own lookups
    /// (the default), one engine's (uniform-grid entries only), or each entry's own
    /// engine's. The first keeps the entries' names; each further one adds the runs
    /// `NAME@WAY` (module [`reads`](crate::reads)). Empty reads as lightvol's.
    pub lookups: Vec<ReadAs>,
    /// Worker threads; `None` runs on the caller's rayon pool (the global one, all cores,
    /// unless called inside `ThreadPool::install`).
    pub threads: Option<usize>,
    /// The sky that `BASE+relit` entries are baked under before they are relit to the
    /// scene's own ([`Entry::Relit`]).
    pub relight_from: Option<lightvol_scene::Environment>,
}

impl CompareConfig {
    /// The comparison of \[KL06\] Fig. 6 on `grid` and `plate`: `point`, `prefilter` and
    /// `doi`, 256 samples, order 3, seed 1, unbiased paths with all light, Eq. 6's average,
    /// no views, no sweep, all cores.
    #[must_use]
    pub fn new(grid: GridSpec, plate: PlateConfig) -> Self {
        Self {
            grid,
            coeffs: 9,
            methods: [Method::Point, Method::Prefilter, Method::DoiPaper, Method::Doi]
                .map(|m| NamedEntry::new(Entry::Uniform(m)))
                .to_vec(),
            samples: samples(256),
            seed: 1,
            noise: None,
            transport: TransportSettings::default(),
            fit: Fit::Average,
            gradient_estimator: None,
            plate,
            memory_sweep: None,
            views: ViewsConfig::default(),
            lookups: vec![ReadAs::default()],
            threads: None,
            relight_from: None,
        }
    }

    /// The context of this configuration's bakes over `transport`, reporting to `observer`.
    #[must_use]
    pub fn bake_context<'a>(&self, transport: Transport<'a>, observer: &'a dyn Observer) -> BakeContext<'a> {
        BakeContext {
            transport,
            samples: self.samples,
            coeffs: self.coeffs,
            seed: self.seed,
            noise: self.noise,
            observer,
        }
    }

    /// Checks everything that can be checked before tracing a ray: at least one entry,
    /// nonzero sample counts, 4, 9 or 16 coefficients, valid sweep scales, nonzero threads, an axis-aligned grid, a plate
    /// inside it ([`PlateConfig::validate`]), no gradient entry that needs the basis
    /// estimator on a `point` bake, and valid views ([`ViewsConfig::validate`]).
    ///
    /// # Errors
    /// The first problem found, in that order.
    pub fn validate(&self) -> Result<(), EvalError> {
        if self.methods.is_empty() {
            return Err(EvalError::NoMethods);
        }
        check_coeffs(self.coeffs)?;
        if let Some(sweep) = &self.memory_sweep {
            check_scales(&sweep.scales)?;
        }
        if self.threads == Some(0) {
            return Err(EvalError::ZeroThreads);
        }
        if self.grid.placement().is_some() {
            return Err(EvalError::PlacedGrid);
        }
        for &way in &self.lookups {
            if let Some(m) = self.methods.iter().find(|m| way.needs_grid(m.entry)) {
                return Err(EvalError::EngineLookupNeedsGrid {
                    lookup: way.name().to_owned(),
                    entry: m.name.clone(),
                });
            }
        }
        self.plate.validate(&self.grid)?;
        let basis_on_point = |m: &NamedEntry| match m.entry {
            Entry::Gradient(base, _) => !self
                .gradient_estimator
                .unwrap_or_else(|| GradientEstimator::default_for(base))
                .supports(base),
            _ => false,
        };
        if let Some(m) = self.methods.iter().find(|m| basis_on_point(m)) {
            return Err(EvalError::BasisNeedsCells { entry: m.name.clone() });
        }
        self.views.validate()
    }
}

/// A finished comparison.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// The plate, its classification and its reference.
    pub plate: Plate,
    /// Mean reference luminance over the plate's valid points.
    pub mean_truth: f64,
    /// Every entry's run, in the configured order.
    pub methods: Vec<MethodRun>,
    /// Every camera's views, in the configured order (empty without cameras).
    pub views: Vec<ComparedView>,
    /// The error-against-memory study, when configured.
    pub memory_sweep: Option<SweepReport>,
}

/// Runs the comparison (module docs) on `scene`, reporting progress to `observer`: builds
/// the ray tracer, the plate and its reference, bakes and measures every entry in order
/// (gradient entries on one base method share one bake), renders the views, then the
/// memory sweep.
///
/// # Errors
/// An invalid `config` ([`CompareConfig::validate`], before anything is traced), a camera
/// that sees no surface inside the grid ([`EvalError::ViewSeesNothing`], before the plate), a plate without
/// a valid point ([`EvalError::NoValidPoints`]), and the bakes' errors.
pub fn compare(
    scene: &Scene,
    config: &CompareConfig,
    observer: &dyn Observer,
) -> Result<Comparison, EvalError> {
    config.validate()?;
    match config.threads {
        None => compare_here(scene, config, observer),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(EvalError::ThreadPool)?
            .install(|| compare_here(scene, config, observer)),
    }
}

/// [`compare`] on the current rayon pool, `config` validated.
fn compare_here(
    scene: &Scene,
    config: &CompareConfig,
    observer: &dyn Observer,
) -> Result<Comparison, EvalError> {
    let tracer = Tracer::new(scene);
    let ctx = config.bake_context(Transport::new(scene, &tracer, config.transport), observer);
    let grid = &config.grid;
    check_cameras(&ctx.transport, grid, &config.views)?;
    let plate = Plate::build(&ctx.transport, grid, &config.plate, config.seed, observer)?;
    let mean_truth = plate.mean_truth().ok_or(EvalError::NoValidPoints(plate.height))?;
    let mut baked = Vec::with_capacity(config.methods.len());
    let mut gradient_bakes = GradientCache::default();
    let mut brick_octree = crate::runs::BrickOctree::default();
    for NamedEntry { name, entry } in &config.methods {
        let run = match *entry {
            // The comparison's fit is for the cell-sample bakes; the per-node ones (point,
            // doi, doi-node) take their own values, as a `BASE+lsq` entry would refuse.
            Entry::Uniform(method) => {
                let fit = if matches!(method, Method::Prefilter | Method::DoiPaper) {
                    config.fit
                } else {
                    Fit::Average
                };
                run_uniform(&ctx, grid, name, method, fit, &plate)?
            }
            Entry::Fitted(method, fit) => run_uniform(&ctx, grid, name, method, fit, &plate)?,
            Entry::Gradient(base, lookup) => {
                let gv = gradient_bakes.get(&ctx, grid, base, config.gradient_estimator, name)?;
                run_gradient(gv, name, lookup, config.samples, &plate)?
            }
            Entry::Adaptive(levels) => run_adaptive(&ctx, grid, name, levels, &plate)?,
            Entry::Bricks(divisor) => {
                crate::runs::run_bricks(&ctx, grid, name, divisor, &mut brick_octree, &plate)?
            }
            Entry::Baseline(b) => run_baseline(&ctx, grid, name, b, &plate)?,
            Entry::Targeted(method, lookup) => run_targeted(&ctx, grid, name, method, lookup, &plate)?,
            Entry::Bound(lookup) => run_bound(&ctx, grid, name, lookup, &plate)?,
            Entry::Relit(method, order) => {
                let from = config.relight_from.as_ref().ok_or(EvalError::NoRelightFrom)?;
                crate::relight::run_relit(&ctx, grid, name, method, order, from, &plate)?
            }
            Entry::SkyOcclusion(method) => {
                let from = config.relight_from.as_ref().ok_or(EvalError::NoRelightFrom)?;
                crate::relight::run_sky_occlusion(&ctx, grid, name, method, from, &plate)?
            }
        };
        baked.push(run);
    }
    let ways = if config.lookups.is_empty() { vec![ReadAs::default()] } else { config.lookups.clone() };
    let mut runs = Vec::with_capacity(baked.len() * ways.len());
    for (i, &way) in ways.iter().enumerate() {
        for (run, m) in baked.iter().zip(&config.methods) {
            let mut read = read_as(run.clone(), m.entry, way, &plate);
            if i > 0 {
                read.name = format!("{}@{way}", m.name);
            }
            runs.push(read);
        }
    }
    let views = compare_views(&ctx.transport, grid, &config.views, &runs, config.seed, observer)?;
    let sweep = match &config.memory_sweep {
        Some(sweep) => Some(memory_sweep(&ctx, grid, &plate, sweep)?),
        None => None,
    };
    Ok(Comparison { plate, mean_truth, methods: runs, views, memory_sweep: sweep })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::baked::RunVolume;
    use crate::observer::Silent;
    use crate::runs::RunDetail;
    use lightvol_scene::builtin;
    use lightvol_volume::EngineLookup;
    use lightvol_volume::gradient::GradientLookup;
    use std::sync::Mutex;

    /// The maze at reduced settings: its recommended grid (11 × 11 × 3), a 12-point plate
    /// (also the views' tests' fixture).
    /// The stages a comparison starts, in order.
    #[derive(Default)]
    struct Log(Mutex<Vec<String>>);
    impl Observer for Log {
        fn stage_started(&self, label: &str) {
            self.0.lock().unwrap().push(label.to_owned());
        }
    }

    pub(crate) fn maze_config() -> (builtin::BuiltinScene, CompareConfig) {
        let maze = builtin::maze();
        let plate = PlateConfig {
            height: maze.plate_heights[0],
            res: 12,
            reference_samples: samples(16),
            classify_dirs: 64,
        };
        let mut c = CompareConfig::new(maze.grid.clone(), plate);
        c.samples = samples(8);
        c.threads = Some(2);
        (maze, c)
    }

    /// `lookup`: read as plain trilinear, `point` (no mask, no reach) measures what
    /// lightvol's lookup measures (up to the f32 against f64 lookups), while `doi`, whose
    /// node reach no engine reads, changes; three.js's normal offset changes both; an octree
    /// entry is refused before any bake.
    #[test]
    fn engine_lookups_read_every_entry() {
        // f32 trilinear lookups against f64: 1e-6 relative per point, far below 1e-5 in
        // the mean.
        const F32_TOL: f64 = 1e-5;
        let (maze, mut config) = maze_config();
        config.methods = ["point", "doi"].iter().map(|m| NamedEntry::parse(m).unwrap()).collect();
        let own = compare(&maze.scene, &config, &Silent).unwrap();
        config.lookups = vec![ReadAs::Engine(EngineLookup::Trilinear)];
        let tri = compare(&maze.scene, &config, &Silent).unwrap();
        config.lookups = vec![ReadAs::Engine(EngineLookup::Three)];
        let three = compare(&maze.scene, &config, &Silent).unwrap();
        let rmse = |c: &Comparison, i: usize| c.methods[i].metrics.rel_rmse;
        assert!((rmse(&own, 0) - rmse(&tri, 0)).abs() < F32_TOL, "{} {}", rmse(&own, 0), rmse(&tri, 0));
        assert!((rmse(&own, 1) - rmse(&tri, 1)).abs() > 1e-3, "the reach changes doi's plate");
        assert!((rmse(&own, 0) - rmse(&three, 0)).abs() > 1e-3, "three's offset changes point's plate");
        assert!(matches!(tri.methods[1].volume, RunVolume::Engine(_, EngineLookup::Trilinear)));
        config.methods.push(NamedEntry::parse("adaptive").unwrap());
        assert!(matches!(
            compare(&maze.scene, &config, &Silent),
            Err(EvalError::EngineLookupNeedsGrid { lookup, .. }) if lookup == "three"
        ));
        // Several ways at once: the same bakes, the first way under the entries' names.
        config.methods.pop();
        config.lookups = [EngineLookup::Lightvol, EngineLookup::Trilinear, EngineLookup::Three]
            .map(ReadAs::Engine)
            .to_vec();
        let all = compare(&maze.scene, &config, &Silent).unwrap();
        let names: Vec<&str> = all.methods.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(names, ["point", "doi", "point@trilinear", "doi@trilinear", "point@three", "doi@three"]);
        for (i, c) in [(0, &own), (2, &tri), (4, &three)] {
            for j in 0..2 {
                assert_eq!(all.methods[i + j].estimate, c.methods[j].estimate, "run {}", i + j);
            }
        }
    }

    /// \[KL06\]'s claim on a small built-in scene: at equal samples, domain-of-interest
    /// sampling has a lower relative RMSE on the plate than point sampling and fewer dark
    /// points near surfaces; every run measures the plate's valid points, and the numbers
    /// do not depend on the thread count.
    #[test]
    fn doi_beats_point_on_the_maze() {
        let (maze, config) = maze_config();
        let r = compare(&maze.scene, &config, &Silent).unwrap();
        let names: Vec<&str> = r.methods.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["point", "prefilter", "doi-paper", "doi"]);
        let point = &r.methods[0].metrics;
        for doi in [&r.methods[2].metrics, &r.methods[3].metrics] {
            println!("point {point:?}\ndoi {doi:?}");
            assert!(doi.rel_rmse < 0.8 * point.rel_rmse, "doi {} vs point {}", doi.rel_rmse, point.rel_rmse);
            assert!(doi.too_dark_near < point.too_dark_near);
        }
        let valid = r.plate.valid_points();
        assert!(valid > 0 && valid < r.plate.points.len(), "the maze's walls cut the plate");
        for m in &r.methods {
            assert_eq!(m.metrics.valid_points, valid);
            assert_eq!(m.metrics, r.plate.metrics(&m.estimate));
            // 9 RGB coefficients of f32 per node, and doi's node reach: 6 f32 per node.
            let reach = if m.name == "doi" { 11 * 11 * 3 * 6 * 4 } else { 0 };
            assert_eq!(m.memory_bytes, 11 * 11 * 3 * 27 * 4 + reach, "{}", m.name);
            assert!(m.rays.total() > 0);
        }
        let one = compare(&maze.scene, &CompareConfig { threads: Some(1), ..config }, &Silent).unwrap();
        for (a, b) in one.methods.iter().zip(&r.methods) {
            assert_eq!(a.estimate, b.estimate, "{}", a.name);
        }
        assert_eq!(one.plate.truth, r.plate.truth);
    }

    /// Gradient entries on one base share one bake; the octree stays within the uniform
    /// grid's bytes; the engine baselines count their validity rays; the memory sweep's
    /// scale-1 uniform point is the `doi-paper` entry itself; the observer sees every stage.
    #[test]
    fn entries_and_sweep() {
        let (maze, mut config) = maze_config();
        config.methods =
            ["doi-paper", "doi-paper+taylor", "doi-paper+hermite", "adaptive1", "point", "point+validity"]
                .iter()
                .map(|s| NamedEntry::parse(s).unwrap())
                .collect();
        config.memory_sweep = Some(SweepConfig { scales: vec![1.0], gradient_estimator: None });
        let log = Log::default();
        let r = compare(&maze.scene, &config, &log).unwrap();
        let m = |name: &str| r.methods.iter().find(|m| m.name == name).unwrap();
        assert_eq!(
            *log.0.lock().unwrap(),
            [
                "reference",
                "doi-paper",
                "doi-paper+taylor",
                "adaptive1",
                "point",
                "sweep x1",
                "doi x1",
                "adaptive x1",
                "adaptive1 x1"
            ]
        );
        assert_eq!(m("doi-paper+taylor").rays, m("doi-paper+hermite").rays);
        assert_eq!(m("doi-paper+taylor").rays, m("doi-paper").rays);
        assert_eq!(m("doi-paper+hermite").memory_bytes, 4 * m("doi-paper").memory_bytes);
        assert!(matches!(
            m("doi-paper+hermite").detail,
            RunDetail::Gradient { lookup: GradientLookup::Hermite, estimator: GradientEstimator::Basis, .. }
        ));
        // The octree's budget is the uniform doi grid's: coefficients and node reach.
        assert!(
            m("adaptive1").memory_bytes <= crate::entries::uniform_doi_memory_bytes(&maze.grid, 3)
                && crate::entries::uniform_doi_memory_bytes(&maze.grid, 3)
                    == m("doi-paper").memory_bytes + maze.grid.node_count() * 24
        );
        assert!(m("point+validity").rays.total() > m("point").rays.total());
        let sweep = r.memory_sweep.unwrap();
        // uniform, its three gradient lookups, uniform doi, the two octrees and the level-2
        // octree's bricks.
        assert_eq!(sweep.points.len(), 8);
        let bricks = sweep.points.iter().find(|p| p.series == "bricks").unwrap();
        let octree = sweep.points.iter().find(|p| p.series == "adaptive").unwrap();
        assert!(bricks.memory_bytes > 0 && bricks.rays == octree.rays);
        let uniform = sweep.points.iter().find(|p| p.series == "uniform").unwrap();
        assert_eq!(uniform.rel_rmse, m("doi-paper").metrics.rel_rmse);
    }

    /// The brick entries export one octree, baked once, each under its own budget.
    #[test]
    fn brick_entries_share_one_octree() {
        let (maze, mut config) = maze_config();
        config.methods = ["bricks", "bricks2"].iter().map(|s| NamedEntry::parse(s).unwrap()).collect();
        let log = Log::default();
        let r = compare(&maze.scene, &config, &log).unwrap();
        assert_eq!(*log.0.lock().unwrap(), ["reference", "bricks"]);
        let m = |name: &str| r.methods.iter().find(|m| m.name == name).unwrap();
        assert_eq!(m("bricks").rays, m("bricks2").rays);
        let probes = |name: &str| match &m(name).detail {
            RunDetail::Bricks { report, .. } => report.probe_bytes,
            d => panic!("{d:?}"),
        };
        let cap = crate::entries::uniform_probe_bytes(&maze.grid, config.coeffs) / 2;
        assert!(probes("bricks2") <= cap && probes("bricks2") <= probes("bricks"));
    }

    #[test]
    fn invalid_configs_are_refused_before_tracing() {
        let (_, config) = maze_config();
        let check = |f: &dyn Fn(&mut CompareConfig)| {
            let mut c = config.clone();
            f(&mut c);
            c.validate().unwrap_err()
        };
        assert!(matches!(check(&|c| c.methods.clear()), EvalError::NoMethods));
        assert!(matches!(check(&|c| c.threads = Some(0)), EvalError::ZeroThreads));
        assert!(matches!(check(&|c| c.coeffs = 5), EvalError::Volume(_)));
        assert!(matches!(check(&|c| c.plate.height = 99.0), EvalError::PlateOutsideGrid { .. }));
        assert!(matches!(
            check(&|c| c.memory_sweep = Some(SweepConfig { scales: vec![], gradient_estimator: None })),
            EvalError::NoSweepScales
        ));
        let e = check(&|c| {
            c.methods = vec![NamedEntry::parse("point+taylor").unwrap()];
            c.gradient_estimator = Some(GradientEstimator::Basis);
        });
        assert!(matches!(e, EvalError::BasisNeedsCells { ref entry } if entry == "point+taylor"));
        assert!(config.validate().is_ok());
    }
}
