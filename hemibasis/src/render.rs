//! Visual comparison like \[Ish11\] Fig. 3.3 / 3.4: each basis's reconstruction of the
//! irradiance of an HDR sky with the sun at a grazing angle, drawn as hemisphere disk images.
//!
//! - [`Sky`]: an analytic sky (linear zenith-to-horizon gradient, constant ground, and a
//!   smooth sun lobe `I exp(k (cos γ - 1))`), projected to SH exactly: the gradient and the
//!   ground by Gauss-Legendre rules on each hemisphere (each part is a polynomial there), the
//!   sun lobe as a zonal function (`f_lm = 2π ∫ f(t) P_l(t) dt · y_lm(s)`, Funk-Hecke) with a
//!   Gauss-Legendre rule concentrated where the lobe lives.
//! - The reference irradiance is its clamped-cosine convolution with [`REFERENCE_BANDS`]
//!   bands (the factors fall like `l^-2.5`, the sky coefficients at least like `l^-1`).
//! - [`visual_comparison`] fits every compiled-in basis of Table 3.1 and draws disks with
//!   [`render_disk`] ([`DiskProjection::Orthographic`] or [`DiskProjection::EqualArea`]);
//!   [`contact_sheet`] tiles them. Writing PNGs is left to the caller (see
//!   `examples/visual.rs`), so the library needs no image crate.

use std::f64::consts::PI;

use lightvol_sh::eval::eval_into;
use lightvol_sh::irradiance::normalized_cosine_lobe_factor;
use lightvol_sh::quadrature::{SphereQuadrature, gauss_legendre};

use crate::basis::HemiBasis;
use crate::imse::table_bases;
use crate::quad::HemiRule;
use crate::sh_basis::ShBasis;

/// SH bands of the reference irradiance.
pub const REFERENCE_BANDS: usize = 16;

/// An analytic HDR sky in the tangent space of an upward-facing surface (`z` up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sky {
    /// Unit direction towards the sun.
    pub sun_dir: [f64; 3],
    /// Peak radiance of the sun lobe.
    pub sun_radiance: [f64; 3],
    /// Lobe sharpness `k` (angular radius about `1/sqrt(k)` radians).
    pub sun_sharpness: f64,
    /// Sky radiance at the zenith.
    pub zenith: [f64; 3],
    /// Sky radiance at the horizon.
    pub horizon: [f64; 3],
    /// Radiance from below the horizon.
    pub ground: [f64; 3],
}

impl Sky {
    /// A clear sky with the sun 5° above the horizon (the worst case of \[Ish11\] §3.2).
    #[must_use]
    pub fn grazing_sun() -> Self {
        let (elev, azim) = (5f64.to_radians(), 30f64.to_radians());
        Self {
            sun_dir: [elev.cos() * azim.cos(), elev.cos() * azim.sin(), elev.sin()],
            sun_radiance: [3000.0, 2600.0, 2000.0],
            sun_sharpness: 600.0,
            zenith: [0.10, 0.20, 0.45],
            horizon: [0.35, 0.40, 0.45],
            ground: [0.08, 0.07, 0.05],
        }
    }

    /// Radiance arriving from direction `dir`.
    #[must_use]
    pub fn radiance(&self, dir: [f64; 3]) -> [f64; 3] {
        let sky = self.sky_part(dir);
        let c = dir[0] * self.sun_dir[0] + dir[1] * self.sun_dir[1] + dir[2] * self.sun_dir[2];
        let lobe = (self.sun_sharpness * (c - 1.0)).exp();
        [0, 1, 2].map(|i| sky[i] + self.sun_radiance[i] * lobe)
    }

    fn sky_part(&self, dir: [f64; 3]) -> [f64; 3] {
        if dir[2] >= 0.0 {
            [0, 1, 2].map(|i| self.horizon[i] + (self.zenith[i] - self.horizon[i]) * dir[2])
        } else {
            self.ground
        }
    }

    /// Radiance SH coefficients (coefficient-major RGB) with `bands` bands.
    #[must_use]
    pub fn radiance_sh(&self, bands: usize) -> Vec<[f64; 3]> {
        let n = bands * bands;
        let mut out = vec![[0.0; 3]; n];
        let mut y = vec![0.0; n];
        // Sky and ground: polynomial on each hemisphere; the lower rule mirrors the upper.
        let upper = SphereQuadrature::hemisphere(bands + 2, 2 * bands + 2);
        for node in upper.nodes() {
            for dir in [node.dir, [node.dir[0], node.dir[1], -node.dir[2]]] {
                let l = self.sky_part(dir);
                eval_into(bands, dir, &mut y);
                for (o, yj) in out.iter_mut().zip(&y) {
                    for ch in 0..3 {
                        o[ch] += node.weight * l[ch] * yj;
                    }
                }
            }
        }
        // Sun lobe: zonal, f_lm = 2π ∫ f(t) P_l(t) dt · y_lm(s). The lobe is e^{-k(1-t)}:
        // integrate [1 - 60/k, 1] (where it is above e^-60) with 64 Gauss-Legendre nodes.
        let (x, w) = gauss_legendre(64);
        let lo = (1.0 - 60.0 / self.sun_sharpness).max(-1.0);
        let half = 0.5 * (1.0 - lo);
        let mut g = vec![0.0; bands];
        for (xi, wi) in x.iter().zip(&w) {
            let t = lo + half * (xi + 1.0);
            let f = (self.sun_sharpness * (t - 1.0)).exp();
            for (l, gl) in g.iter_mut().enumerate() {
                *gl += 2.0 * PI * half * wi * f * lightvol_sh::reference::legendre_p(l as u32, 0, t);
            }
        }
        eval_into(bands, self.sun_dir, &mut y);
        for (j, o) in out.iter_mut().enumerate() {
            let gl = g[j.isqrt()];
            for ch in 0..3 {
                o[ch] += self.sun_radiance[ch] * gl * y[j];
            }
        }
        out
    }

    /// Irradiance SH coefficients (normalised clamped cosine, i.e. exit radiance of a white
    /// diffuse surface) with `bands` bands.
    #[must_use]
    pub fn irradiance_sh(&self, bands: usize) -> Vec<[f64; 3]> {
        let mut e = self.radiance_sh(bands);
        for (j, c) in e.iter_mut().enumerate() {
            let a = normalized_cosine_lobe_factor(j.isqrt() as u32);
            *c = c.map(|v| v * a);
        }
        e
    }
}

/// How the hemisphere is flattened to a disk (unit radius, pole at the centre).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DiskProjection {
    /// Orthographic view from above: `(x, y)` of the normal.
    #[default]
    Orthographic,
    /// Lambert azimuthal equal-area: disk radius `ρ = sqrt(1 - z)`.
    EqualArea,
}

impl DiskProjection {
    /// The normal shown at disk coordinates `(u, v)` (`v` up), or `None` outside the disk.
    #[must_use]
    pub fn direction(self, u: f64, v: f64) -> Option<[f64; 3]> {
        let r2 = u * u + v * v;
        if r2 > 1.0 {
            return None;
        }
        Some(match self {
            Self::Orthographic => [u, v, (1.0 - r2).max(0.0).sqrt()],
            Self::EqualArea => {
                let s = (2.0 - r2).sqrt();
                [u * s, v * s, 1.0 - r2]
            }
        })
    }
}

/// A linear RGB image.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major linear RGB, top row first.
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    /// An image filled with `color`.
    #[must_use]
    pub fn filled(width: usize, height: usize, color: [f32; 3]) -> Self {
        Self { width, height, pixels: vec![color; width * height] }
    }

    /// 8-bit sRGB bytes (RGB, row-major) after scaling by `exposure` and clamping to `[0, 1]`.
    #[must_use]
    pub fn to_srgb8(&self, exposure: f32) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| p.map(|c| lightvol_core::color::srgb8(c * exposure))).collect()
    }
}

/// Background colour outside the disk.
const BACKGROUND: [f32; 3] = [0.02, 0.02, 0.02];

/// Draws `f(normal)` on a `size × size` disk.
#[must_use]
pub fn render_disk(size: usize, proj: DiskProjection, f: &dyn Fn([f64; 3]) -> [f64; 3]) -> Image {
    let mut img = Image::filled(size, size, BACKGROUND);
    for py in 0..size {
        for px in 0..size {
            let u = 2.0 * (px as f64 + 0.5) / size as f64 - 1.0;
            let v = 1.0 - 2.0 * (py as f64 + 0.5) / size as f64;
            if let Some(n) = proj.direction(u, v) {
                img.pixels[py * size + px] = f(n).map(|c| c as f32);
            }
        }
    }
    img
}

/// Tiles equally sized images into a grid with `cols` columns and `gap` pixels between them.
///
/// # Panics
/// If `images` is empty, `cols == 0`, or the sizes differ.
#[must_use]
pub fn contact_sheet(images: &[&Image], cols: usize, gap: usize) -> Image {
    assert!(!images.is_empty() && cols > 0, "contact sheet needs images and columns");
    let (w, h) = (images[0].width, images[0].height);
    assert!(images.iter().all(|i| i.width == w && i.height == h), "contact sheet images differ in size");
    let rows = images.len().div_ceil(cols);
    let cols = cols.min(images.len());
    let (sw, sh) = (cols * w + (cols + 1) * gap, rows * h + (rows + 1) * gap);
    let mut sheet = Image::filled(sw, sh, [0.0; 3]);
    for (k, img) in images.iter().enumerate() {
        let (ox, oy) = (gap + (k % cols) * (w + gap), gap + (k / cols) * (h + gap));
        for y in 0..h {
            let dst = (oy + y) * sw + ox;
            sheet.pixels[dst..dst + w].copy_from_slice(&img.pixels[y * w..(y + 1) * w]);
        }
    }
    sheet
}

/// One panel of the comparison.
#[derive(Clone, Debug)]
pub struct Panel {
    /// `"reference"` or the basis tag (`"hsh9"`).
    pub name: String,
    /// The disk image.
    pub image: Image,
    /// RMS irradiance error against the reference over the hemisphere (mean of the three
    /// channels' `sqrt(∫_H (fit - E)² dω / 2π)`); 0 for the reference.
    pub rms_error: f64,
}

/// Renders the reference irradiance of `sky` and every compiled-in basis of Table 3.1.
///
/// With `thesis_pipeline` the bases are converted from the 9-coefficient SH irradiance, as in
/// \[Ish11\] Listing 2.1; otherwise each is the least-squares fit of the reference irradiance
/// (the best the basis can do).
#[must_use]
pub fn visual_comparison(sky: &Sky, size: usize, proj: DiskProjection, thesis_pipeline: bool) -> Vec<Panel> {
    let e_ref = sky.irradiance_sh(REFERENCE_BANDS);
    let reference = ShBasis::new(REFERENCE_BANDS);
    let source: Vec<[f64; 3]> = if thesis_pipeline { e_ref[..9].to_vec() } else { e_ref.clone() };
    let rule = HemiRule::for_orders(REFERENCE_BANDS, REFERENCE_BANDS);
    let mut panels = vec![Panel {
        name: "reference".into(),
        image: render_disk(size, proj, &|n| reference.reconstruct_rgb_f64(&e_ref, n)),
        rms_error: 0.0,
    }];
    for b in table_bases() {
        let c = b.convert_sh_irradiance_rgb(&source);
        let mut err = [0.0; 3];
        for node in rule.nodes() {
            let (f, e) =
                (b.reconstruct_rgb_f64(&c, node.dir), reference.reconstruct_rgb_f64(&e_ref, node.dir));
            for ch in 0..3 {
                err[ch] += node.weight * (f[ch] - e[ch]) * (f[ch] - e[ch]);
            }
        }
        let rms_error = err.iter().map(|e| (e / (2.0 * PI)).sqrt()).sum::<f64>() / 3.0;
        let image = render_disk(size, proj, &|n| b.reconstruct_rgb_f64(&c, n));
        panels.push(Panel { name: b.tag(), image, rms_error });
    }
    panels
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact-rule SH projection vs. brute-force quadrature of a smooth lobe: the brute-force
    /// rule (400 × 800 nodes on a lobe of radius ~2°) converges to ~1e-6 relative.
    const SUN_TOL: f64 = 1e-5;

    #[test]
    fn sun_projection_matches_brute_force() {
        let sky = Sky { zenith: [0.0; 3], horizon: [0.0; 3], ground: [0.0; 3], ..Sky::grazing_sun() };
        let sh = sky.radiance_sh(4);
        let q = SphereQuadrature::sphere(400, 800);
        let mut y = vec![0.0; 16];
        let mut brute = [0.0; 16];
        for node in q.nodes() {
            let l = sky.radiance(node.dir)[0];
            eval_into(4, node.dir, &mut y);
            for j in 0..16 {
                brute[j] += node.weight * l * y[j];
            }
        }
        let scale = brute[0].abs();
        for j in 0..16 {
            assert!((sh[j][0] - brute[j]).abs() < SUN_TOL * scale, "j={j}: {} vs {}", sh[j][0], brute[j]);
        }
    }

    #[test]
    fn disk_projections_are_unit_and_upper() {
        for proj in [DiskProjection::Orthographic, DiskProjection::EqualArea] {
            for &(u, v) in &[(0.0, 0.0), (0.3, -0.4), (0.99, 0.0), (-0.5, 0.5)] {
                let d = proj.direction(u, v).unwrap();
                assert!(((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) - 1.0).abs() < 1e-12);
                assert!(d[2] >= 0.0);
            }
            assert!(proj.direction(0.8, 0.8).is_none());
        }
        assert_eq!(DiskProjection::EqualArea.direction(0.0, 0.0), Some([0.0, 0.0, 1.0]));
    }

    #[test]
    fn contact_sheet_places_tiles() {
        let a = Image::filled(2, 2, [1.0, 0.0, 0.0]);
        let b = Image::filled(2, 2, [0.0, 1.0, 0.0]);
        let s = contact_sheet(&[&a, &b, &a], 2, 1);
        assert_eq!((s.width, s.height), (7, 7));
        assert_eq!(s.pixels[7 + 1], [1.0, 0.0, 0.0]);
        assert_eq!(s.pixels[7 + 4], [0.0, 1.0, 0.0]);
        assert_eq!(s.pixels[4 * 7 + 1], [1.0, 0.0, 0.0]);
        assert_eq!(s.pixels[0], [0.0; 3]);
    }

    #[test]
    fn sh9_panel_error_is_below_hl2_error() {
        let panels = visual_comparison(&Sky::grazing_sun(), 8, DiskProjection::Orthographic, false);
        assert_eq!(panels[0].name, "reference");
        let err = |name: &str| panels.iter().find(|p| p.name == name).map(|p| p.rms_error);
        let sh9 = err("sh9").unwrap();
        if let Some(hl2) = err("hl23") {
            assert!(sh9 < hl2, "sh9 {sh9} vs hl2 {hl2}");
        }
        assert!(sh9 > 0.0);
    }
}
