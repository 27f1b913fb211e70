//! The f32 per-receiver kernels of the image-space pipeline: proxy accumulation (Eq. 4, 8,
//! 12, 15) and the exponentiation pass (HYB, Eq. 9), with precomputed, pre-scaled,
//! smooth-clamped f32 tables. [`crate::accumulate::shade_receiver`] is the f64 reference;
//! `tests/kernel.rs` compares the two.
//!
//! Only bands 0-2 of the incident radiance reach a diffuse receiver (the clamped cosine has
//! no band-3 term), so the kernels output `L_p` with 9 coefficients per channel even when
//! shadows are accumulated with 16.

use lightvol_sh::coeffs::ShRgb;
use lightvol_sh::eval::eval_basis;
use lightvol_sh::gaunt::GauntTable;
use lightvol_sh::irradiance::radiance_to_irradiance_rgb;
use lightvol_sh::shexp::{HYB_NORM_THRESHOLD, OlTable, exp_hyb_with};
use lightvol_sh::zonal::zh_scale;

use crate::accumulate::shared_ol_table;
use crate::lanes::BasisRecurrence;
use crate::light::LightField;
use crate::operators::d_paper_fit;
use crate::proxy::{SphereProxy, view_f32};
use crate::tables::{MAX_BANDS, ProxyTables, SQRT_4PI, SmoothClamp, TABLE_ENTRIES, Table, table_alpha};

/// A ZH table entry in f32 (up to 4 bands).
pub type Zh4f = [f32; MAX_BANDS];

/// RGB × 9 coefficients: incident radiance as the diffuse shader sees it.
pub type Rgb9 = [f32; 27];

/// A proxy prepared for the kernels: f32 geometry and `(ρ/π) L̃(c)` per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedProxy<const N: usize> {
    /// Centre.
    pub center: [f32; 3],
    /// Radius.
    pub radius: f32,
    /// `(ρ_c / π) L̃_c(centre)`: the proxy's exit radiance per unit `κ` weight (Eq. 15).
    pub exit: [[f32; N]; 3],
}

/// Prepares proxies: light at each centre, convolved to irradiance, times albedo/π.
#[must_use]
pub fn prepare<const N: usize>(proxies: &[SphereProxy], light: &impl LightField<N>) -> Vec<PreparedProxy<N>> {
    proxies
        .iter()
        .map(|p| {
            let irr: ShRgb<f64, N> = radiance_to_irradiance_rgb(&light.radiance_at(p.center));
            PreparedProxy {
                center: p.center.map(|v| v as f32),
                radius: p.radius as f32,
                exit: core::array::from_fn(|c| {
                    core::array::from_fn(|i| (irr.0[c].0[i] * p.albedo[c] / std::f64::consts::PI) as f32)
                }),
            }
        })
        .collect()
}

/// Per-receiver accumulators (the receiver buffer's accumulation targets).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Accum<const N: usize> {
    /// `Σ rot(O^log)` (Eq. 4).
    pub log_vis: [f32; N],
    /// `Ĩ_p` (bands 0-2, RGB).
    pub indirect: Rgb9,
    /// `ω_p` (clamped).
    pub omega: f32,
    /// Number of proxies that touched the receiver.
    pub count: u32,
}

impl<const N: usize> Default for Accum<N> {
    fn default() -> Self {
        Self { log_vis: [0.0; N], indirect: [0.0; 27], omega: 0.0, count: 0 }
    }
}

/// Output of the exponentiation pass for one receiver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// `O_p * L` (bands 0-2).
    pub shadowed: Rgb9,
    /// `I_p = ξ_p Ĩ_p` (bands 0-2).
    pub indirect: Rgb9,
}

/// Per-light data of the exponentiation pass (see [`Kernel::light_matrix`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightMatrix<const N: usize> {
    pub(crate) m: [[[f32; N]; 9]; 3],
    pub(crate) l9: Rgb9,
}

/// The f32 tables and product schedules for `N` = 9 or 16 coefficients.
#[derive(Clone, Debug)]
pub struct Kernel<const N: usize> {
    pub(crate) olog: Vec<[f32; MAX_BANDS]>,
    pub(crate) vis: Vec<[f32; MAX_BANDS]>,
    pub(crate) omega: Vec<f32>,
    pub(crate) d: Vec<[f32; MAX_BANDS]>,
    pub(crate) alpha_shadow: f32,
    pub(crate) alpha_indirect: f32,
    pub(crate) indirect: bool,
    pub(crate) ol: &'static OlTable<N>,
    /// Squaring schedule grouped by output: `square_start[k]..square_start[k+1]` index
    /// `square_ij` (packed `i`, `j`) and `square_v` (with the factor 2 for `i < j`).
    pub(crate) square_start: Vec<usize>,
    pub(crate) square_ij: Vec<[u8; 2]>,
    pub(crate) square_v: Vec<f32>,
    pub(crate) prod9: Vec<(u16, u16, u16, f32)>,
    pub(crate) basis: BasisRecurrence,
}

/// Which `D` the kernel uses for the averaged indirect light (Eq. 15).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelIndirect {
    /// No indirect light.
    None,
    /// The exact `D(α)` table.
    Averaged,
    /// The paper's polynomial fits.
    AveragedPaperFit,
}

impl<const N: usize> Kernel<N> {
    /// Builds the kernel: tables scaled by `sqrt(4π/(2l+1))` (Eq. 8) and smooth-clamped at
    /// `1/eta_shadow` (log visibility) and `1/eta_indirect` (visibility).
    #[must_use]
    pub fn new(eta_shadow: f64, eta_indirect: f64, indirect: KernelIndirect) -> Self {
        let t = ProxyTables::shared::<N>();
        let (cs, ci) = (SmoothClamp::new(eta_shadow), SmoothClamp::new(eta_indirect));
        let scaled = |z: [f64; MAX_BANDS], w: f64| -> [f32; MAX_BANDS] {
            core::array::from_fn(|l| (z[l] * w * zh_scale(l as u32)) as f32)
        };
        let mut k = Self {
            olog: Vec::new(),
            vis: Vec::new(),
            omega: Vec::new(),
            d: Vec::new(),
            alpha_shadow: (1.0 / eta_shadow) as f32,
            alpha_indirect: (1.0 / eta_indirect) as f32,
            indirect: indirect != KernelIndirect::None,
            ol: shared_ol_table::<N>(),
            square_start: vec![0; N + 1],
            square_ij: Vec::new(),
            square_v: Vec::new(),
            prod9: Vec::new(),
            basis: BasisRecurrence::new(),
        };
        for i in 0..TABLE_ENTRIES {
            let a = table_alpha(i);
            k.olog.push(scaled(t.entry(Table::LogVisibility, i), cs.weight(a)));
            let v = t.entry(Table::Visibility, i);
            k.vis.push(scaled(v, ci.weight(a)));
            k.omega.push((v[0] * ci.weight(a) * SQRT_4PI) as f32);
            let d = match indirect {
                KernelIndirect::AveragedPaperFit => {
                    let f = d_paper_fit(a);
                    [f[0], f[1], f[2], 0.0]
                }
                _ => t.entry(Table::Averaged, i),
            };
            k.d.push(scaled(d, 1.0));
        }
        let bands = N.isqrt();
        for e in GauntTable::cached(bands).entries() {
            // Entries come sorted by (k, i, j).
            if e.i <= e.j {
                let v = if e.i == e.j { e.value } else { 2.0 * e.value };
                k.square_ij.push([e.i as u8, e.j as u8]);
                k.square_v.push(v as f32);
                k.square_start[e.k as usize + 1] = k.square_ij.len();
            }
            if e.k < 9 {
                k.prod9.push((e.i, e.j, e.k, e.value as f32));
            }
        }
        for kk in 1..=N {
            k.square_start[kk] = k.square_start[kk].max(k.square_start[kk - 1]);
        }
        k
    }

    /// The kernel's f32 tables per entry: `O^log` and `V` scaled by `sqrt(4π/(2l+1))` and
    /// smooth-clamped, `ω` (clamped), and the scaled `D` — for ports of this kernel (the GPU
    /// evaluator) that must use exactly the same numbers.
    #[must_use]
    pub fn tables(&self) -> (&[Zh4f], &[Zh4f], &[f32], &[Zh4f]) {
        (&self.olog, &self.vis, &self.omega, &self.d)
    }

    /// Adds the proxies `list` (indices into `proxies`) seen from receiver `p`, normal `n`.
    pub fn accumulate(
        &self,
        p: [f32; 3],
        n: [f32; 3],
        proxies: &[PreparedProxy<N>],
        list: &[u32],
        acc: &mut Accum<N>,
    ) {
        let alpha_min =
            if self.indirect { self.alpha_shadow.min(self.alpha_indirect) } else { self.alpha_shadow };
        for &pi in list {
            let pr = &proxies[pi as usize];
            // Cheap rejection outside the sphere of influence: the replacement sphere lies
            // inside the original, so its α is no larger than the original's r / d.
            let v = [pr.center[0] - p[0], pr.center[1] - p[1], pr.center[2] - p[2]];
            let d2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
            if d2 * alpha_min * alpha_min >= pr.radius * pr.radius {
                continue;
            }
            let Some((dir, alpha)) = view_f32(pr.center, pr.radius, p, n) else { continue };
            let shadow = alpha > self.alpha_shadow;
            let ind = self.indirect && alpha > self.alpha_indirect;
            if !shadow && !ind {
                continue;
            }
            acc.count += 1;
            let y = eval_basis::<f32, N>(dir);
            let x = alpha * (TABLE_ENTRIES - 1) as f32;
            let i = (x as usize).min(TABLE_ENTRIES - 2);
            // Linear in α² (see `tables::locate`): t = (x² - i²) / (2i + 1).
            let t = (x * x - (i * i) as f32) / (2 * i + 1) as f32;
            let lerp = |tab: &[[f32; MAX_BANDS]]| -> [f32; MAX_BANDS] {
                core::array::from_fn(|l| tab[i][l] + t * (tab[i + 1][l] - tab[i][l]))
            };
            if shadow {
                let z = lerp(&self.olog);
                for j in 0..N {
                    acc.log_vis[j] += z[band(j)] * y[j];
                }
            }
            if ind {
                let v = lerp(&self.vis);
                let d = lerp(&self.d);
                acc.omega += self.omega[i] + t * (self.omega[i + 1] - self.omega[i]);
                let dy: [f32; N] = core::array::from_fn(|j| d[band(j)] * y[j]);
                let vy: [f32; 9] = core::array::from_fn(|j| v[band(j)] * y[j]);
                for c in 0..3 {
                    let e = &pr.exit[c];
                    let mut kappa = 0.0;
                    for j in 0..N {
                        kappa += dy[j] * e[j];
                    }
                    for j in 0..9 {
                        acc.indirect[9 * c + j] += kappa * vy[j];
                    }
                }
            }
        }
    }

    /// The exponentiation pass: `O_p = exp(f)` by HYB, `O_p * L` and `ξ_p Ĩ_p` (Eq. 9, 12).
    #[must_use]
    pub fn finish(&self, acc: &Accum<N>, light: &[[f32; N]; 3]) -> Incident {
        self.finish_with(acc, &self.light_matrix(light))
    }

    /// The SH product matrices of the light restricted to output bands 0-2,
    /// `(M_L)_{ki} = Σ_j G_ijk L_j`, so that `(O * L)_k = Σ_i (M_L)_{ki} O_i`. For a uniform
    /// light they are computed once per frame.
    #[must_use]
    pub fn light_matrix(&self, light: &[[f32; N]; 3]) -> LightMatrix<N> {
        let mut m = LightMatrix { m: [[[0.0; N]; 9]; 3], l9: [0.0; 27] };
        for &(i, j, k, v) in &self.prod9 {
            for c in 0..3 {
                m.m[c][k as usize][i as usize] += v * light[c][j as usize];
            }
        }
        for c in 0..3 {
            m.l9[9 * c..9 * c + 9].copy_from_slice(&light[c][..9]);
        }
        m
    }

    /// [`Self::finish`] with precomputed light matrices.
    #[must_use]
    pub fn finish_with(&self, acc: &Accum<N>, light: &LightMatrix<N>) -> Incident {
        let mut out = Incident { shadowed: light.l9, indirect: [0.0; 27] };
        if acc.count == 0 {
            return out;
        }
        let o = self.exp_hyb(&acc.log_vis);
        for c in 0..3 {
            for k in 0..9 {
                let row = &light.m[c][k];
                let mut s = 0.0;
                for i in 0..N {
                    s += row[i] * o[i];
                }
                out.shadowed[9 * c + k] = s;
            }
        }
        if acc.omega > 0.0 {
            let xi = (SQRT_4PI as f32 - o[0]) / (acc.omega / SQRT_4PI as f32);
            for j in 0..27 {
                out.indirect[j] = xi * acc.indirect[j];
            }
        }
        out
    }

    /// HYB exponential in f32 (Ren et al. 2006, \[SGNS07\] Eq. 9): the f32 twin of the f64
    /// reference `lightvol_sh::shexp::exp_hyb` (the same [`exp_hyb_with`], with the shared OL
    /// table), squaring with [`Self::square`] instead of `lightvol_sh::gaunt::product`.
    /// `tests/kernel.rs` compares the two.
    #[must_use]
    pub fn exp_hyb(&self, f: &[f32; N]) -> [f32; N] {
        exp_hyb_with(self.ol, f, HYB_NORM_THRESHOLD, |g| self.square(g))
    }

    /// The SH square `g * g` in f32 by the packed symmetric schedule (`G_ijk` over `i <= j`,
    /// doubled for `i < j`): the f32 twin of `lightvol_sh::gaunt::product(g, g)`, and the
    /// squaring that the batched pass repeats per lane.
    #[must_use]
    pub fn square(&self, g: &[f32; N]) -> [f32; N] {
        let mut h = [0.0f32; N];
        for (kk, hk) in h.iter_mut().enumerate() {
            let (a, b) = (self.square_start[kk], self.square_start[kk + 1]);
            let mut s = 0.0f32;
            for (ij, v) in self.square_ij[a..b].iter().zip(&self.square_v[a..b]) {
                s += v * g[ij[0] as usize] * g[ij[1] as usize];
            }
            *hk = s;
        }
        h
    }
}

/// Band `l` of flat index `j < 16`.
#[inline(always)]
pub(crate) const fn band(j: usize) -> usize {
    match j {
        0 => 0,
        1..=3 => 1,
        4..=8 => 2,
        _ => 3,
    }
}

/// The light at `p` as f32 arrays.
#[must_use]
pub fn light_f32<const N: usize>(light: &impl LightField<N>, p: [f32; 3]) -> [[f32; N]; 3] {
    let l = light.radiance_at(p.map(f64::from));
    core::array::from_fn(|c| l.0[c].0.map(|v| v as f32))
}
