//! One texel's coefficients: sample points on the texel's footprint, restricted to the domain
//! of interest (Kontkanen & Laine 2006 §5-6, Algorithm 2 adapted to a texel footprint), and the
//! incident radiance over each point's tangent-space hemisphere projected to SH (\[Ish11\]
//! Eq. 2.1-2.2), convolved with the clamped cosine (Eq. 2.3) and fitted to the basis.
//!
//! **Estimator.** Candidate `i` of a texel takes its footprint point from dimensions 0-2 and
//! its direction (uniform on the tangent-space hemisphere, density `1/2π`) from dimensions
//! 3-4 of a scrambled Halton stream keyed by `(seed, object, texel)`; the path beyond the
//! first hit uses a [`PathRng`] keyed by `(seed, object·texel stream, i)`. With light
//! sampling on, each sample adds one light sample at its point, MIS-weighted (power
//! heuristic) against the `1/2π` direction density; light directions below the tangent-space
//! hemisphere are dropped (the integrand of Eq. 2.1 is zero there). The SH coefficients are
//! `s_j = (1/K) Σ_i [2π L_i y_j(ω_i) + (L/p)_light y_j(ω_light)]` over the `K` kept samples.
//!
//! **Domain of interest.** A candidate whose sampling ray meets a back face becomes a
//! back-face point and is dropped; later candidates first send query rays to the known
//! back-face points and are dropped if one of them is a back face; every new back-face point
//! re-tests the kept samples (Algorithm 2 with the query direction, as lightvol-sampler's
//! `domain::classify_cell` does for grid cells). Candidates are drawn until `samples` are kept or
//! `max_candidates_factor × samples` were tried: the samples move to the valid part of the
//! footprint.

use lightvol_core::samples::Samples;
use std::f64::consts::PI;

use glam::{DVec2, DVec3};
use lightvol_hemibasis::Matrix;
use lightvol_sh::eval::eval_into;
use lightvol_sh::lowdisc::hash2;
use lightvol_sh::sampling::sample_uniform_hemisphere;

use super::InvalidTexels;
use super::atlas::Footprint;
use super::geometry::SurfaceGeometry;
use super::tangent::TangentFrame;
use lightvol_scene::bvh::Hit;
use lightvol_scene::qmc::Qmc;
use lightvol_scene::stats::RayCounts;
use lightvol_scene::transport::{PathRng, Transport};

/// Density of uniform directions on the hemisphere.
pub const HEMISPHERE_PDF: f64 = 1.0 / (2.0 * PI);

/// What the texel integrator needs besides the footprint.
pub(crate) struct TexelJob<'a> {
    pub transport: &'a Transport<'a>,
    pub geo: &'a SurfaceGeometry,
    pub size: [u32; 2],
    pub object: u32,
    pub seed: u64,
    pub samples: Samples,
    pub max_candidates: u32,
    pub light_sampling: bool,
    pub invalid: InvalidTexels,
    pub bands: usize,
    /// Per SH coefficient: `A_l` × the quantity's scale.
    pub factors: Vec<f64>,
    /// SH irradiance → basis (`K × bands²`).
    pub matrix: &'a Matrix,
}

/// One texel's result.
#[derive(Clone, Debug, Default)]
pub(crate) struct TexelOut {
    /// Basis coefficients (RGB); `None` when no sample point was valid.
    pub coeffs: Option<Vec<[f64; 3]>>,
    /// Candidates that saw a back face (invalid points).
    pub invalid_points: u32,
    /// Samples used.
    pub kept: u32,
    pub rays: RayCounts,
}

/// A sample point with its frame and first ray.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    index: u64,
    origin: DVec3,
    frame: TangentFrame,
    dir: DVec3,
    hit: Option<Hit>,
}

/// Bytes a texel holds per sample while it is integrated: a kept candidate (its index,
/// origin, tangent frame, direction and first hit).
pub const SAMPLE_BYTES: u128 = size_of::<Candidate>() as u128;

impl TexelJob<'_> {
    fn stream(&self, texel: u32) -> u64 {
        hash2(u64::from(self.object), u64::from(texel))
    }

    /// The sample point, frame and direction of candidate `i`.
    fn candidate(&self, fp: &Footprint, p: [f64; 5], index: u64) -> Candidate {
        let (tri, q) = fp.sample([p[0], p[1], p[2]]);
        let uv = q / DVec2::new(f64::from(self.size[0]), f64::from(self.size[1]));
        let bary = barycentric(self.geo.triangle(tri).expect("object triangle").uv, uv);
        let scene_tri = &self.transport.scene().triangles[tri as usize];
        let x = scene_tri.point(bary[0], bary[1]);
        let frame = self.geo.frame(tri, bary).expect("object triangle");
        let ng = self.geo.geometric_normal(tri);
        let origin = x + ng * self.transport.epsilon();
        let local = sample_uniform_hemisphere([p[3], p[4]]);
        let dir = frame.to_world(DVec3::from_array(local)).normalize();
        Candidate { index, origin, frame, dir, hit: None }
    }

    /// Integrates one texel.
    pub(crate) fn run(&self, fp: &Footprint) -> TexelOut {
        let stream = self.stream(fp.texel);
        let h = Qmc::<5>::new(self.seed, stream);
        let tracer = self.transport.tracer();
        let mut out = TexelOut::default();
        let kept: Vec<Candidate> = match self.invalid {
            InvalidTexels::Keep => (0..u64::from(self.samples.get()))
                .map(|i| {
                    let mut c = self.candidate(fp, h.point(i), i);
                    out.rays.sampling += 1;
                    c.hit = tracer.closest_hit(c.origin, c.dir, 0.0, f64::INFINITY);
                    out.invalid_points += u32::from(c.hit.is_some_and(|h| h.back_face));
                    c
                })
                .collect(),
            InvalidTexels::Fix => {
                let mut kept: Vec<Candidate> = Vec::new();
                let mut back_face_points: Vec<DVec3> = Vec::new();
                let query = |o: DVec3, target: DVec3, rays: &mut RayCounts| -> bool {
                    let q = target - o;
                    let len = q.length();
                    if !(len > 0.0) {
                        return false;
                    }
                    rays.query += 1;
                    tracer.closest_hit(o, q / len, 0.0, f64::INFINITY).is_some_and(|h| h.back_face)
                };
                for i in 0..u64::from(self.max_candidates) {
                    if kept.len() >= self.samples.get() as usize {
                        break;
                    }
                    let mut c = self.candidate(fp, h.point(i), i);
                    if back_face_points.iter().any(|&p| query(c.origin, p, &mut out.rays)) {
                        out.invalid_points += 1;
                        continue;
                    }
                    out.rays.sampling += 1;
                    c.hit = tracer.closest_hit(c.origin, c.dir, 0.0, f64::INFINITY);
                    match c.hit {
                        Some(hit) if hit.back_face => {
                            let p = c.origin + c.dir * hit.t;
                            back_face_points.push(p);
                            out.invalid_points += 1;
                            let before = kept.len();
                            kept.retain(|k| !query(k.origin, p, &mut out.rays));
                            out.invalid_points += (before - kept.len()) as u32;
                        }
                        _ => kept.push(c),
                    }
                }
                kept
            }
        };
        out.kept = kept.len() as u32;
        if kept.is_empty() {
            return out;
        }
        let n = self.bands * self.bands;
        let mut s = vec![[0.0f64; 3]; n];
        let mut y = vec![0.0; n];
        let mut add = |frame: &TangentFrame, dir: DVec3, value: [f64; 3]| {
            let local = frame.to_local(dir);
            eval_into(self.bands, local.to_array(), &mut y);
            for (sj, yj) in s.iter_mut().zip(&y) {
                for c in 0..3 {
                    sj[c] += value[c] * yj;
                }
            }
        };
        let dir_pdf = self.light_sampling.then_some(HEMISPHERE_PDF);
        for c in &kept {
            let mut rng = PathRng::new(self.seed, stream, c.index);
            let l = self.transport.radiance_from_hit(c.dir, c.hit, dir_pdf, &mut rng, &mut out.rays);
            add(&c.frame, c.dir, l.map(|v| v / HEMISPHERE_PDF));
            if self.light_sampling {
                let u = rng.next3();
                if let Some((ld, lr)) =
                    self.transport.light_sample(c.origin, HEMISPHERE_PDF, u, &mut out.rays)
                    && c.frame.n.dot(ld) > 0.0
                {
                    add(&c.frame, ld, lr);
                }
            }
        }
        let k = 1.0 / kept.len() as f64;
        let e: Vec<[f64; 3]> = s.iter().zip(&self.factors).map(|(sj, f)| sj.map(|v| v * k * f)).collect();
        out.coeffs = Some(self.matrix.mul_rgb(&e));
        out
    }
}

/// Barycentric weights `(u, v)` of corners 1 and 2 of the UV triangle `t` at `p`, clamped into
/// the triangle (footprint points lie in it up to rounding).
#[must_use]
pub fn barycentric(t: [DVec2; 3], p: DVec2) -> [f64; 2] {
    let (d1, d2, r) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let det = d1.perp_dot(d2);
    let mut u = (r.perp_dot(d2) / det).max(0.0);
    let mut v = (d1.perp_dot(r) / det).max(0.0);
    let s = u + v;
    if s > 1.0 {
        u /= s;
        v /= s;
    }
    if !(u.is_finite() && v.is_finite()) {
        return [1.0 / 3.0; 2];
    }
    [u, v]
}
