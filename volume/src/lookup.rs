//! Run-time lookup: trilinear interpolation of the coefficients and irradiance/radiance
//! evaluation (Kontkanen & Laine 2006, Eq. 1-3 and Algorithm 1).
//!
//! `E(x, n) ≈ Σ_j A_j (Σ_{i∈B(x)} c_ij b_i(x)) Y_j(n)` (Eq. 3), with `A_j` the clamped-cosine
//! factors of the band of `j` (Ramamoorthi & Hanrahan 2001; `lightvol_sh::irradiance`) and
//! `b_i` the trilinear weights. Radiance is the same sum without `A_j`.
//!
//! Three implementations, tested against each other:
//!
//! - [`IrradianceVolume::irradiance_reference`]: Algorithm 1 verbatim in f64 (corner by
//!   corner, coefficient by coefficient) with
//!   [`GridSpec::trilinear_world`](crate::grid::GridSpec::trilinear_world); slow, obvious.
//! - [`IrradianceVolume::irradiance`] / [`IrradianceVolume::radiance`]: the f32 scalar path:
//!   interpolate the `3·coeffs` floats of the 8 corners (one contiguous run per corner),
//!   then dot with `A_j Y_j(n)`.
//! - [`IrradianceVolume::irradiance_batch`] / [`IrradianceVolume::radiance_batch`]: the same
//!   arithmetic reorganised for throughput: blocks of [`LANES`] queries, cell location and
//!   weights computed structure-of-arrays across lanes (auto-vectorised), the interpolation
//!   monomorphised per coefficient count so its fixed-length loops vectorise over
//!   coefficients, and rayon parallelism over chunks of [`PAR_CHUNK`] queries. Every query
//!   performs exactly the operations of the scalar path in the same order (no fused
//!   multiply-add, no reassociation), so the results are bit-identical to it for any
//!   thread count; a test asserts this.
//!
//! **Validity.** When the volume carries a [`crate::ValidityMask`], all of these (and
//! [`IrradianceVolume::coeffs_at`], [`IrradianceVolume::sh_at`],
//! [`IrradianceVolume::coeffs_reference`]) renormalise the trilinear weights over the valid
//! corners of the cell before interpolating, Unity APV's run-time validity weighting; every
//! corner valid, or no valid corner with weight, leaves the plain trilinear weights
//! ([`crate::validity`]). The f32 paths reweight in f32 (batched and scalar alike, so they
//! stay bit-identical), the references in f64. Without a mask nothing changes.
//!
//! **Reach.** When the volume carries a [`crate::NodeReach`], the same lookups then
//! renormalise the weights over the corners that see the query ([`crate::reach`]): the
//! irradiance lookups test the point moved a tenth of a cell along the normal
//! ([`crate::reach::REACH_NORMAL_BIAS`]), the radiance and coefficient lookups the point
//! itself. A reach of one cell on every axis changes no bit.
//!
//! Points are world-space (the volume's placement, if any, maps them to grid space);
//! normals and directions are world-space unit vectors. Points outside the box are clamped
//! to it (see [`crate::grid`]); a NaN coordinate is treated as the box's min on that axis.
//!
//! [`expand`] is the f64 expansion `Σ_j A_j c_j Y_j(n)` of already interpolated
//! coefficients, shared by the lookups that interpolate in f64 elsewhere (the gradient
//! lookups, the octree's reference, [`crate::field`]). The f32 constants the fast paths
//! read (the world-to-cell map, the corner offsets, the factors `A_j`) are computed once per
//! volume, with it, below it (`lookup_params`).

use rayon::prelude::*;

use lightvol_sh::coeffs::{Sh, ShRgb};
use lightvol_sh::eval::{eval_basis, eval_into};
use lightvol_sh::index::sh_lm;
use lightvol_sh::irradiance::cosine_lobe_factor;

use crate::error::VolumeError;
use crate::lookup_params::{LookupParams, weights8};
use crate::volume::IrradianceVolume;

pub use crate::reach::reach_bias;

/// Queries per structure-of-arrays block in the batched path.
pub const LANES: usize = 8;
/// Queries per rayon task in the parallel batched path.
pub const PAR_CHUNK: usize = 2048;

/// Interpolated coefficients `c` (`[coeff][rgb]`, `coeffs` per channel) expanded in the
/// direction `d`: irradiance `Σ_j A_j c_j Y_j(d)` (\[KL06\] Eq. 3, `A_j` the clamped-cosine
/// factor of `j`'s band) or, with `irradiance` false, radiance `Σ_j c_j Y_j(d)` (Eq. 2). The
/// f64 expansion of every coefficient lookup (the gradient lookups, the octree's reference).
#[must_use]
pub fn expand(coeffs: usize, c: &[f64], d: [f64; 3], irradiance: bool) -> [f64; 3] {
    let mut y = vec![0.0; coeffs];
    eval_into(coeffs.isqrt(), d, &mut y);
    let mut e = [0.0; 3];
    for j in 0..coeffs {
        let a = if irradiance { cosine_lobe_factor(sh_lm(j).0) * y[j] } else { y[j] };
        for ch in 0..3 {
            e[ch] += a * c[3 * j + ch];
        }
    }
    e
}

/// `Σ_c w_c · node_c[q]` for the `K` floats of the 8 corners, corner by corner.
#[inline(always)]
fn interpolate<const K: usize>(data: &[f32], base: usize, offsets: &[usize; 8], w: &[f32; 8]) -> [f32; K] {
    let corner = |c: usize| -> &[f32; K] {
        let s = (base + offsets[c]) * K;
        data[s..s + K].try_into().expect("K floats")
    };
    let mut acc = [0.0f32; K];
    let c0 = corner(0);
    for q in 0..K {
        acc[q] = w[0] * c0[q];
    }
    for c in 1..8 {
        let cc = corner(c);
        for q in 0..K {
            acc[q] += w[c] * cc[q];
        }
    }
    acc
}

/// `Σ_j (f_j Y_j(n)) · acc[j][ch]`, j ascending.
#[inline(always)]
fn shade<const N: usize, const K: usize>(acc: &[f32; K], f: &[f32; 16], n: [f32; 3]) -> [f32; 3] {
    let y: [f32; N] = eval_basis(n);
    let mut out = [0.0f32; 3];
    for j in 0..N {
        let t = f[j] * y[j];
        out[0] += t * acc[3 * j];
        out[1] += t * acc[3 * j + 1];
        out[2] += t * acc[3 * j + 2];
    }
    out
}

/// [`shade`] for a run-time coefficient count (4, 9 or 16); `acc` holds at least
/// `3 · coeffs` floats `[coeff][rgb]`.
pub(crate) fn shade_dyn(coeffs: usize, acc: &[f32], f: &[f32; 16], n: [f32; 3]) -> [f32; 3] {
    match coeffs {
        4 => shade::<4, 12>(acc[..12].try_into().expect("12 floats"), f, n),
        9 => shade::<9, 27>(acc[..27].try_into().expect("27 floats"), f, n),
        _ => shade::<16, 48>(acc[..48].try_into().expect("48 floats"), f, n),
    }
}

/// One query of the scalar path.
#[inline(always)]
fn query<const N: usize, const K: usize>(
    vol: &IrradianceVolume,
    lp: &LookupParams,
    f: &[f32; 16],
    p: [f32; 3],
    n: [f32; 3],
    irr: bool,
) -> [f32; 3] {
    let [nx, ny, _] = vol.spec().res().map(|v| v as usize);
    let (base, mut w) = lp.locate(nx, nx * ny, p);
    reweight(vol, lp, base, &mut w);
    reach_reweight(vol, lp, base, p, irr.then_some(n), &mut w);
    let acc = interpolate::<K>(vol.data(), base, &lp.offsets, &w);
    shade::<N, K>(&acc, f, n)
}

/// The validity weighting of the corners of the cell at `base` (nothing without a mask).
#[inline(always)]
fn reweight(vol: &IrradianceVolume, lp: &LookupParams, base: usize, w: &mut [f32; 8]) {
    if let Some(mask) = vol.validity() {
        mask.reweight_f32(|c| base + lp.offsets[c], w);
    }
}

/// The node-reach weighting ([`crate::reach`]) of the corners of the cell at `base` for a
/// query at `p`, tested at `p + n · bias` for a surface normal `n` (at `p` without one);
/// nothing without a reach. After the validity weighting, in f32 like it.
#[inline(always)]
fn reach_reweight(
    vol: &IrradianceVolume,
    lp: &LookupParams,
    base: usize,
    p: [f32; 3],
    n: Option<[f32; 3]>,
    w: &mut [f32; 8],
) {
    if let Some(reach) = vol.reach() {
        let q = n.map_or(p, |n| std::array::from_fn(|a| p[a] + n[a] * lp.reach_bias));
        let g = lp.grid_point(q);
        let [nx, ny, _] = vol.spec().res().map(|v| v as usize);
        let idx = [base % nx, (base / nx) % ny, base / (nx * ny)];
        let f = std::array::from_fn(|a| f64::from((g[a] - lp.min[a]) * lp.scale[a]) - idx[a] as f64);
        reach.reweight_f32(|c| base + lp.offsets[c], f, w);
    }
}

/// Signature of a monomorphised batched kernel.
type BatchKernel = fn(&IrradianceVolume, &[f32; 16], &[[f32; 3]], &[[f32; 3]], &mut [[f32; 3]], bool);

/// The batched kernel over one contiguous run of queries (single thread).
fn batch_kernel<const N: usize, const K: usize>(
    vol: &IrradianceVolume,
    f: &[f32; 16],
    points: &[[f32; 3]],
    dirs: &[[f32; 3]],
    out: &mut [[f32; 3]],
    irr: bool,
) {
    let lp = vol.lookup_params();
    let [nx, ny, _] = vol.spec().res().map(|v| v as usize);
    let nxy = nx * ny;
    let data = vol.data();
    for ((pb, db), ob) in points.chunks(LANES).zip(dirs.chunks(LANES)).zip(out.chunks_mut(LANES)) {
        let m = pb.len();
        // Stage 1, structure of arrays: grid coordinates, cells and fractions per lane.
        let mut g = [[0.0f32; LANES]; 3];
        for l in 0..m {
            let q = lp.grid_point(pb[l]);
            for a in 0..3 {
                g[a][l] = q[a];
            }
        }
        let mut cell = [[0u32; LANES]; 3];
        let mut frac = [[0.0f32; LANES]; 3];
        for a in 0..3 {
            for l in 0..LANES {
                let (i, fr) = lp.axis(a, g[a][l]);
                cell[a][l] = i;
                frac[a][l] = fr;
            }
        }
        let mut base = [0usize; LANES];
        for l in 0..m {
            base[l] = cell[0][l] as usize + nx * cell[1][l] as usize + nxy * cell[2][l] as usize;
        }
        // Stage 2, memory-level parallelism: touch both ends of the 4 corner-pair rows
        // (2·K contiguous floats each) of every lane before any arithmetic, so the cache
        // misses of all lanes overlap instead of being taken one lookup at a time. The sum
        // only keeps the loads alive; it does not enter the results.
        let mut touch = 0.0f32;
        for l in 0..m {
            for r in [0, 2, 4, 6] {
                let s = (base[l] + lp.offsets[r]) * K;
                touch += data[s] + data[s + 2 * K - 1];
            }
        }
        std::hint::black_box(touch);
        // Stage 3 per lane: gather-interpolate (vectorised over coefficients), shade.
        for l in 0..m {
            let base = base[l];
            let mut w = weights8(frac[0][l], frac[1][l], frac[2][l]);
            reweight(vol, lp, base, &mut w);
            reach_reweight(vol, lp, base, pb[l], irr.then_some(db[l]), &mut w);
            let acc = interpolate::<K>(data, base, &lp.offsets, &w);
            ob[l] = shade::<N, K>(&acc, f, db[l]);
        }
    }
}

/// Checks that a batched lookup has as many `dirs` (normals or directions, named `what`) and
/// outputs as points.
///
/// # Errors
/// [`VolumeError::Mismatch`] naming the three lengths.
pub(crate) fn check_batch(
    points: &[[f32; 3]],
    dirs: &[[f32; 3]],
    out: &[[f32; 3]],
    what: &str,
) -> Result<(), VolumeError> {
    if points.len() != dirs.len() || points.len() != out.len() {
        return Err(VolumeError::Mismatch(format!(
            "batch lookup: {} points, {} {what}, {} outputs",
            points.len(),
            dirs.len(),
            out.len()
        )));
    }
    Ok(())
}

/// A batched lookup over rayon's pool: [`check_batch`], then `kernel` on chunks of
/// [`PAR_CHUNK`] queries (each query's result depends on that query alone, so any split
/// gives the same bits).
///
/// # Errors
/// [`check_batch`]'s.
pub(crate) fn par_batch(
    points: &[[f32; 3]],
    dirs: &[[f32; 3]],
    out: &mut [[f32; 3]],
    what: &str,
    kernel: impl Fn(&[[f32; 3]], &[[f32; 3]], &mut [[f32; 3]]) + Sync,
) -> Result<(), VolumeError> {
    check_batch(points, dirs, out, what)?;
    out.par_chunks_mut(PAR_CHUNK).enumerate().for_each(|(c, o)| {
        let s = c * PAR_CHUNK;
        kernel(&points[s..s + o.len()], &dirs[s..s + o.len()], o);
    });
    Ok(())
}

impl IrradianceVolume {
    /// Irradiance `E(x, n)` (Kontkanen & Laine 2006 Eq. 3) at world point `p` for the
    /// world-space unit normal `n`: the scalar f32 path.
    #[must_use]
    pub fn irradiance(&self, p: [f32; 3], n: [f32; 3]) -> [f32; 3] {
        self.eval_scalar(p, n, true)
    }

    /// Radiance `L(x, ω) ≈ Σ_j L_j(x) Y_j(ω)` (Eq. 2 with the SH expansion) arriving at `p`
    /// from the world-space unit direction `dir` (pointing from `p` toward the source, the
    /// direction a baker's ray travels): the scalar f32 path.
    #[must_use]
    pub fn radiance(&self, p: [f32; 3], dir: [f32; 3]) -> [f32; 3] {
        self.eval_scalar(p, dir, false)
    }

    fn eval_scalar(&self, p: [f32; 3], n: [f32; 3], irr: bool) -> [f32; 3] {
        let lp = self.lookup_params();
        let f = &lp.factors[usize::from(!irr)];
        match self.coeffs() {
            4 => query::<4, 12>(self, lp, f, p, n, irr),
            9 => query::<9, 27>(self, lp, f, p, n, irr),
            _ => query::<16, 48>(self, lp, f, p, n, irr),
        }
    }

    /// The interpolated coefficients `L_j(x)` (Eq. 2) at world point `p`, written to
    /// `out[..3·coeffs]` as `[coeff][rgb]` (f32 path).
    ///
    /// # Panics
    /// If `out` is shorter than `3 · coeffs`.
    pub fn coeffs_at(&self, p: [f32; 3], out: &mut [f32]) {
        let lp = self.lookup_params();
        let [nx, ny, _] = self.spec().res().map(|v| v as usize);
        let (base, mut w) = lp.locate(nx, nx * ny, p);
        reweight(self, lp, base, &mut w);
        reach_reweight(self, lp, base, p, None, &mut w);
        let k = self.coeffs() * 3;
        match self.coeffs() {
            4 => out[..k].copy_from_slice(&interpolate::<12>(self.data(), base, &lp.offsets, &w)),
            9 => out[..k].copy_from_slice(&interpolate::<27>(self.data(), base, &lp.offsets, &w)),
            _ => out[..k].copy_from_slice(&interpolate::<48>(self.data(), base, &lp.offsets, &w)),
        }
    }

    /// The interpolated coefficients at world point `p` as a lightvol-sh [`ShRgb`] (f32
    /// path); errors if `N` is not the volume's coefficient count.
    pub fn sh_at<const N: usize>(&self, p: [f32; 3]) -> Result<ShRgb<f32, N>, VolumeError> {
        if N != self.coeffs() {
            return Err(VolumeError::Mismatch(format!(
                "{N} coefficients requested, volume has {}",
                self.coeffs()
            )));
        }
        let mut flat = [0.0f32; 48];
        self.coeffs_at(p, &mut flat);
        Ok(ShRgb(std::array::from_fn(|ch| Sh(std::array::from_fn(|j| flat[3 * j + ch])))))
    }

    /// Batched irradiance: `out[q] = E(points[q], normals[q])`, parallel over rayon's
    /// pool, bit-identical to [`Self::irradiance`] per query. Errors if the slice lengths
    /// differ.
    pub fn irradiance_batch(
        &self,
        points: &[[f32; 3]],
        normals: &[[f32; 3]],
        out: &mut [[f32; 3]],
    ) -> Result<(), VolumeError> {
        self.batch(points, normals, out, true, true)
    }

    /// Batched radiance, like [`Self::irradiance_batch`].
    pub fn radiance_batch(
        &self,
        points: &[[f32; 3]],
        dirs: &[[f32; 3]],
        out: &mut [[f32; 3]],
    ) -> Result<(), VolumeError> {
        self.batch(points, dirs, out, false, true)
    }

    /// [`Self::irradiance_batch`] on the calling thread only (no rayon).
    pub fn irradiance_batch_serial(
        &self,
        points: &[[f32; 3]],
        normals: &[[f32; 3]],
        out: &mut [[f32; 3]],
    ) -> Result<(), VolumeError> {
        self.batch(points, normals, out, true, false)
    }

    fn batch(
        &self,
        points: &[[f32; 3]],
        dirs: &[[f32; 3]],
        out: &mut [[f32; 3]],
        irr: bool,
        parallel: bool,
    ) -> Result<(), VolumeError> {
        let f = self.lookup_params().factors[usize::from(!irr)];
        let kernel: BatchKernel = match self.coeffs() {
            4 => batch_kernel::<4, 12>,
            9 => batch_kernel::<9, 27>,
            _ => batch_kernel::<16, 48>,
        };
        if parallel {
            par_batch(points, dirs, out, "directions", |p, d, o| kernel(self, &f, p, d, o, irr))
        } else {
            check_batch(points, dirs, out, "directions")?;
            kernel(self, &f, points, dirs, out, irr);
            Ok(())
        }
    }

    /// Algorithm 1 of Kontkanen & Laine 2006 in f64, verbatim: for each corner node `i` of
    /// the cell and each coefficient `j`, accumulate `A_j Y_j(n) b_i(x) c(i, j)`. The slow
    /// reference for the fast paths (which must agree to f32 rounding).
    #[must_use]
    pub fn irradiance_reference(&self, p: [f64; 3], n: [f64; 3]) -> [f64; 3] {
        self.reference(p, n, true)
    }

    /// Radiance by the same f64 reference loop (without `A_j`).
    #[must_use]
    pub fn radiance_reference(&self, p: [f64; 3], dir: [f64; 3]) -> [f64; 3] {
        self.reference(p, dir, false)
    }

    fn reference(&self, p: [f64; 3], n: [f64; 3], irr: bool) -> [f64; 3] {
        let (nodes, b) = self.reference_weights(p, irr.then_some(n));
        let mut y = vec![0.0f64; self.coeffs()];
        eval_into(self.bands(), n, &mut y);
        let mut l = [0.0f64; 3];
        for c in 0..8 {
            if (self.validity().is_some() || self.reach().is_some()) && b[c] == 0.0 {
                // A dropped corner adds nothing (not even the sign of a zero).
                continue;
            }
            let node = self.node(nodes[c]);
            for j in 0..self.coeffs() {
                let a = if irr { cosine_lobe_factor(sh_lm(j).0) } else { 1.0 };
                for ch in 0..3 {
                    l[ch] += a * y[j] * b[c] * f64::from(node[3 * j + ch]);
                }
            }
        }
        l
    }

    /// The interpolated coefficients at world point `p` in f64 (reference for
    /// [`Self::coeffs_at`]).
    #[must_use]
    pub fn coeffs_reference(&self, p: [f64; 3]) -> Vec<f64> {
        let (nodes, b) = self.reference_weights(p, None);
        let k = self.coeffs() * 3;
        let mut out = vec![0.0; k];
        for c in 0..8 {
            for (o, v) in out.iter_mut().zip(self.node(nodes[c])) {
                *o += b[c] * f64::from(*v);
            }
        }
        out
    }

    /// The corners and f64 trilinear weights of world point `p`, reweighted by the validity
    /// mask and then the node reach (tested at `p + n · bias` for a surface normal `n`) if
    /// the volume has them (the references' weights).
    pub(crate) fn reference_weights(&self, p: [f64; 3], n: Option<[f64; 3]>) -> ([usize; 8], [f64; 8]) {
        let (nodes, mut b) = self.spec().trilinear_world(p);
        if let Some(mask) = self.validity() {
            mask.reweight_f64(|c| nodes[c], &mut b);
        }
        if let Some(reach) = self.reach() {
            let bias = reach_bias(self.spec());
            let q = n.map_or(p, |n| std::array::from_fn(|a| p[a] + n[a] * bias));
            let g = self.spec().to_grid(q);
            let (min, max) = self.spec().bounds();
            let res = self.spec().res();
            let idx = self.spec().node_coords(nodes[0]);
            let f = std::array::from_fn(|a| {
                (g[a] - min[a]) / (max[a] - min[a]) * f64::from(res[a] - 1) - f64::from(idx[a])
            });
            reach.reweight_f64(|c| nodes[c], f, &mut b);
        }
        (nodes, b)
    }
}
