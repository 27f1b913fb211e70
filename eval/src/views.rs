//! The comparison seen through cameras: for each camera a path-traced view and one view per
//! compared entry, the scene shaded by that entry's volume ([`lightvol_view`], quantity
//! [`Quantity::Shaded`]: emission + albedo · E / π at the surface a pixel sees), and the
//! metrics of each entry's view against the path-traced one.
//!
//! **Metrics.** The plate metrics of [`crate::metrics`] (\[KL06\] Fig. 6), with the
//! pixels as points: `E` is the luminance of the entry's pixel, `T` that of the path-traced
//! pixel, so `rel_rmse = sqrt(mean((E - T)²)) / mean(T)` over the *measured* pixels: those
//! whose primary ray meets a surface inside the compared grid's box. A pixel that sees the
//! sky shows the environment in every view alike, and counting it would only dilute the
//! error with exact zeros; a surface outside the grid is lit by the volume's clamped
//! boundary, which the grid never sampled (the plate, too, lies inside the grid). Surfaces
//! seen from behind and emitters count like any other surface (they are what a person sees;
//! an emitter adds the same emission to both pixels). There is no near-surface split on a
//! view (`too_dark_near` is 0 with `near_points` 0). The images show every pixel.
//!
//! **Streams.** The path-traced view samples pixel `i` on stream
//! `hash2(REFERENCE_STREAM, i)` of the comparison's seed ([`lightvol_view::render_reference`]), so it is
//! the image `lightvol render --reference` makes for the same camera, seed, samples and
//! light paths, and it does not depend on the thread count.

use lightvol_core::samples::{Samples, samples};
use std::collections::BTreeSet;
use std::time::Instant;

use glam::DVec3;
use lightvol_volume::GridSpec;
use lightvol_volume::engine_lookup::{EngineField, EngineLookup};
use rayon::prelude::*;

use crate::error::EvalError;
use crate::metrics::{Metrics, PlatePoint, compute};
use crate::observer::Observer;
use crate::runs::MethodRun;
use lightvol_scene::envmap::luminance;
use lightvol_scene::transport::Transport;
use lightvol_view::{
    Camera, Quantity, ReferenceConfig, ViewConfig, ViewImage, render_reference_with_noise, render_volume,
    visible_surface,
};

/// One camera of a comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewCamera {
    /// The view's name in reports and file names (unique in a comparison).
    pub label: String,
    /// The camera.
    pub camera: Camera,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl ViewCamera {
    /// The image of this camera's views.
    #[must_use]
    pub fn view_config(&self) -> ViewConfig {
        ViewConfig { width: self.width, height: self.height, quantity: Quantity::Shaded }
    }
}

/// The views of a comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewsConfig {
    /// The cameras, in the order they are rendered and reported (none: no views).
    pub cameras: Vec<ViewCamera>,
    /// Path-traced irradiance samples per pixel of the reference views.
    pub reference_samples: Samples,
    /// Engines whose reading of the [`ENGINE_VIEW_ENTRY`] entry's volume is also drawn in
    /// every view, as `doi@ENGINE` ([`EngineLookup`]: what that engine shows of the same
    /// file); none by default, and nothing when the entry is absent or not a uniform grid.
    pub engine_views: Vec<EngineLookup>,
}

/// The entry whose volume the engine views read: lightvol's default method.
pub const ENGINE_VIEW_ENTRY: &str = "doi";

/// The name of `lookup`'s view of `entry`'s volume: `entry@engine`.
#[must_use]
pub fn engine_view_name(entry: &str, lookup: EngineLookup) -> String {
    format!("{entry}@{}", lookup.name())
}

impl ViewsConfig {
    /// Default width of a view.
    pub const DEFAULT_WIDTH: u32 = 192;
    /// Default height of a view (without a file camera's aspect ratio).
    pub const DEFAULT_HEIGHT: u32 = 128;
    /// Default [`reference_samples`](Self::reference_samples).
    pub const DEFAULT_REFERENCE_SAMPLES: Samples = samples(64);

    /// Checks the cameras: non-empty unique labels, valid image sizes, and (with a camera)
    /// at least one reference sample.
    ///
    /// # Errors
    /// [`EvalError::ViewLabel`], [`EvalError::DuplicateView`], [`EvalError::View`].
    pub fn validate(&self) -> Result<(), EvalError> {
        let mut seen = BTreeSet::new();
        for c in &self.cameras {
            if c.label.is_empty() {
                return Err(EvalError::ViewLabel);
            }
            if !seen.insert(c.label.as_str()) {
                return Err(EvalError::DuplicateView(c.label.clone()));
            }
            c.view_config().validate()?;
        }
        Ok(())
    }
}

impl Default for ViewsConfig {
    /// No camera, [`DEFAULT_REFERENCE_SAMPLES`](Self::DEFAULT_REFERENCE_SAMPLES).
    fn default() -> Self {
        Self {
            cameras: Vec::new(),
            reference_samples: Self::DEFAULT_REFERENCE_SAMPLES,
            engine_views: Vec::new(),
        }
    }
}

/// One entry's view of one camera.
#[derive(Clone, Debug)]
pub struct MethodView {
    /// The entry's name.
    pub name: String,
    /// The view shaded by the entry's volume.
    pub image: ViewImage,
    /// Its metrics against the path-traced view (module docs).
    pub metrics: Metrics,
}

/// One camera's views.
#[derive(Clone, Debug)]
pub struct ComparedView {
    /// The camera's label.
    pub label: String,
    /// The path-traced view.
    pub reference: ViewImage,
    /// Per pixel: measured (it sees a surface inside the grid, module docs).
    pub measured: Vec<bool>,
    /// Wall time of the path-traced view, in seconds.
    pub reference_seconds: f64,
    /// Mean luminance of the path-traced view over the measured pixels.
    pub mean_reference: f64,
    /// The path-traced view's own noise in relative-RMSE units: the root mean square of
    /// the measured pixels' estimated errors
    /// ([`lightvol_view::render_reference_with_noise`]) over `mean_reference`, the part of
    /// every method's view error that is the reference's. `None` below four samples.
    pub reference_noise: Option<f64>,
    /// Every entry's view, in the comparison's order.
    pub methods: Vec<MethodView>,
}

/// Relative slack of the grid's box when deciding whether a surface is inside it: a
/// surface on the box's face (a floor at the grid's lowest z) has hit points that scatter
/// around the face by the f32 intersection test's rounding (~1e-7 of the distance), so the
/// box is widened by this share of its largest extent, well above that and far below a
/// cell.
pub const GRID_BOX_SLACK: f64 = 1e-6;

/// The metrics (module docs) of `image` against `reference`, two views of one camera, over
/// the pixels where `measured` holds.
///
/// # Panics
/// If the images or the mask differ in size.
#[must_use]
pub fn view_metrics(image: &ViewImage, reference: &ViewImage, measured: &[bool]) -> Metrics {
    assert_eq!((image.width, image.height), (reference.width, reference.height), "views of one camera");
    assert_eq!(measured.len(), reference.pixels.len(), "one flag per pixel");
    let points: Vec<PlatePoint> = (0..reference.pixels.len())
        .map(|i| PlatePoint {
            estimate: luminance(image.pixels[i].map(f64::from)),
            truth: luminance(reference.pixels[i].map(f64::from)),
            valid: measured[i],
            near: false,
        })
        .collect();
    compute(&points)
}

/// Per pixel of `camera`'s view: its primary ray meets a surface inside `grid`'s box
/// (widened by [`GRID_BOX_SLACK`]).
#[must_use]
pub fn measured_pixels(transport: &Transport<'_>, grid: &GridSpec, camera: &ViewCamera) -> Vec<bool> {
    let (lo, hi) = grid.bounds();
    let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
    let slack = GRID_BOX_SLACK * (hi - lo).max_element();
    let (w, h) = (camera.width, camera.height);
    (0..w as usize * h as usize)
        .into_par_iter()
        .map(|i| {
            let d = camera.camera.ray((i % w as usize) as u32, (i / w as usize) as u32, w, h);
            visible_surface(transport.scene(), transport.tracer(), camera.camera.eye(), d)
                .is_some_and(|s| s.position.cmpge(lo - slack).all() && s.position.cmple(hi + slack).all())
        })
        .collect()
}

/// Refuses a camera none of whose pixels is measured (its metrics would be empty), by
/// tracing its primary rays only.
///
/// # Errors
/// [`EvalError::ViewSeesNothing`].
pub fn check_cameras(
    transport: &Transport<'_>,
    grid: &GridSpec,
    views: &ViewsConfig,
) -> Result<(), EvalError> {
    for c in &views.cameras {
        if !measured_pixels(transport, grid, c).contains(&true) {
            return Err(EvalError::ViewSeesNothing(c.label.clone()));
        }
    }
    Ok(())
}

/// Renders every camera's path-traced view (stage `view LABEL` of `observer`, on `seed`'s
/// streams) and every run's view shaded by its volume, and measures each against the
/// path-traced one over the pixels that see a surface inside `grid` (module docs).
///
/// # Errors
/// An invalid `views` ([`ViewsConfig::validate`]), a path-traced view that is black where
/// it is measured ([`EvalError::BlackView`]), a lookup a volume refuses.
pub fn compare_views(
    transport: &Transport<'_>,
    grid: &GridSpec,
    views: &ViewsConfig,
    runs: &[MethodRun],
    seed: u64,
    observer: &dyn Observer,
) -> Result<Vec<ComparedView>, EvalError> {
    views.validate()?;
    let reference_config = ReferenceConfig { samples: views.reference_samples, seed };
    let mut out = Vec::with_capacity(views.cameras.len());
    for c in &views.cameras {
        let config = c.view_config();
        let t0 = Instant::now();
        observer.stage_started(&format!("view {}", c.label));
        let report = |p| observer.progress(p);
        let reference =
            render_reference_with_noise(transport, &c.camera, &config, &reference_config, Some(&report));
        observer.stage_finished();
        let (reference, pixel_errors) = reference?;
        let reference_seconds = t0.elapsed().as_secs_f64();
        let measured = measured_pixels(transport, grid, c);
        let lum: Vec<f64> = (0..reference.pixels.len())
            .filter(|&i| measured[i])
            .map(|i| luminance(reference.pixels[i].map(f64::from)))
            .collect();
        let mean_reference = lum.iter().sum::<f64>() / lum.len().max(1) as f64;
        if !(mean_reference > 0.0) {
            return Err(EvalError::BlackView(c.label.clone()));
        }
        let errors: Option<Vec<f64>> =
            (0..pixel_errors.len()).filter(|&i| measured[i]).map(|i| pixel_errors[i]).collect();
        let reference_noise =
            errors.and_then(|e| lightvol_core::metric::rel_rmse_of_errors(&e, mean_reference));
        let mut methods = runs
            .iter()
            .map(|run| {
                let image =
                    render_volume(transport.scene(), transport.tracer(), &c.camera, &config, &run.volume)?;
                let metrics = view_metrics(&image, &reference, &measured);
                Ok(MethodView { name: run.name.clone(), image, metrics })
            })
            .collect::<Result<Vec<_>, EvalError>>()?;
        let engine_source =
            runs.iter().find(|r| r.name == ENGINE_VIEW_ENTRY).and_then(|r| r.volume.uniform());
        if let Some(volume) = engine_source {
            for &lookup in &views.engine_views {
                let field = EngineField { volume, lookup };
                let image = render_volume(transport.scene(), transport.tracer(), &c.camera, &config, &field)?;
                let metrics = view_metrics(&image, &reference, &measured);
                methods.push(MethodView {
                    name: engine_view_name(ENGINE_VIEW_ENTRY, lookup),
                    image,
                    metrics,
                });
            }
        }
        out.push(ComparedView {
            label: c.label.clone(),
            reference,
            measured,
            reference_seconds,
            mean_reference,
            reference_noise,
            methods,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::compare::{CompareConfig, compare};
    use crate::entries::NamedEntry;
    use crate::observer::Silent;
    use lightvol_scene::Tracer;
    use lightvol_scene::builtin;
    use lightvol_view::ViewError;
    use lightvol_volume::VolumeField;

    fn image(pixels: &[f32], surface: &[bool]) -> ViewImage {
        ViewImage {
            width: pixels.len() as u32,
            height: 1,
            pixels: pixels.iter().map(|&v| [v; 3]).collect(),
            surface: surface.to_vec(),
        }
    }

    /// The view metrics are the plate's (\[KL06\] Fig. 6) over the measured pixels: a
    /// pixel left out counts in neither the error nor the mean.
    #[test]
    fn metrics_leave_the_sky_out() {
        let surface = [true, true, true, false];
        let reference = image(&[2.0, 2.0, 4.0, 1.0], &surface);
        let m = view_metrics(&image(&[2.0, 1.0, 4.5, 100.0], &surface), &reference, &surface);
        let mean_t = 8.0 / 3.0;
        assert!((m.rel_rmse - (1.25f64 / 3.0).sqrt() / mean_t).abs() < 1e-12, "{m:?}");
        assert!((m.bias - (-0.5 / 3.0) / mean_t).abs() < 1e-12);
        assert!((m.too_dark - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!((m.too_bright, m.too_dark_near, m.valid_points, m.near_points), (0.0, 0.0, 3, 0));
        assert_eq!(view_metrics(&reference, &reference, &surface).rel_rmse, 0.0);
    }

    /// The maze at reduced settings through its overview camera.
    fn maze_with_view(methods: &[&str]) -> (builtin::BuiltinScene, CompareConfig) {
        let (maze, mut c) = crate::compare::tests::maze_config();
        c.methods = methods.iter().map(|s| NamedEntry::parse(s).unwrap()).collect();
        let (lo, hi) = maze.grid.bounds();
        let camera = Camera::overview(DVec3::from(lo), DVec3::from(hi)).unwrap();
        c.views = ViewsConfig {
            cameras: vec![ViewCamera { label: "over".into(), camera, width: 32, height: 20 }],
            reference_samples: samples(4),
            engine_views: vec![EngineLookup::Three, EngineLookup::Bevy],
        };
        (maze, c)
    }

    /// Every entry kind is seen through the camera: each run's volume, read through its
    /// entry's lookup, gives the plate's estimate at the plate points; each entry's view is
    /// the scene shaded by that volume, the reference view is the path-traced view of the
    /// same camera on the comparison's seed, each metric is that view's against it, and
    /// nothing depends on the thread count.
    #[test]
    fn views_of_every_entry_kind() {
        let (maze, config) =
            maze_with_view(&["point", "doi", "doi-paper+hermite", "adaptive1", "point+apv", "point+vlm"]);
        let r = compare(&maze.scene, &config, &Silent).unwrap();
        for run in &r.methods {
            for (p, e) in r.plate.points.iter().zip(&run.estimate) {
                assert_eq!(run.volume.irradiance(p.to_array(), [0.0, 0.0, 1.0]).unwrap(), *e, "{}", run.name);
            }
        }
        assert_eq!(r.views.len(), 1);
        let v = &r.views[0];
        assert_eq!(v.label, "over");
        let names: Vec<&str> = v.methods.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "point",
                "doi",
                "doi-paper+hermite",
                "adaptive1",
                "point+apv",
                "point+vlm",
                "doi@three",
                "doi@bevy"
            ]
        );
        let tracer = Tracer::new(&maze.scene);
        let transport = Transport::new(&maze.scene, &tracer, config.transport);
        let cam = &config.views.cameras[0];
        let reference = ReferenceConfig { samples: samples(4), seed: config.seed };
        assert_eq!(
            lightvol_view::render_reference(&transport, &cam.camera, &cam.view_config(), &reference, None)
                .unwrap(),
            v.reference
        );
        let surface = v.reference.surface_pixels();
        assert!(surface > 0 && surface < 32 * 20, "the overview sees the maze and the sky: {surface}");
        // The overview of the grid sees ground outside it, which is not measured.
        let measured = v.measured.iter().filter(|&&m| m).count();
        assert!(measured > 0 && measured < surface, "{measured} of {surface}");
        assert_eq!(v.measured, measured_pixels(&transport, &config.grid, cam));
        for i in 0..v.measured.len() {
            assert!(!v.measured[i] || v.reference.surface[i]);
        }
        for (m, run) in v.methods.iter().zip(&r.methods) {
            let image =
                render_volume(&maze.scene, &tracer, &cam.camera, &cam.view_config(), &run.volume).unwrap();
            assert_eq!(image, m.image, "{}", m.name);
            assert_eq!(m.metrics, view_metrics(&m.image, &v.reference, &v.measured));
            assert_eq!(m.metrics.valid_points, measured);
            assert!(
                m.metrics.rel_rmse > 0.0 && m.metrics.rel_rmse.is_finite(),
                "{}: {:?}",
                m.name,
                m.metrics
            );
        }
        // The engines' views of doi's volume: the scene shaded through their lookups.
        let doi = r.methods.iter().find(|m| m.name == "doi").unwrap().volume.uniform().unwrap();
        for (m, lookup) in v.methods[r.methods.len()..].iter().zip([EngineLookup::Three, EngineLookup::Bevy])
        {
            let field = EngineField { volume: doi, lookup };
            let image = render_volume(&maze.scene, &tracer, &cam.camera, &cam.view_config(), &field).unwrap();
            assert_eq!(image, m.image, "{}", m.name);
            assert_eq!(m.metrics, view_metrics(&m.image, &v.reference, &v.measured));
            assert_ne!(m.image, v.methods[1].image, "{} reads doi's volume its own way", m.name);
        }
        let one = compare(&maze.scene, &CompareConfig { threads: Some(1), ..config }, &Silent).unwrap();
        assert_eq!(one.views[0].reference, v.reference);
        for (a, b) in one.views[0].methods.iter().zip(&v.methods) {
            assert_eq!((&a.image, a.metrics), (&b.image, b.metrics), "{}", a.name);
        }
    }

    /// Invalid views are refused before anything is traced; a camera that sees only sky is
    /// refused before the plate.
    #[test]
    fn invalid_views_are_refused() {
        let (maze, config) = maze_with_view(&["point"]);
        let check = |f: &dyn Fn(&mut ViewsConfig)| {
            let mut c = config.clone();
            f(&mut c.views);
            c.validate().unwrap_err()
        };
        assert!(matches!(check(&|v| v.cameras[0].width = 0), EvalError::View(ViewError::ImageSize { .. })));
        assert!(matches!(check(&|v| v.cameras[0].label.clear()), EvalError::ViewLabel));
        let e = check(&|v| v.cameras.push(v.cameras[0].clone()));
        assert!(matches!(e, EvalError::DuplicateView(ref l) if l == "over"));
        // No camera: nothing to check.
        let mut none = config.clone();
        none.views =
            ViewsConfig { cameras: Vec::new(), reference_samples: samples(1), engine_views: Vec::new() };
        assert!(none.validate().is_ok());
        let mut sky = config.clone();
        let up = Camera::look_at(DVec3::new(0.0, 0.0, 50.0), DVec3::new(0.0, 1.0, 100.0), 30.0).unwrap();
        sky.views.cameras[0].camera = up;
        let e = compare(&maze.scene, &sky, &Silent).unwrap_err();
        assert!(matches!(e, EvalError::ViewSeesNothing(ref l) if l == "over"), "{e}");
        // Under a black sky with no sun every view is black: no relative error.
        let mut dark = maze.scene.clone();
        dark.environment = lightvol_scene::lights::Environment::Black;
        dark.sun = None;
        dark.punctual.clear();
        let e = compare(&dark, &config, &Silent).unwrap_err();
        assert!(matches!(e, EvalError::BlackView(ref l) if l == "over"), "{e}");
    }
}
