//! Base-colour textures: linear RGB texels, bilinear lookup with repeat wrapping.

/// A decoded texture in *linear* RGB (sRGB-encoded 8-bit images are linearised on load,
/// glTF 2.0 §3.9.2 and the usual `map_Kd` convention).
#[derive(Clone, Debug)]
pub struct Texture {
    width: u32,
    height: u32,
    texels: Vec<[f32; 3]>,
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1), 8-bit code to linear.
#[must_use]
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

impl Texture {
    /// A texture from linear texels, row-major, first row at v = 0 (glTF convention: the
    /// image's top row). Returns `None` when the size does not match or is zero.
    #[must_use]
    pub fn from_linear(width: u32, height: u32, texels: Vec<[f32; 3]>) -> Option<Self> {
        (width > 0 && height > 0 && texels.len() == width as usize * height as usize).then_some(Self {
            width,
            height,
            texels,
        })
    }

    /// Decodes an 8-bit sRGB image (PNG or JPEG bytes already decoded by `image`).
    #[must_use]
    pub fn from_image(img: &image::DynamicImage) -> Option<Self> {
        let rgb = img.to_rgb8();
        let lut: Vec<f32> = (0..256).map(|c| srgb_to_linear(f64::from(c) / 255.0) as f32).collect();
        let texels =
            rgb.pixels().map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]]).collect();
        Self::from_linear(rgb.width(), rgb.height(), texels)
    }

    /// Width in texels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in texels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The texel at integer coordinates, wrapped (repeat addressing).
    #[must_use]
    pub fn texel(&self, x: i64, y: i64) -> [f32; 3] {
        let xi = x.rem_euclid(i64::from(self.width)) as usize;
        let yi = y.rem_euclid(i64::from(self.height)) as usize;
        self.texels[yi * self.width as usize + xi]
    }

    /// Bilinear lookup at texture coordinates `uv` with repeat wrapping; texel centres sit at
    /// half-integer positions (the OpenGL/Vulkan convention glTF uses).
    #[must_use]
    pub fn sample(&self, uv: [f64; 2]) -> [f64; 3] {
        if !(uv[0].is_finite() && uv[1].is_finite()) {
            return self.texel(0, 0).map(f64::from);
        }
        let x = uv[0] * f64::from(self.width) - 0.5;
        let y = uv[1] * f64::from(self.height) - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let mut out = [0.0; 3];
        for (dx, dy, w) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            let t = self.texel(x0 + dx, y0 + dy);
            for c in 0..3 {
                out[c] += w * f64::from(t[c]);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bilinear interpolation reproduces texels at their centres and averages between them.
    #[test]
    fn bilinear_hits_centres_and_midpoints() {
        let t = Texture::from_linear(2, 1, vec![[0.0, 0.0, 0.0], [1.0, 0.5, 0.25]]).unwrap();
        assert_eq!(t.sample([0.25, 0.5]), [0.0, 0.0, 0.0]);
        assert_eq!(t.sample([0.75, 0.5]), [1.0, 0.5, 0.25]);
        // Halfway between the centres: the mean; at u = 0 the repeat wrap also gives the mean.
        for u in [0.5, 0.0, 1.0] {
            let s = t.sample([u, 0.5]);
            assert!((s[0] - 0.5).abs() < 1e-12 && (s[2] - 0.125).abs() < 1e-12, "{u} {s:?}");
        }
    }

    /// The sRGB curve is continuous at its breakpoint and maps 0 and 1 to themselves.
    #[test]
    fn srgb_curve() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-15);
        let below = 0.04045 / 12.92;
        let above = ((0.04045f64 + 0.055) / 1.055).powf(2.4);
        // The two branches meet to about 1e-7 (the standard's rounded breakpoint).
        assert!((below - above).abs() < 1e-6);
    }
}
