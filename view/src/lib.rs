#![doc = include_str!("../README.md")]

pub mod camera;
pub mod error;
pub mod picture;
pub mod render;

pub use camera::{Camera, CameraSpec, DEFAULT_FOV_DEG};
pub use error::ViewError;
pub use render::{
    MAX_PIXELS, Quantity, REFERENCE_STREAM, ReferenceConfig, ViewConfig, ViewImage, VisibleSurface,
    render_reference, render_reference_with_noise, render_volume, visible_surface,
};

#[cfg(test)]
mod tests;
