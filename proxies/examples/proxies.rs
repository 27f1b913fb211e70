//! `lightvol proxies [SCENE] [--volume V.exr] [-o DIR] [--size W H] [--samples N] [--order 3|4]`
//!
//! Renders a receiver scene (the built-in default: ground, two walls, a sphere-set
//! character under a sky/sun light; or a JSON scene file, the serde form of
//! `lightvol_proxies::receiver_scene::Scene`) without proxies, with proxy shadows, with shadows and
//! indirect light, and path-traced with the spheres as real geometry. Writes `none.png`,
//! `shadows.png`, `shadows_indirect.png`, `reference.png` and `report.json` (relative RMSE
//! of each variant against the reference on the receivers) to DIR (default `proxies-out`).
//!
//! With `--volume` (EXR, KTX2 or DDS from lightvol-volume) the light is the volume's local
//! radiance SH instead of the scene's sky/sun; there is no path-traced reference for a baked
//! light, so `reference.png` is not written and the `rel_rmse` fields are `null`.

use lightvol_core::samples::{Samples, parse_samples, samples};

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use lightvol_proxies::compare::{CompareConfig, compare, render_variants};
use lightvol_proxies::light::VolumeLight;
use lightvol_proxies::receiver_scene::Scene;

struct Args {
    scene: Option<PathBuf>,
    volume: Option<PathBuf>,
    out: PathBuf,
    size: [usize; 2],
    samples: Samples,
    order: usize,
}

fn parse() -> anyhow::Result<Args> {
    let mut a = Args {
        scene: None,
        volume: None,
        out: PathBuf::from("proxies-out"),
        size: [320, 240],
        samples: samples(256),
        order: 4,
    };
    let mut it = std::env::args().skip(1);
    while let Some(x) = it.next() {
        let mut next = |what: &str| it.next().with_context(|| format!("{x} needs {what}"));
        match x.as_str() {
            "-o" | "--out" => a.out = PathBuf::from(next("a directory")?),
            "--volume" => a.volume = Some(PathBuf::from(next("a volume file")?)),
            "--size" => {
                a.size = [next("a width")?.parse()?, next("a height")?.parse()?];
            }
            "--samples" => a.samples = parse_samples(&next("a number")?).map_err(anyhow::Error::msg)?,
            "--order" => a.order = next("3 or 4")?.parse()?,
            "-h" | "--help" => {
                println!(
                    "usage: proxies [SCENE.json|default] [-o DIR] [--size W H] [--samples N] [--order 3|4]"
                );
                std::process::exit(0);
            }
            s if s.starts_with('-') => bail!("unknown option {s}"),
            s => a.scene = (s != "default").then(|| PathBuf::from(s)),
        }
    }
    if a.size[0] < 8 || a.size[1] < 8 || !a.size[0].is_multiple_of(2) || !a.size[1].is_multiple_of(2) {
        bail!("--size needs even dimensions of at least 8");
    }
    if a.order != 3 && a.order != 4 {
        bail!("--order must be 3 or 4");
    }
    Ok(a)
}

/// Writes `bytes` to `path` atomically (no half-written files).
fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    lightvol_core::fs::write_atomic(path, bytes).with_context(|| format!("writing {}", path.display()))
}

fn save_png(path: &Path, size: [usize; 2], img: &[[f32; 3]], exposure: f32) -> anyhow::Result<()> {
    let [w, h] = size;
    let mut bytes = Vec::with_capacity(w * h * 3);
    for px in img {
        bytes.extend(px.map(|v| lightvol_core::color::srgb8(v * exposure)));
    }
    let im = image::RgbImage::from_raw(w as u32, h as u32, bytes).context("image size")?;
    let mut png = std::io::Cursor::new(Vec::new());
    im.write_to(&mut png, image::ImageFormat::Png)?;
    write_atomic(path, png.get_ref())
}

fn main() -> anyhow::Result<()> {
    let args = parse()?;
    let scene = match &args.scene {
        Some(p) => {
            let text = std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            Scene::from_json(&text)?
        }
        None => Scene::default_scene(),
    };
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let tolerance = 1.0 / 256.0;
    let mut cfg = if args.order == 4 {
        CompareConfig::derived::<16>(args.size[0], args.size[1], tolerance)
    } else {
        CompareConfig::derived::<9>(args.size[0], args.size[1], tolerance)
    };
    cfg.samples = args.samples;
    if let Some(v) = &args.volume {
        return baked(&args, &scene, &cfg, v);
    }
    eprintln!(
        "rendering {}x{} (receivers at 1/{}), eta shadow {:.2}, indirect {:.2}",
        cfg.width, cfg.height, cfg.factor, cfg.eta_shadow, cfg.eta_indirect
    );
    let c = if args.order == 4 { compare::<16>(&scene, &cfg) } else { compare::<9>(&scene, &cfg) };

    // Exposure: the reference's 99th-percentile channel value maps to 0.9.
    let mut vals: Vec<f32> =
        c.reference.iter().zip(&c.mask).filter(|(_, m)| **m).map(|(p, _)| p[0].max(p[1]).max(p[2])).collect();
    vals.sort_by(f32::total_cmp);
    let p99 = vals.get(vals.len() * 99 / 100).copied().unwrap_or(1.0).max(1e-6);
    let exposure = 0.9 / p99;
    for (name, img) in [
        ("none", &c.none),
        ("shadows", &c.shadows),
        ("shadows_indirect", &c.shadows_indirect),
        ("reference", &c.reference),
    ] {
        save_png(&args.out.join(format!("{name}.png")), c.size, img, exposure)?;
    }
    let report = serde_json::json!({
        "variants": {
            "none": {"rel_rmse": c.errors.none},
            "shadows": {"rel_rmse": c.errors.shadows},
            "shadows_indirect": {"rel_rmse": c.errors.shadows_indirect},
        },
        "proxies": scene.proxies.len(),
        "receivers": c.receivers,
        "display": c.size,
        "order": args.order,
        "eta": {"shadow": cfg.eta_shadow, "indirect": cfg.eta_indirect, "tolerance": tolerance},
        "reference_samples": cfg.samples,
        "compared_pixels": c.mask.iter().filter(|m| **m).count(),
        "upsampling_fallbacks": c.fallbacks,
    });
    let path = args.out.join("report.json");
    write_atomic(&path, (serde_json::to_string_pretty(&report)? + "\n").as_bytes())?;
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}

/// The three variants under a baked volume's light (no reference).
fn baked(args: &Args, scene: &Scene, cfg: &CompareConfig, path: &Path) -> anyhow::Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let vol = match ext.as_str() {
        "exr" => lightvol_volume::io::exr::read_exr(path),
        "ktx2" => lightvol_volume::io::ktx2::read_ktx2(path),
        "dds" => lightvol_volume::io::dds::read_dds(path),
        _ => bail!("--volume: unknown extension {ext:?} (want exr, ktx2 or dds)"),
    }
    .with_context(|| format!("reading {}", path.display()))?;
    let light = VolumeLight(&vol);
    let v = if args.order == 4 {
        render_variants::<16>(scene, cfg, &light)
    } else {
        render_variants::<9>(scene, cfg, &light)
    };
    let mut vals: Vec<f32> = v.none.iter().map(|p| p[0].max(p[1]).max(p[2])).collect();
    vals.sort_by(f32::total_cmp);
    let exposure = 0.9 / vals.get(vals.len() * 99 / 100).copied().unwrap_or(1.0).max(1e-6);
    for (name, img) in [("none", &v.none), ("shadows", &v.shadows), ("shadows_indirect", &v.shadows_indirect)]
    {
        save_png(&args.out.join(format!("{name}.png")), v.size, &v.draw(img.clone()), exposure)?;
    }
    let report = serde_json::json!({
        "variants": {"none": {"rel_rmse": null}, "shadows": {"rel_rmse": null}, "shadows_indirect": {"rel_rmse": null}},
        "proxies": scene.proxies.len(),
        "receivers": v.receivers,
        "display": v.size,
        "order": args.order,
        "volume": path.display().to_string(),
        "eta": {"shadow": cfg.eta_shadow, "indirect": cfg.eta_indirect},
        "reference": null,
        "upsampling_fallbacks": v.fallbacks,
    });
    let out = args.out.join("report.json");
    write_atomic(&out, (serde_json::to_string_pretty(&report)? + "\n").as_bytes())?;
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}
