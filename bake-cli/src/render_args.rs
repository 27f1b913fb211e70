//! The options of `lightvol render` and what they resolve to: the image size and the
//! camera (`--camera SPEC`, lightvol-view's `CameraSpec`), shared by the volume and
//! the surface render and by `compare`'s views.

use lightvol_core::samples::{Samples, parse_samples, samples};
use std::path::PathBuf;

use clap::Args;
use lightvol_scene::{Scene, UpAxis};
use lightvol_view::{Camera, CameraSpec, Quantity, ViewConfig, ViewError};

use crate::setup::SceneArgs;

/// `lightvol render`.
#[derive(Debug, Args)]
pub(crate) struct RenderArgs {
    /// Scene and lights (must match the volume's bake).
    #[command(flatten)]
    pub(crate) scene: SceneArgs,
    /// The baked volume to shade with (required unless --reference).
    #[arg(long)]
    pub(crate) volume: Option<PathBuf>,
    /// Camera `EYE_X,EYE_Y,EYE_Z:TARGET_X,TARGET_Y,TARGET_Z[:FOV_DEG]` in the scene file's
    /// frame (glTF +Y up, OBJ per --up), or `gltf:NAME` /
    /// `gltf:INDEX` for a camera of the scene file (its yfov, and its aspect ratio unless
    /// --height is given; `lightvol inspect` lists them). Default: a view from above one
    /// corner of the scene bounds, looking at their centre.
    #[arg(long, allow_hyphen_values = true)]
    pub(crate) camera: Option<String>,
    /// Image width.
    #[arg(long, default_value_t = 480)]
    pub(crate) width: u32,
    /// Image height (default 320, or width / aspect ratio of a file camera that has one).
    #[arg(long)]
    pub(crate) height: Option<u32>,
    /// Shade by path tracing instead of the volume (the ground truth for the same view).
    #[arg(long)]
    pub(crate) reference: bool,
    /// Path-traced irradiance samples per pixel with --reference.
    #[arg(long, value_parser = parse_samples, default_value_t = samples(64))]
    pub(crate) reference_samples: Samples,
    /// Exposure multiplier (default: maps the mean pixel to 0.35).
    #[arg(long)]
    pub(crate) exposure: Option<f32>,
    /// Seed of the reference's streams.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Worker threads.
    #[arg(long)]
    pub(crate) threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub(crate) quiet: bool,
    /// Output image: `.png` (sRGB, scaled by --exposure) or `.exr` (linear HDR, unscaled, for
    /// numeric comparison in other tools) (with --surface: output directory, default
    /// `surface_render`).
    #[arg(short, long, default_value = "render.png")]
    pub(crate) output: PathBuf,
    /// What a pixel holds: `shaded` (emission + albedo · E / π, what a camera sees),
    /// `radiosity` (albedo · E / π, the reflected light alone) or `irradiance` (E at the
    /// surface point and normal).
    #[arg(long, default_value = "shaded", value_parser = ["shaded", "radiosity", "irradiance"])]
    pub(crate) quantity: String,
    /// Path length and direct light of the path-traced view (--reference), as for `bake`.
    #[command(flatten)]
    pub(crate) path: crate::setup::PathArgs,
    /// Shade lightmapped surfaces from the coefficient maps that `bake-surface` wrote to this
    /// directory, one image per basis next to a path-traced reference, with `report.json`
    /// (Ishmukhametov 2011 Fig. 3.5).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["volume", "reference"])]
    pub(crate) surface: Option<PathBuf>,
    /// Read the volume as this engine does: `lightvol` (its own lookup, with validity and
    /// node reach), `trilinear` (plain, Godot-style), `three` (three.js LightProbeGrid: half
    /// a cell along the normal), `bevy` (Bevy's ambient cube) or `apv` (Unity APV: validity
    /// weights at a point pushed along the normal and towards the eye). Engines other than
    /// lightvol read uniform grids only.
    #[arg(long, default_value_t = lightvol_volume::EngineLookup::Lightvol, conflicts_with = "surface")]
    pub(crate) lookup: lightvol_volume::EngineLookup,
    /// Normal map for --surface: `procedural[:FREQ[:SLOPE]]` (default), `flat` or an RGB PNG.
    #[arg(long, requires = "surface")]
    pub(crate) normal_map: Option<String>,
}

/// Default image height when neither --height nor a file camera's aspect ratio sets it.
pub(crate) const DEFAULT_HEIGHT: u32 = 320;

impl RenderArgs {
    /// The image size: `--width`, and `--height`, else `width / aspect` rounded (and at
    /// least one pixel) for a camera with an aspect ratio, else [`DEFAULT_HEIGHT`]. Refuses
    /// empty images and images over 64 Mpixels.
    pub(crate) fn size(&self, aspect: Option<f64>) -> anyhow::Result<(u32, u32)> {
        image_size(self.width, self.height, aspect, DEFAULT_HEIGHT)
    }
}

/// The size of an image `width` wide: `height`, else `width / aspect` rounded (at least one
/// pixel) for a camera with an aspect ratio, else `default_height`; checked by
/// [`ViewConfig::validate`].
pub(crate) fn image_size(
    width: u32,
    height: Option<u32>,
    aspect: Option<f64>,
    default_height: u32,
) -> anyhow::Result<(u32, u32)> {
    let h = match (height, aspect) {
        (Some(h), _) => h,
        (None, Some(a)) => ((f64::from(width) / a).round() as u32).max(1),
        (None, None) => default_height,
    };
    ViewConfig { width, height: h, quantity: Quantity::Shaded }.validate()?;
    Ok((width, h))
}

/// A camera error in the words of the `--camera SPEC` option: what is wrong with the
/// specification itself after `--camera`, a missing file camera after `--camera SPEC`.
#[must_use]
pub(crate) fn camera_error(spec: &str, e: ViewError) -> anyhow::Error {
    match e {
        ViewError::CameraSyntax
        | ViewError::CameraNumber { .. }
        | ViewError::CameraPoint(_)
        | ViewError::FovNumber(_) => anyhow::Error::new(e).context("--camera"),
        ViewError::NoFileCameras | ViewError::NoSuchCamera { .. } => {
            anyhow::Error::new(e).context(format!("--camera {spec}"))
        }
        e => e.into(),
    }
}

/// Resolves `--camera SPEC` in `scene`, whose file frame is `frame` ([`CameraSpec`]):
/// the camera and the file camera's aspect ratio.
pub(crate) fn resolve_camera(
    spec: &str,
    scene: &Scene,
    frame: UpAxis,
) -> anyhow::Result<(Camera, Option<f64>)> {
    spec.parse::<CameraSpec>().and_then(|c| c.resolve(scene, frame)).map_err(|e| camera_error(spec, e))
}
