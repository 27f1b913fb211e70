//! `lightvol render`: a pinhole view in which every visible surface is shaded by the
//! volume (irradiance at the hit point and normal, times albedo / π), or by path tracing
//! with `--reference`. This is the "helicopter" view of Kontkanen & Laine 2006 Fig. 1: it
//! shows leaking where a person can see it.
//!
//! The view itself is lightvol-sampler's `view` module; this verb reads the volume, turns
//! the options into a camera and a `ViewConfig`, and encodes the image.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_sampler::view::{
    Camera, CameraSpec, Quantity, ReferenceConfig, ViewConfig, ViewError, ViewImage, render_reference,
    render_volume,
};
use lightvol_sampler::{DVec3, Scene, Tracer, Transport, UpAxis};

use crate::imaging::{Rgb32, auto_exposure};
use crate::setup::{SceneArgs, with_threads};

/// `lightvol render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene and lights (must match the volume's bake).
    #[command(flatten)]
    pub scene: SceneArgs,
    /// The baked volume to shade with (required unless --reference).
    #[arg(long)]
    pub volume: Option<PathBuf>,
    /// Camera `EYE_X,EYE_Y,EYE_Z:TARGET_X,TARGET_Y,TARGET_Z[:FOV_DEG]` in the scene file's
    /// frame (glTF +Y up, OBJ per --up), or `gltf:NAME` /
    /// `gltf:INDEX` for a camera of the scene file (its yfov, and its aspect ratio unless
    /// --height is given; `lightvol inspect` lists them). Default: a view from above one
    /// corner of the scene bounds, looking at their centre.
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Image width.
    #[arg(long, default_value_t = 480)]
    pub width: u32,
    /// Image height (default 320, or width / aspect ratio of a file camera that has one).
    #[arg(long)]
    pub height: Option<u32>,
    /// Shade by path tracing instead of the volume (the ground truth for the same view).
    #[arg(long)]
    pub reference: bool,
    /// Path-traced irradiance samples per pixel with --reference.
    #[arg(long, default_value_t = 64)]
    pub reference_samples: u32,
    /// Exposure multiplier (default: maps the mean pixel to 0.35).
    #[arg(long)]
    pub exposure: Option<f32>,
    /// Seed of the reference's streams.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output image: `.png` (sRGB, scaled by --exposure) or `.exr` (linear HDR, unscaled, for
    /// numeric comparison in other tools) (with --surface: output directory, default
    /// `surface_render`).
    #[arg(short, long, default_value = "render.png")]
    pub output: PathBuf,
    /// What a pixel holds: `shaded` (emission + albedo · E / π, what a camera sees),
    /// `radiosity` (albedo · E / π, the reflected light alone) or `irradiance` (E at the
    /// surface point and normal).
    #[arg(long, default_value = "shaded", value_parser = ["shaded", "radiosity", "irradiance"])]
    pub quantity: String,
    /// Path length and direct light of the path-traced view (--reference), as for `bake`.
    #[command(flatten)]
    pub path: crate::setup::PathArgs,
    /// Shade lightmapped surfaces from the coefficient maps that `bake-surface` wrote to this
    /// directory, one image per basis next to a path-traced reference, with `report.json`
    /// (Ishmukhametov 2011 Fig. 3.5).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["volume", "reference"])]
    pub surface: Option<PathBuf>,
    /// Normal map for --surface: `procedural[:FREQ[:SLOPE]]` (default), `flat` or an RGB PNG.
    #[arg(long, requires = "surface")]
    pub normal_map: Option<String>,
}

/// Default image height when neither --height nor a file camera's aspect ratio sets it.
pub const DEFAULT_HEIGHT: u32 = 320;

impl RenderArgs {
    /// The image size: `--width`, and `--height`, else `width / aspect` rounded (and at
    /// least one pixel) for a camera with an aspect ratio, else [`DEFAULT_HEIGHT`]. Refuses
    /// empty images and images over 64 Mpixels.
    pub fn size(&self, aspect: Option<f64>) -> anyhow::Result<(u32, u32)> {
        image_size(self.width, self.height, aspect, DEFAULT_HEIGHT)
    }
}

/// The size of an image `width` wide: `height`, else `width / aspect` rounded (at least one
/// pixel) for a camera with an aspect ratio, else `default_height`; checked by
/// [`ViewConfig::validate`].
pub fn image_size(
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
pub fn camera_error(spec: &str, e: ViewError) -> anyhow::Error {
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
pub fn resolve_camera(spec: &str, scene: &Scene, frame: UpAxis) -> anyhow::Result<(Camera, Option<f64>)> {
    spec.parse::<CameraSpec>().and_then(|c| c.resolve(scene, frame)).map_err(|e| camera_error(spec, e))
}

/// The image of a view.
#[must_use]
pub fn to_rgb32(img: ViewImage) -> Rgb32 {
    Rgb32 { width: img.width as usize, height: img.height as usize, pixels: img.pixels }
}

/// Runs `lightvol render`.
pub fn run(args: &RenderArgs) -> anyhow::Result<ExitCode> {
    if let Some(dir) = &args.surface {
        if args.quantity != "shaded" || !args.path.is_default() {
            anyhow::bail!(
                "--quantity, --bounces and --light do not apply to --surface (its maps record their own lighting)"
            );
        }
        return crate::cmd_render_surface::run(args, dir, args.normal_map.as_deref().unwrap_or("procedural"));
    }
    args.size(None)?;
    let quantity: Quantity = args.quantity.parse()?;
    let loaded = args.scene.load()?;
    // A gradient file is shaded from its coefficients (`AnyVolume::trilinear_field`).
    let vol = match (&args.volume, args.reference) {
        (Some(p), _) => Some(lightvol_volume::open(p).with_context(|| format!("reading {}", p.display()))?),
        (None, true) => None,
        (None, false) => bail!("render needs --volume V.exr (or --reference for the path-traced view)"),
    };
    let (cam, aspect) = match &args.camera {
        Some(c) => resolve_camera(c, &loaded.scene, loaded.frame)?,
        None => {
            // Frame the volume (or the built-in's recommended grid), else the scene.
            let grid = vol.as_ref().map(|v| v.field().grid().clone()).or_else(|| loaded.grid.clone());
            let (lo, hi) = match grid {
                Some(g) if g.placement().is_none() => {
                    let (a, b) = g.bounds();
                    (DVec3::from(a), DVec3::from(b))
                }
                _ => loaded.scene.bounds(),
            };
            (Camera::overview(lo, hi)?, None)
        }
    };
    let (width, height) = args.size(aspect)?;
    let config = ViewConfig { width, height, quantity };
    // With --reference the volume (if given) only frames the view.
    let shade_vol = if args.reference { None } else { vol.as_ref() };
    let img = with_threads(args.threads, || -> Result<ViewImage, ViewError> {
        let tracer = Tracer::new(&loaded.scene);
        match shade_vol {
            Some(v) => render_volume(&loaded.scene, &tracer, &cam, &config, v.trilinear_field()),
            None => {
                let transport = Transport::new(&loaded.scene, &tracer, args.path.transport());
                let reference = ReferenceConfig { samples: args.reference_samples, seed: args.seed };
                render_reference(&transport, &cam, &config, &reference, None)
            }
        }
    })?
    .map_err(|e| match e {
        ViewError::ZeroSamples => anyhow::anyhow!("--reference-samples must be at least 1"),
        e => e.into(),
    })?;
    let img = to_rgb32(img);
    let exposure = args.exposure.unwrap_or_else(|| auto_exposure(&img));
    crate::imaging::write_image(&args.output, &img, exposure)?;
    eprintln!("wrote {}", args.output.display());
    Ok(ExitCode::SUCCESS)
}
