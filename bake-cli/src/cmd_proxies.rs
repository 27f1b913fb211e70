//! `lightvol proxies`: soft shadows and bounce light from a sphere-proxy character (Sloan et
//! al. 2007, lightvol-proxies), compared with a path-traced reference in which the spheres
//! are real geometry. Under `--volume`, the light at each receiver is the baked volume's
//! local radiance instead (no reference exists for that case).

use lightvol_core::samples::{Samples, parse_samples, samples};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_proxies::compare::{CompareConfig, compare, render_variants};
use lightvol_proxies::light::VolumeLight;
use lightvol_proxies::receiver_scene::Scene;
use serde_json::json;

use crate::imaging::{Rgb32, write_atomic, write_png_linear};

/// `lightvol proxies`.
#[derive(Debug, Args)]
pub(crate) struct ProxiesArgs {
    /// A receiver scene as JSON (the serde form of `lightvol_proxies::receiver_scene::Scene`), or
    /// `default` (ground, two walls and an 18-sphere character under a sky and sun).
    #[arg(default_value = "default")]
    pub(crate) scene: String,
    /// Light the receivers with this baked volume (EXR, KTX2 or DDS) instead of the scene's
    /// distant light.
    #[arg(long)]
    pub(crate) volume: Option<PathBuf>,
    /// Display size W H (even; receivers are rendered at half resolution).
    #[arg(long, num_args = 2, default_values_t = [320, 240])]
    pub(crate) size: Vec<usize>,
    /// Path-traced samples per pixel of the reference.
    #[arg(long, value_parser = parse_samples, default_value_t = samples(256))]
    pub(crate) samples: Samples,
    /// SH order of the shadows: 3 or 4 bands.
    #[arg(long, default_value_t = 4)]
    pub(crate) order: usize,
    /// Output directory.
    #[arg(short, long, default_value = "proxies-out")]
    pub(crate) output: PathBuf,
}

fn save(path: &Path, size: [usize; 2], img: &[[f32; 3]], exposure: f32) -> anyhow::Result<()> {
    write_png_linear(path, &Rgb32 { width: size[0], height: size[1], pixels: img.to_vec() }, exposure)
}

fn exposure_of(imgs: &[[f32; 3]], mask: Option<&[bool]>) -> f32 {
    let mut vals: Vec<f32> = imgs
        .iter()
        .enumerate()
        .filter(|(i, _)| mask.is_none_or(|m| m[*i]))
        .map(|(_, p)| p[0].max(p[1]).max(p[2]))
        .collect();
    vals.sort_by(f32::total_cmp);
    0.9 / vals.get(vals.len() * 99 / 100).copied().unwrap_or(1.0).max(1e-6)
}

/// Runs `lightvol proxies`.
pub(crate) fn run(args: &ProxiesArgs) -> anyhow::Result<ExitCode> {
    let [w, h] = [args.size[0], args.size[1]];
    if w < 8 || h < 8 || w % 2 != 0 || h % 2 != 0 || w * h > 16 << 20 {
        bail!("--size needs even dimensions of at least 8 (and at most 16 Mpixels), got {w} {h}");
    }
    if args.order != 3 && args.order != 4 {
        bail!("--order must be 3 or 4");
    }
    let scene = if args.scene == "default" {
        Scene::default_scene()
    } else {
        let text = std::fs::read_to_string(&args.scene).with_context(|| format!("reading {}", args.scene))?;
        Scene::from_json(&text).with_context(|| format!("parsing {}", args.scene))?
    };
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    let tolerance = 1.0 / 256.0;
    let mut cfg = if args.order == 4 {
        CompareConfig::derived::<16>(w, h, tolerance)
    } else {
        CompareConfig::derived::<9>(w, h, tolerance)
    };
    cfg.samples = args.samples;
    let report = if let Some(path) = &args.volume {
        if !path.extension().is_some_and(|e| ["exr", "ktx2", "dds"].iter().any(|x| e.eq_ignore_ascii_case(x)))
        {
            bail!("--volume: {} is not an .exr, .ktx2 or .dds file", path.display());
        }
        let opened = lightvol_volume::open(path).with_context(|| format!("reading {}", path.display()))?;
        let Some(vol) = opened.uniform() else {
            bail!(
                "--volume: {} is an adaptive (octree) volume; proxies are lit by a uniform grid (export it to one first)",
                path.display()
            );
        };
        let light = VolumeLight(vol);
        let v = if args.order == 4 {
            render_variants::<16>(&scene, &cfg, &light)
        } else {
            render_variants::<9>(&scene, &cfg, &light)
        };
        let exposure = exposure_of(&v.none, None);
        for (name, img) in
            [("none", &v.none), ("shadows", &v.shadows), ("shadows_indirect", &v.shadows_indirect)]
        {
            save(&args.output.join(format!("{name}.png")), v.size, &v.draw(img.clone()), exposure)?;
        }
        json!({
            "variants": {"none": {"rel_rmse": null}, "shadows": {"rel_rmse": null}, "shadows_indirect": {"rel_rmse": null}},
            "proxies": scene.proxies.len(), "receivers": v.receivers, "display": v.size, "order": args.order,
            "volume": path.display().to_string(), "eta": {"shadow": cfg.eta_shadow, "indirect": cfg.eta_indirect},
            "reference": null, "upsampling_fallbacks": v.fallbacks,
        })
    } else {
        let c = if args.order == 4 { compare::<16>(&scene, &cfg) } else { compare::<9>(&scene, &cfg) };
        let exposure = exposure_of(&c.reference, Some(&c.mask));
        for (name, img) in [
            ("none", &c.none),
            ("shadows", &c.shadows),
            ("shadows_indirect", &c.shadows_indirect),
            ("reference", &c.reference),
        ] {
            save(&args.output.join(format!("{name}.png")), c.size, img, exposure)?;
        }
        json!({
            "variants": {
                "none": {"rel_rmse": c.errors.none},
                "shadows": {"rel_rmse": c.errors.shadows},
                "shadows_indirect": {"rel_rmse": c.errors.shadows_indirect},
            },
            "proxies": scene.proxies.len(), "receivers": c.receivers, "display": c.size, "order": args.order,
            "eta": {"shadow": cfg.eta_shadow, "indirect": cfg.eta_indirect, "tolerance": tolerance},
            "reference_samples": cfg.samples, "compared_pixels": c.mask.iter().filter(|m| **m).count(),
            "upsampling_fallbacks": c.fallbacks,
        })
    };
    let text = serde_json::to_string_pretty(&report)?;
    write_atomic(&args.output.join("report.json"), (text.clone() + "\n").as_bytes())?;
    println!("{text}");
    Ok(ExitCode::SUCCESS)
}
