//! Rendering a view: the surface each primary ray sees, shaded from a volume's irradiance
//! (Kontkanen & Laine 2006 Eq. 3 at the hit point and normal) or from path-traced
//! irradiance at the same point, turned into the pixel [`Quantity`].

use lightvol_core::samples::Samples;
use std::str::FromStr;

use glam::DVec3;
use lightvol_sh::lowdisc::hash2;
use lightvol_volume::VolumeField;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::error::ViewError;
use lightvol_core::progress::Progress;
use lightvol_scene::bvh::Tracer;
use lightvol_scene::reference::reference_irradiance;
use lightvol_scene::scene::Scene;
use lightvol_scene::transport::Transport;

/// Most pixels an image may have (64 Mpixels).
pub const MAX_PIXELS: u64 = 64 << 20;

/// Stream tag of the path-traced view: pixel `i` draws stream `hash2(REFERENCE_STREAM, i)`.
pub const REFERENCE_STREAM: u64 = 0x7e2d;

/// Pixels path-traced between two progress reports of [`render_reference`] (and of
/// [`par_map_reporting`]'s other callers).
pub const PROGRESS_BLOCK: usize = 4096;

/// What a pixel that sees a surface holds. A pixel that sees no surface holds the
/// environment's radiance along its ray for [`Quantity::Shaded`] and zero otherwise.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Quantity {
    /// Emission + albedo · E / π: the radiance a camera sees from a Lambertian surface.
    #[default]
    Shaded,
    /// Albedo · E / π: the reflected light alone.
    Radiosity,
    /// The irradiance E at the surface point and normal.
    Irradiance,
}

impl Quantity {
    /// The name [`FromStr`] reads.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Shaded => "shaded",
            Self::Radiosity => "radiosity",
            Self::Irradiance => "irradiance",
        }
    }

    /// The pixel value of one channel: emission `emission`, albedo `albedo`, irradiance `e`.
    #[must_use]
    pub fn value(self, emission: f64, albedo: f64, e: f64) -> f64 {
        let reflected = albedo * e / std::f64::consts::PI;
        match self {
            Self::Irradiance => e,
            Self::Radiosity => reflected,
            Self::Shaded => emission + reflected,
        }
    }
}

impl FromStr for Quantity {
    type Err = ViewError;

    fn from_str(s: &str) -> Result<Self, ViewError> {
        [Self::Shaded, Self::Radiosity, Self::Irradiance]
            .into_iter()
            .find(|q| q.name() == s)
            .ok_or_else(|| ViewError::UnknownQuantity(s.to_owned()))
    }
}

/// The image of a view: its size and what its pixels hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewConfig {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// What a pixel holds.
    pub quantity: Quantity,
}

impl ViewConfig {
    /// Checks the size: at least one pixel, at most [`MAX_PIXELS`].
    ///
    /// # Errors
    /// [`ViewError::ImageSize`].
    pub fn validate(&self) -> Result<(), ViewError> {
        let (width, height) = (self.width, self.height);
        if width == 0 || height == 0 || u64::from(width) * u64::from(height) > MAX_PIXELS {
            return Err(ViewError::ImageSize { width, height });
        }
        Ok(())
    }
}

/// A rendered view: linear RGB, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB per pixel.
    pub pixels: Vec<[f32; 3]>,
    /// Per pixel: the primary ray met a surface (`false`: it left the scene).
    pub surface: Vec<bool>,
}

impl ViewImage {
    /// Pixels that see a surface.
    #[must_use]
    pub fn surface_pixels(&self) -> usize {
        self.surface.iter().filter(|&&s| s).count()
    }
}

/// What a primary ray sees: the first surface along it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisibleSurface {
    /// The hit point.
    pub position: DVec3,
    /// The unit shading normal of the side the ray meets: the interpolated vertex normal
    /// where the scene has one ([`Scene::shading_normal`]), else the geometric normal, turned
    /// to the side of the face that faces the ray's origin.
    pub normal: DVec3,
    /// Albedo at the hit (material factor × texture).
    pub albedo: [f64; 3],
    /// Emitted radiance of the material.
    pub emission: [f64; 3],
    /// The unit direction from the hit point back to the eye.
    pub to_eye: DVec3,
}

/// The surface seen from `eye` along the unit direction `dir`, or `None` when the ray
/// leaves the scene.
#[must_use]
pub fn visible_surface(scene: &Scene, tracer: &Tracer, eye: DVec3, dir: DVec3) -> Option<VisibleSurface> {
    let hit = tracer.closest_hit(eye, dir, 0.0, f64::INFINITY)?;
    // Shade the side the camera sees, with the file's vertex normals where it has them
    // (as engines do), turned to the side of the face the camera sees.
    let facing = if hit.normal.dot(dir) > 0.0 { -hit.normal } else { hit.normal };
    let normal = match scene.shading_normal(hit.triangle, hit.bary[0], hit.bary[1]) {
        Some(n) if n.dot(facing) < 0.0 => -n,
        Some(n) => n,
        None => facing,
    };
    Some(VisibleSurface {
        position: eye + dir * hit.t,
        normal,
        albedo: scene.albedo(hit.triangle, hit.bary[0], hit.bary[1]),
        emission: scene.material_of(hit.triangle).emission,
        to_eye: -dir,
    })
}

/// How a path-traced view is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReferenceConfig {
    /// Irradiance samples per pixel ([`reference_irradiance`]).
    pub samples: Samples,
    /// Seed of the pixels' streams.
    pub seed: u64,
}

/// Renders `camera`'s view of `scene` shaded by `field`: at every visible surface the
/// field's irradiance at the hit point and facing normal (as seen from the eye,
/// [`VolumeField::irradiance_seen`]), clamped at zero (a truncated SH
/// expansion can ring below zero), enters `config.quantity`.
///
/// # Errors
/// An invalid `config` (before any ray), a lookup the field refuses.
pub fn render_volume<F: VolumeField + ?Sized>(
    scene: &Scene,
    tracer: &Tracer,
    camera: &Camera,
    config: &ViewConfig,
    field: &F,
) -> Result<ViewImage, ViewError> {
    config.validate()?;
    render(scene, tracer, camera, config, None, |_, s| {
        Ok(field
            .irradiance_seen(s.position.to_array(), s.normal.to_array(), s.to_eye.to_array())?
            .map(|c| c.max(0.0)))
    })
}

/// Renders `camera`'s view shaded by path tracing: at every visible surface
/// [`reference_irradiance`] with `reference.samples` samples, pixel `i` (row-major) on
/// stream `hash2(REFERENCE_STREAM, i)` of `reference.seed`, enters `config.quantity`. The
/// image does not depend on the thread count. `progress`, when given, hears the pixels done
/// from the calling thread.
///
/// # Errors
/// An invalid `config`, before any ray.
pub fn render_reference(
    transport: &Transport<'_>,
    camera: &Camera,
    config: &ViewConfig,
    reference: &ReferenceConfig,
    progress: Option<&(dyn Fn(Progress) + Sync)>,
) -> Result<ViewImage, ViewError> {
    config.validate()?;
    render(transport.scene(), transport.tracer(), camera, config, progress, |i, s| {
        let stream = hash2(REFERENCE_STREAM, i as u64);
        Ok(reference_irradiance(transport, s.position, s.normal, reference.samples, reference.seed, stream).0)
    })
}

/// `f` over `0..n` in parallel, results in order, stopping at an error; with `progress`, in
/// blocks of `PROGRESS_BLOCK` items with a report from the calling thread before the first
/// and after each. Every pixel loop of a view (and of a lightmap's shaded view) runs through
/// it, so that one block size decides how often a long render reports.
///
/// # Errors
/// The first error `f` returns, in index order.
pub fn par_map_reporting<T: Send, E: Send>(
    n: usize,
    progress: Option<&(dyn Fn(Progress) + Sync)>,
    f: impl Fn(usize) -> Result<T, E> + Sync + Send,
) -> Result<Vec<T>, E> {
    let Some(report) = progress else {
        return (0..n).into_par_iter().map(f).collect();
    };
    let mut out = Vec::with_capacity(n);
    report(Progress { done: 0, total: n });
    for start in (0..n).step_by(PROGRESS_BLOCK) {
        let end = (start + PROGRESS_BLOCK).min(n);
        let block: Vec<T> = (start..end).into_par_iter().map(&f).collect::<Result<_, _>>()?;
        out.extend(block);
        report(Progress { done: end, total: n });
    }
    Ok(out)
}

/// The image whose surface pixel `i` (row-major) has irradiance `irradiance(i, surface)`;
/// in blocks of [`PROGRESS_BLOCK`] pixels with a report after each when `progress` is given,
/// else all pixels at once.
fn render(
    scene: &Scene,
    tracer: &Tracer,
    camera: &Camera,
    config: &ViewConfig,
    progress: Option<&(dyn Fn(Progress) + Sync)>,
    irradiance: impl Fn(usize, &VisibleSurface) -> Result<[f64; 3], ViewError> + Sync,
) -> Result<ViewImage, ViewError> {
    let (w, h) = (config.width, config.height);
    let n = w as usize * h as usize;
    let pixel = |i: usize| -> Result<([f32; 3], bool), ViewError> {
        let (x, y) = ((i % w as usize) as u32, (i / w as usize) as u32);
        let d = camera.ray(x, y, w, h);
        let Some(s) = visible_surface(scene, tracer, camera.eye(), d) else {
            // The sky behind the scene is seen, not a surface: only `shaded` shows it.
            let sky = match config.quantity {
                Quantity::Shaded => scene.environment.radiance(d).map(|v| v as f32),
                Quantity::Radiosity | Quantity::Irradiance => [0.0; 3],
            };
            return Ok((sky, false));
        };
        let e = irradiance(i, &s)?;
        Ok((core::array::from_fn(|c| config.quantity.value(s.emission[c], s.albedo[c], e[c]) as f32), true))
    };
    let out = par_map_reporting(n, progress, pixel)?;
    Ok(ViewImage {
        width: w,
        height: h,
        pixels: out.iter().map(|p| p.0).collect(),
        surface: out.iter().map(|p| p.1).collect(),
    })
}
