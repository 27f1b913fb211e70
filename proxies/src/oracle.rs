//! The coverage oracle (\[SGNS07\] §4.1): each proxy influences only receivers within `η r`
//! of its centre, i.e. with `α = r/d > 1/η`. `η` is derived here by computation for a
//! shading tolerance, under the paper's conservative configuration:
//!
//! - **Shadows** ([`shadow_eta`]): a delta light at SH order `n` (the peakiest light the
//!   order can represent), the receiver normal pointing at it, the light scaled so that the
//!   unshadowed shading is 1. A single blocker of angular radius `θ` is placed at every polar
//!   angle `β ∈ [0°, 90°)` from the normal (step [`BETA_STEP_DEG`]); its shadow is the exact
//!   projection `H · ((1 - V) * L)` (Eq. 9-10 with `m = 1`). `η = 1 / sin θ*` where `θ*` is
//!   the largest half-angle below which every shading difference stays within the tolerance.
//! - **Indirect** ([`indirect_eta`]): the same normalised delta light from every direction of
//!   a grid, a white (albedo 1) proxy at every polar angle from the normal, its exact
//!   indirect light (Eq. 17) dotted with `H`; `η` as above.
//!
//! - **Shadows for a given light** ([`shadow_eta_for_light`]): the paper's specialisation to
//!   the actual lighting. The worst difference over receiver normals (a Fibonacci set of
//!   [`LIGHT_NORMALS`]) and blocker directions above each normal, relative to the largest
//!   unshadowed shading, for the light's luminance (channel mean). Smooth lights allow much
//!   smaller η than the delta light.
//!
//! The search scans `α` upwards in steps of [`ALPHA_SCAN_STEP`] to the first violation and
//! bisects to [`ALPHA_BISECT_TOL`].

use lightvol_sh::coeffs::{Sh, ShRgb};

use std::f64::consts::PI;

use lightvol_sh::irradiance::radiance_to_irradiance;

use crate::accumulate::{apply_exact_operator, cosine_lobe, delta, single_blocker_exact};
use crate::operators::m_exact;
use crate::proxy::SphereProxy;
use crate::tables::rotate_zh;
use lightvol_sh::gaunt::product;

/// Polar-angle step of the blocker placements (degrees).
pub const BETA_STEP_DEG: f64 = 2.5;

/// Step of the upward scan in `α`; differences grow like `α²`, so the first violation is
/// found well before the scan could skip over a window.
pub const ALPHA_SCAN_STEP: f64 = 2e-3;

/// Bisection tolerance on `α` (`η` to about 0.1% at `η ~ 15`).
pub const ALPHA_BISECT_TOL: f64 = 1e-6;

/// The result of an `η` derivation.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct EtaDerivation {
    /// Shading tolerance (fraction of the unshadowed shading 1).
    pub tolerance: f64,
    /// SH bands (order).
    pub bands: usize,
    /// `α* = sin θ*`.
    pub alpha: f64,
    /// `η = 1/α*`.
    pub eta: f64,
    /// `θ*` in degrees.
    pub theta_deg: f64,
}

impl EtaDerivation {
    fn from_alpha(tolerance: f64, bands: usize, alpha: f64) -> Self {
        Self { tolerance, bands, alpha, eta: 1.0 / alpha, theta_deg: alpha.asin().to_degrees() }
    }
}

fn dir_at(polar_deg: f64, azimuth_deg: f64) -> [f64; 3] {
    let (t, p) = (polar_deg.to_radians(), azimuth_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

fn betas() -> impl Iterator<Item = f64> {
    (0..(90.0 / BETA_STEP_DEG) as usize).map(|k| k as f64 * BETA_STEP_DEG)
}

/// The normalised delta light along `+z` (unshadowed shading 1 at `N = +z`).
fn normalized_delta<const N: usize>(dir: [f64; 3]) -> Sh<f64, N> {
    let l = delta::<N>(dir);
    let s = l.dot(&cosine_lobe::<N>(dir));
    l * (1.0 / s)
}

/// Worst shading difference of a single blocker with `sin θ = alpha` (shadow configuration).
#[must_use]
pub fn shadow_difference<const N: usize>(alpha: f64) -> f64 {
    let z = [0.0, 0.0, 1.0];
    let l = normalized_delta::<N>(z);
    let light = ShRgb([l, l, l]);
    betas()
        .map(|b| (1.0 - single_blocker_exact::<N>(alpha, dir_at(b, 0.0), z, &light)[0]).abs())
        .fold(0.0, f64::max)
}

/// Worst indirect shading of a white proxy with `sin θ = alpha` (indirect configuration),
/// with the exact operator `M(α)` computed at `alpha` (not interpolated from the table).
#[must_use]
pub fn indirect_difference<const N: usize>(alpha: f64) -> f64 {
    let z = [0.0, 0.0, 1.0];
    let h = cosine_lobe::<N>(z);
    let m = m_exact::<N>(alpha);
    let mut worst = 0.0f64;
    for lp in (0..=12).map(|k| 15.0 * f64::from(k)) {
        for la in (0..=6).map(|k| 30.0 * f64::from(k)) {
            let l = radiance_to_irradiance(&normalized_delta::<N>(dir_at(lp, la)));
            let irr = ShRgb([l, l, l]);
            for b in betas() {
                let i = apply_exact_operator(&m, dir_at(b, 0.0), &irr);
                worst = worst.max(i.0[0].dot(&h).abs() / PI);
            }
        }
    }
    worst
}

/// `α*`: the largest `α` with `diff(α') <= tolerance` for all scanned `α' <= α`.
fn search(diff: impl Fn(f64) -> f64, tolerance: f64) -> f64 {
    let mut lo = 0.0;
    let mut hi = 1.0;
    let mut a = ALPHA_SCAN_STEP;
    while a <= 1.0 {
        if diff(a) > tolerance {
            hi = a;
            break;
        }
        lo = a;
        a += ALPHA_SCAN_STEP;
    }
    while hi - lo > ALPHA_BISECT_TOL {
        let mid = 0.5 * (lo + hi);
        if diff(mid) > tolerance { hi = mid } else { lo = mid }
    }
    lo
}

/// `η` for shadows at `N` coefficients and a shading tolerance (e.g. 1/256).
#[must_use]
pub fn shadow_eta<const N: usize>(tolerance: f64) -> EtaDerivation {
    EtaDerivation::from_alpha(tolerance, N.isqrt(), search(shadow_difference::<N>, tolerance))
}

/// `η` for indirect light at `N` coefficients and a shading tolerance.
#[must_use]
pub fn indirect_eta<const N: usize>(tolerance: f64) -> EtaDerivation {
    EtaDerivation::from_alpha(tolerance, N.isqrt(), search(indirect_difference::<N>, tolerance))
}

/// Receiver normals of [`shadow_eta_for_light`].
pub const LIGHT_NORMALS: usize = 256;

/// Worst shadow difference of a blocker with `sin θ = alpha` under `light` (luminance),
/// relative to the largest unshadowed shading. Uses `H · (V * L) = V · (H * L)`.
#[must_use]
pub fn shadow_difference_for_light<const N: usize>(light: &ShRgb<f64, N>, alpha: f64) -> f64 {
    let lum = (light.0[0] + light.0[1] + light.0[2]) * (1.0 / 3.0);
    let normals: Vec<[f64; 3]> = lightvol_sh::sampling::fibonacci_sphere(LIGHT_NORMALS).collect();
    let peak = normals.iter().map(|&n| lum.dot(&cosine_lobe::<N>(n))).fold(0.0, f64::max);
    let cap = lightvol_sh::zonal::Zh::<f64, 4>::cap(alpha.asin()).0;
    let mut worst = 0.0f64;
    for &n in &normals {
        let t = product(&cosine_lobe::<N>(n), &lum);
        let f = lightvol_sh::sampling::Frame::from_normal(n);
        for b in betas() {
            for az in (0..8).map(|k| 45.0 * f64::from(k)) {
                let d = f.to_world(dir_at(b, az));
                let v: Sh<f64, N> = rotate_zh(&cap, d);
                worst = worst.max(v.dot(&t).abs());
            }
        }
    }
    worst / peak
}

/// `η` for shadows under a specific light (\[SGNS07\] §4.1, "specialized to the actual lighting
/// environment").
#[must_use]
pub fn shadow_eta_for_light<const N: usize>(light: &ShRgb<f64, N>, tolerance: f64) -> EtaDerivation {
    EtaDerivation::from_alpha(
        tolerance,
        N.isqrt(),
        search(|a| shadow_difference_for_light(light, a), tolerance),
    )
}

/// The sphere of influence of a proxy: receivers closer than `η r` to its centre.
#[must_use]
pub fn influence_radius(proxy: &SphereProxy, eta: f64) -> f64 {
    proxy.radius * eta
}
