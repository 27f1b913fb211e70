//! # Views: a camera's image of a scene shaded by a volume or by path tracing
//!
//! The "helicopter" view of Kontkanen & Laine 2006 (\[KL06\] Fig. 1): a pinhole camera
//! looks at the scene, and every visible surface is lit by the irradiance a volume gives at
//! the hit point and the normal of the side the camera sees (\[KL06\] Eq. 3), or by
//! path-traced irradiance at the same point for the ground truth. Leaking shows where a
//! person can see it: dark bands along walls, light bleeding under them.
//!
//! ## Modules
//!
//! | module | concept |
//! | --- | --- |
//! | [`camera`] | [`Camera`]: look-at, file cameras ([`CameraSpec`]), the default overview, primary rays |
//! | [`render`](mod@render) | [`render_volume`] (of any `lightvol_volume::VolumeField`), [`render_reference`], the pixel [`Quantity`] |
//! | [`error`] | [`ViewError`] |
//!
//! ## Guide
//!
//! ```
//! use lightvol_sampler::view::{Camera, Quantity, ViewConfig, render_volume};
//! use lightvol_sampler::{DVec3, IrradianceVolume, Tracer, builtin};
//!
//! let maze = builtin::maze();
//! let tracer = Tracer::new(&maze.scene);
//! // A volume that gives E = π everywhere, for every normal (radiance 1 from all sides:
//! // the constant SH coefficient is 2√π).
//! let k = 2.0 * std::f64::consts::PI.sqrt();
//! let vol = IrradianceVolume::from_fn(maze.grid.clone(), 9, |_| {
//!     let mut c = vec![[0.0; 3]; 9];
//!     c[0] = [k; 3];
//!     c
//! })?;
//! let (lo, hi) = maze.scene.bounds();
//! let camera = Camera::overview(lo, hi)?;
//! let config = ViewConfig { width: 32, height: 20, quantity: Quantity::Irradiance };
//! let img = render_volume(&maze.scene, &tracer, &camera, &config, &vol)?;
//! // Every pixel that sees a surface holds E = π (f32 lookup).
//! let px = img.pixels.iter().zip(&img.surface).filter(|(_, s)| **s).map(|(p, _)| p[0]);
//! assert!(px.clone().count() > 0);
//! assert!(px.map(|e| (f64::from(e) - std::f64::consts::PI).abs()).all(|d| d < 1e-5));
//! # Ok::<(), lightvol_sampler::view::ViewError>(())
//! ```
//!
//! Everything is deterministic: the path-traced view seeds every pixel's stream from the
//! seed and the pixel index, so the image is bit-identical across runs and thread counts.
//! Nothing here writes files: the caller encodes [`ViewImage`]s.

pub mod camera;
pub mod error;
pub mod render;

pub use camera::{Camera, CameraSpec, DEFAULT_FOV_DEG};
pub use error::ViewError;
pub use render::{
    MAX_PIXELS, Quantity, REFERENCE_STREAM, ReferenceConfig, ViewConfig, ViewImage, VisibleSurface,
    render_reference, render_volume, visible_surface,
};

#[cfg(test)]
mod tests;
