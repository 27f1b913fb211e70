//! Visual comparison like [Ish11] Fig. 3.3 / 3.4: every compiled-in basis's reconstruction
//! of the irradiance of an HDR sky with a grazing sun, as hemisphere disk PNGs plus a contact
//! sheet.
//!
//! ```text
//! cargo run --release -p lightvol-hemibasis --example visual -- OUT_DIR [--size N] [--equal-area] [--direct] [--exposure X]
//! ```
//!
//! Writes `OUT_DIR/reference.png`, one `OUT_DIR/<tag>.png` per basis (`sh9.png`, `hsh4.png`,
//! …) and `OUT_DIR/contact_sheet.png` (reference first, then Table 3.1's order, 5 per row),
//! and prints each basis's RMS irradiance error. Exposure defaults to mapping the reference's
//! brightest value to 0.95. By default bases are converted from the
//! 9-coefficient SH irradiance as in the thesis's pipeline; `--direct` fits each basis to the
//! reference irradiance instead.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use lightvol_hemibasis::render::{DiskProjection, Image, Sky, contact_sheet, visual_comparison};

struct Args {
    out: PathBuf,
    size: usize,
    proj: DiskProjection,
    thesis_pipeline: bool,
    /// `None`: scale so the reference's brightest channel maps to 0.95.
    exposure: Option<f32>,
}

fn parse() -> Result<Args, String> {
    let mut out = None;
    let mut a = Args {
        out: PathBuf::new(),
        size: 256,
        proj: DiskProjection::Orthographic,
        thesis_pipeline: true,
        exposure: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        match arg.as_str() {
            "--size" => {
                a.size =
                    it.next().ok_or("--size needs a value")?.parse().map_err(|e| format!("--size: {e}"))?;
            }
            "--exposure" => {
                a.exposure = Some(
                    it.next()
                        .ok_or("--exposure needs a value")?
                        .parse()
                        .map_err(|e| format!("--exposure: {e}"))?,
                );
            }
            "--equal-area" => a.proj = DiskProjection::EqualArea,
            "--direct" => a.thesis_pipeline = false,
            "-h" | "--help" => {
                return Err(
                    "usage: visual OUT_DIR [--size N] [--equal-area] [--direct] [--exposure X]".into()
                );
            }
            s if s.starts_with("--") => return Err(format!("unknown option {s:?} (try --help)")),
            s => out = Some(PathBuf::from(s)),
        }
    }
    a.out = out.ok_or("missing OUT_DIR (try --help)")?;
    if !(8..=4096).contains(&a.size) {
        return Err("--size must be in 8..=4096".into());
    }
    Ok(a)
}

/// Writes a PNG atomically (no half-written files).
fn write_png(path: &Path, img: &Image, exposure: f32) -> Result<(), String> {
    let bytes = img.to_srgb8(exposure);
    let buf = image::RgbImage::from_raw(img.width as u32, img.height as u32, bytes)
        .ok_or_else(|| format!("{}: image buffer size mismatch", path.display()))?;
    let mut png = std::io::Cursor::new(Vec::new());
    buf.write_to(&mut png, image::ImageFormat::Png)
        .map_err(|e| format!("encoding {}: {e}", path.display()))?;
    lightvol_core::fs::write_atomic(path, png.get_ref())
        .map_err(|e| format!("writing {}: {e}", path.display()))
}

fn run(a: &Args) -> Result<(), String> {
    std::fs::create_dir_all(&a.out).map_err(|e| format!("creating {}: {e}", a.out.display()))?;
    let panels = visual_comparison(&Sky::grazing_sun(), a.size, a.proj, a.thesis_pipeline);
    let peak = panels[0].image.pixels.iter().flat_map(|p| *p).fold(0.0f32, f32::max);
    let exposure = a.exposure.unwrap_or(if peak > 0.0 { 0.95 / peak } else { 1.0 });
    for p in &panels {
        write_png(&a.out.join(format!("{}.png", p.name)), &p.image, exposure)?;
        println!("{:<14} rms irradiance error {:.5}", p.name, p.rms_error);
    }
    let images: Vec<&Image> = panels.iter().map(|p| &p.image).collect();
    write_png(&a.out.join("contact_sheet.png"), &contact_sheet(&images, 5, 8), exposure)?;
    println!("wrote {} panels and contact_sheet.png to {}", panels.len(), a.out.display());
    Ok(())
}

fn main() -> ExitCode {
    match parse().and_then(|a| run(&a)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
