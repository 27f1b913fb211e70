//! Per-receiver accumulation in f64: the slow, readable reference for the image-space
//! pipeline's f32 kernels (\[SGNS07\] §3-§5, Eq. 4, 8-10, 12-17).
//!
//! For a receiver at `p` with unit normal `N_p` and proxies `i`:
//! 1. each proxy is seen through the replacement rule ([`crate::proxy::view_from`]);
//! 2. `f = Σ_i rot(O^log(α_i), d̂_i)` (Eq. 4, 8), exponentiated once: `O_p = exp(f)`
//!    (HYB or the eigen reference);
//! 3. indirect `Ĩ_p = Σ_i I_i` by point sampling (Eq. 13), averaging (Eq. 15, exact `D` or
//!    the paper's fits) or the exact operator (Eq. 17), each scaled by the proxy's
//!    `albedo / π` (a diffuse proxy's exit radiance is `ρ/π` times its irradiance; the paper's
//!    Eq. 13 leaves the factor implicit);
//! 4. `I_p = ξ_p Ĩ_p` with `ξ_p = (V_p)_0 / (ω_p / sqrt(4π))` (Eq. 12);
//! 5. `L_p = O_p * L + I_p` (Eq. 9) and `ψ_p = H(N_p) · L_p` (Eq. 10), with `*` the SH
//!    product and `H(N) = rot(g_cos, N)`.

use std::any::Any;
use std::f64::consts::PI;
use std::sync::OnceLock;

use lightvol_sh::coeffs::{Sh, ShRgb};
use lightvol_sh::eval::eval_basis;
use lightvol_sh::gaunt::product;
use lightvol_sh::irradiance::radiance_to_irradiance_rgb;
use lightvol_sh::rotate::ShRotation;
use lightvol_sh::sampling::Frame;
use lightvol_sh::shexp::{HYB_NORM_THRESHOLD, OlTable, exp_hyb, exp_reference, unit};
use lightvol_sh::zonal::Zh;

use crate::light::LightField;
use crate::operators::d_paper_fit;
use crate::proxy::{SphereProxy, view_from};
use crate::tables::{MAX_BANDS, ProxyTables, SQRT_4PI, SmoothClamp, Table, rotate_zh, table_alpha};

/// How the indirect radiance of one proxy is computed (\[SGNS07\] §5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum IndirectMethod {
    /// No indirect light.
    None,
    /// Point-sampled: the irradiance at the proxy point facing `p` over the whole disk (Eq. 13).
    PointSampled,
    /// Averaged over the disk with the exact `D(θ)` table (Eq. 14-15).
    Averaged,
    /// Averaged with the paper's polynomial fits of `D` (Fig. 4; band 3 of `D` is dropped).
    AveragedPaperFit,
    /// The exact operator `R⁻¹ M(θ) R L̃` (Eq. 16-17).
    Exact,
}

/// How `exp(f)` is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExpMethod {
    /// Eigen-decomposition of the product matrix (slow, exact).
    Reference,
    /// Ren et al.'s HYB (scaling and squaring with OL), as in the paper.
    Hyb,
}

/// Options of the reference shader.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeOptions {
    /// Indirect method.
    pub indirect: IndirectMethod,
    /// Exponential.
    pub exp: ExpMethod,
    /// Smooth clamp of the shadow tables (`None`: infinite sphere of influence).
    pub shadow_clamp: Option<SmoothClamp>,
    /// Smooth clamp of the indirect tables.
    pub indirect_clamp: Option<SmoothClamp>,
}

impl Default for ShadeOptions {
    fn default() -> Self {
        Self {
            indirect: IndirectMethod::Averaged,
            exp: ExpMethod::Hyb,
            shadow_clamp: None,
            indirect_clamp: None,
        }
    }
}

/// The shading of one receiver, split by term (RGB, `ψ` of Eq. 10 and its parts).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shade<const N: usize> {
    /// `H(N_p) · L`: no proxies.
    pub unshadowed: [f64; 3],
    /// `H(N_p) · (O_p * L)`: shadows only.
    pub shadowed: [f64; 3],
    /// `H(N_p) · I_p`: normalised indirect light.
    pub indirect: [f64; 3],
    /// `O_p` (Eq. 4).
    pub occlusion: Sh<f64, N>,
    /// `ξ_p` (Eq. 12); 1 when no proxy is seen.
    pub xi: f64,
}

impl<const N: usize> Shade<N> {
    /// `ψ_p` with shadows and indirect light.
    #[must_use]
    pub fn total(&self) -> [f64; 3] {
        core::array::from_fn(|k| self.shadowed[k] + self.indirect[k])
    }
}

/// The process-wide OL table for `N` coefficients (Ren et al.'s OL fitted on sphere
/// blockers by lightvol-sh, 64 bins, seed 1), built on first use.
#[must_use]
pub fn shared_ol_table<const N: usize>() -> &'static OlTable<N> {
    const { assert!(N == 9 || N == 16, "OL tables are shared for 9 or 16 coefficients") };
    static T9: OnceLock<Box<dyn Any + Send + Sync>> = OnceLock::new();
    static T16: OnceLock<Box<dyn Any + Send + Sync>> = OnceLock::new();
    let cell = if N == 9 { &T9 } else { &T16 };
    let b = cell.get_or_init(|| Box::new(OlTable::<N>::fit_sphere_blockers(64, 1)));
    b.downcast_ref::<OlTable<N>>().expect("the cell for N holds an OlTable<N>")
}

/// `H(N) = rot(g_cos, N)` (Eq. 10): the clamped cosine around the normal.
#[must_use]
pub fn cosine_lobe<const N: usize>(n: [f64; 3]) -> Sh<f64, N> {
    let g = Zh::<f64, MAX_BANDS>::clamped_cosine().0;
    rotate_zh::<f64, N>(&g, n)
}

/// `exp(f)` by the chosen method.
#[must_use]
pub fn exponentiate<const N: usize>(f: &Sh<f64, N>, method: ExpMethod) -> Sh<f64, N> {
    match method {
        ExpMethod::Reference => exp_reference(f),
        ExpMethod::Hyb => exp_hyb(shared_ol_table::<N>(), f, HYB_NORM_THRESHOLD),
    }
}

/// A rotation taking the unit vector `d` to `+z`.
fn to_canonical(d: [f64; 3]) -> glam::DMat3 {
    let f = Frame::from_normal(d);
    glam::DMat3::from_cols(f.t.into(), f.b.into(), f.n.into()).transpose()
}

/// Indirect radiance `I_i` of one proxy (Eq. 13, 15 or 17) for radiance `light` at its
/// centre, without the clamp.
#[must_use]
pub fn proxy_indirect<const N: usize>(
    tables: &ProxyTables,
    method: IndirectMethod,
    proxy: &SphereProxy,
    dir: [f64; 3],
    alpha: f64,
    light: &ShRgb<f64, N>,
    clamp: Option<&SmoothClamp>,
) -> ShRgb<f64, N> {
    let vis: Sh<f64, N> = rotate_zh(&tables.lookup(Table::Visibility, alpha, clamp), dir);
    let irr = radiance_to_irradiance_rgb(light);
    let kappa: [f64; 3] = match method {
        IndirectMethod::None => return ShRgb([Sh::ZERO; 3]),
        IndirectMethod::PointSampled => irr.eval([-dir[0], -dir[1], -dir[2]]),
        IndirectMethod::Averaged => {
            let d: Sh<f64, N> = rotate_zh(&tables.lookup(Table::Averaged, alpha, None), dir);
            irr.dot_scalar(&d)
        }
        IndirectMethod::AveragedPaperFit => {
            let f = d_paper_fit(alpha);
            let d: Sh<f64, N> = rotate_zh(&[f[0], f[1], f[2], 0.0], dir);
            irr.dot_scalar(&d)
        }
        IndirectMethod::Exact => {
            let m = tables.m_lookup(alpha);
            let w = clamp.map_or(1.0, |c| clamp_weight(c, alpha));
            let out = apply_exact_operator(&m, dir, &irr);
            return ShRgb(core::array::from_fn(|c| out.0[c] * (w * proxy.albedo[c] / PI)));
        }
    };
    ShRgb(core::array::from_fn(|c| vis * (proxy.albedo[c] / PI * kappa[c])))
}

/// `R⁻¹ M R L̃` (Eq. 17) for a canonical operator `m` (row-major `N × N`) and a proxy in
/// direction `dir`: the exact radiance of a white proxy's disk, times π.
#[must_use]
pub fn apply_exact_operator<const N: usize>(m: &[f64], dir: [f64; 3], irr: &ShRgb<f64, N>) -> ShRgb<f64, N> {
    let r = to_canonical(dir);
    let bands = N.isqrt();
    let fwd = ShRotation::from_mat3(bands, r);
    let back = ShRotation::from_mat3(bands, r.transpose());
    ShRgb(core::array::from_fn(|c| {
        let lc = fwd.apply(&irr.0[c]);
        let mut out = Sh::<f64, N>::ZERO;
        for a in 0..N {
            out.0[a] = (0..N).map(|b| m[a * N + b] * lc.0[b]).sum();
        }
        back.apply(&out)
    }))
}

/// The clamp weight interpolated between table entries (what the clamped tables apply).
fn clamp_weight(c: &SmoothClamp, alpha: f64) -> f64 {
    let (i, t) = crate::tables::locate(alpha);
    (1.0 - t) * c.weight(table_alpha(i)) + t * c.weight(table_alpha(i + 1))
}

/// Shades one receiver (the f64 reference of the pipeline). `N` is 9 or 16.
#[must_use]
pub fn shade_receiver<const N: usize>(
    p: [f64; 3],
    normal: [f64; 3],
    proxies: &[SphereProxy],
    light: &impl LightField<N>,
    options: &ShadeOptions,
) -> Shade<N> {
    let tables = ProxyTables::shared::<N>();
    let l = light.radiance_at(p);
    let h = cosine_lobe::<N>(normal);
    let mut f = Sh::<f64, N>::ZERO;
    let mut ind = ShRgb([Sh::<f64, N>::ZERO; 3]);
    let mut omega = 0.0;
    for proxy in proxies {
        let Some(v) = view_from(proxy, p, normal) else { continue };
        let olog = tables.lookup(Table::LogVisibility, v.alpha, options.shadow_clamp.as_ref());
        f += rotate_zh(&olog, v.dir);
        if options.indirect != IndirectMethod::None {
            let clamp = options.indirect_clamp.as_ref();
            omega += tables.lookup(Table::Visibility, v.alpha, clamp)[0] * SQRT_4PI;
            let lc = light.radiance_at(proxy.center);
            ind += proxy_indirect(tables, options.indirect, proxy, v.dir, v.alpha, &lc, clamp);
        }
    }
    let o = exponentiate(&f, options.exp);
    let vp0 = SQRT_4PI - o.0[0];
    let xi = if omega > 0.0 { vp0 / (omega / SQRT_4PI) } else { 1.0 };
    let unshadowed = l.dot_scalar(&h);
    let shadowed: [f64; 3] = core::array::from_fn(|c| product(&o, &l.0[c]).dot(&h));
    let indirect = ind.dot_scalar(&h).map(|v| v * xi);
    Shade { unshadowed, shadowed, indirect, occlusion: o, xi }
}

/// `exp(f)` evaluated for a single blocker straight from the exact cap visibility (Eq. 9
/// with `m = 1`): `(1 - rot(V(α), d̂)) * L`, dotted with `H`. The oracle of the
/// single-proxy shadow test.
#[must_use]
pub fn single_blocker_exact<const N: usize>(
    alpha: f64,
    dir: [f64; 3],
    normal: [f64; 3],
    light: &ShRgb<f64, N>,
) -> [f64; 3] {
    let cap = Zh::<f64, MAX_BANDS>::cap(alpha.asin()).0;
    let o = unit::<N>() - rotate_zh::<f64, N>(&cap, dir);
    let h = cosine_lobe::<N>(normal);
    core::array::from_fn(|c| product(&o, &light.0[c]).dot(&h))
}

/// `y(dir)` as an SH vector (the delta function's projection).
#[must_use]
pub fn delta<const N: usize>(dir: [f64; 3]) -> Sh<f64, N> {
    Sh(eval_basis::<f64, N>(dir))
}
