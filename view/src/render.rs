//! Rendering a view: the surface each primary ray sees, shaded from a volume's irradiance
//! (Kontkanen & Laine 2006 Eq. 3 at the hit point and normal) or from path-traced
//! irradiance at the same point, turned into the pixel [`Quantity`].

use lightvol_core::samples::Samples;
use std::str::FromStr;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use lightvol_sh::lowdisc::hash2;
use lightvol_volume::VolumeField;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::error::ViewError;
use lightvol_core::progress::Progress;
use lightvol_scene::bvh::Tracer;
use lightvol_scene::envmap::luminance;
use lightvol_scene::reference::reference_irradiance_prefixed;
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
    /// Irradiance samples per pixel ([`reference_irradiance`](lightvol_scene::reference::reference_irradiance)).
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
/// [`reference_irradiance`](lightvol_scene::reference::reference_irradiance) with `reference.samples` samples, pixel `i` (row-major) on
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
    Ok(render_reference_with_noise(transport, camera, config, reference, progress)?.0)
}

/// [`render_reference`] (the same image) with each pixel's estimated error: the error of
/// the luminance of its value that the means of the first half and the first quarter of
/// its samples say it has ([`lightvol_scene::reference::PrefixedEstimate::error_of`]); `None` where the pixel sees
/// no surface or the reference has fewer than four samples.
///
/// # Errors
/// An invalid `config`, before any ray.
pub fn render_reference_with_noise(
    transport: &Transport<'_>,
    camera: &Camera,
    config: &ViewConfig,
    reference: &ReferenceConfig,
    progress: Option<&(dyn Fn(Progress) + Sync)>,
) -> Result<(ViewImage, Vec<Option<f64>>), ViewError> {
    config.validate()?;
    let n = config.width as usize * config.height as usize;
    // f64 bits per pixel; NaN: no estimate. Each pixel writes its own slot once.
    let errors: Vec<AtomicU64> = (0..n).map(|_| AtomicU64::new(f64::NAN.to_bits())).collect();
    let image = render(transport.scene(), transport.tracer(), camera, config, progress, |i, s| {
        let stream = hash2(REFERENCE_STREAM, i as u64);
        let (e, _) = reference_irradiance_prefixed(
            transport,
            s.position,
            s.normal,
            reference.samples,
            reference.seed,
            stream,
        );
        let value = |e: [f64; 3]| {
            luminance(std::array::from_fn(|c| config.quantity.value(s.emission[c], s.albedo[c], e[c])))
        };
        if let Some(err) = e.error_of(value) {
            errors[i].store(err.to_bits(), Ordering::Relaxed);
        }
        Ok(e.mean)
    })?;
    let errors =
        errors.into_iter().map(|b| Some(f64::from_bits(b.into_inner())).filter(|e| !e.is_nan())).collect();
    Ok((image, errors))
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

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_core::metric::rel_rmse;
    use lightvol_core::samples::samples;
    use lightvol_scene::builtin;
    use lightvol_scene::transport::TransportSettings;

    /// A path-traced view's estimated noise is what it is: inside the interior (lit through
    /// its windows, so its view is noisy), the noise a 32-sample view reports over its
    /// surface pixels is within a factor of 2 of its actual relative RMS difference from a
    /// 1,024-sample view of the same camera (whose own noise adds a few percent of it);
    /// the image itself is `render_reference`'s, and the sky has no estimate.
    #[test]
    fn a_reference_views_noise_is_calibrated() {
        let b = builtin::interior();
        let tracer = Tracer::new(&b.scene);
        let t = Transport::new(&b.scene, &tracer, TransportSettings::default());
        let camera = Camera::look_at(DVec3::new(1.0, 1.0, 1.5), DVec3::new(5.0, 4.0, 1.0), 70.0).unwrap();
        let config = ViewConfig { width: 32, height: 24, quantity: Quantity::Shaded };
        let view = |n: u32| {
            render_reference_with_noise(
                &t,
                &camera,
                &config,
                &ReferenceConfig { samples: samples(n), seed: 2 },
                None,
            )
            .unwrap()
        };
        let ((rough, errors), (fine, _)) = (view(32), view(1024));
        let plain =
            render_reference(&t, &camera, &config, &ReferenceConfig { samples: samples(32), seed: 2 }, None);
        assert_eq!(plain.unwrap(), rough);
        let surface: Vec<usize> = (0..rough.pixels.len()).filter(|&i| rough.surface[i]).collect();
        assert!(surface.len() > 600, "{} surface pixels", surface.len());
        assert!(
            (0..errors.len()).all(|i| errors[i].is_some() == rough.surface[i]),
            "estimates on surfaces only"
        );
        let lum = |p: [f32; 3]| luminance(p.map(f64::from));
        let actual = rel_rmse(surface.iter().map(|&i| (lum(rough.pixels[i]), lum(fine.pixels[i]))));
        let mean = surface.iter().map(|&i| lum(fine.pixels[i])).sum::<f64>() / surface.len() as f64;
        let estimated =
            (surface.iter().map(|&i| errors[i].unwrap().powi(2)).sum::<f64>() / surface.len() as f64).sqrt()
                / mean;
        eprintln!("view noise: estimated {estimated:.4}, actual {actual:.4}");
        assert!(actual > 0.01, "a noisy view: {actual}");
        assert!(estimated > 0.5 * actual && estimated < 2.0 * actual, "{estimated} against {actual}");
    }
}
