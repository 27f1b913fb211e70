//! Path-traced reference for the maps: irradiance at a surface point for an arbitrary
//! (normal-mapped) normal.

use lightvol_core::samples::Samples;
use std::f64::consts::PI;

use glam::DVec3;
use lightvol_sh::sampling::{Frame, sample_cosine_hemisphere};

use super::Quantity;
use super::geometry::SurfaceGeometry;
use lightvol_scene::light_sampler::{LightSampler, power_heuristic};
use lightvol_scene::qmc::Qmc;
use lightvol_scene::stats::RayCounts;
use lightvol_scene::transport::{PathRng, SHADOW_MARGIN, Transport};

/// The quantity a coefficient map approximates at a surface point: with `F` the tangent frame
/// at `(tri, bary)` and `n = F.to_world(n_tangent)`,
/// `E = ∫ L(ω) max(0, n·ω) [F.n·ω > 0] dω`: light from below the tangent-space hemisphere
/// counts zero, as in \[Ish11\] Eq. 2.1 (the maps cannot represent it). Scaled by `quantity`
/// (`1/π` for radiosity).
///
/// Estimator: `samples` cosine-weighted directions about `n` (dimensions 0-1 of a scrambled
/// Halton stream keyed by `(seed, stream)`), each MIS-combined (power heuristic) with one
/// light sample (dimensions 2-4); paths beyond the first hit as in the bake. The point is
/// offset from the surface by the scene epsilon along the geometric normal. Returns zero for
/// a triangle outside every lightmap object.
#[allow(clippy::too_many_arguments)]
#[must_use]
pub fn reference_surface_irradiance(
    t: &Transport<'_>,
    geo: &SurfaceGeometry,
    tri: u32,
    bary: [f64; 2],
    n_tangent: [f64; 3],
    quantity: Quantity,
    samples: Samples,
    seed: u64,
    stream: u64,
) -> ([f64; 3], RayCounts) {
    let mut rays = RayCounts::default();
    let Some(frame) = geo.frame(tri, bary) else { return ([0.0; 3], rays) };
    let scene = t.scene();
    let x = scene.triangles[tri as usize].point(bary[0], bary[1]);
    let o = x + geo.geometric_normal(tri) * t.epsilon();
    let n = frame.to_world(DVec3::from_array(n_tangent)).normalize_or(frame.n);
    let lights = LightSampler::new(scene);
    let basis = Frame::from_normal(n.to_array());
    let h = Qmc::<5>::new(seed, stream);
    let mut sum = [0.0; 3];
    for i in 0..u64::from(samples.get()) {
        let p = h.point(i);
        let mut rng = PathRng::new(seed, stream, i);
        let local = sample_cosine_hemisphere([p[0], p[1]]);
        let d = DVec3::from_array(basis.to_world(local));
        let pdf = local[2] / PI;
        if pdf > 0.0 && frame.n.dot(d) > 0.0 {
            rays.sampling += 1;
            let hit = t.tracer().closest_hit(o, d, 0.0, f64::INFINITY);
            let l = t.radiance_from_hit(d, hit, Some(pdf), &mut rng, &mut rays);
            // L cos / pdf = π L.
            for c in 0..3 {
                sum[c] += PI * l[c];
            }
        }
        if let Some(s) = lights.sample(scene, o, [p[2], p[3], p[4]])
            && t.settings().direct.allows(s.source)
        {
            let cos = n.dot(s.dir);
            if cos > 0.0 && frame.n.dot(s.dir) > 0.0 {
                rays.shadow += 1;
                let tmax = if s.dist.is_finite() { s.dist * (1.0 - SHADOW_MARGIN) } else { f64::INFINITY };
                if tmax > 0.0 && !t.tracer().occluded(o, s.dir, 0.0, tmax) {
                    let w = if s.delta { 1.0 } else { power_heuristic(s.pdf, cos / PI) };
                    for c in 0..3 {
                        sum[c] += s.radiance[c] * cos * w / s.pdf;
                    }
                }
            }
        }
    }
    let k = quantity.scale() / f64::from(samples.get());
    (sum.map(|v| v * k), rays)
}
