//! What can go wrong in setting up or rendering a view.

use std::num::ParseFloatError;

use lightvol_volume::VolumeError;

/// A view error: a camera that cannot be built or found, an image size out of range, or
/// a volume lookup that failed. Everything but the last is reported before a ray is traced.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// A camera specification is neither `EYE:TARGET[:FOV]` nor `gltf:NAME|INDEX`.
    #[error("expected EYE_X,EYE_Y,EYE_Z:TARGET_X,TARGET_Y,TARGET_Z[:FOV_DEG]")]
    CameraSyntax,
    /// A coordinate of a camera specification is not a number.
    #[error("'{text}' is not a number")]
    CameraNumber {
        /// The text.
        text: String,
        /// The parser's complaint.
        #[source]
        source: ParseFloatError,
    },
    /// A point of a camera specification is not three finite numbers.
    #[error("'{0}' is not three finite numbers")]
    CameraPoint(String),
    /// The field of view of a camera specification is not a number.
    #[error("field of view is not a number")]
    FovNumber(#[source] ParseFloatError),
    /// A field of view outside `[1, 179]` degrees.
    #[error("camera field of view must be in [1, 179] degrees, got {0}")]
    FovRange(f64),
    /// The eye is the target.
    #[error("camera eye and target coincide")]
    EyeAtTarget,
    /// A file camera with a zero view direction.
    #[error("file camera has no view direction")]
    NoViewDirection,
    /// A file camera whose up vector is parallel to its view direction.
    #[error("file camera's up is parallel to its view")]
    UpAlongView,
    /// `gltf:…` on a scene without cameras.
    #[error("the scene file has no perspective camera")]
    NoFileCameras,
    /// `gltf:KEY` names no camera of the scene.
    #[error("no such camera (the file has {available})")]
    NoSuchCamera {
        /// The scene's cameras, `INDEX 'NAME'`, comma separated.
        available: String,
    },
    /// An image with no pixel or more than [`MAX_PIXELS`](crate::MAX_PIXELS).
    #[error("image size {width}x{height} must be positive and at most 64 Mpixels")]
    ImageSize {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// A pixel quantity other than `shaded`, `radiosity`, `irradiance`.
    #[error("unknown quantity '{0}' (shaded, radiosity, irradiance)")]
    UnknownQuantity(String),
    /// The volume refused a lookup.
    #[error(transparent)]
    Volume(#[from] VolumeError),
}
