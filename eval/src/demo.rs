//! What the demo is (`lightvol demo`): the built-in scenes and one real interior, each
//! compared at one [`DemoLevel`]'s settings with the same entries, views from a camera that
//! suits the scene, an error-against-memory study on two scenes, and a resolution sweep
//! drawn as one plot ([`sweep_plot`]). The command line runs these comparisons and writes
//! their files; [`crate::report::index_html`] is the page over them.

use lightvol_core::samples::{Samples, samples};
use lightvol_view::picture::Plot;

use crate::sweep::ResolutionSeries;

/// The settings of one demo level: the same for every scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DemoLevel {
    /// Samples per cell or node of every bake.
    pub samples: Samples,
    /// Plate points along the longer side.
    pub plate_res: u32,
    /// Path-traced samples per plate point.
    pub reference_samples: Samples,
    /// Grid nodes along x of the resolution sweep ([`crate::resolution_sweep`]).
    pub sweep: &'static [u32],
    /// Cell-count scales of the error-against-memory study ([`crate::memory_sweep`]).
    pub memory_scales: &'static [f64],
    /// Width of each scene's views.
    pub view_width: u32,
    /// Path-traced samples per pixel of the reference views.
    pub view_samples: Samples,
}

impl DemoLevel {
    /// `--quick`: finishes in about two minutes on two cores.
    pub const QUICK: Self = Self {
        samples: samples(64),
        plate_res: 64,
        reference_samples: samples(192),
        sweep: &[8, 12, 16, 24],
        memory_scales: &[0.5, 0.7, 1.0],
        view_width: 160,
        view_samples: samples(32),
    };

    /// The full demo.
    pub const FULL: Self = Self {
        samples: samples(256),
        plate_res: 160,
        reference_samples: samples(1024),
        sweep: &[8, 12, 16, 24, 32],
        memory_scales: &[0.4, 0.5, 0.7, 1.0, 1.4, 2.0],
        view_width: 384,
        view_samples: samples(256),
    };
}

/// The entries every built-in scene compares first: the three bakes of Kontkanen & Laine
/// 2006 and `doi`.
pub const BASE_ENTRIES: [&str; 4] = ["point", "prefilter", "doi-paper", "doi"];

/// Entries added to every built-in scene's comparison besides [`BASE_ENTRIES`]: doi-paper
/// with the least-squares node fit, the doi-paper bake read through \[Oat05\]'s gradient
/// lookups, \[Oat05\]'s octree at doi-paper's memory (finest level 2 and 1), the domain test
/// on each node's own cell, and the engines' leak fixes (lightvol-sampler's `baselines`).
pub const EXTRA_ENTRIES: [&str; 10] = [
    "doi-paper+lsq",
    "doi-paper+taylor",
    "doi-paper+hermite",
    "adaptive",
    "adaptive1",
    "doi-node",
    "point+validity",
    "point+apv",
    "point+vlm",
    "point+ddgi",
];

/// The real interior of the demo: the occlusion-culling demo room of the Godot demo
/// projects (`data/scenes/occlusion_room`), lit by a uniform white sky through its openings,
/// sky and bounce light only, as engines bake their probes.
pub const REAL_INTERIOR: &str = "occlusion_room";

/// The real interior's entries: the grid methods and the engines' leak fixes.
pub const REAL_ENTRIES: [&str; 7] =
    ["point", "doi-paper", "doi", "point+validity", "point+apv", "point+vlm", "point+ddgi"];

/// The sky change of the demo: the real interior under a photographed sunset (the
/// repository's `data/env/sunset`), reported under this name.
pub const RELIGHT_SCENE: &str = "occlusion_room_sunset";

/// The sky change's entries: a fresh bake of the sunset, the sky transfer baked under the
/// demo's white sky ([`RELIGHT_FROM`]) and relit to the sunset, and Unity APV's sky
/// occlusion baked and relit the same way.
pub const RELIGHT_ENTRIES: [&str; 3] = ["doi", "doi+relit", "doi+skyocc"];

/// The sky the relit entries of the sky change are baked under: the real interior's white
/// sky, above and below the horizon.
pub const RELIGHT_FROM: &str = "sky:1,1,1:1,1,1";

/// The scenes of the error-against-memory study.
pub const MEMORY_SWEEP_SCENES: [&str; 2] = ["city", "interior"];

/// The scene of the resolution sweep.
pub const SWEEP_SCENE: &str = "city";

/// The camera of a scene's views (a `--camera` spec): the overview of the grid for the open
/// scenes; in the closed rooms, whose ceilings hide the overview, from a corner under the
/// ceiling (the interior's toward the window and its sun patch; the real interior's, in its
/// file's +Y-up frame, toward the far corner).
#[must_use]
pub fn camera(scene: &str) -> &'static str {
    match scene {
        "interior" => "5.6,0.4,2.4:2.6,4.6,0.6:80",
        REAL_INTERIOR => "4.5,3.5,4.5:-2,0.5,-2:80",
        _ => "overview",
    }
}

/// The resolution sweep of [`SWEEP_SCENE`] as a plot: relative RMSE against grid nodes
/// along x, one line per method.
#[must_use]
pub fn sweep_plot(series: Vec<ResolutionSeries>) -> Plot {
    Plot {
        title: format!("{SWEEP_SCENE}: relative RMSE of irradiance on the plate vs grid resolution"),
        x_label: "grid nodes along x".into(),
        y_label: "relative RMSE".into(),
        series: series
            .into_iter()
            .map(|s| (s.name, s.points.iter().map(|(nx, m)| (f64::from(*nx), m.rel_rmse)).collect()))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::entries::parse_entry;
    use crate::metrics::Metrics;

    /// Every entry the demo names parses, the quick level is lighter than the full one on
    /// every axis, and the memory-sweep and sweep scenes are built in.
    #[test]
    fn the_demo_names_what_exists() {
        for e in BASE_ENTRIES.iter().chain(&EXTRA_ENTRIES).chain(&REAL_ENTRIES) {
            assert!(parse_entry(e).is_ok(), "{e}");
        }
        let (q, f) = (DemoLevel::QUICK, DemoLevel::FULL);
        assert!(q.samples < f.samples && q.plate_res < f.plate_res && q.view_width < f.view_width);
        assert!(q.reference_samples < f.reference_samples && q.view_samples < f.view_samples);
        assert!(q.sweep.len() < f.sweep.len() && q.memory_scales.len() < f.memory_scales.len());
        for s in MEMORY_SWEEP_SCENES.iter().chain([&SWEEP_SCENE]) {
            assert!(lightvol_scene::builtin::BUILTIN_NAMES.contains(s), "{s}");
        }
        assert_eq!(camera("maze"), "overview");
    }

    /// The plot carries each method's line in order, x the node counts.
    #[test]
    fn sweep_plot_draws_one_line_per_method() {
        let m = |e: f64| Metrics { rel_rmse: e, ..Metrics::default() };
        let series = vec![
            ResolutionSeries { name: "point".into(), points: vec![(8, m(0.5)), (16, m(0.25))] },
            ResolutionSeries { name: "doi".into(), points: vec![(8, m(0.2))] },
        ];
        let p = sweep_plot(series);
        assert_eq!(p.series.len(), 2);
        assert_eq!(p.series[0], ("point".to_owned(), vec![(8.0, 0.5), (16.0, 0.25)]));
        assert_eq!(p.series[1].0, "doi");
        assert!(p.title.starts_with("city: "));
    }
}
