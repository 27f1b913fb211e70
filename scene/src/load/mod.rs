//! Scene files: Wavefront OBJ/MTL ([`obj`]) and glTF 2.0 ([`gltf`]), chosen by extension
//! ([`load_scene`]), with the [`LoadOptions`] both take.

use std::path::Path;

use crate::error::SceneError;
use crate::scene::Scene;

pub mod gltf;
pub(crate) mod image;
pub mod obj;
pub mod options;

pub use gltf::{load_gltf, load_gltf_slice};
pub use obj::load_obj;
pub use options::{DEFAULT_ALBEDO, LoadOptions};

/// Loads `.obj`, `.gltf` or `.glb` by extension.
///
/// # Errors
/// See [`SceneError`].
pub fn load_scene(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("obj") => load_obj(path, opts),
        Some("gltf" | "glb") => load_gltf(path, opts),
        _ => Err(SceneError::UnsupportedFormat(path.to_owned())),
    }
}
