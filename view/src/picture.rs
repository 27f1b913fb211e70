//! # Pictures: images and plots for people to look at, encoded in memory
//!
//! [`Rgb32`] is a linear RGB float image. [`png_rgb8`], [`png_linear`] (tone-mapped by an
//! exposure, through the sRGB curve of `lightvol_core::color`) and [`exr_linear`] (linear
//! HDR, for other tools to compare numerically) encode images; [`auto_exposure`] picks an
//! exposure, [`diverging`] colours signed errors, and [`Plot`] draws line plots as SVG (with
//! text) and PNG (lines, markers and grid). Nothing here touches the file system: callers
//! write the bytes (atomically, with `lightvol_core::fs::write_atomic`).

/// An image or plot that could not be encoded.
#[derive(Debug, thiserror::Error)]
pub enum PictureError {
    /// PNG encoding failed.
    #[error("encoding a PNG: {0}")]
    Png(String),
    /// EXR encoding failed.
    #[error("encoding an EXR: {0}")]
    Exr(String),
}

/// An RGB float image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb32 {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Linear RGB, row-major.
    pub pixels: Vec<[f32; 3]>,
}

impl Rgb32 {
    /// A black image.
    pub fn new(width: usize, height: usize) -> Self {
        Self { width, height, pixels: vec![[0.0; 3]; width * height] }
    }

    /// Nearest-neighbour enlargement by an integer factor (for small plates).
    #[must_use]
    pub fn upscale(&self, k: usize) -> Self {
        let k = k.max(1);
        let mut out = Self::new(self.width * k, self.height * k);
        for y in 0..out.height {
            for x in 0..out.width {
                out.pixels[y * out.width + x] = self.pixels[(y / k) * self.width + x / k];
            }
        }
        out
    }

    /// Sets a pixel (ignored outside the image).
    pub fn set(&mut self, x: usize, y: usize, c: [f32; 3]) {
        if x < self.width && y < self.height {
            self.pixels[y * self.width + x] = c;
        }
    }
}

/// Equally sized images side by side (4 columns, 2-pixel black gaps), row by row: a contact
/// sheet. Empty for no images.
#[must_use]
pub fn sheet(images: &[&Rgb32]) -> Rgb32 {
    const COLS: usize = 4;
    const GAP: usize = 2;
    let Some(first) = images.first() else { return Rgb32::new(0, 0) };
    let (w, h) = (first.width, first.height);
    let cols = COLS.min(images.len());
    let rows = images.len().div_ceil(COLS);
    let mut out = Rgb32::new(cols * w + (cols - 1) * GAP, rows * h + (rows - 1) * GAP);
    for (k, img) in images.iter().enumerate() {
        let (ox, oy) = ((k % COLS) * (w + GAP), (k / COLS) * (h + GAP));
        for y in 0..h {
            for x in 0..w {
                out.set(ox + x, oy + y, img.pixels[y * w + x]);
            }
        }
    }
    out
}

impl From<crate::ViewImage> for Rgb32 {
    /// A view's pixels (row 0 at the top), without its surface mask.
    fn from(img: crate::ViewImage) -> Self {
        Self { width: img.width as usize, height: img.height as usize, pixels: img.pixels }
    }
}

/// An 8-bit RGB PNG of `width × height` pixels `rgb` (row-major, row 0 at the top).
///
/// # Errors
/// [`PictureError::Png`].
pub fn png_rgb8(width: usize, height: usize, rgb: &[u8]) -> Result<Vec<u8>, PictureError> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    image::write_buffer_with_format(
        &mut bytes,
        rgb,
        width as u32,
        height as u32,
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|e| PictureError::Png(e.to_string()))?;
    Ok(bytes.into_inner())
}

/// `img` tone-mapped by `exposure` (the value mapped to 1.0 is 1/exposure), through the
/// sRGB curve, as an 8-bit PNG.
///
/// # Errors
/// [`PictureError::Png`].
pub fn png_linear(img: &Rgb32, exposure: f32) -> Result<Vec<u8>, PictureError> {
    let bytes: Vec<u8> =
        img.pixels.iter().flat_map(|p| p.map(|v| lightvol_core::color::srgb8(v * exposure))).collect();
    png_rgb8(img.width, img.height, &bytes)
}

/// `img` as a linear HDR OpenEXR (channels R, G, B, f32, row 0 at the top), with no
/// exposure applied, byte-reproducible (attributes in a fixed order).
///
/// # Errors
/// [`PictureError::Exr`].
pub fn exr_linear(img: &Rgb32) -> Result<Vec<u8>, PictureError> {
    exr_linear_coverage(img, None)
}

/// [`exr_linear`] with an alpha channel `A` when `coverage` is given: 1 where a pixel sees
/// a surface, 0 where its ray leaves the scene, so that a miss and a black surface can be
/// told apart. `coverage` has one entry per pixel, row-major.
///
/// # Errors
/// The encoder's (or a coverage of the wrong length).
pub fn exr_linear_coverage(img: &Rgb32, coverage: Option<&[bool]>) -> Result<Vec<u8>, PictureError> {
    use exr::prelude::*;
    let (w, h) = (img.width, img.height);
    let channel = |c: usize| -> Vec<f32> { img.pixels.iter().map(|p| p[c]).collect() };
    let mut channels = vec![
        AnyChannel::new("R", FlatSamples::F32(channel(0))),
        AnyChannel::new("G", FlatSamples::F32(channel(1))),
        AnyChannel::new("B", FlatSamples::F32(channel(2))),
    ];
    if let Some(cov) = coverage {
        if cov.len() != img.pixels.len() {
            return Err(PictureError::Exr(format!(
                "{} coverage values for {} pixels",
                cov.len(),
                img.pixels.len()
            )));
        }
        channels.push(AnyChannel::new(
            "A",
            FlatSamples::F32(cov.iter().map(|&c| f32::from(u8::from(c))).collect()),
        ));
    }
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let ia = ImageAttributes::new(layer.absolute_bounds());
    lightvol_volume::io::exr::encode_image(ia, vec![layer]).map_err(|e| PictureError::Exr(e.to_string()))
}

/// Display value of a view's mean pixel under [`auto_exposure`]: a mid-grey, leaving
/// headroom above it for the lit surfaces and the sky.
pub const AUTO_EXPOSURE_MEAN: f64 = 0.35;

/// The exposure that maps the mean pixel (mean of R, G and B over all pixels) to
/// [`AUTO_EXPOSURE_MEAN`]; 1 for a black image.
#[must_use]
pub fn auto_exposure(img: &Rgb32) -> f32 {
    auto_exposure_of(&img.pixels)
}

/// The exposure that maps the mean of R, G and B over `pixels` (a view's, or those of it
/// that matter) to [`AUTO_EXPOSURE_MEAN`]; 1 when they are black or none.
#[must_use]
pub fn auto_exposure_of<'a>(pixels: impl IntoIterator<Item = &'a [f32; 3]>) -> f32 {
    let mut n = 0usize;
    let sum: f64 = pixels
        .into_iter()
        .map(|p| {
            n += 1;
            f64::from(p[0] + p[1] + p[2]) / 3.0
        })
        .sum();
    let mean = sum / n as f64;
    if mean > 0.0 { (AUTO_EXPOSURE_MEAN / mean) as f32 } else { 1.0 }
}

/// Blue (negative) - white (0) - red (positive) colour for a signed value in [-1, 1].
pub fn diverging(t: f32) -> [f32; 3] {
    let t = t.clamp(-1.0, 1.0);
    if t < 0.0 { [1.0 + t, 1.0 + t, 1.0] } else { [1.0, 1.0 - t, 1.0 - t] }
}

/// A line plot: named series of (x, y) points.
#[derive(Clone, Debug, PartialEq)]
pub struct Plot {
    /// Title above the plot.
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
    /// Named series of (x, y) points.
    pub series: Vec<(String, Vec<(f64, f64)>)>,
}

const COLORS: [[u8; 3]; 6] =
    [[214, 39, 40], [31, 119, 180], [44, 160, 44], [255, 127, 14], [148, 103, 189], [23, 190, 207]];

impl Plot {
    fn ranges(&self) -> (f64, f64, f64, f64) {
        let pts = self.series.iter().flat_map(|s| s.1.iter());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64, f64::NEG_INFINITY);
        for &(x, y) in pts {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if !(x1 > x0) {
            x1 = x0 + 1.0;
        }
        if !(y1 > y0) {
            y1 = y0 + 1.0;
        }
        (x0, x1, y0, y1 * 1.05)
    }

    /// SVG with axes, ticks, labels and a legend.
    pub fn to_svg(&self) -> String {
        let (w, h, ml, mr, mt, mb) = (640.0, 420.0, 70.0, 150.0, 40.0, 55.0);
        let (x0, x1, y0, y1) = self.ranges();
        let sx = |x: f64| ml + (x - x0) / (x1 - x0) * (w - ml - mr);
        let sy = |y: f64| h - mb - (y - y0) / (y1 - y0) * (h - mt - mb);
        let mut s = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
        );
        s += &format!(
            "<text x=\"{}\" y=\"22\" text-anchor=\"middle\" font-size=\"15\">{}</text>\n",
            w / 2.0,
            esc(&self.title)
        );
        for i in 0..=5 {
            let yv = y0 + (y1 - y0) * f64::from(i) / 5.0;
            let xv = x0 + (x1 - x0) * f64::from(i) / 5.0;
            s += &format!(
                "<line x1=\"{ml}\" x2=\"{}\" y1=\"{:.1}\" y2=\"{:.1}\" stroke=\"#ddd\"/>\n",
                w - mr,
                sy(yv),
                sy(yv)
            );
            s += &format!(
                "<text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{:.3}</text>\n",
                ml - 6.0,
                sy(yv) + 4.0,
                yv
            );
            s += &format!(
                "<text x=\"{:.1}\" y=\"{}\" text-anchor=\"middle\">{:.0}</text>\n",
                sx(xv),
                h - mb + 18.0,
                xv
            );
        }
        s += &format!(
            "<rect x=\"{ml}\" y=\"{mt}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"black\"/>\n",
            w - ml - mr,
            h - mt - mb
        );
        s += &format!(
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
            (ml + w - mr) / 2.0,
            h - 12.0,
            esc(&self.x_label)
        );
        s += &format!(
            "<text x=\"16\" y=\"{}\" text-anchor=\"middle\" transform=\"rotate(-90 16 {})\">{}</text>\n",
            (mt + h - mb) / 2.0,
            (mt + h - mb) / 2.0,
            esc(&self.y_label)
        );
        for (k, (name, pts)) in self.series.iter().enumerate() {
            let c = COLORS[k % COLORS.len()];
            let col = format!("rgb({},{},{})", c[0], c[1], c[2]);
            let path: Vec<String> = pts.iter().map(|&(x, y)| format!("{:.1},{:.1}", sx(x), sy(y))).collect();
            s += &format!(
                "<polyline fill=\"none\" stroke=\"{col}\" stroke-width=\"2\" points=\"{}\"/>\n",
                path.join(" ")
            );
            for &(x, y) in pts {
                s += &format!("<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3.5\" fill=\"{col}\"/>\n", sx(x), sy(y));
            }
            let ly = mt + 20.0 + 22.0 * k as f64;
            s += &format!(
                "<line x1=\"{}\" x2=\"{}\" y1=\"{ly}\" y2=\"{ly}\" stroke=\"{col}\" stroke-width=\"3\"/>\n",
                w - mr + 12.0,
                w - mr + 36.0
            );
            s += &format!("<text x=\"{}\" y=\"{}\">{}</text>\n", w - mr + 42.0, ly + 4.0, esc(name));
        }
        s += "</svg>\n";
        s
    }

    /// PNG rendering of the same plot: grid, frame, series lines and markers, legend swatches
    /// (no text: the SVG carries the labels).
    pub fn to_png_rgb8(&self) -> (usize, usize, Vec<u8>) {
        let (w, h, ml, mr, mt, mb) = (640usize, 420usize, 70.0, 150.0, 40.0, 55.0);
        let (x0, x1, y0, y1) = self.ranges();
        let (wf, hf) = (w as f64, h as f64);
        let sx = |x: f64| ml + (x - x0) / (x1 - x0) * (wf - ml - mr);
        let sy = |y: f64| hf - mb - (y - y0) / (y1 - y0) * (hf - mt - mb);
        let mut px = vec![255u8; w * h * 3];
        let mut put = |x: i64, y: i64, c: [u8; 3]| {
            if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                let i = (y as usize * w + x as usize) * 3;
                px[i..i + 3].copy_from_slice(&c);
            }
        };
        let line =
            |a: (f64, f64), b: (f64, f64), c: [u8; 3], thick: i64, put: &mut dyn FnMut(i64, i64, [u8; 3])| {
                let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()) as usize).max(1);
                for i in 0..=n {
                    let t = i as f64 / n as f64;
                    let (x, y) = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
                    for dx in -thick..=thick {
                        for dy in -thick..=thick {
                            put(x.round() as i64 + dx, y.round() as i64 + dy, c);
                        }
                    }
                }
            };
        for i in 0..=5 {
            let yv = sy(y0 + (y1 - y0) * f64::from(i) / 5.0);
            line((ml, yv), (wf - mr, yv), [221, 221, 221], 0, &mut put);
        }
        let frame = [(ml, mt), (wf - mr, mt), (wf - mr, hf - mb), (ml, hf - mb), (ml, mt)];
        for p in frame.windows(2) {
            line(p[0], p[1], [0, 0, 0], 0, &mut put);
        }
        for (k, (_, pts)) in self.series.iter().enumerate() {
            let c = COLORS[k % COLORS.len()];
            for p in pts.windows(2) {
                line((sx(p[0].0), sy(p[0].1)), (sx(p[1].0), sy(p[1].1)), c, 1, &mut put);
            }
            for &(x, y) in pts {
                line((sx(x), sy(y)), (sx(x), sy(y)), c, 3, &mut put);
            }
            let ly = mt + 20.0 + 22.0 * k as f64;
            line((wf - mr + 12.0, ly), (wf - mr + 36.0, ly), c, 1, &mut put);
        }
        (w, h, px)
    }

    /// The plot as `(stem.svg, SVG bytes)` and `(stem.png, PNG bytes)`.
    ///
    /// # Errors
    /// [`PictureError::Png`].
    pub fn files(&self, stem: &std::path::Path) -> Result<[(std::path::PathBuf, Vec<u8>); 2], PictureError> {
        let (w, h, px) = self.to_png_rgb8();
        Ok([
            (stem.with_extension("svg"), self.to_svg().into_bytes()),
            (stem.with_extension("png"), png_rgb8(w, h, &px)?),
        ])
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_exposure_maps_the_mean_to_mid_grey() {
        let mut img = Rgb32::new(2, 1);
        img.set(0, 0, [0.2, 0.2, 0.2]);
        img.set(1, 0, [0.6, 0.6, 0.6]);
        // Mean 0.4: exposure 0.35 / 0.4.
        assert!((f64::from(auto_exposure(&img)) - AUTO_EXPOSURE_MEAN / 0.4).abs() < 1e-6);
        assert_eq!(auto_exposure(&Rgb32::new(3, 3)), 1.0, "a black image keeps exposure 1");
        // Some of the pixels: the bright one alone, mean 0.6.
        let bright = auto_exposure_of(img.pixels.iter().filter(|p| p[0] > 0.5));
        assert!((f64::from(bright) - AUTO_EXPOSURE_MEAN / 0.6).abs() < 1e-6);
        assert_eq!(auto_exposure_of(&img.pixels), auto_exposure(&img));
        assert_eq!(auto_exposure_of(&[]), 1.0, "no pixels keep exposure 1");
    }

    #[test]
    fn diverging_runs_blue_white_red() {
        assert_eq!(diverging(-1.0), [0.0, 0.0, 1.0]);
        assert_eq!(diverging(0.0), [1.0, 1.0, 1.0]);
        assert_eq!(diverging(1.0), [1.0, 0.0, 0.0]);
        assert_eq!(diverging(7.0), diverging(1.0), "clamped");
    }

    #[test]
    fn pngs_decode_to_what_was_encoded() {
        let mut img = Rgb32::new(3, 2);
        img.set(2, 1, [1.0, 0.5, 0.0]);
        let bytes = png_linear(&img, 1.0).unwrap();
        let back = image::load_from_memory(&bytes).unwrap().to_rgb8();
        assert_eq!(back.dimensions(), (3, 2));
        assert_eq!(back.get_pixel(2, 1).0, [255, lightvol_core::color::srgb8(0.5), 0]);
        assert_eq!(back.get_pixel(0, 0).0, [0, 0, 0]);
    }

    #[test]
    fn sheets_tile_four_per_row() {
        let mut a = Rgb32::new(2, 2);
        a.set(1, 1, [1.0; 3]);
        let s = sheet(&[&a; 5]);
        assert_eq!((s.width, s.height), (4 * 2 + 3 * 2, 2 * 2 + 2));
        // The fifth image starts the second row, below the 2-pixel gap.
        assert_eq!(s.pixels[(4 + 1) * s.width + 1], [1.0; 3]);
        assert_eq!(s.pixels[2 * s.width + 2], [0.0; 3], "gaps are black");
    }

    #[test]
    fn upscale_repeats_pixels() {
        let mut img = Rgb32::new(2, 1);
        img.set(1, 0, [1.0; 3]);
        let big = img.upscale(2);
        assert_eq!((big.width, big.height), (4, 2));
        assert_eq!(big.pixels[3], [1.0; 3]);
        assert_eq!(big.pixels[4 + 1], [0.0; 3]);
    }
}
