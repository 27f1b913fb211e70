//! Errors of the surface bake and its file format.

use std::path::PathBuf;

use super::UvSet;

/// Everything that can go wrong while preparing, baking, writing or reading coefficient maps.
#[derive(Debug, thiserror::Error)]
pub enum SurfaceError {
    /// The scene has no lightmap objects (no triangle carries a [`TriangleRef`](lightvol_scene::triangle::TriangleRef);
    /// OBJ files and the built-in scenes have none, glTF files always do).
    #[error(
        "the scene has no lightmap objects (load a glTF file, or build meshes with SceneBuilder::add_mesh)"
    )]
    NoLightmapObjects,
    /// An object lacks the requested UV set (\[Ish11\] §2.1.1: lightmap UVs must be authored;
    /// none are generated).
    #[error("mesh '{mesh}' has no {set} (lightmap UVs must be authored; lightvol does not generate them)")]
    MissingUvSet {
        /// The object.
        mesh: String,
        /// The set asked for.
        set: UvSet,
    },
    /// A lightmap texture coordinate lies outside `[0, 1]` (or is not finite).
    #[error("mesh '{mesh}': triangle {triangle} has lightmap UV {uv:?} outside [0, 1]")]
    UvOutOfRange {
        /// The object.
        mesh: String,
        /// Face index in the object.
        triangle: u32,
        /// The offending coordinate.
        uv: [f64; 2],
    },
    /// A triangle has (numerically) zero area in lightmap UV space: it would get no texel.
    #[error("mesh '{mesh}': triangle {triangle} has zero area in lightmap UV space")]
    DegenerateUv {
        /// The object.
        mesh: String,
        /// Face index in the object.
        triangle: u32,
    },
    /// Two triangles of one object overlap in UV space (by more than
    /// [`UV_OVERLAP_AREA_TOLERANCE`](super::atlas::UV_OVERLAP_AREA_TOLERANCE) of a texel).
    #[error("mesh '{mesh}': lightmap UV triangles {a} and {b} overlap (in texel {texel:?})")]
    UvOverlap {
        /// The object.
        mesh: String,
        /// Face index of the first triangle.
        a: u32,
        /// Face index of the second triangle.
        b: u32,
        /// The first texel `[x, y]` (in index order) where they overlap.
        texel: [u32; 2],
    },
    /// The texel density asks for an atlas larger than [`MAX_ATLAS_SIZE`](super::MAX_ATLAS_SIZE).
    #[error("mesh '{mesh}': {width}×{height} texels exceed the largest atlas; lower --texels-per-unit")]
    AtlasTooLarge {
        /// The object.
        mesh: String,
        /// Requested width.
        width: u64,
        /// Requested height.
        height: u64,
    },
    /// Tangent frames could not be built.
    #[error("mesh '{mesh}': tangents: {message}")]
    Tangents {
        /// The object.
        mesh: String,
        /// What went wrong.
        message: String,
    },
    /// The scene's triangles and attribute tables disagree (e.g. triangles were edited
    /// after loading without updating [`Scene::triangle_refs`](lightvol_scene::Scene)).
    #[error("inconsistent scene: {0}")]
    InconsistentScene(String),
    /// A basis name that no enabled hemispherical basis answers to.
    #[error(
        "unknown basis '{0}' (sh4, sh9, hl2, hsh4, hsh9, makhotkin4, makhotkin9, zernike3, zernike6, hbasis4, hbasis6, hbasis_mod4, hbasis_mod6)"
    )]
    UnknownBasis(String),
    /// Invalid settings.
    #[error("invalid surface bake settings: {0}")]
    Settings(String),
    /// The caller's cancel flag was raised.
    #[error("surface bake cancelled")]
    Cancelled,
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A file is not a valid lightvol coefficient-map EXR.
    #[error("{path}: not a valid lightvol surface EXR: {message}")]
    Exr {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}
