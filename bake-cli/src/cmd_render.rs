//! `lightvol render`: a pinhole view in which every visible surface is shaded by the
//! volume (irradiance at the hit point and normal, times albedo / π), or by path tracing
//! with `--reference`. This is the "helicopter" view of Kontkanen & Laine 2006 Fig. 1: it
//! shows leaking where a person can see it.
//!
//! The view itself is lightvol-view; this verb reads the volume, turns
//! the options into a camera and a `ViewConfig`, and encodes the image.

use std::process::ExitCode;

use anyhow::{Context, bail};
use lightvol_scene::{Tracer, Transport};
use lightvol_view::{
    Camera, Quantity, ReferenceConfig, ViewConfig, ViewError, ViewImage, render_reference, render_volume,
};

use lightvol_volume::EngineLookup;
use lightvol_volume::engine_lookup::EngineField;

use crate::imaging::auto_exposure;
use crate::progress::with_report_bar;
use crate::render_args::{RenderArgs, resolve_camera};
use crate::setup::with_threads;

/// Runs `lightvol render`.
pub(crate) fn run(args: &RenderArgs) -> anyhow::Result<ExitCode> {
    if let Some(e) = args.exposure.filter(|e| !(e.is_finite() && *e > 0.0)) {
        bail!("--exposure must be a positive finite scale, got {e}");
    }
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
    // An engine's lookup (other than lightvol's own) reads the uniform grid.
    let engine = match (&vol, args.lookup) {
        (Some(v), lookup) if lookup != EngineLookup::Lightvol => match v.uniform() {
            Some(volume) => Some(EngineField { volume, lookup }),
            None => bail!(
                "--lookup {lookup} reads a uniform grid and this volume is an adaptive octree; export it to one first (lightvol export --format ktx2 --res NX,NY,NZ)"
            ),
        },
        _ => None,
    };
    let (cam, aspect) = match &args.camera {
        Some(c) => resolve_camera(c, &loaded.scene, loaded.frame)?,
        None => {
            // Frame the volume (or the built-in's recommended grid), else the scene.
            let grid = vol.as_ref().map(|v| v.field().grid().clone()).or_else(|| loaded.grid.clone());
            (Camera::framing(&loaded.scene, grid.as_ref())?, None)
        }
    };
    let (width, height) = args.size(aspect)?;
    let config = ViewConfig { width, height, quantity };
    // With --reference the volume (if given) only frames the view.
    let shade_vol = if args.reference { None } else { vol.as_ref() };
    let img = with_threads(args.threads, || -> Result<ViewImage, ViewError> {
        let tracer = Tracer::new(&loaded.scene);
        match shade_vol {
            Some(v) => match engine {
                None => render_volume(&loaded.scene, &tracer, &cam, &config, v.trilinear_field()),
                Some(field) => render_volume(&loaded.scene, &tracer, &cam, &config, &field),
            },
            None => {
                let transport = Transport::new(&loaded.scene, &tracer, args.path.transport());
                let reference = ReferenceConfig { samples: args.reference_samples, seed: args.seed };
                with_report_bar(args.quiet, "reference", |p| {
                    render_reference(&transport, &cam, &config, &reference, Some(p))
                })
            }
        }
    })?
    .map_err(anyhow::Error::new)?;
    let coverage = img.surface.clone();
    let img = crate::imaging::Rgb32::from(img);
    let exposure = args.exposure.unwrap_or_else(|| auto_exposure(&img));
    crate::imaging::write_image(&args.output, &img, Some(&coverage), exposure)?;
    eprintln!("wrote {}", args.output.display());
    Ok(ExitCode::SUCCESS)
}
