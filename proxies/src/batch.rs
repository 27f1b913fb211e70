//! The f32 kernels of [`crate::kernel`] run on [`LANES`] receivers at once (struct of
//! arrays), so that the compiler vectorises across receivers: proxy accumulation (\[SGNS07\]
//! Eq. 4, 8, 12, 15) and the HYB exponentiation pass (Eq. 9).
//!
//! Every lane performs exactly the f32 operations of the one-receiver kernels
//! ([`Kernel::accumulate`], [`Kernel::finish_with`]) in the same order; a lane that a proxy
//! does not touch adds exactly ±0 (its table values are selected to 0 and its direction is
//! replaced by a finite one first, so no NaN or infinity can leak in). The batched passes are
//! therefore bit-identical to the one-receiver kernels (tested in `tests/batch.rs`), and
//! independent of how receivers are grouped into batches or threads.
//!
//! What the batching buys: the sphere-of-influence test, the replacement rule, the SH
//! rotation's products, the accumulation and the indirect light's dot products run as
//! vector instructions over lanes; per-proxy data (centre, radius, exit radiance) is
//! broadcast once per batch instead of once per receiver; and the squaring schedule of HYB
//! is read once per batch. Table lookups and the SH basis stay per lane (gathers).

use lightvol_sh::shexp::{HYB_NORM_THRESHOLD, hyb_start};

use crate::kernel::{Accum, Incident, Kernel, LightMatrix, PreparedProxy, Rgb9, band};
use crate::lanes::{LANES, Lanes, eval_basis_lanes};
use crate::tables::{MAX_BANDS, SQRT_4PI, TABLE_ENTRIES};

type Mask = [bool; LANES];

/// A batch of receivers: positions and normals as struct of arrays, and which lanes hold a
/// receiver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReceiverBatch {
    /// Positions `p` (x, y, z lanes).
    pub position: [Lanes; 3],
    /// Unit normals `N_p`.
    pub normal: [Lanes; 3],
    /// Lanes that hold a receiver (others accumulate nothing).
    pub valid: [bool; LANES],
}

impl ReceiverBatch {
    /// Gathers up to [`LANES`] receivers; lanes past `position.len()` or with
    /// `valid(k) == false` are empty.
    #[must_use]
    pub fn gather(position: &[[f32; 3]], normal: &[[f32; 3]], valid: impl Fn(usize) -> bool) -> Self {
        let mut b = Self { position: [[0.0; LANES]; 3], normal: [[0.0; LANES]; 3], valid: [false; LANES] };
        for (k, (p, n)) in position.iter().zip(normal).take(LANES).enumerate() {
            for a in 0..3 {
                b.position[a][k] = p[a];
                b.normal[a][k] = n[a];
            }
            b.valid[k] = valid(k);
        }
        b
    }
}

/// A batch's accumulators, struct of arrays (the lanes of [`Accum`]).
#[derive(Clone, Copy, Debug)]
struct AccumLanes<const N: usize> {
    log_vis: [Lanes; N],
    indirect: [Lanes; 27],
    omega: Lanes,
    count: [u32; LANES],
}

impl<const N: usize> Default for AccumLanes<N> {
    fn default() -> Self {
        Self {
            log_vis: [[0.0; LANES]; N],
            indirect: [[0.0; LANES]; 27],
            omega: [0.0; LANES],
            count: [0; LANES],
        }
    }
}

impl<const N: usize> AccumLanes<N> {
    /// Lane `l` as an [`Accum`].
    #[inline]
    fn lane(&self, l: usize) -> Accum<N> {
        Accum {
            log_vis: core::array::from_fn(|j| self.log_vis[j][l]),
            indirect: core::array::from_fn(|j| self.indirect[j][l]),
            omega: self.omega[l],
            count: self.count[l],
        }
    }

    /// Sets lane `l` from an [`Accum`].
    #[inline]
    fn set_lane(&mut self, l: usize, a: &Accum<N>) {
        for j in 0..N {
            self.log_vis[j][l] = a.log_vis[j];
        }
        for j in 0..27 {
            self.indirect[j][l] = a.indirect[j];
        }
        self.omega[l] = a.omega;
        self.count[l] = a.count;
    }
}

/// A batch's exponentiation output, struct of arrays (the lanes of [`Incident`]).
struct IncidentLanes {
    shadowed: [Lanes; 27],
    indirect: [Lanes; 27],
}

/// `v` times a 0/1 weight per lane (`v` finite): `v` or ±0.
#[inline(always)]
fn masked(mut v: [Lanes; MAX_BANDS], w: &Lanes) -> [Lanes; MAX_BANDS] {
    for b in &mut v {
        for l in 0..LANES {
            b[l] *= w[l];
        }
    }
    v
}

#[inline(always)]
fn any(m: &Mask) -> bool {
    m.iter().fold(false, |a, &b| a | b)
}

#[inline(always)]
fn map2(a: &Lanes, b: &Lanes, f: impl Fn(f32, f32) -> f32) -> Lanes {
    core::array::from_fn(|l| f(a[l], b[l]))
}

/// Linearly interpolates a 4-band table row per lane: `tab[i] + t (tab[i+1] - tab[i])`.
#[inline(always)]
fn lerp_rows(tab: &[[f32; MAX_BANDS]], idx: &[usize; LANES], t: &Lanes) -> [Lanes; MAX_BANDS] {
    let mut out = [[0.0; LANES]; MAX_BANDS];
    for l in 0..LANES {
        let (a, b) = (tab[idx[l]], tab[idx[l] + 1]);
        for k in 0..MAX_BANDS {
            out[k][l] = a[k] + t[l] * (b[k] - a[k]);
        }
    }
    out
}

impl<const N: usize> Kernel<N> {
    /// [`Kernel::accumulate`] for a batch of receivers that share the proxy list `list`;
    /// writes the first `out.len()` (at most [`LANES`]) lanes' accumulators to `out`
    /// (empty lanes get [`Accum::default`]).
    pub fn accumulate_batch(
        &self,
        batch: &ReceiverBatch,
        proxies: &[PreparedProxy<N>],
        list: &[u32],
        out: &mut [Accum<N>],
    ) {
        let acc = self.accumulate_soa(batch, proxies, list);
        for (l, o) in out.iter_mut().take(LANES).enumerate() {
            *o = acc.lane(l);
        }
    }

    /// The accumulators of a batch, struct of arrays.
    fn accumulate_soa(
        &self,
        batch: &ReceiverBatch,
        proxies: &[PreparedProxy<N>],
        list: &[u32],
    ) -> AccumLanes<N> {
        let mut acc = AccumLanes::<N>::default();
        if any(&batch.valid) {
            let valid = batch.valid.map(u32::from);
            for &pi in list {
                self.accumulate_lanes(batch, &valid, &proxies[pi as usize], &mut acc);
            }
        }
        acc
    }

    /// Accumulation and exponentiation of a batch in one go, without storing the
    /// accumulators: the total incident radiance `O_p * L + ξ_p Ĩ_p` of the first `out.len()`
    /// lanes (0 for lanes without a receiver), bit-identical to [`Kernel::accumulate`],
    /// [`Kernel::finish_with`] and [`crate::pipeline::total`] per receiver. `light` is
    /// `None` for a light that varies over the receivers, then each lane gets its own light
    /// matrix from `light_at(lane)`.
    pub fn incident_batch(
        &self,
        batch: &ReceiverBatch,
        proxies: &[PreparedProxy<N>],
        list: &[u32],
        light: Option<&LightMatrix<N>>,
        light_at: impl Fn(usize) -> [[f32; N]; 3],
        out: &mut [Rgb9],
    ) {
        let acc = self.accumulate_soa(batch, proxies, list);
        match light {
            Some(m) => {
                let inc = self.finish_soa(&acc, m);
                for (l, o) in out.iter_mut().take(LANES).enumerate() {
                    *o = if batch.valid[l] {
                        core::array::from_fn(|j| inc.shadowed[j][l] + inc.indirect[j][l])
                    } else {
                        [0.0; 27]
                    };
                }
            }
            None => {
                for (l, o) in out.iter_mut().take(LANES).enumerate() {
                    *o = if batch.valid[l] {
                        let inc = self.finish(&acc.lane(l), &light_at(l));
                        core::array::from_fn(|j| inc.shadowed[j] + inc.indirect[j])
                    } else {
                        [0.0; 27]
                    };
                }
            }
        }
    }

    /// One proxy's contribution to a batch (the body of [`Kernel::accumulate`], per lane).
    #[inline(always)]
    fn accumulate_lanes(
        &self,
        batch: &ReceiverBatch,
        valid: &[u32; LANES],
        pr: &PreparedProxy<N>,
        acc: &mut AccumLanes<N>,
    ) {
        let alpha_min =
            if self.indirect { self.alpha_shadow.min(self.alpha_indirect) } else { self.alpha_shadow };
        let [px, py, pz] = &batch.position;
        let [nx, ny, nz] = &batch.normal;
        let [cx, cy, cz] = pr.center;
        let r = pr.radius;
        // Cheap rejection outside the sphere of influence (as in `Kernel::accumulate`).
        let vx = px.map(|p| cx - p);
        let vy = py.map(|p| cy - p);
        let vz = pz.map(|p| cz - p);
        // Masks as 0/1 integers and weights (bool arrays cost byte packing per use).
        let mut near = [0u32; LANES];
        for l in 0..LANES {
            let d2 = vx[l] * vx[l] + vy[l] * vy[l] + vz[l] * vz[l];
            near[l] = valid[l] & u32::from(!(d2 * alpha_min * alpha_min >= r * r));
        }
        if near.iter().fold(0, |a, b| a | b) == 0 {
            return;
        }
        // `crate::proxy::view_f32` per lane: the replacement sphere where it crosses the
        // tangent plane, with the same guards (positive radius, above the plane, d > 0).
        let mut dir = [[0.0f32; LANES]; 3];
        let mut alpha = [0.0f32; LANES];
        let mut shadow = [0.0f32; LANES];
        let mut ind = [0.0f32; LANES];
        let mut active = [0u32; LANES];
        for l in 0..LANES {
            let h = vx[l] * nx[l] + vy[l] * ny[l] + vz[l] * nz[l];
            let whole = h >= r;
            let r2 = if whole { r } else { 0.5 * (h + r) };
            let s = r2 - h;
            let c = if whole { [cx, cy, cz] } else { [cx + s * nx[l], cy + s * ny[l], cz + s * nz[l]] };
            let v = [c[0] - px[l], c[1] - py[l], c[2] - pz[l]];
            let d = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let ok = (near[l] != 0) & (r > 0.0) & !(h <= -r) & (d > 0.0);
            // Lanes the proxy does not touch get a harmless finite direction and α = 0, so
            // that every product below is finite and masking by multiplying with a 0/1
            // weight adds exactly ±0 (an accumulator is never -0: it starts at +0 and
            // round-to-nearest sums are -0 only when both terms are).
            dir[0][l] = if ok { v[0] / d } else { 0.0 };
            dir[1][l] = if ok { v[1] / d } else { 0.0 };
            dir[2][l] = if ok { v[2] / d } else { 1.0 };
            let a = if ok { (r2 / d).min(1.0) } else { 0.0 };
            alpha[l] = a;
            let sh = ok & (a > self.alpha_shadow);
            let id = ok & self.indirect & (a > self.alpha_indirect);
            shadow[l] = if sh { 1.0 } else { 0.0 };
            ind[l] = if id { 1.0 } else { 0.0 };
            active[l] = u32::from(sh | id);
        }
        if active.iter().fold(0, |a, b| a | b) == 0 {
            return;
        }
        for l in 0..LANES {
            acc.count[l] += active[l];
        }
        // The SH basis at the direction, and the table position (linear in α², see
        // `tables::locate`): lanes that no proxy touches hold garbage that is never added.
        let y = eval_basis_lanes::<N>(&self.basis, &dir[0], &dir[1], &dir[2]);
        let mut idx = [0usize; LANES];
        let mut t = [0.0f32; LANES];
        for l in 0..LANES {
            let x = alpha[l] * (TABLE_ENTRIES - 1) as f32;
            let i = (x as i32).clamp(0, TABLE_ENTRIES as i32 - 2);
            idx[l] = i as usize;
            t[l] = (x * x - (i * i) as f32) / (2 * i + 1) as f32;
        }
        if shadow.iter().any(|&w| w != 0.0) {
            let z = masked(lerp_rows(&self.olog, &idx, &t), &shadow);
            for j in 0..N {
                let zj = &z[band(j)];
                let a = &mut acc.log_vis[j];
                for l in 0..LANES {
                    a[l] += zj[l] * y[j][l];
                }
            }
        }
        if ind.iter().any(|&w| w != 0.0) {
            let v = masked(lerp_rows(&self.vis, &idx, &t), &ind);
            let d = lerp_rows(&self.d, &idx, &t);
            for l in 0..LANES {
                let i = idx[l];
                let om = self.omega[i] + t[l] * (self.omega[i + 1] - self.omega[i]);
                acc.omega[l] += om * ind[l];
            }
            let dy: [Lanes; N] = core::array::from_fn(|j| map2(&d[band(j)], &y[j], |a, b| a * b));
            let vyl: [Lanes; 9] = core::array::from_fn(|j| map2(&v[band(j)], &y[j], |a, b| a * b));
            for c in 0..3 {
                let e = &pr.exit[c];
                let mut kappa = [0.0f32; LANES];
                for j in 0..N {
                    for l in 0..LANES {
                        kappa[l] += dy[j][l] * e[j];
                    }
                }
                for j in 0..9 {
                    let a = &mut acc.indirect[9 * c + j];
                    for l in 0..LANES {
                        a[l] += kappa[l] * vyl[j][l];
                    }
                }
            }
        }
    }

    /// [`Kernel::finish_with`] for up to [`LANES`] receivers: `out[k]` from `accs[k]`.
    pub fn finish_batch(&self, accs: &[Accum<N>], light: &LightMatrix<N>, out: &mut [Incident]) {
        let n = accs.len().min(out.len()).min(LANES);
        let mut acc = AccumLanes::<N>::default();
        for (l, a) in accs.iter().take(n).enumerate() {
            acc.set_lane(l, a);
        }
        let inc = self.finish_soa(&acc, light);
        for (l, o) in out.iter_mut().take(n).enumerate() {
            *o = Incident {
                shadowed: core::array::from_fn(|j| inc.shadowed[j][l]),
                indirect: core::array::from_fn(|j| inc.indirect[j][l]),
            };
        }
    }

    /// The exponentiation pass on a batch's accumulators (the body of
    /// [`Kernel::finish_with`], per lane).
    fn finish_soa(&self, acc: &AccumLanes<N>, light: &LightMatrix<N>) -> IncidentLanes {
        // Per lane: HYB's start (`lightvol_sh::shexp::hyb_start`, as in `Kernel::exp_hyb`):
        // the OL value `g`, the number of squarings and the DC factor; lanes without proxies
        // take no squarings.
        let mut g = [[0.0f32; LANES]; N];
        let mut squarings = [0u32; LANES];
        let mut dc = [0.0f32; LANES];
        for l in 0..LANES {
            if acc.count[l] == 0 {
                continue;
            }
            let f: [f32; N] = core::array::from_fn(|j| acc.log_vis[j][l]);
            let start = hyb_start(self.ol, &f, HYB_NORM_THRESHOLD);
            for j in 0..N {
                g[j][l] = start.ol[j];
            }
            squarings[l] = start.squarings;
            dc[l] = start.dc;
        }
        // `Kernel::square` per lane, in lockstep: a lane past its own number of squarings
        // keeps its value.
        let most = squarings.iter().copied().max().unwrap_or(0);
        for round in 0..most {
            let keep: Mask = core::array::from_fn(|l| round >= squarings[l]);
            let mut h = [[0.0f32; LANES]; N];
            for (kk, hk) in h.iter_mut().enumerate() {
                let (a, b) = (self.square_start[kk], self.square_start[kk + 1]);
                for (ij, v) in self.square_ij[a..b].iter().zip(&self.square_v[a..b]) {
                    let (gi, gj) = (&g[ij[0] as usize], &g[ij[1] as usize]);
                    for l in 0..LANES {
                        hk[l] += v * gi[l] * gj[l];
                    }
                }
            }
            for j in 0..N {
                for l in 0..LANES {
                    g[j][l] = if keep[l] { g[j][l] } else { h[j][l] };
                }
            }
        }
        let o: [Lanes; N] = core::array::from_fn(|j| map2(&g[j], &dc, |a, b| a * b));
        let mut shadowed = [[0.0f32; LANES]; 27];
        for c in 0..3 {
            for k in 0..9 {
                let row = &light.m[c][k];
                let s = &mut shadowed[9 * c + k];
                for i in 0..N {
                    for l in 0..LANES {
                        s[l] += row[i] * o[i][l];
                    }
                }
            }
        }
        // `O_p * L` where a proxy touched the receiver, else `L`; `ξ_p Ĩ_p` where `ω_p > 0`.
        let touched: Mask = core::array::from_fn(|l| acc.count[l] > 0);
        let lit: Mask = core::array::from_fn(|l| touched[l] && acc.omega[l] > 0.0);
        let xi: Lanes =
            core::array::from_fn(|l| (SQRT_4PI as f32 - o[0][l]) / (acc.omega[l] / SQRT_4PI as f32));
        let mut out = IncidentLanes { shadowed, indirect: [[0.0; LANES]; 27] };
        for j in 0..27 {
            for l in 0..LANES {
                let sh = out.shadowed[j][l];
                out.shadowed[j][l] = if touched[l] { sh } else { light.l9[j] };
                let ind = xi[l] * acc.indirect[j][l];
                out.indirect[j][l] = if lit[l] { ind } else { 0.0 };
            }
        }
        out
    }
}
