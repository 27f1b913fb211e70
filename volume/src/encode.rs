//! Storage encodings of the coefficients and the error each introduces.
//!
//! | encoding | bytes / node (9 coeffs) | per-coefficient error bound |
//! | --- | --- | --- |
//! | [`Encoding::F32`] | 108 | 0 (lossless) |
//! | [`Encoding::F16`] | 54 | `max(|c| 2^-11, 2^-25)` (round to nearest half) |
//! | [`Encoding::Srgb8`] | 27 | DC: largest half-step of 8-bit sRGB × scale; others: `range · scale / 255` |
//! | [`Encoding::DcNormalized8`] | 30 | `R_l (|Δc₀| + |c₀'| / 255)` |
//!
//! **sRGB-DC with range compression** (Ishmukhametov, \[Ish11\] §2.2.3 and Listing 2.1): each
//! colour channel is divided by a global scale `s_c` (the largest DC coefficient of that
//! channel), so the DC term lies in `[0, 1]`; it is stored in 8-bit sRGB (this crate uses the
//! exact IEC 61966-2-1 curve that sRGB texture formats decode in hardware, where the thesis
//! approximates it by `x^(1/2.2)`). The other coefficients, which can be negative, are
//! range-compressed linearly like normal maps: `byte = round((c/s + f) / (2f) · 255)` with
//! the range factor `f` (0.75 by default, "a rule of thumb", configurable) and decoded as
//! `s (2f · byte/255 - f)` (the thesis' HLSL `2*0.75*tex - 0.75`).
//!
//! **DC-normalized 8-bit** (the layout Unity's and Unreal's probe volumes use for L1/L2): the
//! DC term is kept at f16 per channel, every other coefficient is stored as the ratio
//! `c_lm / c_00` divided by the band range `R_l = sqrt(2l + 1)` in signed 8-bit-normalized
//! form. `R_l` is not a tuning constant: for non-negative radiance `|c_lm| ≤ max|Y_lm| ∫L
//! ≤ sqrt((2l+1)/4π) · sqrt(4π) c_00` (the addition theorem bounds `|Y_lm|`), so physically
//! valid data never clamps.
//!
//! Values outside an encoding's range are clamped and counted; the stated bounds include the
//! clamped excess. [`irradiance_error`] measures the max and RMS irradiance error over random
//! normals and reports the analytic bound beside it (per band, Cauchy-Schwarz with the
//! addition theorem: `|ΔE| ≤ Σ_l A_l sqrt((2l+1)/4π) sqrt(Σ_m δ_lm²)`). Node errors bound the
//! error anywhere in the volume because trilinear interpolation is a convex combination.

use half::f16;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use lightvol_core::color::{srgb_decode, srgb_encode};
use lightvol_sh::eval::eval_into;
use lightvol_sh::index::sh_lm;
use lightvol_sh::irradiance::cosine_lobe_factor;
use lightvol_sh::lowdisc::{SplitMix64, hash2};
use lightvol_sh::sampling::sample_uniform_sphere;

use crate::error::VolumeError;
use crate::volume::IrradianceVolume;

/// Default range-compression factor of [`Encoding::Srgb8`] (\[Ish11\] §2.2.3: "a rule of thumb
/// is that the other coefficients do not exceed the range of [-0.75..0.75]").
pub const DEFAULT_RANGE: f32 = 0.75;

/// How coefficients are stored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Encoding {
    /// 32-bit float, lossless.
    F32,
    /// IEEE half float.
    F16,
    /// 8-bit: DC in sRGB, the rest range-compressed by `range` (\[Ish11\] §2.2.3).
    Srgb8 {
        /// Range-compression factor `f`: non-DC coefficients map `[-f s, f s]` to `[0, 255]`.
        range: f32,
    },
    /// f16 DC, other coefficients 8-bit as a fraction of the DC term (Unity/Unreal style).
    DcNormalized8,
}

impl Encoding {
    /// \[Ish11\]'s scheme (§2.2.3) with the default range 0.75.
    pub const SRGB8: Self = Self::Srgb8 { range: DEFAULT_RANGE };

    /// A short stable name (`f32`, `f16`, `srgb8`, `dc_normalized8`).
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::F32 => "f32",
            Self::F16 => "f16",
            Self::Srgb8 { .. } => "srgb8",
            Self::DcNormalized8 => "dc_normalized8",
        }
    }

    /// Storage bytes per node for `coeffs` RGB coefficients (weights excluded).
    #[must_use]
    pub fn bytes_per_node(&self, coeffs: usize) -> usize {
        match self {
            Self::F32 => coeffs * 12,
            Self::F16 => coeffs * 6,
            Self::Srgb8 { .. } => coeffs * 3,
            Self::DcNormalized8 => 6 + (coeffs - 1) * 3,
        }
    }

    fn validate(&self) -> Result<(), VolumeError> {
        match self {
            Self::Srgb8 { range } if !(range.is_finite() && *range > 0.0) => {
                Err(VolumeError::InvalidData(format!("range-compression factor {range} must be positive")))
            }
            _ => Ok(()),
        }
    }
}

/// The stored form of an encoded volume.
#[derive(Debug, Clone, PartialEq)]
pub enum Payload {
    /// `[node][coeff][rgb]` f32.
    F32(Vec<f32>),
    /// `[node][coeff][rgb]` f16.
    F16(Vec<f16>),
    /// `[node][coeff][rgb]` bytes and the per-channel scale `s_c`.
    Srgb8 {
        /// Per-channel scale (largest DC coefficient, or 1 for an all-black channel).
        scale: [f32; 3],
        /// Encoded bytes.
        bytes: Vec<u8>,
    },
    /// `[node][rgb]` f16 DC terms and `[node][coeff-1][rgb]` ratio bytes.
    DcNormalized8 {
        /// DC coefficients.
        dc: Vec<f16>,
        /// Encoded ratios of the non-DC coefficients.
        ratios: Vec<u8>,
    },
}

/// A volume's coefficients in some [`Encoding`] (the grid, weights and metadata are kept
/// in the [`IrradianceVolume`] template it decodes into).
#[derive(Debug, Clone, PartialEq)]
pub struct EncodedVolume {
    encoding: Encoding,
    payload: Payload,
    template: IrradianceVolume,
    clamped: usize,
}

/// The largest decode error of 8-bit sRGB for values in `[0, 1]`: the largest distance from
/// a code's decoded value to the decoded midpoint with its neighbour (computed over all 256
/// codes, not typed in).
#[must_use]
pub fn srgb8_max_error() -> f64 {
    (0..256)
        .map(|k| {
            let c = srgb_decode(f64::from(k) / 255.0);
            let up = if k < 255 { srgb_decode((f64::from(k) + 0.5) / 255.0) - c } else { 0.0 };
            let down = if k > 0 { c - srgb_decode((f64::from(k) - 0.5) / 255.0) } else { 0.0 };
            up.max(down)
        })
        .fold(0.0, f64::max)
}

/// Band range `R_l = sqrt(2l + 1)` of [`Encoding::DcNormalized8`] (see the module docs).
fn band_range(j: usize) -> f64 {
    f64::from(2 * sh_lm(j).0 + 1).sqrt()
}

/// Signed-normalized 8-bit: `[-1, 1] → [0, 255]`.
fn snorm8(x: f64) -> u8 {
    ((x.clamp(-1.0, 1.0) + 1.0) * 0.5 * 255.0).round() as u8
}

fn unsnorm8(b: u8) -> f64 {
    f64::from(b) / 255.0 * 2.0 - 1.0
}

fn unit8(x: f64) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Encodes the coefficients of `vol`. Errors on an invalid range factor or (f16 paths) a
/// coefficient too large for half precision (|c| > 65504).
pub fn encode(vol: &IrradianceVolume, encoding: Encoding) -> Result<EncodedVolume, VolumeError> {
    encoding.validate()?;
    let data = vol.data();
    let coeffs = vol.coeffs();
    let k = coeffs * 3;
    let to_f16 = |v: f32, what: &str| -> Result<f16, VolumeError> {
        let h = f16::from_f32(v);
        if h.is_finite() {
            Ok(h)
        } else {
            Err(VolumeError::InvalidData(format!("{what} {v} exceeds the f16 range (65504)")))
        }
    };
    let mut clamped = 0usize;
    let payload = match encoding {
        Encoding::F32 => Payload::F32(data.to_vec()),
        Encoding::F16 => {
            Payload::F16(data.iter().map(|&v| to_f16(v, "coefficient")).collect::<Result<_, _>>()?)
        }
        Encoding::Srgb8 { range } => {
            let scale = srgb8_scale(vol);
            let r = f64::from(range);
            let bytes = data
                .iter()
                .enumerate()
                .map(|(i, &v)| {
                    let (j, ch) = ((i % k) / 3, i % 3);
                    let x = f64::from(v) / f64::from(scale[ch]);
                    if j == 0 {
                        clamped += usize::from(!(0.0..=1.0).contains(&x));
                        unit8(srgb_encode(x.clamp(0.0, 1.0)))
                    } else {
                        clamped += usize::from(x.abs() > r);
                        unit8((x.clamp(-r, r) + r) / (2.0 * r))
                    }
                })
                .collect();
            Payload::Srgb8 { scale, bytes }
        }
        Encoding::DcNormalized8 => {
            let n = vol.spec().node_count();
            let mut dc = Vec::with_capacity(n * 3);
            let mut ratios = Vec::with_capacity(n * (k - 3));
            for node in 0..n {
                let s = vol.node(node);
                for ch in 0..3 {
                    dc.push(to_f16(s[ch], "DC coefficient")?);
                }
                for j in 1..coeffs {
                    for ch in 0..3 {
                        let c0 = f64::from(s[ch]);
                        let c = f64::from(s[3 * j + ch]);
                        let rho = if c0 > 0.0 { c / (c0 * band_range(j)) } else { 0.0 };
                        clamped += usize::from(rho.abs() > 1.0 || (c0 <= 0.0 && c != 0.0));
                        ratios.push(snorm8(rho));
                    }
                }
            }
            Payload::DcNormalized8 { dc, ratios }
        }
    };
    Ok(EncodedVolume { encoding, payload, template: vol.clone(), clamped })
}

/// Per-channel scale of [`Encoding::Srgb8`]: the largest DC coefficient (1 if none is
/// positive).
fn srgb8_scale(vol: &IrradianceVolume) -> [f32; 3] {
    let mut s = [0.0f32; 3];
    for node in 0..vol.spec().node_count() {
        let c = vol.node(node);
        for ch in 0..3 {
            s[ch] = s[ch].max(c[ch]);
        }
    }
    s.map(|v| if v > 0.0 { v } else { 1.0 })
}

impl EncodedVolume {
    /// The encoding.
    #[must_use]
    pub fn encoding(&self) -> Encoding {
        self.encoding
    }

    /// The stored data.
    #[must_use]
    pub fn payload(&self) -> &Payload {
        &self.payload
    }

    /// Coefficients that were outside the encoding's range and clamped.
    #[must_use]
    pub fn clamped(&self) -> usize {
        self.clamped
    }

    /// Bytes of coefficient storage.
    #[must_use]
    pub fn byte_size(&self) -> usize {
        self.encoding.bytes_per_node(self.template.coeffs()) * self.template.spec().node_count()
    }

    /// Decodes back to an f32 volume (same grid, weights and metadata as the original).
    #[must_use]
    pub fn decode(&self) -> IrradianceVolume {
        let mut out = self.template.clone();
        let coeffs = out.coeffs();
        let k = coeffs * 3;
        let n = out.spec().node_count();
        let mut node_vals = vec![0.0f32; k];
        for node in 0..n {
            for (q, v) in node_vals.iter_mut().enumerate() {
                let i = node * k + q;
                let (j, ch) = (q / 3, q % 3);
                *v = match &self.payload {
                    Payload::F32(d) => d[i],
                    Payload::F16(d) => d[i].to_f32(),
                    Payload::Srgb8 { scale, bytes } => {
                        let Encoding::Srgb8 { range } = self.encoding else { unreachable!() };
                        let b = f64::from(bytes[i]) / 255.0;
                        let x = if j == 0 {
                            srgb_decode(b)
                        } else {
                            let r = f64::from(range);
                            2.0 * r * b - r
                        };
                        (x * f64::from(scale[ch])) as f32
                    }
                    Payload::DcNormalized8 { dc, ratios } => {
                        let c0 = f64::from(dc[node * 3 + ch].to_f32());
                        if j == 0 {
                            c0 as f32
                        } else {
                            let rho = unsnorm8(ratios[node * (k - 3) + q - 3]);
                            (c0 * band_range(j) * rho) as f32
                        }
                    }
                };
            }
            out.set_node(node, &node_vals).expect("decoded values are finite");
        }
        out
    }
}

/// Volume-wide constants of the error bounds (the sRGB scale needs a pass over all nodes).
#[derive(Debug, Clone, Copy)]
struct BoundContext {
    encoding: Encoding,
    scale: [f32; 3],
    srgb_err: f64,
}

impl BoundContext {
    fn new(vol: &IrradianceVolume, encoding: Encoding) -> Self {
        Self { encoding, scale: srgb8_scale(vol), srgb_err: srgb8_max_error() }
    }

    fn bound(&self, vol: &IrradianceVolume, node: usize, j: usize, ch: usize) -> f64 {
        let s = vol.node(node);
        let c = f64::from(s[3 * j + ch]);
        let half_ulp16 = |v: f64| (v.abs() * 2f64.powi(-11)).max(2f64.powi(-25));
        let base = match self.encoding {
            Encoding::F32 => return 0.0,
            Encoding::F16 => half_ulp16(c),
            Encoding::Srgb8 { range } => {
                let scale = f64::from(self.scale[ch]);
                let r = f64::from(range);
                let x = c / scale;
                if j == 0 {
                    let excess = if x < 0.0 { -x } else { (x - 1.0).max(0.0) };
                    scale * (self.srgb_err + excess)
                } else {
                    scale * (r / 255.0 + (x.abs() - r).max(0.0))
                }
            }
            Encoding::DcNormalized8 => {
                let c0 = f64::from(s[ch]);
                let d0 = half_ulp16(c0);
                let rr = band_range(j);
                if j == 0 {
                    d0
                } else if c0 <= 0.0 {
                    // Stored as ratio 0 (code 128, which decodes to 1/255).
                    c.abs() + rr * (c0.abs() + d0) / 255.0
                } else {
                    let excess = (c.abs() - c0 * rr).max(0.0);
                    rr * (d0 + (c0 + d0) / 255.0) + excess
                }
            }
        };
        // The decode rounds its f64 result to f32 once: half an ulp of the decoded magnitude.
        base + (c.abs() + base) * 2f64.powi(-24)
    }
}

/// The analytic bound on `|decoded - original|` for coefficient `(j, ch)` of `node` under
/// `encoding` (see the module docs; includes clamped excess and the f32 rounding of the
/// decode). Costs a pass over the volume for [`Encoding::Srgb8`]; [`irradiance_error`]
/// evaluates all bounds at once.
#[must_use]
pub fn coefficient_error_bound(
    vol: &IrradianceVolume,
    encoding: Encoding,
    node: usize,
    j: usize,
    ch: usize,
) -> f64 {
    BoundContext::new(vol, encoding).bound(vol, node, j, ch)
}

/// All coefficient bounds of a volume, `[node][coeff][rgb]`.
#[must_use]
pub fn coefficient_error_bounds(vol: &IrradianceVolume, encoding: Encoding) -> Vec<f64> {
    let ctx = BoundContext::new(vol, encoding);
    let k = vol.coeffs() * 3;
    (0..vol.data().len()).map(|i| ctx.bound(vol, i / k, (i % k) / 3, i % 3)).collect()
}

/// Max and RMS irradiance error an encoding introduces, with the analytic bound.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EncodingErrorReport {
    /// The encoding measured.
    pub encoding: Encoding,
    /// Largest `|E_decoded(n) - E(n)|` over nodes, channels and random normals.
    pub max_abs: f64,
    /// Root mean square of the same differences.
    pub rms: f64,
    /// Largest `|E(n)|` seen, for scale.
    pub max_irradiance: f64,
    /// Largest error relative to the node's mean irradiance `Ē = π Y_00 c_00` (per
    /// channel, nodes with `Ē > 0`): what a viewer notices in dim regions, where a
    /// volume-wide scale (as in [`Encoding::Srgb8`]) costs the most precision.
    pub max_rel: f64,
    /// The analytic bound (max over nodes and channels) that `max_abs` must respect.
    pub bound: f64,
    /// Coefficients clamped by the encoding.
    pub clamped: usize,
    /// Bytes of coefficient storage.
    pub bytes: usize,
}

/// Encodes `vol`, decodes it, and compares irradiance (Kontkanen & Laine Eq. 1, in f64) at
/// every node for `normals_per_node` random unit normals (seeded per node by
/// `hash2(seed, node)`, so the result is independent of thread count).
pub fn irradiance_error(
    vol: &IrradianceVolume,
    encoding: Encoding,
    normals_per_node: usize,
    seed: u64,
) -> Result<EncodingErrorReport, VolumeError> {
    let enc = encode(vol, encoding)?;
    let dec = enc.decode();
    let coeffs = vol.coeffs();
    let bands = vol.bands();
    let a: Vec<f64> = (0..coeffs).map(|j| cosine_lobe_factor(sh_lm(j).0)).collect();
    // Per band: A_l sqrt((2l+1)/4π).
    let band_factor: Vec<f64> = (0..bands)
        .map(|l| cosine_lobe_factor(l as u32) * ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt())
        .collect();
    let ctx = BoundContext::new(vol, encoding);
    let y00 = 0.5 / std::f64::consts::PI.sqrt();
    let per_node: Vec<[f64; 5]> = (0..vol.spec().node_count())
        .into_par_iter()
        .map(|node| {
            let (orig, got) = (vol.node(node), dec.node(node));
            let mut bound = 0.0f64;
            for ch in 0..3 {
                let mut per_band = vec![0.0f64; bands];
                for j in 0..coeffs {
                    per_band[sh_lm(j).0 as usize] += ctx.bound(vol, node, j, ch).powi(2);
                }
                let b: f64 = per_band.iter().zip(&band_factor).map(|(s, f)| f * s.sqrt()).sum();
                bound = bound.max(b);
            }
            let mut rng = SplitMix64::new(hash2(seed, node as u64));
            let mut y = vec![0.0f64; coeffs];
            let (mut max_abs, mut sum_sq, mut max_e, mut max_rel) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for _ in 0..normals_per_node {
                let n = sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
                eval_into(bands, n, &mut y);
                for ch in 0..3 {
                    let (mut e0, mut e1) = (0.0, 0.0);
                    for j in 0..coeffs {
                        e0 += a[j] * y[j] * f64::from(orig[3 * j + ch]);
                        e1 += a[j] * y[j] * f64::from(got[3 * j + ch]);
                    }
                    max_abs = max_abs.max((e1 - e0).abs());
                    sum_sq += (e1 - e0).powi(2);
                    max_e = max_e.max(e0.abs());
                    let mean = std::f64::consts::PI * y00 * f64::from(orig[ch]);
                    if mean > 0.0 {
                        max_rel = max_rel.max((e1 - e0).abs() / mean);
                    }
                }
            }
            [max_abs, sum_sq, max_e, bound, max_rel]
        })
        .collect();
    let count = (vol.spec().node_count() * normals_per_node * 3).max(1) as f64;
    let (mut max_abs, mut sum_sq, mut max_e, mut bound, mut max_rel) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    // Reduced in node order: the same sums for any thread count.
    for [m, s, e, b, r] in per_node {
        max_abs = max_abs.max(m);
        sum_sq += s;
        max_e = max_e.max(e);
        bound = bound.max(b);
        max_rel = max_rel.max(r);
    }
    Ok(EncodingErrorReport {
        encoding,
        max_abs,
        rms: (sum_sq / count).sqrt(),
        max_irradiance: max_e,
        max_rel,
        bound,
        clamped: enc.clamped(),
        bytes: enc.byte_size(),
    })
}
