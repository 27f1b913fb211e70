//! The light the proxies shadow and reflect: radiance `L` as an RGB SH vector that may vary
//! with the receiver position (\[SGNS07\] Eq. 9 uses one distant `L`).
//!
//! [`LightField`] is the interface; [`DistantLight`] is the paper's distant environment,
//! [`FnLight`] wraps a closure, and [`VolumeLight`] reads the local radiance SH of a baked
//! lightvol irradiance volume.
//!
//! **What baked light as the source assumes.** With `L = L(p)` from an irradiance volume,
//! Eq. 9 becomes `L_p = O_p * L(p) + I_p`: the proxies multiply *all* light arriving at `p`,
//! direct and bounced from the static scene alike, by their visibility, as if every source of
//! that light lay beyond the proxies. This holds when the proxies are small and near the
//! receiver compared with the distance to what lights it (sky, sun, distant walls); it is
//! wrong for light from static geometry *between* a proxy and the receiver (that light would
//! not be blocked), and the volume's trilinear `L(p)` already averages over a cell, so
//! shadows do not sharpen below the cell size of the baked light. The proxies' indirect
//! light uses `L` at each proxy's centre (each proxy is lit unshadowed by the light around
//! it, the §5 assumption). The volume also does not know about the moving object, so light
//! the object itself would block before it reaches its surroundings is not removed (only
//! the receivers' view of it is).

use lightvol_sh::coeffs::{Sh, ShRgb};
use lightvol_sh::quadrature::SphereQuadrature;
use lightvol_volume::volume::IrradianceVolume;

/// Radiance arriving at a point, as an RGB SH vector with `N` coefficients.
pub trait LightField<const N: usize>: Sync {
    /// The radiance SH `L` at world point `p`.
    fn radiance_at(&self, p: [f64; 3]) -> ShRgb<f64, N>;

    /// `Some(L)` when `L` is the same everywhere (lets the pipeline precompute per-frame
    /// products); `None` by default.
    fn uniform(&self) -> Option<ShRgb<f64, N>> {
        None
    }
}

/// A distant environment: the same `L` everywhere (\[SGNS07\] §3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistantLight<const N: usize>(pub ShRgb<f64, N>);

impl<const N: usize> LightField<N> for DistantLight<N> {
    #[inline]
    fn radiance_at(&self, _p: [f64; 3]) -> ShRgb<f64, N> {
        self.0
    }

    fn uniform(&self) -> Option<ShRgb<f64, N>> {
        Some(self.0)
    }
}

/// A light field from a closure.
#[derive(Clone, Copy, Debug)]
pub struct FnLight<F>(pub F);

impl<F: Fn([f64; 3]) -> ShRgb<f64, N> + Sync, const N: usize> LightField<N> for FnLight<F> {
    #[inline]
    fn radiance_at(&self, p: [f64; 3]) -> ShRgb<f64, N> {
        (self.0)(p)
    }
}

/// The local radiance SH of a baked irradiance volume (Kontkanen & Laine 2006 Eq. 2,
/// trilinear lookup). Coefficients beyond the volume's order are 0; beyond `N` they are
/// dropped.
#[derive(Clone, Copy, Debug)]
pub struct VolumeLight<'a>(pub &'a IrradianceVolume);

impl<const N: usize> LightField<N> for VolumeLight<'_> {
    fn radiance_at(&self, p: [f64; 3]) -> ShRgb<f64, N> {
        let k = self.0.coeffs();
        let mut buf = vec![0.0f32; 3 * k];
        self.0.coeffs_at(p.map(|v| v as f32), &mut buf);
        let mut out = ShRgb([Sh::ZERO; 3]);
        for j in 0..k.min(N) {
            for ch in 0..3 {
                out.0[ch].0[j] = f64::from(buf[3 * j + ch]);
            }
        }
        out
    }
}

/// A sky-and-sun environment whose radiance is a polynomial of degree 2 in the direction,
/// hence exactly representable with 9 (or more) coefficients and non-negative everywhere:
/// `L(s) = sun · ((1 + s·u)/2)² + sky · (1 + s_z)/2 + ground · (1 - s_z)/2`.
///
/// Because it is band-limited, the path-traced reference and the SH pipeline see the same
/// light, and comparisons measure the proxies, not light truncation.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SkySun {
    /// Unit direction towards the sun lobe's peak.
    pub sun_dir: [f64; 3],
    /// Radiance of the sun lobe at its peak.
    pub sun: [f64; 3],
    /// Sky radiance at the zenith (`+z`).
    pub sky: [f64; 3],
    /// Ground-bounce radiance at the nadir.
    pub ground: [f64; 3],
}

impl SkySun {
    /// Radiance arriving from unit direction `s`.
    #[must_use]
    pub fn radiance(&self, s: [f64; 3]) -> [f64; 3] {
        let c = s[0] * self.sun_dir[0] + s[1] * self.sun_dir[1] + s[2] * self.sun_dir[2];
        let lobe = 0.25 * (1.0 + c) * (1.0 + c);
        let (up, down) = (0.5 * (1.0 + s[2]), 0.5 * (1.0 - s[2]));
        core::array::from_fn(|k| self.sun[k] * lobe + self.sky[k] * up + self.ground[k] * down)
    }

    /// The exact SH projection (exact quadrature of a degree-2 polynomial times the basis).
    #[must_use]
    pub fn sh<const N: usize>(&self) -> ShRgb<f64, N> {
        let quad = SphereQuadrature::exact_for_degree(2 + N.isqrt());
        let mut out = ShRgb([Sh::ZERO; 3]);
        for node in quad.nodes() {
            let y = lightvol_sh::eval::eval_basis::<f64, N>(node.dir);
            let l = self.radiance(node.dir);
            for ch in 0..3 {
                for i in 0..N {
                    out.0[ch].0[i] += node.weight * l[ch] * y[i];
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sky_sun_is_band_limited_to_two() {
        let s = SkySun {
            sun_dir: [0.48, 0.0, 0.8768],
            sun: [3.0, 2.5, 2.0],
            sky: [0.3, 0.5, 0.9],
            ground: [0.2; 3],
        };
        let sun_dir_norm: f64 = s.sun_dir.iter().map(|x| x * x).sum::<f64>().sqrt();
        let s = SkySun { sun_dir: s.sun_dir.map(|x| x / sun_dir_norm), ..s };
        let l16 = s.sh::<16>();
        // Band 3 is empty and the 9-coefficient vector reproduces L exactly.
        for ch in 0..3 {
            for i in 9..16 {
                assert!(l16.0[ch].0[i].abs() < 1e-13);
            }
        }
        let l9 = s.sh::<9>();
        for d in [[0.0, 0.0, 1.0], [0.6, 0.0, -0.8], [0.0, 1.0, 0.0]] {
            let e = l9.eval(d);
            let r = s.radiance(d);
            for ch in 0..3 {
                assert!((e[ch] - r[ch]).abs() < 1e-12);
            }
        }
    }
}
