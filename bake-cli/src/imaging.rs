//! Image and plot files for people to look at: lightvol-view's `picture` encodes them,
//! these write them atomically, naming the path in errors.

use std::path::Path;

use anyhow::Context;
pub(crate) use lightvol_view::picture::{Plot, Rgb32, auto_exposure};
use lightvol_view::picture::{exr_linear_coverage, png_linear, png_rgb8};

/// Writes an 8-bit RGB PNG atomically (temporary file, then rename).
pub(crate) fn write_png_rgb8(path: &Path, width: usize, height: usize, rgb: &[u8]) -> anyhow::Result<()> {
    let bytes = png_rgb8(width, height, rgb).with_context(|| format!("encoding {}", path.display()))?;
    write_atomic(path, &bytes)
}

/// Tone-maps a linear image by `exposure` (value mapped to 1.0 = 1/exposure) and writes it.
pub(crate) fn write_png_linear(path: &Path, img: &Rgb32, exposure: f32) -> anyhow::Result<()> {
    let bytes = png_linear(img, exposure).with_context(|| format!("encoding {}", path.display()))?;
    write_atomic(path, &bytes)
}

/// Writes `img` by the output's extension: `.exr` linear HDR (with an alpha channel from
/// `coverage`, 1 on surfaces and 0 where rays miss, when given), else an sRGB PNG scaled by
/// `exposure`.
pub(crate) fn write_image(
    path: &Path,
    img: &Rgb32,
    coverage: Option<&[bool]>,
    exposure: f32,
) -> anyhow::Result<()> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        let bytes =
            exr_linear_coverage(img, coverage).with_context(|| format!("encoding {}", path.display()))?;
        write_atomic(path, &bytes)
    } else {
        write_png_linear(path, img, exposure)
    }
}

/// Writes `stem.svg` and `stem.png` of `plot`.
pub(crate) fn write_plot(plot: &Plot, stem: &Path) -> anyhow::Result<()> {
    for (path, bytes) in plot.files(stem).with_context(|| format!("encoding {}", stem.display()))? {
        write_atomic(&path, &bytes)?;
    }
    Ok(())
}

/// Writes bytes to `path` atomically (`lightvol_core::fs::write_atomic`: synced, renamed
/// into place, nothing left behind on error), naming the path in the error.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    lightvol_core::fs::write_atomic(path, bytes).with_context(|| format!("writing {}", path.display()))
}
