//! The domain of interest's ray budget: at equal samples, a `doi-paper` or `doi` bake traces at most
//! [`DOI_RAY_BUDGET`] times the rays of a `point` bake, on every built-in scene (at its
//! recommended grid) and every vendored real scene (16 cells along its longest axis,
//! under a uniform white sky, as the CLI lights a scene without lights). Algorithm 2's
//! query rays are the extra cost; the classification rays' hits are reused for lighting.
//! `doi`'s node reach adds a cost per node that does not grow with the samples: one ray
//! per direction inside the budget, and at most [`REACH_BUNDLE_RAYS`](lightvol_sampler::reach::REACH_BUNDLE_RAYS)` − 1` more where
//! something stops that ray.

use lightvol_core::samples::samples;

use lightvol_core::progress::BakeControl;
use lightvol_sampler::{BakeSettings, Method, bake};
use lightvol_scene::builtin::{BUILTIN_NAMES, builtin};
use lightvol_scene::lights::Environment;
use lightvol_scene::{DVec3, LoadOptions, Scene, Tracer, Transport, TransportSettings, load_scene};
use lightvol_volume::GridSpec;
use vendored::{VENDORED_SCENES, vendored};

mod vendored;

/// `doi` may trace this many times `point`'s rays.
const DOI_RAY_BUDGET: f64 = 1.25;

/// The node reach's rays per node and grid direction, on average over the grid: one where
/// nothing stops the first ray, at most [`REACH_BUNDLE_RAYS`](lightvol_sampler::reach::REACH_BUNDLE_RAYS) elsewhere.
const REACH_RAYS_PER_DIRECTION: f64 = 2.0;

/// Samples per cell or node: enough for every cell near a wall to find its back faces.
const SAMPLES: u32 = 16;

/// All rays, and the node reach's among them.
fn rays(scene: &Scene, grid: &GridSpec, method: Method) -> (u64, u64) {
    let tracer = Tracer::new(scene);
    let t = Transport::new(scene, &tracer, TransportSettings::default());
    let s = BakeSettings { method, samples: samples(SAMPLES), seed: 3, ..BakeSettings::default() };
    let stats = bake(&t, grid, &s, &BakeControl::default()).unwrap().stats;
    (stats.rays.total(), stats.reach_rays)
}

/// The CLI's default grid: the bounds grown by 5%, 16 cells along the longest axis.
fn default_grid(scene: &Scene) -> GridSpec {
    let (lo, hi) = scene.bounds();
    let pad = (hi - lo) * 0.05 + DVec3::splat(1e-3);
    let (lo, hi) = (lo - pad, hi + pad);
    let longest = (hi - lo).max_element();
    let res = ((hi - lo) / longest * 16.0).ceil().to_array().map(|c| c as u32 + 1);
    GridSpec::new(lo.to_array(), hi.to_array(), res.map(|r| r.max(2))).unwrap()
}

/// Every built-in scene at its recommended grid and every vendored real scene at the CLI's
/// default grid, a scene without lights under a uniform white sky.
fn cases() -> Vec<(String, Scene, GridSpec)> {
    let mut cases: Vec<(String, Scene, GridSpec)> = BUILTIN_NAMES
        .iter()
        .map(|n| {
            let b = builtin(n).unwrap();
            (format!("builtin:{n}"), b.scene, b.grid)
        })
        .collect();
    for rel in VENDORED_SCENES {
        let mut s = load_scene(&vendored(rel), &LoadOptions::default()).unwrap();
        if s.sun.is_none() && s.punctual.is_empty() && !s.materials.iter().any(|m| m.is_emissive()) {
            s.environment = Environment::UniformSky { sky: [1.0; 3], ground: None };
        }
        let g = default_grid(&s);
        cases.push((rel.to_owned(), s, g));
    }
    cases
}

#[test]
fn doi_stays_within_its_ray_budget() {
    for (name, scene, grid) in &cases() {
        let (point, _) = rays(scene, grid, Method::Point);
        for method in [Method::DoiPaper, Method::Doi] {
            let (doi, reach) = rays(scene, grid, method);
            let ratio = (doi - reach) as f64 / point as f64;
            let per_direction = reach as f64 / (6 * grid.node_count()) as f64;
            eprintln!(
                "{name}: {method:?} {doi} rays, {reach} of them the reach's ({per_direction:.2} a node \
                 and direction), point {point}: {ratio:.3} less the reach"
            );
            assert!(ratio <= DOI_RAY_BUDGET, "{name}: {method:?} traces {ratio:.3} x point's rays");
            assert!(
                per_direction <= REACH_RAYS_PER_DIRECTION,
                "{name}: {method:?} reach traces {per_direction:.2} rays a node and direction"
            );
        }
    }
}

/// `bake --target` may add this share to a `doi` bake's rays: the fit reuses the bake's
/// light and traces only the rays that find its sample points.
const TARGET_RAY_BUDGET: f64 = 0.05;

/// Samples per node of the method table's bakes, at which the budget is stated.
const TABLE_SAMPLES: u32 = 128;

/// At the method table's settings, fitting a `doi` bake for an engine's lookup adds at
/// most 5% to its rays, on every scene.
#[test]
fn target_fits_stay_within_their_ray_budget() {
    use lightvol_sampler::target::{TargetSettings, fit_for_lookup, own_samples_mask};
    use lightvol_volume::EngineLookup;
    for (name, scene, grid) in &cases() {
        let tracer = Tracer::new(scene);
        let t = Transport::new(scene, &tracer, TransportSettings::default());
        let s = BakeSettings { samples: samples(TABLE_SAMPLES), seed: 3, ..BakeSettings::default() };
        let out = bake(&t, grid, &s, &BakeControl::default()).unwrap();
        let valid = own_samples_mask(&out.accumulator);
        let doi = out.stats.rays.total();
        let (vol, _) = out.finish();
        let (_, r) =
            fit_for_lookup(&t, &vol, &TargetSettings::new(EngineLookup::Three, 3), Some(valid), None)
                .unwrap();
        let share = r.rays as f64 / doi as f64;
        eprintln!("{name}: doi {doi} rays, the fit {} more ({:.2}%)", r.rays, 100.0 * share);
        assert!(r.rays > 0 && share <= TARGET_RAY_BUDGET, "{name}: the fit adds {:.2}%", 100.0 * share);
    }
}
