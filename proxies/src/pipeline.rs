//! The image-space pipeline on the CPU (\[SGNS07\] §4, Fig. 2), rayon-parallel and
//! deterministic (each receiver sums its proxies in scene order; no shared accumulators):
//!
//! 1. receiver setup: a [`ReceiverBuffer`] at 1/2 or 1/4 of display resolution;
//! 2. splatting: each proxy's sphere of influence (radius `η r`, [`crate::oracle`]) is
//!    bounded in screen space and binned into square tiles ([`bin_proxies`]); every receiver
//!    of a tile runs the per-pixel test (`α > 1/η`) against the tile's list;
//! 3. accumulation ([`accumulate_pass`]) and exponentiation ([`exponentiate_pass`]);
//! 4. bilateral upsampling of the incident radiance `L_p` to display resolution and diffuse
//!    shading there with each display pixel's own normal ([`shade_display`]).
//!
//! The paper upsamples `O_p` and the indirect shading; we upsample `L_p = O_p * L + I_p`
//! (9 coefficients per channel), which is linear in `O_p` for a fixed `L`, hence the same for
//! a distant light, and lets the display pass shade with the target's own normal.

use rayon::prelude::*;

use crate::batch::ReceiverBatch;
use crate::kernel::{Accum, Incident, Kernel, PreparedProxy, Rgb9, light_f32};
use crate::lanes::LANES;
use crate::light::LightField;
use crate::proxy::SphereProxy;
use crate::receiver_scene::{CameraFrame, ReceiverBuffer};
use crate::upsample::{Geometry, bilateral_upsample_map, bilateral_upsample_map_into};

/// Proxies binned into square screen tiles.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TileBins {
    /// Tile edge in pixels.
    pub tile: usize,
    /// Tiles per row.
    pub tiles_x: usize,
    /// Tile rows.
    pub tiles_y: usize,
    /// Proxy indices per tile, ascending.
    pub lists: Vec<Vec<u32>>,
}

/// Screen-space pixel bounds `[x0, x1) × [y0, y1)` of a sphere, conservative: the bounds of
/// its bounding cube's projected corners, or the whole image when a corner is not in front
/// of the eye.
#[must_use]
pub fn screen_bounds(cam: &CameraFrame, center: [f64; 3], radius: f64, w: usize, h: usize) -> [usize; 4] {
    let (mut x0, mut y0, mut x1, mut y1) =
        (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for k in 0..8 {
        let s = |b: usize| if k >> b & 1 == 1 { radius } else { -radius };
        let c = [center[0] + s(0), center[1] + s(1), center[2] + s(2)];
        match cam.project(c, w, h) {
            Some((x, y, _)) => {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
            None => return [0, 0, w, h],
        }
    }
    let cl = |v: f64, m: usize| v.clamp(0.0, m as f64);
    [
        cl(x0.floor(), w) as usize,
        cl(y0.floor(), h) as usize,
        cl(x1.ceil(), w) as usize,
        cl(y1.ceil(), h) as usize,
    ]
}

/// Bins each proxy's sphere of influence (radius `eta · r`) into `tile × tile` tiles.
#[must_use]
pub fn bin_proxies(
    cam: &CameraFrame,
    w: usize,
    h: usize,
    proxies: &[SphereProxy],
    eta: f64,
    tile: usize,
) -> TileBins {
    let tiles_x = w.div_ceil(tile);
    let tiles_y = h.div_ceil(tile);
    let mut lists = vec![Vec::new(); tiles_x * tiles_y];
    for (i, p) in proxies.iter().enumerate() {
        let [x0, y0, x1, y1] = screen_bounds(cam, p.center, p.radius * eta, w, h);
        if x1 <= x0 || y1 <= y0 {
            continue;
        }
        for ty in y0 / tile..y1.div_ceil(tile) {
            for tx in x0 / tile..x1.div_ceil(tile) {
                lists[ty * tiles_x + tx].push(i as u32);
            }
        }
    }
    TileBins { tile, tiles_x, tiles_y, lists }
}

/// The accumulation pass: every receiver sums the proxies of its tile, in batches of
/// [`LANES`] receivers of one tile row segment ([`Kernel::accumulate_batch`], bit-identical
/// to [`Kernel::accumulate`] per receiver); parallel over pixel rows.
#[must_use]
pub fn accumulate_pass<const N: usize>(
    kernel: &Kernel<N>,
    buffer: &ReceiverBuffer,
    bins: &TileBins,
    proxies: &[PreparedProxy<N>],
) -> Vec<Accum<N>> {
    let w = buffer.width;
    let mut out = vec![Accum::<N>::default(); w * buffer.height];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let ty = y / bins.tile;
        for (tx, tile_row) in row.chunks_mut(bins.tile).enumerate() {
            let list = &bins.lists[ty * bins.tiles_x + tx];
            if list.is_empty() {
                continue;
            }
            let x0 = tx * bins.tile;
            for (b, accs) in tile_row.chunks_mut(LANES).enumerate() {
                let i0 = y * w + x0 + b * LANES;
                let i1 = i0 + accs.len();
                let batch = ReceiverBatch::gather(&buffer.position[i0..i1], &buffer.normal[i0..i1], |k| {
                    buffer.valid(i0 + k)
                });
                kernel.accumulate_batch(&batch, proxies, list, accs);
            }
        }
    });
    out
}

/// The exponentiation pass: `O_p`, `O_p * L(p)` and `ξ_p Ĩ_p` per receiver. With a uniform
/// light, in batches of [`LANES`] receivers ([`Kernel::finish_batch`], bit-identical to
/// [`Kernel::finish_with`]); otherwise one receiver at a time with its own light.
#[must_use]
pub fn exponentiate_pass<const N: usize>(
    kernel: &Kernel<N>,
    buffer: &ReceiverBuffer,
    accum: &[Accum<N>],
    light: &impl LightField<N>,
) -> Vec<Incident> {
    let empty = Incident { shadowed: [0.0; 27], indirect: [0.0; 27] };
    let mut out = vec![empty; accum.len()];
    match light.uniform() {
        Some(l) => {
            let m = kernel.light_matrix(&core::array::from_fn(|c| l.0[c].0.map(|v| v as f32)));
            out.par_chunks_mut(EXP_CHUNK).zip(accum.par_chunks(EXP_CHUNK)).enumerate().for_each(
                |(c, (out, acc))| {
                    for (b, (o, a)) in out.chunks_mut(LANES).zip(acc.chunks(LANES)).enumerate() {
                        kernel.finish_batch(a, &m, o);
                        let i0 = c * EXP_CHUNK + b * LANES;
                        for (k, o) in o.iter_mut().enumerate() {
                            if !buffer.valid(i0 + k) {
                                *o = empty;
                            }
                        }
                    }
                },
            );
        }
        None => {
            out.par_chunks_mut(EXP_CHUNK).enumerate().for_each(|(c, out)| {
                for (k, o) in out.iter_mut().enumerate() {
                    let i = c * EXP_CHUNK + k;
                    if buffer.valid(i) {
                        *o = kernel.finish(&accum[i], &light_f32(light, buffer.position[i]));
                    }
                }
            });
        }
    }
    out
}

/// Accumulation and exponentiation fused ([`Kernel::incident_batch`]): the total incident
/// radiance `L_p = O_p * L + ξ_p Ĩ_p` per receiver (0 where there is no receiver), written to
/// `out` (one per receiver), without storing the accumulators. Bit-identical to
/// [`accumulate_pass`], [`exponentiate_pass`] and [`total`]; parallel over pixel rows.
///
/// # Panics
/// If `out.len()` is not the number of receivers.
pub fn incident_pass_into<const N: usize>(
    kernel: &Kernel<N>,
    buffer: &ReceiverBuffer,
    bins: &TileBins,
    proxies: &[PreparedProxy<N>],
    light: &impl LightField<N>,
    out: &mut [Rgb9],
) {
    let w = buffer.width;
    assert_eq!(out.len(), w * buffer.height, "one output per receiver");
    let uniform =
        light.uniform().map(|l| kernel.light_matrix(&core::array::from_fn(|c| l.0[c].0.map(|v| v as f32))));
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let ty = y / bins.tile;
        for (tx, tile_row) in row.chunks_mut(bins.tile).enumerate() {
            let list = &bins.lists[ty * bins.tiles_x + tx];
            let x0 = tx * bins.tile;
            for (b, o) in tile_row.chunks_mut(LANES).enumerate() {
                let i0 = y * w + x0 + b * LANES;
                let i1 = i0 + o.len();
                let batch = ReceiverBatch::gather(&buffer.position[i0..i1], &buffer.normal[i0..i1], |k| {
                    buffer.valid(i0 + k)
                });
                kernel.incident_batch(
                    &batch,
                    proxies,
                    list,
                    uniform.as_ref(),
                    |k| light_f32(light, buffer.position[i0 + k]),
                    o,
                );
            }
        }
    });
}

/// [`incident_pass_into`] into a new vector.
#[must_use]
pub fn incident_pass<const N: usize>(
    kernel: &Kernel<N>,
    buffer: &ReceiverBuffer,
    bins: &TileBins,
    proxies: &[PreparedProxy<N>],
    light: &impl LightField<N>,
) -> Vec<Rgb9> {
    let mut out = vec![[0.0; 27]; buffer.width * buffer.height];
    incident_pass_into(kernel, buffer, bins, proxies, light, &mut out);
    out
}

/// Receivers per parallel work item of [`exponentiate_pass`].
const EXP_CHUNK: usize = 256;

/// Diffuse shading `ψ = H(N) · L_p` (Eq. 10) of 9-coefficient RGB radiance, times
/// `albedo / π`: the receiver's outgoing radiance.
#[must_use]
#[inline]
pub fn shade_rgb9(l: &Rgb9, n: [f32; 3], albedo: [f32; 3]) -> [f32; 3] {
    let y = lightvol_sh::eval::eval_basis::<f32, 9>(n);
    let a = [1.0f32, 2.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0, 0.25, 0.25, 0.25, 0.25, 0.25];
    // H_lm = A_l y_lm(N) and A_l / π = (1, 2/3, 1/4): ψ/π = Σ (A_l/π) y_lm L_lm.
    core::array::from_fn(|c| albedo[c] * (0..9).map(|j| a[j] * y[j] * l[9 * c + j]).sum::<f32>())
}

/// Upsamples per-receiver radiance `L_p` bilaterally to the `fine` buffer and shades it.
/// Display pixels with no matching coarse receiver are computed from scratch by `exact`.
#[must_use]
pub fn shade_display(
    coarse: &ReceiverBuffer,
    incident: &[Rgb9],
    fine: &ReceiverBuffer,
    exact: impl Fn(usize) -> Rgb9 + Sync,
) -> (Vec<[f32; 3]>, usize) {
    bilateral_upsample_map(
        Geometry { width: coarse.width, height: coarse.height, normal: &coarse.normal, depth: &coarse.depth },
        incident,
        Geometry { width: fine.width, height: fine.height, normal: &fine.normal, depth: &fine.depth },
        exact,
        |i, l| shade_rgb9(l, fine.normal[i], fine.albedo[i]),
        [0.0; 3],
    )
}

/// [`shade_display`] into `out` (one per display pixel); returns the fallback count.
///
/// # Panics
/// If `out.len()` is not the number of display pixels.
pub fn shade_display_into(
    coarse: &ReceiverBuffer,
    incident: &[Rgb9],
    fine: &ReceiverBuffer,
    exact: impl Fn(usize) -> Rgb9 + Sync,
    out: &mut [[f32; 3]],
) -> usize {
    bilateral_upsample_map_into(
        Geometry { width: coarse.width, height: coarse.height, normal: &coarse.normal, depth: &coarse.depth },
        incident,
        Geometry { width: fine.width, height: fine.height, normal: &fine.normal, depth: &fine.depth },
        exact,
        |i, l| shade_rgb9(l, fine.normal[i], fine.albedo[i]),
        [0.0; 3],
        out,
    )
}

/// Total incident radiance `O_p * L + I_p` of a receiver.
#[must_use]
#[inline]
pub fn total(inc: &Incident) -> Rgb9 {
    core::array::from_fn(|j| inc.shadowed[j] + inc.indirect[j])
}

/// Shades one display pixel from scratch with every proxy (the upsampling fallback).
#[must_use]
pub fn shade_from_scratch<const N: usize>(
    kernel: &Kernel<N>,
    fine: &ReceiverBuffer,
    i: usize,
    proxies: &[PreparedProxy<N>],
    light: &impl LightField<N>,
) -> Incident {
    let all: Vec<u32> = (0..proxies.len() as u32).collect();
    let mut acc = Accum::<N>::default();
    kernel.accumulate(fine.position[i], fine.normal[i], proxies, &all, &mut acc);
    kernel.finish(&acc, &light_f32(light, fine.position[i]))
}
