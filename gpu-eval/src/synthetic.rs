//! Seeded synthetic volumes and query batches for tests, benchmarks and examples.
//!
//! [`smooth_random_volume`] fills a grid with coefficients that vary smoothly in space
//! (a few random sinusoids per coefficient and channel) with a dominant, positive DC term,
//! so irradiance is positive and well away from zero for every normal: relative errors
//! are meaningful on it. The GPU-vs-CPU tests run on it beside a baked built-in scene
//! (see `tests/lookup.rs`, `TEST_VOLUME`); benchmarks use it because it needs no bake.

use lightvol_sh::index::sh_lm;
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_volume::{GridSpec, IrradianceVolume, NodeReach, ValidityMask, VolumeError};

/// Sinusoids per coefficient and channel.
const WAVES: usize = 2;

/// A volume over `spec` with `coeffs` (4, 9 or 16) smooth random RGB coefficients per
/// node, reproducible from `seed`.
///
/// Coefficient `j` (band `l`) of channel `ch` at world point `x` is
/// `dc(j) + amp(l) Σ_w sin(k_w · x + φ_w)` with wave vectors of about one to two waves
/// across the box; `dc(0) ∈ [1, 2]`, `dc(j > 0) = 0`, `amp(0) = 0.1` and
/// `amp(l ≥ 1) = 0.08 / l`. For irradiance this keeps the DC term (≥ 0.6) above the sum of
/// all other terms' magnitudes (≤ 0.5, worst case), so `E > 0` everywhere.
pub fn smooth_random_volume(
    spec: GridSpec,
    coeffs: usize,
    seed: u64,
) -> Result<IrradianceVolume, VolumeError> {
    let (min, max) = spec.bounds();
    let (min_w, max_w) = (spec.to_world(min), spec.to_world(max));
    let extent: [f64; 3] = std::array::from_fn(|a| (max_w[a] - min_w[a]).abs().max(1e-9));
    let mut rng = SplitMix64::new(seed);
    // Per (coefficient, channel): DC and WAVES (wave vector, phase) pairs, drawn in a fixed
    // order so the volume depends on the seed only.
    let mut params = Vec::with_capacity(coeffs * 3);
    for j in 0..coeffs {
        let l = sh_lm(j).0;
        let amp = if l == 0 { 0.1 } else { 0.08 / l as f64 };
        for _ in 0..3 {
            let dc = if j == 0 { rng.range(1.0, 2.0) } else { 0.0 };
            let waves: [([f64; 3], f64); WAVES] = std::array::from_fn(|_| {
                let k = std::array::from_fn(|a| {
                    rng.range(1.0, 2.0) * std::f64::consts::TAU / extent[a]
                        * if rng.next_f64() < 0.5 { -1.0 } else { 1.0 }
                });
                (k, rng.range(0.0, std::f64::consts::TAU))
            });
            params.push((dc, amp / WAVES as f64, waves));
        }
    }
    IrradianceVolume::from_fn(spec, coeffs, |x| {
        (0..coeffs)
            .map(|j| {
                std::array::from_fn(|ch| {
                    let (dc, amp, waves) = &params[3 * j + ch];
                    dc + amp
                        * waves
                            .iter()
                            .map(|(k, ph)| (k[0] * x[0] + k[1] * x[1] + k[2] * x[2] + ph).sin())
                            .sum::<f64>()
                })
            })
            .collect()
    })
}

/// `n` random queries: world points uniform in the volume's box enlarged by `margin` (a
/// fraction of the box size per side, so points outside exercise clamping), and uniform
/// unit directions. Reproducible from `seed`; query `q` depends only on `(seed, q)`.
#[must_use]
pub fn random_queries(spec: &GridSpec, n: usize, margin: f64, seed: u64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let (min, max) = spec.bounds();
    let mut points = Vec::with_capacity(n);
    let mut dirs = Vec::with_capacity(n);
    for q in 0..n {
        let mut rng = SplitMix64::new(lightvol_sh::lowdisc::hash2(seed, q as u64));
        let g: [f64; 3] = std::array::from_fn(|a| {
            let pad = margin * (max[a] - min[a]);
            rng.range(min[a] - pad, max[a] + pad)
        });
        points.push(spec.to_world(g).map(|v| v as f32));
        let d = lightvol_sh::sampling::sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
        dirs.push(d.map(|v| v as f32));
    }
    (points, dirs)
}

/// A random validity mask (about 70% valid) and node reach (half the directions a full
/// cell, the others a multiple of an eighth of a cell below it) for `nodes` nodes,
/// reproducible from `seed`: the masks the GPU-vs-CPU tests of the weighted lookups use.
#[must_use]
pub fn random_masks(nodes: usize, seed: u64) -> (ValidityMask, NodeReach) {
    let mut rng = SplitMix64::new(seed);
    let valid = (0..nodes).map(|_| rng.next_f64() < 0.7).collect();
    let reach = (0..nodes)
        .map(|_| {
            std::array::from_fn(
                |_| if rng.next_f64() < 0.5 { 1.0 } else { (rng.next_u64() % 8) as f32 / 8.0 },
            )
        })
        .collect();
    (ValidityMask::new(valid), NodeReach::new(reach).expect("reaches in [0, 1]"))
}

/// How far, in cells, [`clear_of_reach_decisions`] keeps a test point from every multiple
/// of an eighth of a cell: the f32 roundings of the test point on a GPU and on the CPU
/// differ by a few ulps of the grid coordinate (~1e-6 cells), far below this.
pub const REACH_DECISION_MARGIN: f64 = 1e-3;

/// Whether the node-reach test point of a query at `p` (`p + n · bias` with a normal `n`,
/// `p` without) lies farther than [`REACH_DECISION_MARGIN`] cells from every multiple of an
/// eighth of a cell on every axis (computed in f64): there a lookup's f32 rounding of the
/// test point cannot change its decisions against [`random_masks`]' reaches, which are
/// such multiples.
#[must_use]
pub fn clear_of_reach_decisions(spec: &GridSpec, p: [f32; 3], n: Option<[f32; 3]>) -> bool {
    let bias = lightvol_volume::lookup::reach_bias(spec);
    let t: [f64; 3] = std::array::from_fn(|a| f64::from(p[a]) + n.map_or(0.0, |n| bias * f64::from(n[a])));
    let g = spec.to_grid(t);
    let (min, max) = spec.bounds();
    let res = spec.res();
    (0..3).all(|a| {
        let u = (g[a] - min[a]) * f64::from(res[a] - 1) / (max[a] - min[a]);
        let e = (8.0 * u).rem_euclid(1.0);
        e.min(1.0 - e) / 8.0 > REACH_DECISION_MARGIN
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn irradiance_is_positive_and_reproducible() {
        let spec = GridSpec::new([0.0; 3], [2.0, 1.0, 1.5], [6, 4, 5]).unwrap();
        let v = smooth_random_volume(spec.clone(), 9, 5).unwrap();
        assert_eq!(v, smooth_random_volume(spec.clone(), 9, 5).unwrap());
        assert_ne!(v, smooth_random_volume(spec.clone(), 9, 6).unwrap());
        let (p, n) = random_queries(&spec, 500, 0.1, 1);
        assert_eq!((p.clone(), n.clone()), random_queries(&spec, 500, 0.1, 1));
        for (p, n) in p.iter().zip(&n) {
            let e = v.irradiance_reference(p.map(f64::from), n.map(f64::from));
            // DC bound: pi * Y00 * 0.9 ≈ 0.8 minus at most 0.5 from the other bands.
            assert!(e.iter().all(|&c| c > 0.3), "{e:?}");
            let len: f32 = n.iter().map(|x| x * x).sum();
            assert!((len - 1.0).abs() < 1e-6);
        }
    }
}
