//! The views of `lightvol compare` (`--camera`): the options and the cameras they name in
//! the scene. The views themselves are lightvol-eval's `views`, their files and
//! report entries `eval::report::view_files`.

use anyhow::Context;
use clap::Args;
use lightvol_core::samples::{Samples, parse_samples};
use lightvol_eval::{ViewCamera, ViewsConfig};
use lightvol_scene::DVec3;
use lightvol_view::{Camera, CameraSpec};
use lightvol_volume::GridSpec;

use crate::render_args::{camera_error, image_size};
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
    #[arg(long, value_parser = parse_samples, default_value_t = ViewsConfig::DEFAULT_REFERENCE_SAMPLES)]
    pub(crate) view_samples: Samples,
    /// Also draw every view as these engines read the `doi` volume (comma-separated:
    /// `three`, `bevy`, `apv`, `trilinear`; `render --lookup` names them), as
    /// `view_LABEL_doi@ENGINE.png` with its relative RMSE in `report.json`.
    #[arg(long, value_delimiter = ',')]
    pub(crate) engine_views: Vec<lightvol_volume::EngineLookup>,
}

impl ViewArgs {
    /// The views of these options through `cameras` (resolved by [`cameras`]).
    pub(crate) fn config(&self, cameras: Vec<ViewCamera>) -> ViewsConfig {
        ViewsConfig { cameras, reference_samples: self.view_samples, engine_views: self.engine_views.clone() }
    }
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
