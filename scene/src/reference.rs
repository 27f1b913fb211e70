//! Ground truth for evaluation: reference irradiance `E(x, n)` by path tracing with many
//! quasi-Monte Carlo samples (the "ray traced" row of Kontkanen & Laine 2006 Fig. 6).

use crate::qmc::Qmc;
use glam::DVec3;
use lightvol_core::samples::Samples;
use rayon::prelude::*;

use crate::stats::RayCounts;
use crate::transport::{PathRng, Transport};
use lightvol_core::metric::prefix_error;

/// Reference irradiance at `x` for receiver normal `n` (unit) with `samples` QMC samples:
/// the first five dimensions (cosine direction, light choice and position) come from a
/// [`Qmc`] stream keyed by `(seed, stream)`, the path beyond from a per-sample
/// generator. `x` is moved off surfaces by the scene's epsilon along `n`.
#[must_use]
pub fn reference_irradiance(
    t: &Transport<'_>,
    x: DVec3,
    n: DVec3,
    samples: Samples,
    seed: u64,
    stream: u64,
) -> ([f64; 3], RayCounts) {
    let (e, rays) = reference_irradiance_prefixed(t, x, n, samples, seed, stream);
    (e.mean, rays)
}

/// A reference estimate with the means of the first half and the first quarter of its
/// samples, which say how far the mean is from converged ([`Self::error_of`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrefixedEstimate {
    /// The mean of all samples: [`reference_irradiance`]'s value.
    pub mean: [f64; 3],
    /// The mean of the first half of the samples.
    pub half: [f64; 3],
    /// The mean of the first quarter of the samples.
    pub quarter: [f64; 3],
    /// Samples in the mean.
    pub samples: u32,
}

impl PrefixedEstimate {
    /// The estimated error of `f(mean)` for a quantity `f` affine in the irradiance (its
    /// luminance, a pixel's shaded value): [`prefix_error`] of `f` at the three means, the
    /// estimate `bake --noise` stops on. `None` below four samples.
    #[must_use]
    pub fn error_of(&self, f: impl Fn([f64; 3]) -> f64) -> Option<f64> {
        (self.samples >= 4).then(|| prefix_error(f(self.mean), f(self.half), f(self.quarter)))
    }
}

/// [`reference_irradiance`] (the same value, bit for bit) with its prefixes' means.
#[must_use]
pub fn reference_irradiance_prefixed(
    t: &Transport<'_>,
    x: DVec3,
    n: DVec3,
    samples: Samples,
    seed: u64,
    stream: u64,
) -> (PrefixedEstimate, RayCounts) {
    let h = Qmc::<5>::new(seed, stream);
    let x = x + n * t.epsilon();
    let mut rays = RayCounts::default();
    let mut sum = [0.0; 3];
    let count = u64::from(samples.get());
    let (mut quarter, mut half) = ([0.0; 3], [0.0; 3]);
    for i in 0..count {
        let p = h.point(i);
        let mut rng = PathRng::new(seed, stream, i);
        let e = t.irradiance_sample(x, n, [p[0], p[1]], [p[2], p[3], p[4]], &mut rng, &mut rays);
        for c in 0..3 {
            sum[c] += e[c];
        }
        if i + 1 == count / 4 {
            quarter = sum.map(|s| s / (count / 4) as f64);
        }
        if i + 1 == count / 2 {
            half = sum.map(|s| s / (count / 2) as f64);
        }
    }
    let k = 1.0 / f64::from(samples.get());
    (PrefixedEstimate { mean: sum.map(|s| s * k), half, quarter, samples: samples.get() }, rays)
}

/// [`reference_irradiance`] over many points in parallel (point `i` uses stream `i`;
/// bit-identical for any thread count).
#[must_use]
pub fn reference_irradiance_many(
    t: &Transport<'_>,
    points: &[(DVec3, DVec3)],
    samples: Samples,
    seed: u64,
) -> Vec<[f64; 3]> {
    reference_irradiance_many_prefixed(t, points, samples, seed).into_iter().map(|e| e.mean).collect()
}

/// [`reference_irradiance_prefixed`] over many points in parallel (the streams of
/// [`reference_irradiance_many`]).
#[must_use]
pub fn reference_irradiance_many_prefixed(
    t: &Transport<'_>,
    points: &[(DVec3, DVec3)],
    samples: Samples,
    seed: u64,
) -> Vec<PrefixedEstimate> {
    points
        .par_iter()
        .enumerate()
        .map(|(i, &(x, n))| reference_irradiance_prefixed(t, x, n, samples, seed, i as u64).0)
        .collect()
}

#[cfg(test)]
mod tests {
    //! Light transport against analytic answers.
    use super::*;
    use crate::builder::SceneBuilder;
    use crate::bvh::Tracer;
    use crate::lights::{Environment, Sun};
    use crate::material::Material;
    use crate::scene::Scene;
    use crate::transport::TransportSettings;
    use lightvol_core::samples::samples;
    use std::f64::consts::PI;

    fn plane(albedo: f64, half: f64) -> SceneBuilder {
        let mut b = SceneBuilder::new("plane");
        let m = b.add_material(Material::diffuse("ground", [albedo; 3])).unwrap();
        b.add_quad(
            [
                DVec3::new(-half, -half, 0.0),
                DVec3::new(half, -half, 0.0),
                DVec3::new(half, half, 0.0),
                DVec3::new(-half, half, 0.0),
            ],
            m,
        )
        .unwrap();
        b
    }

    /// A horizontal plane under a uniform sky L: E = πL for an upward receiver (every
    /// cosine-sampled ray escapes, so each sample is exactly πL), and for a receiver tilted
    /// by θ: πL(1 + cos θ)/2 from the sky plus πaL(1 - cos θ)/2 from the plane, whose
    /// radiance is aL (it receives πL and reflects a/π of it).
    #[test]
    fn plane_under_uniform_sky() {
        let l = 1.5;
        let mut b = plane(0.5, 1e4);
        b.environment = Environment::UniformSky { sky: [l; 3], ground: None };
        let s = b.build().unwrap();
        let tr = Tracer::new(&s);
        let t = Transport::new(&s, &tr, TransportSettings::default());
        let x = DVec3::new(0.3, -0.2, 0.0);
        let (e, _) = reference_irradiance(&t, x, DVec3::Z, samples(256), 1, 0);
        // Every sample is πL up to the f64 rounding of the sum.
        assert!((e[0] - PI * l).abs() < 1e-12, "{e:?}");
        let th = 1.0f64;
        let n = DVec3::new(th.sin(), 0.0, th.cos());
        let (e, _) = reference_irradiance(&t, DVec3::new(0.0, 0.0, 1.0), n, samples(8192), 2, 0);
        let exact = PI * l * (1.0 + th.cos()) / 2.0 + PI * 0.5 * l * (1.0 - th.cos()) / 2.0;
        // QMC over a two-valued integrand (sky or ground) with edge discontinuity: ~1e-3.
        assert!((e[0] - exact).abs() < 3e-3 * exact, "{} {exact}", e[0]);
    }

    /// Furnace: inside a closed box whose walls have albedo a and emit Le (uniform), the
    /// radiance is the geometric series Le (1 + a + a² + …) = Le / (1 - a) everywhere, so
    /// E = π Le / (1 - a) for any receiver.
    #[test]
    fn furnace_matches_geometric_series() {
        for (a, tol) in [(0.5, 0.012), (0.8, 0.025)] {
            let mut b = SceneBuilder::new("furnace");
            let m = b.add_material(Material::emitter("wall", [a; 3], [1.0; 3])).unwrap();
            b.add_box(DVec3::splat(-1.0), DVec3::new(1.0, 2.0, 1.5), m, false, false).unwrap();
            let s: Scene = b.build().unwrap();
            let tr = Tracer::new(&s);
            let t = Transport::new(&s, &tr, TransportSettings::default());
            let exact = PI / (1.0 - a);
            for (i, n) in [DVec3::Z, DVec3::new(0.6, 0.0, -0.8)].into_iter().enumerate() {
                let (e, rays) =
                    reference_irradiance(&t, DVec3::new(0.2, 0.1, -0.3), n, samples(16384), 3, i as u64);
                // Russian roulette keeps the series unbiased; the tolerance is ~4 standard
                // errors of the 16384-sample mean (per-sample relative sd ≈ 0.33 at a = 0.5,
                // measured with 3M samples: mean 2.00005 ± 0.0002 of the exact 2).
                assert!((e[1] - exact).abs() < tol * exact, "a={a}: {} vs {exact}", e[1]);
                assert!(rays.bounce > 0 && rays.shadow > 0);
            }
            // incident_radiance alone: Le / (1 - a) along any direction.
            let mut sum = 0.0;
            let mut rays = RayCounts::default();
            for k in 0..4096u64 {
                let mut rng = PathRng::new(5, 0, k);
                let d = DVec3::from_array(lightvol_sh::sampling::sample_uniform_sphere(rng.next2()));
                sum += t.incident_radiance(DVec3::new(0.1, 0.2, 0.3), d, &mut rng, &mut rays)[0];
            }
            let mean = sum / 4096.0;
            assert!((mean - 1.0 / (1.0 - a)).abs() < 2.0 * tol / (1.0 - a), "{mean}");
        }
    }

    /// A small sun of irradiance E_sun at zenith angle θ gives E = E_sun cos θ on an upward
    /// receiver (exact for a uniform disk wholly above the horizon), for a cone sun through
    /// MIS and for a delta sun through next-event estimation.
    #[test]
    fn small_sun_gives_cosine_law() {
        for radius in [0.01, 0.0] {
            let mut b = plane(0.0, 1.0);
            // Move the plane far below so it does not matter; ground is black anyway.
            b.sun = Some(Sun::from_angles(50.0, 30.0, [2.0, 1.0, 0.5], radius));
            let s = b.build().unwrap();
            let tr = Tracer::new(&s);
            let t = Transport::new(&s, &tr, TransportSettings::default());
            let (e, _) = reference_irradiance(&t, DVec3::new(5.0, 5.0, 3.0), DVec3::Z, samples(1024), 7, 0);
            let exact = 2.0 * 50f64.to_radians().sin();
            // Cone: light samples dominate and vary only with cos over a 0.01 rad disk.
            assert!((e[0] - exact).abs() < 1e-3 * exact, "r={radius}: {} vs {exact}", e[0]);
        }
    }

    /// A constant lat-long environment map L (importance-sampled and MIS-combined) gives
    /// E = πL on any receiver in open space, and a point light of intensity I at distance
    /// d gives E = I cos θ / d² (next-event estimation only).
    #[test]
    fn environment_map_and_point_light() {
        let mut b = plane(0.0, 0.01);
        let texels = vec![[0.5f32, 1.0, 2.0]; 32 * 16];
        b.environment = Environment::Map(crate::envmap::EnvMap::from_linear(32, 16, texels).unwrap());
        let s = b.build().unwrap();
        let tr = Tracer::new(&s);
        let t = Transport::new(&s, &tr, TransportSettings::default());
        for n in [DVec3::Z, DVec3::new(0.6, 0.0, -0.8)] {
            let (e, rays) = reference_irradiance(&t, DVec3::new(5.0, 0.0, 3.0), n, samples(1024), 4, 0);
            // Unbiased MIS of two low-variance techniques; 1024 QMC samples: ~1e-3.
            assert!((e[2] - 2.0 * PI).abs() < 3e-3 * 2.0 * PI, "{e:?}");
            assert!(rays.shadow > 0);
        }
        let mut b = plane(0.0, 0.01);
        b.punctual.push(crate::lights::PunctualLight::Point {
            position: DVec3::new(3.0, 4.0, 12.0),
            intensity: [100.0; 3],
        });
        let s = b.build().unwrap();
        let tr = Tracer::new(&s);
        let t = Transport::new(&s, &tr, TransportSettings::default());
        let (e, _) =
            reference_irradiance(&t, DVec3::ZERO + DVec3::new(0.0, 0.0, 0.5), DVec3::Z, samples(16), 4, 0);
        let d = DVec3::new(3.0, 4.0, 11.5);
        let exact = 100.0 * (11.5 / d.length()) / d.length_squared();
        // The reference moves x off the plane by the scene epsilon: relative 1e-5 effect.
        assert!((e[0] - exact).abs() < 1e-4 * exact, "{} {exact}", e[0]);
    }

    /// A furnace: inside a closed box whose walls all emit `Le` and reflect `ρ`, radiance is
    /// `Le Σ_k ρ^k`. A path truncated after `N` bounces (`TransportSettings::truncated`)
    /// sums `k = 0..=N + 1` (the last surface still gets its direct light): irradiance
    /// `π Le (1 + ρ + … + ρ^(N+1))`; with Russian roulette it is the full `π Le / (1 − ρ)`.
    /// So `--bounces 0` is direct light only, not "roulette from the first bounce".
    #[test]
    fn truncated_paths_sum_exactly_their_bounces_in_a_furnace() {
        let (le, rho) = (1.0, 0.5);
        let mut b = SceneBuilder::new("furnace");
        let m = b.add_material(Material::emitter("wall", [rho; 3], [le; 3])).unwrap();
        // Six inward-facing walls of [-1, 1]³ (counter-clockwise seen from inside).
        let c = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let faces = [
            [c(-1., -1., -1.), c(1., -1., -1.), c(1., 1., -1.), c(-1., 1., -1.)],
            [c(-1., -1., 1.), c(-1., 1., 1.), c(1., 1., 1.), c(1., -1., 1.)],
            [c(-1., -1., -1.), c(-1., 1., -1.), c(-1., 1., 1.), c(-1., -1., 1.)],
            [c(1., -1., -1.), c(1., -1., 1.), c(1., 1., 1.), c(1., 1., -1.)],
            [c(-1., -1., -1.), c(-1., -1., 1.), c(1., -1., 1.), c(1., -1., -1.)],
            [c(-1., 1., -1.), c(1., 1., -1.), c(1., 1., 1.), c(-1., 1., 1.)],
        ];
        for q in faces {
            b.add_triangle([q[0], q[1], q[2]], [glam::DVec2::ZERO; 3], m).unwrap();
            b.add_triangle([q[0], q[2], q[3]], [glam::DVec2::ZERO; 3], m).unwrap();
        }
        let mut scene = b.build().unwrap();
        scene.environment = Environment::Black;
        let tracer = Tracer::new(&scene);
        let x = DVec3::new(0.1, -0.2, 0.05);
        let n = DVec3::new(0.0, 0.6, 0.8);
        let count = samples(32_768);
        let cases = [
            (TransportSettings::truncated(0), 1.0 + rho),
            (TransportSettings::truncated(1), 1.0 + rho + rho * rho),
            (TransportSettings::truncated(2), (0..=3).map(|k| rho.powi(k)).sum::<f64>()),
            (TransportSettings::default(), 1.0 / (1.0 - rho)),
        ];
        for (ts, sum) in cases {
            let t = Transport::new(&scene, &tracer, ts);
            let (e, _) = reference_irradiance(&t, x, n, count, 3, 11);
            let want = PI * le * sum;
            // Emission is exact along every path; the next-event estimates of the walls'
            // light (and the roulette) carry the noise: at 8192 samples it measured 0.01% to
            // 1.3% over three seeds, so 2% at 32768 samples (half the noise) has margin,
            // while neighbouring cases differ by 7% or more.
            const FURNACE_REL: f64 = 0.02;
            assert!((e[0] - want).abs() < FURNACE_REL * want, "{}: {} vs {want}", ts.label(), e[0]);
        }
    }

    /// Direct light selection on a plane of albedo ρ under a uniform sky L and a delta sun of
    /// irradiance E_s at elevation cosine c: an upward receiver sees `πL + E_s c` with
    /// everything, `πL` without the sun (`sky+indirect`), 0 with nothing direct
    /// (`indirect`); a downward one sees the plane, lit by both, `ρ(πL + E_s c)` in every
    /// mode (bounced light always counts).
    #[test]
    fn direct_light_selection_keeps_bounced_light() {
        use crate::transport::DirectLight;
        let (l, es, rho) = (0.4, 3.0, 0.5);
        let dir = DVec3::new(0.6, 0.0, 0.8);
        let mut b = plane(rho, 1e4);
        b.environment = Environment::UniformSky { sky: [l; 3], ground: None };
        b.sun = Some(Sun { direction: dir, irradiance: [es; 3], angular_radius: 0.0 });
        let s = b.build().unwrap();
        let tr = Tracer::new(&s);
        let x = DVec3::new(0.1, 0.2, 0.5);
        let lit = PI * l + es * dir.z;
        for (direct, up) in
            [(DirectLight::All, lit), (DirectLight::SkyAndIndirect, PI * l), (DirectLight::Indirect, 0.0)]
        {
            let t = Transport::new(&s, &tr, TransportSettings { direct, ..TransportSettings::default() });
            let (e_up, _) = reference_irradiance(&t, x, DVec3::Z, samples(4096), 5, 1);
            let (e_down, _) = reference_irradiance(&t, x, -DVec3::Z, samples(4096), 5, 2);
            // Upward: the sky part is exact per sample, the delta sun's light sample is
            // exact too: f64 rounding only.
            assert!((e_up[0] - up).abs() < 1e-9 * lit, "{direct:?} up: {} vs {up}", e_up[0]);
            // Downward: the plane's radiance through one bounce, sampled (the sun's part
            // through the bounce's next-event estimate): QMC noise, 1%.
            let down = rho * lit;
            assert!((e_down[0] - down).abs() < 0.01 * down, "{direct:?} down: {} vs {down}", e_down[0]);
        }
    }
}
