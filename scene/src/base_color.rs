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

/// A decoded texture in *linear* RGB (sRGB-encoded 8-bit images are linearised on load,
/// glTF 2.0 §3.9.2 and the usual `map_Kd` convention), with the image's alpha channel
/// (linear, as glTF defines base-colour alpha) when it has one.
#[derive(Clone, Debug)]
pub struct Texture {
    width: u32,
    height: u32,
    texels: Vec<[f32; 3]>,
    alpha: Option<Vec<f32>>,
    wrap: [Wrap; 2],
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
            alpha: None,
            wrap: [Wrap::Repeat; 2],
        })
    }

    /// The same texture with an alpha channel (row-major like the texels, values in [0, 1]).
    /// Returns `None` when the length does not match.
    #[must_use]
    pub fn with_alpha(mut self, alpha: Vec<f32>) -> Option<Self> {
        (alpha.len() == self.texels.len()).then(|| {
            self.alpha = Some(alpha);
            self
        })
    }

    /// The same texture with the given wrap modes in `u` (`wrapS`) and `v` (`wrapT`).
    #[must_use]
    pub fn with_wrap(mut self, wrap: [Wrap; 2]) -> Self {
        self.wrap = wrap;
        self
    }

    /// Decodes an 8-bit sRGB image (PNG or JPEG bytes already decoded by `image`). The
    /// colour channels are linearised; an alpha channel, if the image has one, is kept as is.
    #[must_use]
    pub fn from_image(img: &image::DynamicImage) -> Option<Self> {
        let rgba = img.to_rgba8();
        let lut: Vec<f32> =
            (0..256).map(|c| lightvol_core::color::srgb_decode(f64::from(c) / 255.0) as f32).collect();
        let texels =
            rgba.pixels().map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]]).collect();
        let t = Self::from_linear(rgba.width(), rgba.height(), texels)?;
        if img.color().has_alpha() {
            t.with_alpha(rgba.pixels().map(|p| f32::from(p[3]) / 255.0).collect())
        } else {
            Some(t)
        }
    }

    /// True when the texture has an alpha channel.
    #[must_use]
    pub fn has_alpha(&self) -> bool {
        self.alpha.is_some()
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
        self.texels[self.index(x, y)]
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
            let t = self.texels[i];
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
        let Some(a) = &self.alpha else { return 1.0 };
        self.taps(uv).iter().map(|&(i, w)| w * f64::from(a[i])).sum()
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
