//! Latitude-longitude environment maps (from OpenEXR) with importance sampling.
//!
//! Mapping (world +Z up): texel column `u = φ / 2π` with `φ = atan2(y, x)` wrapped to
//! [0, 2π), row `v = θ / π` with `θ = acos(z)`, so the first row is the zenith. Radiance is
//! piecewise constant per texel, which makes the sampling density below exact.

use std::f64::consts::PI;
use std::path::Path;

use glam::DVec3;

use crate::error::SceneError;

/// A lat-long radiance map with a piecewise-constant sampling distribution proportional to
/// luminance × sin θ (pbrt-v4's `PiecewiseConstant2D` over the map).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    width: usize,
    height: usize,
    texels: Vec<[f32; 3]>,
    /// Cumulative row weights, `height + 1` entries, last = total.
    row_cdf: Vec<f64>,
    /// Per row, cumulative texel weights, `width + 1` entries each.
    col_cdf: Vec<f64>,
    total: f64,
}

/// Most texels a map may have: 2^26 (8192 × 8192; about 1.3 GB with its sampling tables).
/// The size is read from the header and refused before anything is allocated, so a map
/// whose header claims more (a damaged or hostile file) is a one-line error, not an abort.
pub const MAX_TEXELS: usize = 1 << 26;

/// Rec. 709 luminance, the sampling weight of a texel.
#[must_use]
#[inline]
pub fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

impl EnvMap {
    /// A map from linear RGB texels, row-major, row 0 at the zenith.
    ///
    /// # Errors
    /// [`SceneError::EnvironmentMap`] for a size mismatch, an empty map, or non-finite or
    /// negative texels.
    pub fn from_linear(width: usize, height: usize, texels: Vec<[f32; 3]>) -> Result<Self, SceneError> {
        let bad = |m: &str| SceneError::EnvironmentMap { path: "<memory>".into(), message: m.to_owned() };
        if width == 0 || height == 0 || texels.len() != width * height {
            return Err(bad("size does not match the texel count"));
        }
        if !texels.iter().flatten().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(bad("texels must be finite and non-negative"));
        }
        let mut col_cdf = Vec::with_capacity(height * (width + 1));
        let mut row_cdf = vec![0.0];
        for y in 0..height {
            let sin_t = (PI * (y as f64 + 0.5) / height as f64).sin();
            let mut acc = 0.0;
            col_cdf.push(0.0);
            for x in 0..width {
                acc += luminance(texels[y * width + x].map(f64::from)) * sin_t;
                col_cdf.push(acc);
            }
            row_cdf.push(row_cdf[y] + acc);
        }
        let total = row_cdf[height];
        Ok(Self { width, height, texels, row_cdf, col_cdf, total })
    }

    /// Reads the first RGB(A) layer of an OpenEXR file.
    ///
    /// # Errors
    /// [`SceneError::NotFound`] or [`SceneError::EnvironmentMap`].
    pub fn from_exr(path: &Path) -> Result<Self, SceneError> {
        if !path.exists() {
            return Err(SceneError::NotFound(path.to_owned()));
        }
        let err = |message: String| SceneError::EnvironmentMap { path: path.to_owned(), message };
        let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| err(e.to_string()))?;
        for h in &meta.headers {
            let (w, ht) = (h.layer_size.width(), h.layer_size.height());
            if w.checked_mul(ht).is_none_or(|n| n > MAX_TEXELS) {
                return Err(err(format!("{w}×{ht} texels, more than the {MAX_TEXELS} a map may have")));
            }
        }
        let img = exr::prelude::read_first_rgba_layer_from_file(
            path,
            |res, _| (res.width(), vec![[0.0f32; 3]; res.width() * res.height()]),
            |px: &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = px.0;
                px.1[pos.y() * w + pos.x()] = [r, g, b];
            },
        )
        .map_err(|e| SceneError::EnvironmentMap { path: path.to_owned(), message: e.to_string() })?;
        let (w, texels) = img.layer_data.channel_data.pixels;
        let h = texels.len() / w.max(1);
        Self::from_linear(w, h, texels).map_err(|e| match e {
            SceneError::EnvironmentMap { message, .. } => {
                SceneError::EnvironmentMap { path: path.to_owned(), message }
            }
            other => other,
        })
    }

    /// Width in texels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in texels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    fn uv_of(dir: DVec3) -> (f64, f64) {
        let phi = dir.y.atan2(dir.x).rem_euclid(2.0 * PI);
        let theta = dir.z.clamp(-1.0, 1.0).acos();
        (phi / (2.0 * PI), theta / PI)
    }

    fn texel_of(&self, dir: DVec3) -> usize {
        let (u, v) = Self::uv_of(dir);
        let x = ((u * self.width as f64) as usize).min(self.width - 1);
        let y = ((v * self.height as f64) as usize).min(self.height - 1);
        y * self.width + x
    }

    /// Radiance from direction `dir` (nearest texel: the map is piecewise constant).
    #[must_use]
    pub fn radiance(&self, dir: DVec3) -> [f64; 3] {
        self.texels[self.texel_of(dir)].map(f64::from)
    }

    /// True when the whole map is black (nothing to sample).
    #[must_use]
    pub fn is_black(&self) -> bool {
        !(self.total > 0.0)
    }

    /// Samples a direction ∝ luminance; returns `(dir, pdf per steradian)`.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> Option<(DVec3, f64)> {
        if self.is_black() {
            return None;
        }
        let (y, fy) = sample_cdf(&self.row_cdf, u[0]);
        let row = &self.col_cdf[y * (self.width + 1)..(y + 1) * (self.width + 1)];
        let (x, fx) = sample_cdf(row, u[1]);
        let uu = (x as f64 + fx) / self.width as f64;
        let vv = (y as f64 + fy) / self.height as f64;
        let (phi, theta) = (2.0 * PI * uu, PI * vv);
        let dir = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
        let pdf = self.pdf(dir);
        (pdf > 0.0).then_some((dir, pdf))
    }

    /// Density per steradian of [`sample`](Self::sample) producing `dir`.
    #[must_use]
    pub fn pdf(&self, dir: DVec3) -> f64 {
        if self.is_black() {
            return 0.0;
        }
        let i = self.texel_of(dir);
        let y = i / self.width;
        let (x0, x1) = (
            self.col_cdf[y * (self.width + 1) + i % self.width],
            self.col_cdf[y * (self.width + 1) + i % self.width + 1],
        );
        let p_uv = (x1 - x0) / self.total * (self.width * self.height) as f64;
        let sin_t = (1.0 - dir.z * dir.z).max(0.0).sqrt();
        if sin_t <= 0.0 { 0.0 } else { p_uv / (2.0 * PI * PI * sin_t) }
    }
}

/// Inverts a cumulative table (`cdf[0] = 0`, increasing): the bin and the offset in it.
fn sample_cdf(cdf: &[f64], u: f64) -> (usize, f64) {
    let n = cdf.len() - 1;
    let target = u * cdf[n];
    // First index with cdf[i + 1] > target, skipping empty bins.
    let mut lo = 0usize;
    let mut hi = n - 1;
    while lo < hi {
        let mid = (lo + hi) / 2;
        if cdf[mid + 1] > target {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    let w = cdf[lo + 1] - cdf[lo];
    let f = if w > 0.0 { ((target - cdf[lo]) / w).clamp(0.0, 1.0 - f64::EPSILON) } else { 0.5 };
    (lo, f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_sh::lowdisc::Halton;
    use lightvol_sh::quadrature::SphereQuadrature;

    fn test_map() -> EnvMap {
        let (w, h) = (16, 8);
        let texels =
            (0..w * h).map(|i| [(i % 7) as f32 * 0.3, 1.0 + (i % 5) as f32, (i / w) as f32]).collect();
        EnvMap::from_linear(w, h, texels).unwrap()
    }

    /// The sampling density integrates to one over the sphere (fine product quadrature;
    /// the density is piecewise smooth so the rule converges, hence the loose bound).
    #[test]
    fn pdf_integrates_to_one() {
        let m = test_map();
        let q = SphereQuadrature::sphere(256, 512);
        let total = q.integrate(|d| m.pdf(DVec3::from_array(d)));
        // Texel edges cut the rule's cells: error O(1/n_theta) ≈ 4e-3.
        assert!((total - 1.0).abs() < 1e-2, "{total}");
    }

    /// Importance-sampled estimate of ∫ L dω equals the texel sum Σ L_texel ΔΩ_texel.
    #[test]
    fn importance_sampling_is_unbiased() {
        let m = test_map();
        let mut exact = 0.0;
        for y in 0..m.height() {
            let (t0, t1) = (PI * y as f64 / m.height() as f64, PI * (y + 1) as f64 / m.height() as f64);
            let d_omega = 2.0 * PI / m.width() as f64 * (t0.cos() - t1.cos());
            for x in 0..m.width() {
                exact += luminance(m.texels[y * m.width() + x].map(f64::from)) * d_omega;
            }
        }
        let h = Halton::new(3, 2);
        let n = 1 << 14;
        let est: f64 = (0..n)
            .map(|i| {
                // `None` only on the measure-zero poles: a zero contribution.
                m.sample(h.point::<2>(i)).map_or(0.0, |(d, p)| luminance(m.radiance(d)) / p)
            })
            .sum::<f64>()
            / n as f64;
        // The integrand/pdf ratio only varies through sin θ inside a row: QMC error ~1e-3.
        assert!((est - exact).abs() < 5e-3 * exact, "{est} {exact}");
    }

    #[test]
    fn exr_round_trip_and_missing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("env.exr");
        exr::prelude::write_rgb_file(&path, 8, 4, |x, y| ((x + y) as f32, 1.0f32, 0.5f32)).unwrap();
        let m = EnvMap::from_exr(&path).unwrap();
        assert_eq!((m.width(), m.height()), (8, 4));
        // Direction of texel (x = 3, y = 1) centre.
        let (phi, theta) = (2.0 * PI * 3.5 / 8.0, PI * 1.5 / 4.0);
        let d = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
        assert_eq!(m.radiance(d), [4.0, 1.0, 0.5]);
        assert!(matches!(EnvMap::from_exr(&dir.path().join("none.exr")), Err(SceneError::NotFound(_))));
    }

    /// A header that claims more texels than [`MAX_TEXELS`] is refused in one line before
    /// anything is allocated (the file's real pixels are a few bytes).
    #[test]
    fn oversized_map_is_refused_from_its_header() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("env.exr");
        exr::prelude::write_rgb_file(&path, 8, 4, |_, _| (1.0f32, 1.0f32, 1.0f32)).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        // Both windows (box2i: x_min, y_min, x_max, y_max) claim 100000 × 100000 texels.
        for name in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
            let at = bytes.windows(name.len()).position(|w| w == name).unwrap() + name.len() + 4;
            bytes[at + 8..at + 16]
                .copy_from_slice(&[99_999i32.to_le_bytes(), 99_999i32.to_le_bytes()].concat());
        }
        std::fs::write(&path, &bytes).unwrap();
        let e = EnvMap::from_exr(&path).unwrap_err().to_string();
        assert!(e.contains("100000×100000 texels, more than") && !e.contains('\n'), "{e}");
    }
}
