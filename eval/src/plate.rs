//! The evaluation plate of Kontkanen & Laine 2006 (\[KL06\] Fig. 6): a horizontal lattice of
//! points over the grid's horizontal extent, normal up, where every method's irradiance is
//! compared with a path-traced reference.
//!
//! Each point is
//! - *valid* when it sees no back faces ([`classify_point`] with
//!   [`PlateConfig::classify_dirs`] directions): only valid points enter the metrics, since
//!   a point inside a solid has no meaningful irradiance;
//! - *near* a surface when the nearest hit of [`NEAREST_DIRS`] spherical-Fibonacci rays is
//!   closer than half the grid's largest cell edge: where leaks show (`too_dark_near`).
//!
//! The reference is [`reference_irradiance_many_prefixed`] at every point with normal +Z,
//! with the error its samples' prefixes estimate ([`Plate::reference_noise`]).

use lightvol_core::samples::{Samples, samples};
use std::time::Instant;

use glam::DVec3;
use lightvol_sh::lowdisc::hash2;
use lightvol_volume::{EngineLookup, GridSpec, IrradianceVolume};
use rayon::prelude::*;

use crate::error::EvalError;
use crate::metrics::{Metrics, PlatePoint, compute};
use crate::observer::Observer;
use lightvol_core::progress::Progress;
use lightvol_sampler::domain::classify_point;
use lightvol_scene::envmap::luminance;
use lightvol_scene::reference::reference_irradiance_many_prefixed;
use lightvol_scene::scene::Scene;
use lightvol_scene::transport::Transport;

/// Rays traced per point to find the nearest surface (spherical Fibonacci set).
pub const NEAREST_DIRS: u32 = 128;

/// Stream tag of the plate's back-face classification.
const CLASSIFY_STREAM: u64 = 0xc1a5;
/// Stream tag of the plate's reference paths.
const REFERENCE_STREAM: u64 = 0x7e7e;

/// Where the plate lies and how finely it is measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlateConfig {
    /// Height of the plate (internal +Z, which is the scene file's up axis); inside the
    /// grid's z range.
    pub height: f64,
    /// Points along the plate's longer side (at least 2); the shorter side keeps the
    /// grid's aspect.
    pub res: u32,
    /// Path-traced samples per point for the reference.
    pub reference_samples: Samples,
    /// Directions traced per point to decide whether it sees back faces.
    pub classify_dirs: u32,
}

impl PlateConfig {
    /// Default [`res`](Self::res).
    pub const DEFAULT_RES: u32 = 128;
    /// The most plate points along the longer side: 4096 (16.8 M points, each path-traced
    /// for the reference; about 1 GiB of per-point data with a few methods). Beyond it the
    /// request is refused before anything is allocated.
    pub const MAX_RES: u32 = 4096;
    /// Default [`reference_samples`](Self::reference_samples).
    pub const DEFAULT_REFERENCE_SAMPLES: Samples = samples(512);
    /// Default [`classify_dirs`](Self::classify_dirs).
    pub const DEFAULT_CLASSIFY_DIRS: u32 = 256;

    /// A plate at `height` with the default resolution and sample counts.
    #[must_use]
    pub fn at_height(height: f64) -> Self {
        Self {
            height,
            res: Self::DEFAULT_RES,
            reference_samples: Self::DEFAULT_REFERENCE_SAMPLES,
            classify_dirs: Self::DEFAULT_CLASSIFY_DIRS,
        }
    }

    /// Checks the plate against `grid`: a finite height inside its z range, at least 2
    /// and at most [`Self::MAX_RES`] points along the longer side.
    ///
    /// # Errors
    /// [`EvalError::PlateHeightNotFinite`], [`EvalError::PlateOutsideGrid`],
    /// [`EvalError::PlateResolution`].
    pub fn validate(&self, grid: &GridSpec) -> Result<(), EvalError> {
        let height = self.height;
        if !height.is_finite() {
            return Err(EvalError::PlateHeightNotFinite(height));
        }
        let (min, max) = grid.bounds();
        if !(min[2]..=max[2]).contains(&height) {
            return Err(EvalError::PlateOutsideGrid { height, min: min[2], max: max[2] });
        }
        if !(2..=Self::MAX_RES).contains(&self.res) {
            return Err(EvalError::PlateResolution { res: self.res, max: Self::MAX_RES });
        }
        Ok(())
    }
}

/// The default plate height: the first of `recommended` (a built-in scene's
/// `plate_heights`), else 10% of the scene's height above its lowest point.
#[must_use]
pub fn default_plate_height(scene: &Scene, recommended: &[f64]) -> f64 {
    if let Some(&h) = recommended.first() {
        return h;
    }
    let (lo, hi) = scene.bounds();
    lo.z + 0.1 * (hi.z - lo.z)
}

/// Everything measured on the plate once, before any method is baked.
#[derive(Clone, Debug)]
pub struct Plate {
    /// Points along x and y.
    pub res: [usize; 2],
    /// Plate height.
    pub height: f64,
    /// World positions, row-major (row 0 at min y, x fastest), at texel centres (no point
    /// lies on the grid's boundary).
    pub points: Vec<DVec3>,
    /// Sees no back faces.
    pub valid: Vec<bool>,
    /// Nearest surface closer than half the largest cell edge.
    pub near: Vec<bool>,
    /// Reference irradiance (RGB, normal +Z).
    pub truth: Vec<[f64; 3]>,
    /// The estimated luminance error of each point's reference (`None` below four samples;
    /// [`reference_irradiance_many_prefixed`]).
    pub truth_error: Vec<Option<f64>>,
    /// Wall time of the reference, in seconds.
    pub reference_seconds: f64,
}

impl Plate {
    /// Lays the plate over `grid`'s horizontal extent, classifies its points, finds their
    /// nearest surfaces and path-traces the reference with `transport` (stage `reference`
    /// of `observer`). Random streams derive from `seed`; the result does not depend on
    /// the thread count.
    ///
    /// # Errors
    /// An invalid `config` ([`PlateConfig::validate`]).
    pub fn build(
        transport: &Transport<'_>,
        grid: &GridSpec,
        config: &PlateConfig,
        seed: u64,
        observer: &dyn Observer,
    ) -> Result<Self, EvalError> {
        config.validate(grid)?;
        let tracer = transport.tracer();
        let (min, max) = grid.bounds();
        let (ex, ey) = (max[0] - min[0], max[1] - min[1]);
        let long = f64::from(config.res);
        let res = if ex >= ey {
            [config.res as usize, ((long * ey / ex).round() as usize).max(2)]
        } else {
            [((long * ex / ey).round() as usize).max(2), config.res as usize]
        };
        let height = config.height;
        let points: Vec<DVec3> = (0..res[1])
            .flat_map(|j| (0..res[0]).map(move |i| (i, j)))
            .map(|(i, j)| {
                DVec3::new(
                    min[0] + ex * (i as f64 + 0.5) / res[0] as f64,
                    min[1] + ey * (j as f64 + 0.5) / res[1] as f64,
                    height,
                )
            })
            .collect();
        let half_cell = 0.5 * grid.cell_size().iter().fold(0.0f64, |a, &b| a.max(b));
        let classes: Vec<(bool, bool)> = points
            .par_iter()
            .enumerate()
            .map(|(i, &x)| {
                let valid =
                    classify_point(tracer, x, config.classify_dirs, hash2(seed ^ CLASSIFY_STREAM, i as u64))
                        .inside;
                let nearest = lightvol_sh::sampling::fibonacci_sphere(NEAREST_DIRS as usize)
                    .filter_map(|d| {
                        tracer.closest_hit(x, DVec3::from_array(d), 0.0, f64::INFINITY).map(|h| h.t)
                    })
                    .fold(f64::INFINITY, f64::min);
                (valid, nearest < half_cell)
            })
            .collect();
        let t0 = Instant::now();
        observer.stage_started("reference");
        observer.progress(Progress { done: 0, total: 1 });
        let pts: Vec<(DVec3, DVec3)> = points.iter().map(|&p| (p, DVec3::Z)).collect();
        let (truth, truth_error) = reference_irradiance_many_prefixed(
            transport,
            &pts,
            config.reference_samples,
            seed ^ REFERENCE_STREAM,
        )
        .into_iter()
        .map(|e| (e.mean, e.error_of(luminance)))
        .unzip();
        observer.stage_finished();
        Ok(Self {
            res,
            height,
            points,
            valid: classes.iter().map(|c| c.0).collect(),
            near: classes.iter().map(|c| c.1).collect(),
            truth,
            truth_error,
            reference_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// Points that see no back faces.
    #[must_use]
    pub fn valid_points(&self) -> usize {
        self.valid.iter().filter(|&&v| v).count()
    }

    /// Valid points near a surface.
    #[must_use]
    pub fn near_points(&self) -> usize {
        (0..self.points.len()).filter(|&i| self.valid[i] && self.near[i]).count()
    }

    /// Mean reference luminance over the valid points; `None` when no point is valid.
    #[must_use]
    pub fn mean_truth(&self) -> Option<f64> {
        let valid_truth: Vec<f64> =
            (0..self.points.len()).filter(|&i| self.valid[i]).map(|i| luminance(self.truth[i])).collect();
        if valid_truth.is_empty() {
            return None;
        }
        Some(valid_truth.iter().sum::<f64>() / valid_truth.len() as f64)
    }

    /// The reference's own noise in the units of the relative RMSE: the root mean square of
    /// the valid points' estimated reference errors over their mean reference luminance.
    /// A method's relative RMSE against the reference holds this noise too (independent of
    /// the method's error, they add in quadrature), so it is the floor no method goes
    /// below, and it draws every method's ratio to another toward 1. The prefix estimate
    /// errs high (1.3 times the actual noise in `the_reference_noise_is_calibrated`).
    /// `None` when no point is valid or the reference has fewer than four samples.
    #[must_use]
    pub fn reference_noise(&self) -> Option<f64> {
        let errors: Vec<f64> = (0..self.points.len())
            .filter(|&i| self.valid[i])
            .map(|i| self.truth_error[i])
            .collect::<Option<_>>()?;
        lightvol_core::metric::rel_rmse_of_errors(&errors, self.mean_truth()?)
    }

    /// Irradiance (normal up) of a uniform volume at every point, by its trilinear f32
    /// lookup (\[KL06\] Eq. 2-3).
    #[must_use]
    pub fn evaluate(&self, vol: &IrradianceVolume) -> Vec<[f64; 3]> {
        self.points
            .par_iter()
            .map(|p| vol.irradiance(p.as_vec3().to_array(), [0.0, 0.0, 1.0]).map(f64::from))
            .collect()
    }

    /// Irradiance (normal up, viewed from above) of a uniform volume at every point,
    /// through `lookup`'s engine rule
    /// ([`IrradianceVolume::engine_irradiance`], f64).
    #[must_use]
    pub fn engine_estimate(&self, vol: &IrradianceVolume, lookup: EngineLookup) -> Vec<[f64; 3]> {
        let up = [0.0, 0.0, 1.0];
        self.points.par_iter().map(|p| vol.engine_irradiance(lookup, p.to_array(), up, up)).collect()
    }

    /// The metrics ([`compute`]) of `estimate` (one RGB irradiance per point, in point
    /// order) against the reference, by luminance.
    ///
    /// # Panics
    /// If `estimate` has fewer entries than the plate has points.
    #[must_use]
    pub fn metrics(&self, estimate: &[[f64; 3]]) -> Metrics {
        let pts: Vec<PlatePoint> = (0..self.points.len())
            .map(|i| PlatePoint {
                estimate: luminance(estimate[i]),
                truth: luminance(self.truth[i]),
                valid: self.valid[i],
                near: self.near[i],
            })
            .collect();
        compute(&pts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observer::Silent;
    use lightvol_scene::{Tracer, TransportSettings, builtin};

    /// A hand-made plate: 4 points, one invalid; the metrics of a hand-made estimate equal
    /// the values computed by hand from \[KL06\] Fig. 6's definitions (module
    /// `metrics`), through the luminance of RGB estimates.
    #[test]
    fn metrics_of_a_hand_made_estimate() {
        let grey = |v: f64| [v; 3];
        let plate = Plate {
            res: [2, 2],
            height: 1.0,
            points: vec![DVec3::ZERO; 4],
            valid: vec![true, true, true, false],
            near: vec![false, true, true, true],
            truth: vec![grey(2.0), grey(2.0), grey(4.0), grey(1.0)],
            truth_error: vec![Some(0.2), Some(0.2), Some(0.4), Some(9.0)],
            reference_seconds: 0.0,
        };
        // Errors on the valid points: 0, -1 (too dark, near), +0.5 (within 1.25 T).
        let m = plate.metrics(&[grey(2.0), grey(1.0), grey(4.5), grey(100.0)]);
        let mean_t = 8.0 / 3.0;
        assert!((m.rel_rmse - (1.25f64 / 3.0).sqrt() / mean_t).abs() < 1e-12, "{m:?}");
        assert!((m.bias - (-0.5 / 3.0) / mean_t).abs() < 1e-12);
        assert!((m.too_dark - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(m.too_dark_near, 0.5);
        assert_eq!(m.too_bright, 0.0);
        assert_eq!((m.valid_points, m.near_points), (3, 2));
        assert_eq!((plate.valid_points(), plate.near_points()), (3, 2));
        assert!((plate.mean_truth().unwrap() - mean_t).abs() < 1e-12);
        // The invalid point's error is left out: sqrt((0.04 + 0.04 + 0.16) / 3) / (8/3).
        let noise = plate.reference_noise().unwrap();
        assert!((noise - 0.08f64.sqrt() / mean_t).abs() < 1e-12, "{noise}");
        let unknown = Plate { truth_error: vec![None; 4], ..plate };
        assert_eq!(unknown.reference_noise(), None);
    }

    /// The reference's estimated noise is what it is: on the interior's plate (dark, lit
    /// through windows, so its reference is noisy), the noise a 64-sample reference reports
    /// is within a factor of 2 of its actual relative RMS difference from a 2,048-sample
    /// reference (whose own noise adds about 3% of it), and the 2,048-sample reference
    /// reports about `√32` times less.
    #[test]
    fn the_reference_noise_is_calibrated() {
        let b = builtin::interior();
        let tracer = Tracer::new(&b.scene);
        let t = Transport::new(&b.scene, &tracer, TransportSettings::default());
        let config = PlateConfig { height: 0.6, res: 24, reference_samples: samples(64), classify_dirs: 32 };
        let rough = Plate::build(&t, &b.grid, &config, 3, &Silent).unwrap();
        let fine = Plate::build(
            &t,
            &b.grid,
            &PlateConfig { reference_samples: samples(2048), ..config },
            3,
            &Silent,
        )
        .unwrap();
        let valid: Vec<usize> = (0..rough.points.len()).filter(|&i| rough.valid[i]).collect();
        assert!(valid.len() > 100, "{} valid points", valid.len());
        let actual = lightvol_core::metric::rel_rmse(
            valid.iter().map(|&i| (luminance(rough.truth[i]), luminance(fine.truth[i]))),
        );
        let (estimated, fine_noise) = (rough.reference_noise().unwrap(), fine.reference_noise().unwrap());
        eprintln!("reference noise: estimated {estimated:.4}, actual {actual:.4}; at 2048: {fine_noise:.4}");
        assert!(actual > 0.01, "a noisy reference: {actual}");
        assert!(estimated > 0.5 * actual && estimated < 2.0 * actual, "{estimated} against {actual}");
        assert!(fine_noise < 0.5 * estimated, "{fine_noise} against {estimated}");
    }

    /// The plate covers the grid's horizontal extent with the grid's aspect, at texel
    /// centres; invalid settings are refused before anything is traced.
    #[test]
    fn layout_and_validation() {
        let maze = builtin::maze();
        let tracer = Tracer::new(&maze.scene);
        let t = Transport::new(&maze.scene, &tracer, TransportSettings::truncated(0));
        // The maze's recommended grid, x and y halved: 20 m by 10 m.
        let grid = GridSpec::new([-10.0, -5.0, -0.5], [10.0, 5.0, 3.5], [11, 6, 3]).unwrap();
        // 0.4 m between points: some land inside the 0.4 m thick walls on the 3 m pitch.
        let config = PlateConfig { height: 1.0, res: 50, reference_samples: samples(2), classify_dirs: 64 };
        let p = Plate::build(&t, &grid, &config, 1, &Silent).unwrap();
        assert_eq!(p.res, [50, 25]);
        let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-12;
        assert!(close(p.points[0], DVec3::new(-10.0 + 0.2, -5.0 + 0.2, 1.0)), "{}", p.points[0]);
        assert!(close(p.points[1249], DVec3::new(10.0 - 0.2, 5.0 - 0.2, 1.0)), "{}", p.points[1249]);
        let valid = p.valid_points();
        assert!(valid > 0 && valid < 1250, "the maze walls cut the plate: {valid} valid");
        assert!(p.near_points() > 0 && p.near_points() <= valid);
        let bad = |c: PlateConfig| Plate::build(&t, &grid, &c, 1, &Silent).unwrap_err();
        assert!(matches!(bad(PlateConfig { height: 9.0, ..config }), EvalError::PlateOutsideGrid { .. }));
        assert!(matches!(
            bad(PlateConfig { height: f64::NAN, ..config }),
            EvalError::PlateHeightNotFinite(_)
        ));
        assert!(matches!(bad(PlateConfig { res: 1, ..config }), EvalError::PlateResolution { res: 1, .. }));
        let huge = PlateConfig::MAX_RES + 1;
        assert!(
            matches!(bad(PlateConfig { res: huge, ..config }), EvalError::PlateResolution { res, max } if res == huge && max == PlateConfig::MAX_RES)
        );
    }

    #[test]
    fn default_height() {
        let maze = builtin::maze();
        assert_eq!(default_plate_height(&maze.scene, &[1.5, 2.0]), 1.5);
        let (lo, hi) = maze.scene.bounds();
        assert_eq!(default_plate_height(&maze.scene, &[]), lo.z + 0.1 * (hi.z - lo.z));
    }
}
