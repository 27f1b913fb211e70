//! `lightvol render SCENE --surface DIR -o OUT`: \[Ish11\] Fig. 3.5, rendered by
//! lightvol-surface's `shaded_view` (each basis's maps at the normal-mapped
//! tangent-space normal, the modified H-basis's lower levels of detail, and a path-traced
//! reference of the same quantity).
//!
//! The maps record what lit their bake (`lightvol_scene::fingerprint::lighting_fingerprint`:
//! environment, sun, punctual lights, emitters and the bounce count). The render refuses, with
//! one line and before writing anything, maps in `DIR` that disagree with each other (a stale
//! file) or with its own scene and lights under the maps' bounce count; the reference is
//! traced with that bounce count (lightvol-surface's `map_dir`). `invalid_texels`
//! is read from the EXR maps.
//!
//! `OUT/sheet.png` tiles the reference, the bases in file-name order, `lightmap` and
//! `lightmap4`, four per row. `OUT/report.json`:
//! `{"bases": {"<basis>": {"rel_rmse", "bytes_per_texel", "coefficients", "image"}},
//!   "invalid_texels", "reference": {"image", "samples"}, "pixels", "normal_map"}`.
//! `rel_rmse` is lightvol-core's relative RMSE over the lightmapped pixels and the three
//! channels of the shaded radiance. `bytes_per_texel` is the 8-bit storage of \[Ish11\]
//! §2.2.3 as RGB8 (PNG): 3 bytes per coefficient (an uncompressed RGBA8 KTX2 stores 4, BC7 1,
//! BC1 0.5; see `bake-surface`'s summary).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use lightvol_surface::SurfaceGeometry;
use lightvol_surface::map_dir::{MapDirError, check_lighting, check_objects, read_map_dir};
use lightvol_surface::shaded_view::{
    MapSet, NormalMap, ShadedViewReport, ShadedViewSettings, image_file, render_shaded_view,
};
use lightvol_view::Camera;
use lightvol_view::picture::sheet;

use crate::imaging::{Rgb32, write_atomic, write_png_linear};
use crate::progress::with_report_bar;
use crate::render_args::{RenderArgs, resolve_camera};
use crate::setup::with_threads;

/// The map folder's errors, those about the folder as a whole named by `--surface`.
fn surface_error(e: MapDirError) -> anyhow::Error {
    if e.is_folder_error() { anyhow::Error::new(e).context("--surface") } else { e.into() }
}

/// Runs `lightvol render --surface`.
pub(crate) fn run(args: &RenderArgs, dir: &Path, normal_map: &str) -> anyhow::Result<ExitCode> {
    args.size(None)?;
    let nmap = NormalMap::parse(normal_map).map_err(|e| anyhow::Error::new(e).context("--normal-map"))?;
    // Default `-o` of the volume render is a file name; a surface render writes a folder.
    let out_dir = if args.output == Path::new("render.png") {
        PathBuf::from("surface_render")
    } else {
        args.output.clone()
    };
    if out_dir.exists() && !out_dir.is_dir() {
        bail!("output {} exists and is not a directory", out_dir.display());
    }
    let maps = read_map_dir(dir).map_err(surface_error)?;
    for p in &maps.skipped {
        eprintln!("note: skipping {} (not a lightvol surface EXR)", p.display());
    }
    let invalid_texels = maps.invalid_texels;
    let loaded = args.scene.load_flattened()?;
    // The reference is traced with the maps' bounce count, under the same lighting.
    let bounces = check_lighting(&maps, dir, &loaded.scene).map_err(surface_error)?;
    let uv_set = maps.sets[0].set.maps[0].uv_set;
    let geo = SurfaceGeometry::new(&loaded.scene, uv_set).context("lightmap objects of the scene")?;
    check_objects(&maps, &geo).map_err(surface_error)?;
    let (camera, aspect) = match &args.camera {
        Some(c) => resolve_camera(c, &loaded.scene, loaded.frame)?,
        None => (Camera::framing(&loaded.scene, None)?, None),
    };
    let (width, height) = args.size(aspect)?;
    let settings = ShadedViewSettings {
        camera,
        width,
        height,
        reference_samples: args.reference_samples,
        seed: args.seed,
        transport: bounces,
    };
    let map_sets: Vec<MapSet> = maps.sets.into_iter().map(|s| s.set).collect();
    let view = with_threads(args.threads, || {
        with_report_bar(args.quiet, "reference", |p| {
            render_shaded_view(&loaded.scene, &geo, &map_sets, &nmap, &settings, Some(p))
        })
    })?;
    let pixels = view.pixels;
    if pixels == 0 {
        bail!("no lightmapped surface is visible from the camera (use --camera)");
    }
    let (w, h) = (width as usize, height as usize);
    let image = |px: &[[f32; 3]]| Rgb32 { width: w, height: h, pixels: px.to_vec() };
    let reference = image(&view.reference);
    let images: Vec<Rgb32> = view.images.iter().map(|i| image(&i.pixels)).collect();
    let exposure = args.exposure.unwrap_or_else(|| view.auto_exposure());
    let report = ShadedViewReport::new(&view, invalid_texels, args.reference_samples, normal_map);
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    write_png_linear(&out_dir.join(&report.reference.image), &reference, exposure)?;
    for (i, img) in view.images.iter().zip(&images) {
        write_png_linear(&out_dir.join(image_file(&i.name)), img, exposure)?;
    }
    let mut tiles = vec![&reference];
    tiles.extend(images.iter());
    write_png_linear(&out_dir.join("sheet.png"), &sheet(&tiles), exposure)?;
    write_atomic(&out_dir.join("report.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    for (name, b) in &report.bases {
        eprintln!("{name:>12}: rel RMSE {:.4} ({} bytes/texel)", b.rel_rmse, b.bytes_per_texel);
    }
    eprintln!(
        "wrote {} ({} lightmapped pixels, {} invalid texels)",
        out_dir.display(),
        pixels,
        invalid_texels
    );
    Ok(ExitCode::SUCCESS)
}
