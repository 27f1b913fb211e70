//! A small, seeded, deterministic path tracer in which the proxies are real spheres: the
//! ground truth for the proxies' shadows and bounce light (`tests/compare.rs`,
//! the `proxies` example).
//!
//! What it computes, per receiver `p` with normal `N`: the irradiance
//! `E(p) = ∫ L_in(s) max(0, N·s) ds`, where a ray that escapes brings the environment
//! radiance `L(s)` and a ray that meets a sphere brings that sphere's diffuse exit radiance,
//! itself traced (sphere-to-sphere shadowing and inter-reflection up to [`MAX_BOUNCES`]).
//!
//! The receiving rectangles are *not* geometry here: for the proxies the static scene's own
//! occlusion and bounce are part of the light `L` (as they are for a baked volume), so the
//! reference isolates what the proxies model. Sampling: cosine-weighted first directions
//! from a jittered `k × k` grid of strata (`k² = samples`, rounded up) and independent
//! uniform numbers for the bounces, all from a SplitMix64 stream per receiver (seeded by the
//! receiver's index), so results do not depend on thread count or order.

use lightvol_core::samples::Samples;
use std::f64::consts::PI;

use lightvol_sh::lowdisc::{SplitMix64, hash2};
use lightvol_sh::sampling::{Frame, sample_cosine_hemisphere};

use crate::light::SkySun;
use crate::proxy::SphereProxy;

/// Sphere-to-sphere bounces traced after the first hit (albedo <= 0.8 makes the truncated
/// energy below 0.8^4 ≈ 0.4 of a bounce that is itself a few percent of the total).
pub const MAX_BOUNCES: usize = 3;

/// Offset of secondary ray origins along the normal, relative to the sphere radius.
const RAY_OFFSET: f64 = 1e-9;

/// Closest sphere hit of the ray `o + t d` (`t > 0`): `(t, sphere index)`.
#[must_use]
pub fn intersect(spheres: &[SphereProxy], o: [f64; 3], d: [f64; 3]) -> Option<(f64, usize)> {
    let mut best: Option<(f64, usize)> = None;
    for (i, s) in spheres.iter().enumerate() {
        let oc = [o[0] - s.center[0], o[1] - s.center[1], o[2] - s.center[2]];
        let b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
        let c = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - s.radius * s.radius;
        let disc = b * b - c;
        if disc < 0.0 {
            continue;
        }
        let sq = disc.sqrt();
        let t = if -b - sq > 0.0 { -b - sq } else { -b + sq };
        if t > 0.0 && best.is_none_or(|(bt, _)| t < bt) {
            best = Some((t, i));
        }
    }
    best
}

/// The path tracer.
#[derive(Clone, Copy, Debug)]
pub struct PathTracer<'a> {
    /// Spheres (real geometry).
    pub spheres: &'a [SphereProxy],
    /// Environment.
    pub light: &'a SkySun,
    /// Paths per receiver (rounded up to a square number).
    pub samples: Samples,
    /// Seed of the sample streams.
    pub seed: u64,
}

impl PathTracer<'_> {
    /// Irradiance at receiver `p` (unit normal `n`); `stream` selects the receiver's
    /// independent sample stream (use the receiver's index).
    #[must_use]
    pub fn irradiance(&self, p: [f64; 3], n: [f64; 3], stream: u64) -> [f64; 3] {
        let mut rng = SplitMix64::new(hash2(self.seed, stream));
        let frame = Frame::from_normal(n);
        let k = f64::from(self.samples.get()).sqrt().ceil() as u32;
        let mut sum = [0.0; 3];
        for a in 0..k {
            for b in 0..k {
                let u = [
                    (f64::from(a) + rng.next_f64()) / f64::from(k),
                    (f64::from(b) + rng.next_f64()) / f64::from(k),
                ];
                let d = frame.to_world(sample_cosine_hemisphere(u));
                let l = self.trace(p, d, &mut rng);
                for c in 0..3 {
                    sum[c] += l[c];
                }
            }
        }
        // Cosine-weighted estimator: E = π · mean(L_in).
        sum.map(|v| PI * v / f64::from(k * k))
    }

    fn trace(&self, mut o: [f64; 3], mut d: [f64; 3], rng: &mut SplitMix64) -> [f64; 3] {
        let mut throughput = [1.0; 3];
        for bounce in 0..=MAX_BOUNCES {
            let Some((t, i)) = intersect(self.spheres, o, d) else {
                let l = self.light.radiance(d);
                return core::array::from_fn(|c| throughput[c] * l[c]);
            };
            if bounce == MAX_BOUNCES {
                break;
            }
            let s = &self.spheres[i];
            let q: [f64; 3] = core::array::from_fn(|c| o[c] + t * d[c]);
            let m: [f64; 3] = core::array::from_fn(|c| (q[c] - s.center[c]) / s.radius);
            // Diffuse, cosine-sampled: f cos / pdf = ρ.
            for c in 0..3 {
                throughput[c] *= s.albedo[c];
            }
            let u = [rng.next_f64(), rng.next_f64()];
            d = Frame::from_normal(m).to_world(sample_cosine_hemisphere(u));
            o = core::array::from_fn(|c| q[c] + RAY_OFFSET * s.radius * m[c]);
        }
        [0.0; 3]
    }
}

/// Whether `p` lies inside any sphere (such receivers are hidden inside the object and are
/// left out of comparisons).
#[must_use]
pub fn inside_any(spheres: &[SphereProxy], p: [f64; 3]) -> bool {
    spheres.iter().any(|s| {
        let v = [p[0] - s.center[0], p[1] - s.center[1], p[2] - s.center[2]];
        v[0] * v[0] + v[1] * v[1] + v[2] * v[2] < s.radius * s.radius
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_core::samples::samples;

    /// A lone receiver under a uniform sky gets E = π L exactly (every path escapes).
    #[test]
    fn unoccluded_uniform_sky_is_exact() {
        let sky = SkySun { sun_dir: [0.0, 0.0, 1.0], sun: [0.0; 3], sky: [1.0; 3], ground: [1.0; 3] };
        let pt = PathTracer { spheres: &[], light: &sky, samples: samples(16), seed: 3 };
        let e = pt.irradiance([0.0; 3], [0.0, 0.0, 1.0], 7);
        assert!((e[0] - PI).abs() < 1e-12);
    }

    /// A black sphere of angular radius θ straight above the normal blocks exactly
    /// `π sin²θ` of a uniform sky's irradiance; 64 × 64 jittered strata get it to 0.5%.
    #[test]
    fn black_sphere_overhead() {
        let sky = SkySun { sun_dir: [0.0, 0.0, 1.0], sun: [0.0; 3], sky: [1.0; 3], ground: [1.0; 3] };
        let s = [SphereProxy::new([0.0, 0.0, 2.0], 1.0, [0.0; 3])];
        let pt = PathTracer { spheres: &s, light: &sky, samples: samples(4096), seed: 1 };
        let e = pt.irradiance([0.0; 3], [0.0, 0.0, 1.0], 0)[0];
        let exact = PI * (1.0 - 0.25);
        assert!((e - exact).abs() < 5e-3 * exact, "{e} vs {exact}");
    }
}
