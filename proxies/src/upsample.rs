//! Bilateral upsampling of coarse receiver-buffer results to display resolution (\[SGNS07\]
//! §4.2, Eq. 11): each display pixel blends its 2×2 coarse neighbours with
//! `w̃_i = w_b · (N_p · N_i)^32 · ε / (ε + |z_p - z_i|)`, normalised.
//!
//! The depth factor is written `ε / (ε + |dz|)` instead of `1 / (ε + |dz|)`: the constant
//! factor `ε` cancels in the normalisation, and makes "all weights nearly zero" a
//! scale-free test. `ε` is relative to the target's depth ([`DEPTH_EPS_REL`]), so the filter
//! behaves the same at every distance.
//!
//! When every `w̃_i` is below [`WEIGHT_FLOOR`] (silhouettes, thin features missed by the coarse
//! buffer), the pixel is computed by the caller's fallback — the paper's robust option of
//! shading it from scratch with all proxies.

use rayon::prelude::*;

/// `ε` as a fraction of the target pixel's eye depth: 1% depth differences halve a weight.
pub const DEPTH_EPS_REL: f32 = 0.01;

/// Exponent of the normal factor `(N_p · N_i)^32` (Eq. 11).
pub const NORMAL_POWER: i32 = 32;

/// Sum of unnormalised weights below which the fallback is used: the best neighbour is then
/// at least 1000 `ε` away in depth or 12° off in normal, i.e. on another surface.
pub const WEIGHT_FLOOR: f32 = 1e-3;

/// Geometry of a buffer for the filter: normals and eye depth (`∞`: no receiver).
#[derive(Clone, Copy, Debug)]
pub struct Geometry<'a> {
    /// Width.
    pub width: usize,
    /// Height.
    pub height: usize,
    /// Unit normals.
    pub normal: &'a [[f32; 3]],
    /// Eye depth.
    pub depth: &'a [f32],
}

/// `c^32` by five squarings (`powi` is an out-of-line call).
#[inline(always)]
fn pow32(c: f32) -> f32 {
    const { assert!(NORMAL_POWER == 32) };
    let c2 = c * c;
    let c4 = c2 * c2;
    let c8 = c4 * c4;
    let c16 = c8 * c8;
    c16 * c16
}

/// Result of an upsampling.
#[derive(Clone, Debug, PartialEq)]
pub struct Upsampled<const K: usize> {
    /// One value per display pixel (zeros where there is no receiver).
    pub values: Vec<[f32; K]>,
    /// Display pixels that used the fallback.
    pub fallbacks: usize,
}

/// Bilaterally upsamples `coarse` values (one per coarse pixel) to the `fine` geometry.
/// `fallback(i)` computes display pixel `i` directly when no coarse neighbour matches.
#[must_use]
pub fn bilateral_upsample<const K: usize>(
    coarse: Geometry<'_>,
    values: &[[f32; K]],
    fine: Geometry<'_>,
    fallback: impl Fn(usize) -> [f32; K] + Sync,
) -> Upsampled<K> {
    let (values, fallbacks) = bilateral_upsample_map(coarse, values, fine, fallback, |_, v| *v, [0.0; K]);
    Upsampled { values, fallbacks }
}

/// [`bilateral_upsample`] followed by `map(pixel, value)` in the same pass (e.g. shading),
/// without storing the upsampled values; pixels without a receiver get `empty`. Returns the
/// mapped values and the fallback count.
#[must_use]
pub fn bilateral_upsample_map<const K: usize, R: Copy + Send + Sync>(
    coarse: Geometry<'_>,
    values: &[[f32; K]],
    fine: Geometry<'_>,
    fallback: impl Fn(usize) -> [f32; K] + Sync,
    map: impl Fn(usize, &[f32; K]) -> R + Sync,
    empty: R,
) -> (Vec<R>, usize) {
    let mut out = vec![empty; fine.width * fine.height];
    let fallbacks = bilateral_upsample_map_into(coarse, values, fine, fallback, map, empty, &mut out);
    (out, fallbacks)
}

/// [`bilateral_upsample_map`] into `out` (one per display pixel, e.g. a buffer reused from
/// frame to frame); returns the fallback count.
///
/// # Panics
/// If `out.len()` is not the number of display pixels.
pub fn bilateral_upsample_map_into<const K: usize, R: Copy + Send + Sync>(
    coarse: Geometry<'_>,
    values: &[[f32; K]],
    fine: Geometry<'_>,
    fallback: impl Fn(usize) -> [f32; K] + Sync,
    map: impl Fn(usize, &[f32; K]) -> R + Sync,
    empty: R,
    out: &mut [R],
) -> usize {
    assert_eq!(out.len(), fine.width * fine.height, "one output per display pixel");
    let sx = coarse.width as f32 / fine.width as f32;
    let sy = coarse.height as f32 / fine.height as f32;
    out.par_chunks_mut(fine.width)
        .enumerate()
        .map(|(y, row)| {
            let mut count = 0;
            for (x, o) in row.iter_mut().enumerate() {
                let i = y * fine.width + x;
                let zp = fine.depth[i];
                if !zp.is_finite() {
                    *o = empty;
                    continue;
                }
                let np = fine.normal[i];
                // Position in coarse pixel-centre coordinates.
                let cx = ((x as f32 + 0.5) * sx - 0.5).clamp(0.0, (coarse.width - 1) as f32);
                let cy = ((y as f32 + 0.5) * sy - 0.5).clamp(0.0, (coarse.height - 1) as f32);
                // cx, cy >= 0 after the clamp, so truncation is floor (and avoids an out-of-line floorf).
                let (x0, y0) = (cx as usize, cy as usize);
                let (x1, y1) = ((x0 + 1).min(coarse.width - 1), (y0 + 1).min(coarse.height - 1));
                let (fx, fy) = (cx - x0 as f32, cy - y0 as f32);
                let eps = DEPTH_EPS_REL * zp;
                let taps = [
                    (x0, y0, (1.0 - fx) * (1.0 - fy)),
                    (x1, y0, fx * (1.0 - fy)),
                    (x0, y1, (1.0 - fx) * fy),
                    (x1, y1, fx * fy),
                ];
                let mut acc = [0.0f32; K];
                let mut wsum = 0.0f32;
                let mut bsum = 0.0f32;
                for (tx, ty, wb) in taps {
                    let j = ty * coarse.width + tx;
                    let zi = coarse.depth[j];
                    if !zi.is_finite() {
                        continue;
                    }
                    let ni = coarse.normal[j];
                    let c = (np[0] * ni[0] + np[1] * ni[1] + np[2] * ni[2]).max(0.0);
                    let w = wb * pow32(c) * eps / (eps + (zp - zi).abs());
                    bsum += wb;
                    wsum += w;
                    for k in 0..K {
                        acc[k] += w * values[j][k];
                    }
                }
                // Compare against the bilinear weight mass actually available, so a pixel whose
                // taps all match is never sent to the fallback because of small bilinear weights.
                if wsum <= WEIGHT_FLOOR * bsum.max(f32::MIN_POSITIVE) || wsum == 0.0 {
                    *o = map(i, &fallback(i));
                    count += 1;
                } else {
                    let inv = 1.0 / wsum;
                    *o = map(i, &acc.map(|v| v * inv));
                }
            }
            count
        })
        .sum()
}

/// Plain bilinear upsampling (no depth or normal weights), for comparisons.
#[must_use]
pub fn bilinear_upsample<const K: usize>(
    coarse: Geometry<'_>,
    values: &[[f32; K]],
    fine: Geometry<'_>,
) -> Vec<[f32; K]> {
    let ones = vec![[0.0f32, 0.0, 1.0]; coarse.width * coarse.height];
    let zeros = vec![1.0f32; coarse.width * coarse.height];
    let fine_n = vec![[0.0f32, 0.0, 1.0]; fine.width * fine.height];
    let fine_z: Vec<f32> =
        fine.depth.iter().map(|z| if z.is_finite() { 1.0 } else { f32::INFINITY }).collect();
    let c = Geometry { normal: &ones, depth: &zeros, ..coarse };
    let f = Geometry { normal: &fine_n, depth: &fine_z, ..fine };
    bilateral_upsample(c, values, f, |_| [0.0; K]).values
}
