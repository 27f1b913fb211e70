//! Errors of scene loading and assembly.

use std::path::PathBuf;

/// Everything that can go wrong while loading or assembling a [`Scene`](crate::Scene).
///
/// Missing MTL files and missing textures are *not* errors: the loaders record a warning in
/// [`LoadReport::warnings`](crate::LoadReport) and fall back to the material factor.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file does not exist.
    #[error("scene file not found: {0}")]
    NotFound(PathBuf),
    /// The file exists but could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file extension names no format we read.
    #[error("unsupported scene format {0:?} (expected .obj, .gltf or .glb)")]
    UnsupportedFormat(PathBuf),
    /// The OBJ parser failed.
    #[error("OBJ error in {path}: {message}")]
    Obj {
        /// The file.
        path: PathBuf,
        /// What tobj said.
        message: String,
    },
    /// The glTF parser failed.
    #[error("glTF error in {path}: {message}")]
    Gltf {
        /// The file.
        path: PathBuf,
        /// What the gltf crate said.
        message: String,
    },
    /// An environment map could not be read.
    #[error("environment map {path}: {message}")]
    EnvironmentMap {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A vertex or a material value is NaN or infinite.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Which value (e.g. "vertex 2 of triangle 17 in mesh 'floor'").
        what: String,
    },
    /// A material index does not exist.
    #[error("triangle refers to material {index}, but only {count} materials exist")]
    BadMaterial {
        /// The index used.
        index: u32,
        /// The number of materials.
        count: usize,
    },
    /// A triangle refers to a lightmap object or vertex that does not exist.
    #[error("bad mesh reference: {0}")]
    BadMesh(String),
    /// After loading, no (non-degenerate) triangle remained.
    #[error("scene {0} has no triangles")]
    Empty(String),
    /// The scene places more triangles than a `u32` scene index can number.
    #[error("scene {name} places {triangles} triangles, more than the {max} a scene can number")]
    TooManyTriangles {
        /// The scene.
        name: String,
        /// Triangles placed (instances included).
        triangles: u64,
        /// The limit (`u32::MAX`).
        max: u32,
    },
}
