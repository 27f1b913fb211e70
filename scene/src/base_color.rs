//! Base-colour textures: linear RGB texels plus an optional alpha channel, bilinear lookup
//! with the glTF 2.0 sampler wrap modes (§5.26, `wrapS`/`wrapT`).

/// How texture coordinates outside [0, 1] are folded back (glTF 2.0 §5.26.4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// `REPEAT` (10497), the glTF default.
    #[default]
    Repeat,
    /// `CLAMP_TO_EDGE` (33071).
    Clamp,
    /// `MIRRORED_REPEAT` (33648).
    Mirror,
}

impl Wrap {
    /// The wrap mode of a glTF sampler code; unknown codes fall back to `REPEAT`.
    #[must_use]
    pub fn from_gl(code: u64) -> Self {
        match code {
            33071 => Self::Clamp,
            33648 => Self::Mirror,
            _ => Self::Repeat,
        }
    }

    /// Folds an integer texel coordinate into `0..n`.
    #[must_use]
    #[inline]
    pub fn fold(self, i: i64, n: u32) -> usize {
        let n = i64::from(n);
        match self {
            Self::Repeat => i.rem_euclid(n) as usize,
            Self::Clamp => i.clamp(0, n - 1) as usize,
            Self::Mirror => {
                let m = i.rem_euclid(2 * n);
                (if m < n { m } else { 2 * n - 1 - m }) as usize
            }
        }
    }
}

/// A decoded texture: *linear* RGB at lookup (sRGB-encoded 8-bit images are linearised,
/// glTF 2.0 §3.9.2 and the usual `map_Kd` convention), with the image's alpha channel
/// (linear, as glTF defines base-colour alpha) when it has one.
#[derive(Clone, Debug)]
pub struct Texture {
    width: u32,
    height: u32,
    texels: Texels,
    wrap: [Wrap; 2],
}

/// How a texture keeps its texels.
#[derive(Clone, Debug)]
enum Texels {
    /// An 8-bit image as decoded: sRGB colour and linear alpha (255 where the image has
    /// none), four bytes a texel, decoded at lookup through [`srgb8_table`] and
    /// [`unorm8_table`]. A lookup reads the same f32 values a linear copy would hold, in a
    /// third of the memory (a quarter with alpha), so fewer cache misses.
    Srgb8 { rgba: Vec<[u8; 4]>, has_alpha: bool },
    /// Linear f32 texels, and alpha when given.
    Linear { rgb: Vec<[f32; 3]>, alpha: Option<Vec<f32>> },
}

/// The linear value of each 8-bit sRGB code, rounded to f32 (IEC 61966-2-1).
fn srgb8_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|c| lightvol_core::color::srgb_decode(c as f64 / 255.0) as f32))
}

/// Each 8-bit code as an f32 in [0, 1] (`c / 255`): alpha is stored linear.
fn unorm8_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|c| c as f32 / 255.0))
}

impl Texture {
    /// A texture from linear texels, row-major, first row at v = 0 (glTF convention: the
    /// image's top row). Returns `None` when the size does not match or is zero.
    #[must_use]
    pub fn from_linear(width: u32, height: u32, texels: Vec<[f32; 3]>) -> Option<Self> {
        (width > 0 && height > 0 && texels.len() == width as usize * height as usize).then_some(Self {
            width,
            height,
            texels: Texels::Linear { rgb: texels, alpha: None },
            wrap: [Wrap::Repeat; 2],
        })
    }

    /// The same texture with an alpha channel (row-major like the texels, values in [0, 1]).
    /// Returns `None` when the length does not match. An 8-bit texture becomes a linear
    /// one (its colours decoded) to carry it.
    #[must_use]
    pub fn with_alpha(self, alpha: Vec<f32>) -> Option<Self> {
        let n = self.width as usize * self.height as usize;
        if alpha.len() != n {
            return None;
        }
        let rgb = match self.texels {
            Texels::Linear { rgb, .. } => rgb,
            Texels::Srgb8 { rgba, .. } => {
                let lut = srgb8_table();
                rgba.iter().map(|t| [lut[t[0] as usize], lut[t[1] as usize], lut[t[2] as usize]]).collect()
            }
        };
        Some(Self { texels: Texels::Linear { rgb, alpha: Some(alpha) }, ..self })
    }

    /// The same texture with the given wrap modes in `u` (`wrapS`) and `v` (`wrapT`).
    #[must_use]
    pub fn with_wrap(mut self, wrap: [Wrap; 2]) -> Self {
        self.wrap = wrap;
        self
    }

    /// An 8-bit sRGB image (PNG or JPEG bytes already decoded by `image`), kept as its
    /// 8-bit codes and linearised at lookup; an alpha channel, if the image has one, is
    /// kept as is.
    #[must_use]
    pub fn from_image(img: &image::DynamicImage) -> Option<Self> {
        let rgba = img.to_rgba8();
        let (width, height) = rgba.dimensions();
        let has_alpha = img.color().has_alpha();
        let texels: Vec<[u8; 4]> = rgba.pixels().map(|p| p.0).collect();
        (width > 0 && height > 0).then_some(Self {
            width,
            height,
            texels: Texels::Srgb8 { rgba: texels, has_alpha },
            wrap: [Wrap::Repeat; 2],
        })
    }

    /// Bytes the texels take (what [`crate::estimate`] models per texel).
    #[must_use]
    pub fn texel_bytes(&self) -> usize {
        match &self.texels {
            Texels::Srgb8 { rgba, .. } => rgba.len() * 4,
            Texels::Linear { rgb, alpha } => rgb.len() * 12 + alpha.as_ref().map_or(0, |a| a.len() * 4),
        }
    }

    /// True when the texture has an alpha channel.
    #[must_use]
    pub fn has_alpha(&self) -> bool {
        match &self.texels {
            Texels::Srgb8 { has_alpha, .. } => *has_alpha,
            Texels::Linear { alpha, .. } => alpha.is_some(),
        }
    }

    /// The wrap modes in `u` and `v`.
    #[must_use]
    pub fn wrap(&self) -> [Wrap; 2] {
        self.wrap
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

    /// Row-major index of the texel at integer coordinates, folded by the wrap modes.
    #[inline]
    fn index(&self, x: i64, y: i64) -> usize {
        self.wrap[1].fold(y, self.height) * self.width as usize + self.wrap[0].fold(x, self.width)
    }

    /// The texel at integer coordinates, folded by the wrap modes.
    #[must_use]
    pub fn texel(&self, x: i64, y: i64) -> [f32; 3] {
        self.rgb(self.index(x, y))
    }

    /// The linear RGB of texel `i`.
    #[inline]
    fn rgb(&self, i: usize) -> [f32; 3] {
        match &self.texels {
            Texels::Srgb8 { rgba, .. } => {
                let (lut, t) = (srgb8_table(), rgba[i]);
                [lut[t[0] as usize], lut[t[1] as usize], lut[t[2] as usize]]
            }
            Texels::Linear { rgb, .. } => rgb[i],
        }
    }

    /// The four bilinear taps at `uv`: texel indices and weights. Texel centres sit at
    /// half-integer positions (the OpenGL/Vulkan convention glTF uses). Non-finite
    /// coordinates read texel (0, 0).
    fn taps(&self, uv: [f64; 2]) -> [(usize, f64); 4] {
        if !(uv[0].is_finite() && uv[1].is_finite()) {
            return [(0, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)];
        }
        // Far outside [0, 1] the i64 conversion saturates; fold first so it cannot.
        let fold = |c: f64| if c.abs() > 1e9 { c.rem_euclid(2.0) } else { c };
        let x = fold(uv[0]) * f64::from(self.width) - 0.5;
        let y = fold(uv[1]) * f64::from(self.height) - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        [
            (self.index(x0, y0), (1.0 - fx) * (1.0 - fy)),
            (self.index(x0 + 1, y0), fx * (1.0 - fy)),
            (self.index(x0, y0 + 1), (1.0 - fx) * fy),
            (self.index(x0 + 1, y0 + 1), fx * fy),
        ]
    }

    /// Bilinear lookup of the linear RGB at texture coordinates `uv`.
    #[must_use]
    pub fn sample(&self, uv: [f64; 2]) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (i, w) in self.taps(uv) {
            let t = self.rgb(i);
            for c in 0..3 {
                out[c] += w * f64::from(t[c]);
            }
        }
        out
    }

    /// Bilinear lookup of the alpha channel at `uv` (1 when the texture has none), as a
    /// GPU samples base-colour alpha before an alpha test (glTF 2.0 §3.9.4).
    #[must_use]
    pub fn sample_alpha(&self, uv: [f64; 2]) -> f64 {
        match &self.texels {
            Texels::Srgb8 { rgba, has_alpha: true } => {
                let lut = unorm8_table();
                self.taps(uv).iter().map(|&(i, w)| w * f64::from(lut[rgba[i][3] as usize])).sum()
            }
            Texels::Linear { alpha: Some(a), .. } => {
                self.taps(uv).iter().map(|&(i, w)| w * f64::from(a[i])).sum()
            }
            _ => 1.0,
        }
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

    /// An 8-bit image kept as its codes reads exactly what its linear f32 copy reads
    /// (the reference: every texel decoded by the sRGB formula on load), colour and alpha,
    /// at texel centres, between them and past the edges; and keeps 4 bytes a texel.
    #[test]
    fn eight_bit_texels_read_as_their_linear_copy() {
        let (w, h) = (5u32, 3u32);
        let code = |i: u32, c: u32| ((i * 53 + c * 97 + 11) % 256) as u8;
        let img = image::RgbaImage::from_fn(w, h, |x, y| {
            let i = y * w + x;
            image::Rgba([code(i, 0), code(i, 1), code(i, 2), code(i, 3)])
        });
        let t = Texture::from_image(&image::DynamicImage::ImageRgba8(img)).unwrap();
        assert!(t.has_alpha());
        assert_eq!(t.texel_bytes(), (w * h * 4) as usize);
        let decode = |c: u8| lightvol_core::color::srgb_decode(f64::from(c) / 255.0) as f32;
        let linear: Vec<[f32; 3]> = (0..w * h).map(|i| [0, 1, 2].map(|c| decode(code(i, c)))).collect();
        let alpha: Vec<f32> = (0..w * h).map(|i| f32::from(code(i, 3)) / 255.0).collect();
        let reference = Texture::from_linear(w, h, linear).unwrap().with_alpha(alpha).unwrap();
        for k in 0..200 {
            let uv = [f64::from(k) * 0.0173 - 0.4, f64::from(k * 7 % 200) * 0.0091 - 0.3];
            assert_eq!(t.sample(uv), reference.sample(uv), "{uv:?}");
            assert_eq!(t.sample_alpha(uv), reference.sample_alpha(uv), "{uv:?}");
        }
        assert_eq!(t.texel(3, 2), reference.texel(3, 2));
        // Code 255 is 1 and code 0 is 0 through the sRGB curve; without alpha, alpha reads 1.
        let rgb = image::RgbImage::from_fn(2, 1, |x, _| image::Rgb([255 * x as u8, 0, 0]));
        let t = Texture::from_image(&image::DynamicImage::ImageRgb8(rgb)).unwrap();
        assert!(!t.has_alpha());
        assert_eq!((t.texel(0, 0), t.texel(1, 0)), ([0.0; 3], [1.0, 0.0, 0.0]));
        assert_eq!(t.sample_alpha([0.3, 0.5]), 1.0);
        // Giving an 8-bit texture alpha keeps its colours.
        let with = t.clone().with_alpha(vec![0.5, 0.5]).unwrap();
        assert_eq!(with.sample([0.6, 0.5]), t.sample([0.6, 0.5]));
        assert_eq!(with.sample_alpha([0.6, 0.5]), 0.5);
    }

    /// Wrap modes fold texel coordinates as the GL samplers do: repeat, clamp, mirror.
    #[test]
    fn wrap_modes_fold_like_gl() {
        let fold = |w: Wrap| (-4..8).map(|i| w.fold(i, 3)).collect::<Vec<_>>();
        assert_eq!(fold(Wrap::Repeat), [2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1]);
        assert_eq!(fold(Wrap::Clamp), [0, 0, 0, 0, 0, 1, 2, 2, 2, 2, 2, 2]);
        // Mirrored: 0 1 2 2 1 0, period 2n = 6, so -4 ≡ 2 → 2 and -1 ≡ 5 → 0.
        assert_eq!(fold(Wrap::Mirror), [2, 2, 1, 0, 0, 1, 2, 2, 1, 0, 0, 1]);
        assert_eq!(Wrap::from_gl(33071), Wrap::Clamp);
        assert_eq!(Wrap::from_gl(33648), Wrap::Mirror);
        assert_eq!(Wrap::from_gl(10497), Wrap::Repeat);
    }

    /// Alpha is interpolated bilinearly and is 1 without an alpha channel; clamping keeps
    /// the edge texel's alpha past the edge where repeating would blend the far side in.
    #[test]
    fn alpha_channel_is_bilinear_and_wrap_aware() {
        let t = Texture::from_linear(2, 1, vec![[1.0; 3]; 2]).unwrap();
        assert_eq!(t.sample_alpha([0.5, 0.5]), 1.0);
        let t = t.with_alpha(vec![0.0, 1.0]).unwrap();
        assert!(t.has_alpha());
        assert_eq!(t.sample_alpha([0.25, 0.5]), 0.0);
        assert_eq!(t.sample_alpha([0.75, 0.5]), 1.0);
        assert!((t.sample_alpha([0.5, 0.5]) - 0.5).abs() < 1e-12);
        // At u = 1: repeat blends texel 1 with texel 0 -> 0.5; clamp keeps texel 1 -> 1.
        assert!((t.sample_alpha([1.0, 0.5]) - 0.5).abs() < 1e-12);
        let c = t.clone().with_wrap([Wrap::Clamp; 2]);
        assert_eq!(c.sample_alpha([1.0, 0.5]), 1.0);
        assert!(Texture::from_linear(2, 1, vec![[1.0; 3]; 2]).unwrap().with_alpha(vec![0.0]).is_none());
    }
}
