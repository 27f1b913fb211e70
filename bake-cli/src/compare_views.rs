//! The views of `lightvol compare` (`--camera`): the options, the cameras they name in
//! the scene, and what each camera's views write: `view_LABEL_reference.png`,
//! `view_LABEL_METHOD.png` and the camera's entry in `report.json`. The views themselves
//! are lightvol-sampler's `eval::views`.

use std::path::Path;

use anyhow::Context;
use clap::Args;
use lightvol_sampler::eval::{ComparedView, ViewCamera, ViewsConfig};
use lightvol_sampler::view::{Camera, CameraSpec};
use lightvol_sampler::{DVec3, GridSpec};
use serde::Serialize;
use serde_json::{Map, Value};

use crate::imaging::{auto_exposure, write_png_linear};
use crate::render_args::{camera_error, image_size, to_rgb32};
use crate::report_parts::ReferenceJson;
use crate::setup::LoadedScene;

/// The views of `compare`: cameras, image size and reference samples.
#[derive(Debug, Args, Clone)]
pub(crate) struct ViewArgs {
    /// Also compare the methods as a person sees them, through camera SPEC (repeatable): a
    /// path-traced view and one view per method (the scene shaded by that method's volume, as
    /// `render` shades it), written as `view_LABEL_reference.png` and `view_LABEL_METHOD.png`,
    /// and in `report.json` each method's relative RMSE over the pixels that see a surface
    /// inside the grid. SPEC is `render --camera`'s `EYE:TARGET[:FOV_DEG]` (labelled `camN`, N
    /// its position among the --camera options) or `gltf:NAME|INDEX` (labelled with the
    /// camera's name), or `overview` for `render`'s default view of the grid.
    #[arg(long = "camera", value_name = "SPEC", allow_hyphen_values = true)]
    pub(crate) cameras: Vec<String>,
    /// Width of the views.
    #[arg(long, default_value_t = ViewsConfig::DEFAULT_WIDTH)]
    pub(crate) view_width: u32,
    /// Height of the views (default 128, or width / aspect ratio of a file camera that has
    /// one).
    #[arg(long)]
    pub(crate) view_height: Option<u32>,
    /// Path-traced irradiance samples per pixel of the reference views.
    #[arg(long, default_value_t = ViewsConfig::DEFAULT_REFERENCE_SAMPLES)]
    pub(crate) view_samples: u32,
}

/// One camera's views in `report.json`.
#[derive(Debug, Serialize, Clone)]
pub(crate) struct ViewJson {
    /// The camera's label (in the image file names).
    pub(crate) camera: String,
    /// The `--camera` specification.
    pub(crate) spec: String,
    /// Width and height in pixels.
    pub(crate) resolution: [u32; 2],
    /// Pixels that see a surface.
    pub(crate) surface_pixels: usize,
    /// Pixels that see a surface inside the grid: the pixels measured.
    pub(crate) measured_pixels: usize,
    /// The path-traced view: samples per pixel, mean luminance over the measured pixels,
    /// wall time.
    pub(crate) reference: ReferenceJson,
    /// Per method, by name: its view's metrics against the reference view.
    pub(crate) methods: Map<String, Value>,
}

/// One method's view metrics in `report.json`.
#[derive(Debug, Serialize, Clone)]
pub(crate) struct ViewMetricsJson {
    /// `sqrt(mean((E - T)²)) / mean(T)` over the measured pixels, `E` and `T` the
    /// luminances of the method's and the reference's pixel.
    pub(crate) rel_rmse: f64,
    /// `mean(E - T) / mean(T)`.
    pub(crate) bias: f64,
    /// Share of pixels with `E < 0.8 T`.
    pub(crate) too_dark: f64,
    /// Share of pixels with `E > 1.25 T`.
    pub(crate) too_bright: f64,
}

/// Characters kept in a file camera's name when it labels a view (the rest become `_`).
fn label_char(c: char) -> char {
    if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }
}

/// The cameras of `--camera` (in order) in `loaded`'s scene, with `grid` framing
/// `overview`: labelled `overview`, the file camera's name (characters other than letters,
/// digits, `-` and `_` as `_`) or `camN` for the N-th option, sized by `--view-width` and
/// `--view-height` (else the file camera's aspect ratio, else the default height).
pub(crate) fn cameras(
    args: &ViewArgs,
    loaded: &LoadedScene,
    grid: &GridSpec,
) -> anyhow::Result<Vec<ViewCamera>> {
    args.cameras
        .iter()
        .enumerate()
        .map(|(k, spec)| {
            let (camera, aspect, label) = if spec == "overview" {
                let (lo, hi) = grid.bounds();
                (Camera::overview(DVec3::from(lo), DVec3::from(hi))?, None, "overview".to_owned())
            } else {
                let words = |e| camera_error(spec, e);
                let parsed: CameraSpec = spec.parse().map_err(words)?;
                let (camera, aspect) = parsed.resolve(&loaded.scene, loaded.frame).map_err(words)?;
                let name = parsed.file_camera_name(&loaded.scene).map_err(words)?;
                let name: Option<String> = name.map(|n| n.chars().map(label_char).collect());
                (camera, aspect, name.filter(|n| !n.is_empty()).unwrap_or_else(|| format!("cam{k}")))
            };
            let (width, height) =
                image_size(args.view_width, args.view_height, aspect, ViewsConfig::DEFAULT_HEIGHT)
                    .context("--view-width/--view-height")?;
            Ok(ViewCamera { label, camera, width, height })
        })
        .collect()
}

/// Writes one camera's images, `view_LABEL_reference.png` and `view_LABEL_METHOD.png`, all
/// at the reference view's automatic exposure (so that they compare by eye, and the
/// reference is the image `render --reference` writes), and returns its report entry.
pub(crate) fn write_view(
    dir: &Path,
    view: &ComparedView,
    spec: &str,
    samples: u32,
) -> anyhow::Result<ViewJson> {
    let reference = to_rgb32(view.reference.clone());
    let exposure = auto_exposure(&reference);
    let label = &view.label;
    write_png_linear(&dir.join(format!("view_{label}_reference.png")), &reference, exposure)?;
    let mut methods = Map::new();
    for m in &view.methods {
        write_png_linear(
            &dir.join(format!("view_{label}_{}.png", m.name)),
            &to_rgb32(m.image.clone()),
            exposure,
        )?;
        let metrics = ViewMetricsJson {
            rel_rmse: m.metrics.rel_rmse,
            bias: m.metrics.bias,
            too_dark: m.metrics.too_dark,
            too_bright: m.metrics.too_bright,
        };
        methods.insert(m.name.clone(), serde_json::to_value(metrics)?);
    }
    Ok(ViewJson {
        camera: label.clone(),
        spec: spec.to_owned(),
        resolution: [view.reference.width, view.reference.height],
        surface_pixels: view.reference.surface_pixels(),
        measured_pixels: view.measured.iter().filter(|&&m| m).count(),
        reference: ReferenceJson { samples, mean: view.mean_reference, seconds: view.reference_seconds },
        methods,
    })
}
