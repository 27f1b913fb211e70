//! Coefficient maps: a texture of basis coefficients, its 8-bit planes (\[Ish11\] §2.2.3)
//! and the irradiance error that storing it costs.
//!
//! A [`CoeffMap`] holds `width × height` texels of `K` RGB coefficients, texel-major
//! (`data[(y·width + x)·K + j]`). [`Encoding::encode_map`] turns it into `K` [`Plane`]s, one
//! RGBA8 texture per coefficient as in \[Ish11\] Listing 2.2 (`h1 … h6`; alpha is 255), which
//! [`crate::bc`] can block-compress; [`Encoding::decode_map`] reads them back. [`map_error`]
//! measures any round trip in irradiance: per texel the exact hemispherical RMS
//! `sqrt(Δcᵀ G Δc / 2π)` (as [`crate::encode::encoding_error`]), aggregated over texels and
//! channels, absolute and relative to the map's own RMS irradiance.
//!
//! [`sky_test_map`] makes a realistic map for measuring those errors: the analytic sky of
//! [`crate::render`] with the sun sweeping azimuth and elevation across the map and a
//! hard-edged shadow.

use std::f64::consts::PI;

use crate::HemiBasis;
use crate::encode::{ClampStats, Encoding};
use crate::render::Sky;

/// A map of RGB basis coefficients, texel-major.
#[derive(Clone, Debug, PartialEq)]
pub struct CoeffMap {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Coefficients per texel (the basis size `K`).
    pub len: usize,
    /// `width · height · len` RGB coefficients, `data[(y·width + x)·len + j]`.
    pub data: Vec<[f32; 3]>,
}

impl CoeffMap {
    /// A zero map.
    #[must_use]
    pub fn zeros(width: usize, height: usize, len: usize) -> Self {
        Self { width, height, len, data: vec![[0.0; 3]; width * height * len] }
    }

    /// The coefficients of texel `(x, y)`.
    #[must_use]
    #[inline]
    pub fn texel(&self, x: usize, y: usize) -> &[[f32; 3]] {
        let i = (y * self.width + x) * self.len;
        &self.data[i..i + self.len]
    }

    /// The coefficients of texel `(x, y)`, mutable.
    #[inline]
    pub fn texel_mut(&mut self, x: usize, y: usize) -> &mut [[f32; 3]] {
        let i = (y * self.width + x) * self.len;
        &mut self.data[i..i + self.len]
    }

    /// Number of texels.
    #[must_use]
    pub fn texels(&self) -> usize {
        self.width * self.height
    }
}

/// One 8-bit RGBA texture holding one coefficient of every texel (alpha 255).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Plane {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Row-major RGBA8 texels, top row first.
    pub texels: Vec<[u8; 4]>,
}

impl Plane {
    /// Tightly packed RGBA bytes.
    #[must_use]
    pub fn rgba_bytes(&self) -> Vec<u8> {
        self.texels.iter().flatten().copied().collect()
    }

    /// Tightly packed RGB bytes (alpha dropped), as for an RGB PNG.
    #[must_use]
    pub fn rgb_bytes(&self) -> Vec<u8> {
        self.texels.iter().flat_map(|t| [t[0], t[1], t[2]]).collect()
    }
}

impl Encoding {
    /// Encodes every coefficient of `map` into one RGBA8 plane per coefficient (\[Ish11\]
    /// §2.2.3: coefficient `basis.dc_index()` through the DC transfer, the others
    /// range-compressed), with the counts of clamped values.
    ///
    /// # Panics
    /// If `map.len != basis.len()`.
    #[must_use]
    pub fn encode_map(&self, basis: &dyn HemiBasis, map: &CoeffMap) -> (Vec<Plane>, ClampStats) {
        assert_eq!(map.len, basis.len(), "map and basis sizes differ");
        let n = map.texels();
        let mut planes: Vec<Plane> = (0..map.len)
            .map(|_| Plane { width: map.width, height: map.height, texels: vec![[0, 0, 0, 255]; n] })
            .collect();
        let mut stats = ClampStats::default();
        let mut texel = vec![[0.0f64; 3]; map.len];
        for i in 0..n {
            for (t, c) in texel.iter_mut().zip(&map.data[i * map.len..(i + 1) * map.len]) {
                *t = c.map(f64::from);
            }
            let (bytes, s) = self.encode_u8(basis, &texel);
            stats.dc_clamped += s.dc_clamped;
            stats.ac_clamped += s.ac_clamped;
            for (plane, b) in planes.iter_mut().zip(&bytes) {
                plane.texels[i] = [b[0], b[1], b[2], 255];
            }
        }
        (planes, stats)
    }

    /// Decodes planes written by [`Self::encode_map`] (or their block-compressed round trip)
    /// back to a coefficient map (\[Ish11\] Listing 2.2's decode).
    ///
    /// # Panics
    /// If the plane count differs from `basis.len()` or the planes differ in size.
    #[must_use]
    pub fn decode_map(&self, basis: &dyn HemiBasis, planes: &[Plane]) -> CoeffMap {
        assert_eq!(planes.len(), basis.len(), "one plane per coefficient");
        let (w, h) = (planes[0].width, planes[0].height);
        assert!(planes.iter().all(|p| p.width == w && p.height == h), "planes differ in size");
        let k = planes.len();
        let mut map = CoeffMap::zeros(w, h, k);
        let mut texel = vec![[0u8; 3]; k];
        for i in 0..w * h {
            for (t, p) in texel.iter_mut().zip(planes) {
                let v = p.texels[i];
                *t = [v[0], v[1], v[2]];
            }
            let back = self.decode_u8(basis, &texel);
            for (d, b) in map.data[i * k..(i + 1) * k].iter_mut().zip(&back) {
                *d = b.map(|v| v as f32);
            }
        }
        map
    }
}

/// The irradiance error of a stored coefficient map against the original.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapError {
    /// `sqrt(mean over texels and channels of ∫_H (E' - E)² dω / 2π)`: the RMS irradiance
    /// error over texels, channels and the hemisphere of normals.
    pub rms: f64,
    /// `rms` divided by the same RMS of the original irradiance (`sqrt(mean cᵀ G c / 2π)`).
    pub rel_rms: f64,
    /// Largest `|c' - c|` over all texels, coefficients and channels.
    pub max_coeff_error: f64,
}

/// Measures the irradiance error of `stored` against `original` (both maps in `basis`),
/// exactly over the hemisphere with the basis's Gram matrix.
///
/// # Panics
/// If the maps differ in shape or do not match the basis size.
#[must_use]
pub fn map_error(basis: &dyn HemiBasis, original: &CoeffMap, stored: &CoeffMap) -> MapError {
    assert_eq!(
        (original.width, original.height, original.len),
        (stored.width, stored.height, stored.len),
        "maps differ in shape"
    );
    assert_eq!(original.len, basis.len(), "map and basis sizes differ");
    let g = basis.gram();
    let k = original.len;
    let quad = |v: &[f64]| -> f64 {
        let gv = g.mul_vec(v);
        v.iter().zip(&gv).map(|(a, b)| a * b).sum::<f64>().max(0.0)
    };
    let (mut err2, mut sig2, mut max_coeff_error) = (0.0, 0.0, 0.0f64);
    let mut d = vec![0.0; k];
    let mut c = vec![0.0; k];
    for (a, b) in original.data.chunks_exact(k).zip(stored.data.chunks_exact(k)) {
        for ch in 0..3 {
            for j in 0..k {
                c[j] = f64::from(a[j][ch]);
                d[j] = f64::from(b[j][ch]) - c[j];
                max_coeff_error = max_coeff_error.max(d[j].abs());
            }
            err2 += quad(&d);
            sig2 += quad(&c);
        }
    }
    let norm = 2.0 * PI * 3.0 * original.texels() as f64;
    let rms = (err2 / norm).sqrt();
    let signal = (sig2 / norm).sqrt();
    MapError { rms, rel_rms: if signal > 0.0 { rms / signal } else { 0.0 }, max_coeff_error }
}

/// A realistic `width × height` coefficient map in `basis` for measuring storage errors:
/// the grazing-sun sky of \[Ish11\] §3.2 ([`Sky::grazing_sun`]) with the sun's azimuth
/// sweeping 0-360° along x and its elevation 2-60° along y, the sun hidden (a hard shadow
/// edge) inside a disk of radius `0.3·min(w, h)` centred in the map, 3-band SH irradiance
/// converted to the basis (Listing 2.1), and scaled so the largest DC value is `dc_peak` of
/// the encodable `[0, 1]` (the thesis's assumption for the range compression, §2.2.3).
#[must_use]
pub fn sky_test_map(basis: &dyn HemiBasis, width: usize, height: usize, dc_peak: f64) -> CoeffMap {
    let base = Sky::grazing_sun();
    let m = basis.sh_irradiance_matrix(3);
    let mut raw = Vec::with_capacity(width * height);
    let (cx, cy, r) = (width as f64 / 2.0, height as f64 / 2.0, 0.3 * width.min(height) as f64);
    for y in 0..height {
        for x in 0..width {
            let azim = 2.0 * PI * (x as f64 + 0.5) / width as f64;
            let elev = (2.0 + 58.0 * (y as f64 + 0.5) / height as f64).to_radians();
            let shadow = (x as f64 + 0.5 - cx).hypot(y as f64 + 0.5 - cy) < r;
            let sky = Sky {
                sun_dir: [elev.cos() * azim.cos(), elev.cos() * azim.sin(), elev.sin()],
                sun_radiance: if shadow { [0.0; 3] } else { base.sun_radiance },
                ..base
            };
            raw.push(m.mul_rgb(&sky.irradiance_sh(3)));
        }
    }
    let dc = basis.dc_index().unwrap_or(0);
    let peak = raw.iter().flat_map(|t| t[dc]).fold(0.0f64, f64::max);
    let scale = if peak > 0.0 { dc_peak / peak } else { 1.0 };
    let mut map = CoeffMap::zeros(width, height, basis.len());
    for (dst, src) in map.data.chunks_exact_mut(basis.len()).zip(&raw) {
        for (d, s) in dst.iter_mut().zip(src) {
            *d = s.map(|v| (v * scale) as f32);
        }
    }
    map
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ShBasis;

    /// f32 storage of O(1) coefficients against f64: relative 2^-24 per value.
    const F32_TOL: f64 = 1e-6;
    /// RMS irradiance differences caused only by f32 storage of the decoded coefficients:
    /// a few 2^-24 rounding errors of O(1) values.
    const F32_RMS_TOL: f64 = 1e-7;

    #[test]
    fn map_round_trip_matches_per_texel_encoding() {
        let basis = ShBasis::new(3);
        let map = sky_test_map(&basis, 6, 5, 0.9);
        let enc = Encoding::default();
        let (planes, _) = enc.encode_map(&basis, &map);
        assert_eq!(planes.len(), 9);
        assert!(planes.iter().all(|p| p.texels.len() == 30 && p.texels.iter().all(|t| t[3] == 255)));
        let back = enc.decode_map(&basis, &planes);
        // Texel (4, 3) through the per-texel path.
        let t: Vec<[f64; 3]> = map.texel(4, 3).iter().map(|c| c.map(f64::from)).collect();
        let (bytes, _) = enc.encode_u8(&basis, &t);
        let want = enc.decode_u8(&basis, &bytes);
        for (a, b) in back.texel(4, 3).iter().zip(&want) {
            for ch in 0..3 {
                assert!((f64::from(a[ch]) - b[ch]).abs() < F32_TOL);
            }
        }
        assert_eq!(planes[0].texels[3 * 6 + 4], [bytes[0][0], bytes[0][1], bytes[0][2], 255]);
    }

    #[test]
    fn map_error_is_zero_for_identical_maps_and_matches_encoding_error_for_one_texel() {
        let basis = ShBasis::new(2);
        let map = sky_test_map(&basis, 1, 1, 0.8);
        let zero = map_error(&basis, &map, &map);
        assert_eq!((zero.rms, zero.max_coeff_error), (0.0, 0.0));
        let enc = Encoding::default();
        let (planes, _) = enc.encode_map(&basis, &map);
        let e = map_error(&basis, &map, &enc.decode_map(&basis, &planes));
        let t: Vec<[f64; 3]> = map.data.iter().map(|c| c.map(f64::from)).collect();
        let want = crate::encode::encoding_error(&basis, &t, &enc);
        let want_rms = (want.rms.iter().map(|r| r * r).sum::<f64>() / 3.0).sqrt();
        assert!((e.rms - want_rms).abs() < F32_RMS_TOL, "{} vs {want_rms}", e.rms);
    }

    #[test]
    fn sky_test_map_peaks_at_the_requested_dc_and_has_a_shadow() {
        let basis = ShBasis::new(3);
        let map = sky_test_map(&basis, 16, 16, 0.9);
        let dc_max = map.data.chunks_exact(9).flat_map(|t| t[0]).fold(0.0f32, f32::max);
        assert!((f64::from(dc_max) - 0.9).abs() < F32_TOL);
        // The shadowed centre is darker than the lit corner in the same row band.
        assert!(map.texel(8, 8)[0][0] < map.texel(0, 8)[0][0]);
    }
}
