//! Light transport: `incidentRadiance` of Kontkanen & Laine 2006 Algorithm 2, by path
//! tracing with the diffuse BRDF, next-event estimation and multiple importance sampling.
//!
//! A path bounces `bounces` times (default 2) unconditionally, then either continues under
//! Russian roulette, so the estimate is unbiased for any albedo < 1 (the default), or stops
//! after the last surface's direct light ([`TransportSettings::truncated`]: at most N
//! bounces, 0 meaning direct light only). Back-face hits on
//! single-sided materials end a path with zero radiance (the inside of a solid is dark;
//! that is exactly what point sampling picks up inside buildings).
//!
//! Random numbers come from a per-path [`SplitMix64`] seeded from (stream, sample), never
//! from a shared generator, so results do not depend on thread scheduling.

use std::f64::consts::PI;

use glam::DVec3;
use lightvol_sh::lowdisc::{SplitMix64, hash2};
use lightvol_sh::sampling::{Frame, sample_cosine_hemisphere};

use crate::bvh::{Hit, Tracer};
use crate::light_groups::{LightGroups, LightKey};
use crate::light_sampler::{LightSampler, LightSource, power_heuristic};
use crate::scene::Scene;
use crate::stats::RayCounts;

/// Shadow rays towards a sampled point stop this fraction of the distance short of it:
/// far above f32 intersection error (~1e-7 relative), far below any real occluder gap.
pub const SHADOW_MARGIN: f64 = 1e-4;

/// Path-tracing settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransportSettings {
    /// Diffuse bounces traced unconditionally (0: the first surface's direct light only);
    /// then Russian roulette or the end of the path, per `russian_roulette`.
    pub bounces: u32,
    /// Continue with Russian roulette after `bounces` (unbiased); `false` truncates.
    pub russian_roulette: bool,
    /// Hard cap on path length (guards against albedo ≥ 1 scenes).
    pub max_depth: u32,
    /// Which light may reach the receiver directly ([`DirectLight`]).
    pub direct: DirectLight,
}

/// Which light counts when it reaches the receiver (a probe or texel) directly, without a
/// bounce. Light that bounced at least once always counts. Engines often bake sky and bounce
/// light into probes and add the sun from shadow maps at run time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DirectLight {
    /// Everything (`all`).
    #[default]
    All,
    /// The sky (environment) and emissive surfaces, not the sun nor punctual lights
    /// (`sky+indirect`).
    SkyAndIndirect,
    /// Nothing direct: only light that bounced (`indirect`).
    Indirect,
}

impl DirectLight {
    /// Whether light of `source` counts when it arrives directly.
    #[must_use]
    pub fn allows(self, source: LightSource) -> bool {
        match self {
            Self::All => true,
            Self::SkyAndIndirect => matches!(source, LightSource::Environment | LightSource::Emitter),
            Self::Indirect => false,
        }
    }

    /// The command-line name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::All => "all",
            Self::SkyAndIndirect => "sky+indirect",
            Self::Indirect => "indirect",
        }
    }

    /// Parses [`Self::name`].
    #[must_use]
    pub fn parse(s: &str) -> Option<Self> {
        [Self::All, Self::SkyAndIndirect, Self::Indirect].into_iter().find(|d| d.name() == s)
    }
}

impl Default for TransportSettings {
    fn default() -> Self {
        Self { bounces: 2, russian_roulette: true, max_depth: 64, direct: DirectLight::All }
    }
}

impl TransportSettings {
    /// At most `bounces` diffuse bounces (0: the first surface's direct light only), no
    /// roulette: what a user asking for `N` bounces means.
    #[must_use]
    pub fn truncated(bounces: u32) -> Self {
        Self { bounces, russian_roulette: false, ..Self::default() }
    }

    /// The path length in words for records: `N` (truncated after N bounces) or `N+roulette`
    /// (N bounces, then unbiased Russian roulette).
    #[must_use]
    pub fn label(&self) -> String {
        let mut s = if self.russian_roulette {
            format!("{}+roulette", self.bounces)
        } else {
            self.bounces.to_string()
        };
        if self.direct != DirectLight::All {
            s.push_str(" light=");
            s.push_str(self.direct.name());
        }
        s
    }

    /// Parses [`Self::label`] (`max_depth` is the default's).
    #[must_use]
    pub fn from_label(s: &str) -> Option<Self> {
        let (s, direct) = match s.split_once(" light=") {
            Some((a, d)) => (a, DirectLight::parse(d.trim())?),
            None => (s, DirectLight::All),
        };
        let (n, rr) = match s.strip_suffix("+roulette") {
            Some(n) => (n, true),
            None => (s, false),
        };
        Some(Self { bounces: n.trim().parse().ok()?, russian_roulette: rr, direct, ..Self::default() })
    }
}

/// The per-path random source.
#[derive(Clone, Debug)]
pub struct PathRng(SplitMix64);

impl PathRng {
    /// The generator for sample `sample` of stream `stream` (a cell, node or plate point)
    /// under bake seed `seed`.
    #[must_use]
    pub fn new(seed: u64, stream: u64, sample: u64) -> Self {
        Self(SplitMix64::new(hash2(hash2(seed, stream), sample)))
    }

    /// Uniform in [0, 1).
    #[inline]
    #[allow(clippy::should_implement_trait, reason = "an endless f64 stream, not an Iterator of Options")]
    pub fn next(&mut self) -> f64 {
        self.0.next_f64()
    }

    /// Two uniforms.
    #[inline]
    pub fn next2(&mut self) -> [f64; 2] {
        [self.next(), self.next()]
    }

    /// Three uniforms.
    #[inline]
    pub fn next3(&mut self) -> [f64; 3] {
        [self.next(), self.next(), self.next()]
    }
}

/// The light-transport engine for one scene.
#[derive(Debug)]
pub struct Transport<'a> {
    scene: &'a Scene,
    tracer: &'a Tracer,
    lights: LightSampler,
    settings: TransportSettings,
    eps: f64,
    groups: Option<LightGroups>,
}

/// Where a path's radiance terms go: one light's radiance times the path's throughput and
/// a weight, tagged with the light ([`crate::light_groups`]).
trait Terms {
    fn add(&mut self, key: LightKey, radiance: [f64; 3], s: f64);
    /// The sky's radiance `sky` seen along `dir` through `throughput`, weighted by `s`: the
    /// term `throughput ⊙ sky · s`.
    fn add_sky(&mut self, _dir: DVec3, throughput: [f64; 3], sky: [f64; 3], s: f64) {
        self.add(LightKey::Sky, mul(throughput, sky), s);
    }
}

/// The sum of every term: the path's radiance.
struct Total([f64; 3]);

impl Terms for Total {
    #[inline]
    fn add(&mut self, _: LightKey, radiance: [f64; 3], s: f64) {
        add_scaled(&mut self.0, radiance, s);
    }
}

/// The sum of every term, with the same arithmetic as [`Total`], and each term also added to
/// its light's group.
struct Grouped<'g> {
    total: [f64; 3],
    groups: &'g LightGroups,
    per_group: &'g mut [[f64; 3]],
}

impl Terms for Grouped<'_> {
    #[inline]
    fn add(&mut self, key: LightKey, radiance: [f64; 3], s: f64) {
        add_scaled(&mut self.total, radiance, s);
        add_scaled(&mut self.per_group[self.groups.group_of(key)], radiance, s);
    }

    /// With a sky transfer the sky's term goes to its SH groups instead: group `base + j`
    /// gets `throughput · Y_j(dir) · s`, the term a sky of radiance `Y_j` (white) would give,
    /// so that a sky `L = Σ_j l_j Y_j` gives `Σ_j l_j ⊙ group_j` (Sloan, Kautz & Snyder 2002).
    #[inline]
    fn add_sky(&mut self, dir: DVec3, throughput: [f64; 3], sky: [f64; 3], s: f64) {
        let Some((base, coeffs)) = self.groups.sky_transfer() else {
            return self.add(LightKey::Sky, mul(throughput, sky), s);
        };
        add_scaled(&mut self.total, mul(throughput, sky), s);
        let mut y = [0.0; 16];
        lightvol_sh::eval::eval_into(bands(coeffs), dir.to_array(), &mut y[..coeffs]);
        for (j, &yj) in y[..coeffs].iter().enumerate() {
            add_scaled(&mut self.per_group[base + j], throughput, yj * s);
        }
    }
}

/// SH bands of `coeffs` (4, 9 or 16) coefficients.
fn bands(coeffs: usize) -> usize {
    match coeffs {
        4 => 2,
        9 => 3,
        _ => 4,
    }
}

#[inline]
fn mul(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}

#[inline]
fn add_scaled(acc: &mut [f64; 3], a: [f64; 3], s: f64) {
    for c in 0..3 {
        acc[c] += a[c] * s;
    }
}

impl<'a> Transport<'a> {
    /// An engine over `scene` traced by `tracer` (built from the same scene).
    #[must_use]
    pub fn new(scene: &'a Scene, tracer: &'a Tracer, settings: TransportSettings) -> Self {
        Self { scene, tracer, lights: LightSampler::new(scene), settings, eps: scene.epsilon(), groups: None }
    }

    /// The same engine, also splitting each path's radiance by light group
    /// ([`Self::radiance_from_hit_grouped`]); the groups must be of this scene.
    #[must_use]
    pub fn with_groups(mut self, groups: LightGroups) -> Self {
        self.groups = Some(groups);
        self
    }

    /// The light groups, if the engine splits by them.
    #[must_use]
    pub fn groups(&self) -> Option<&LightGroups> {
        self.groups.as_ref()
    }

    /// The scene.
    #[must_use]
    pub fn scene(&self) -> &'a Scene {
        self.scene
    }

    /// The tracer.
    #[must_use]
    pub fn tracer(&self) -> &'a Tracer {
        self.tracer
    }

    /// The self-intersection offset used for secondary rays.
    #[must_use]
    pub fn epsilon(&self) -> f64 {
        self.eps
    }

    /// The settings.
    #[must_use]
    pub fn settings(&self) -> &TransportSettings {
        &self.settings
    }

    /// Radiance arriving at `origin` from direction `dir` (unit): Algorithm 2's
    /// `incidentRadiance`. Lights seen directly along `dir` count fully.
    pub fn incident_radiance(
        &self,
        origin: DVec3,
        dir: DVec3,
        rng: &mut PathRng,
        rays: &mut RayCounts,
    ) -> [f64; 3] {
        rays.sampling += 1;
        let hit = self.tracer.closest_hit(origin, dir, 0.0, f64::INFINITY);
        self.radiance_from_hit(dir, hit, None, rng, rays)
    }

    /// Radiance arriving at `origin` along `dir` given the already traced first hit (the
    /// classification rays of Algorithm 2 are reused this way). `dir_pdf` is the density
    /// (per steradian) of the technique that chose `dir` when the caller also samples lights
    /// at `origin` (see [`light_sample`](Self::light_sample)): lights seen directly along
    /// `dir` are then weighted by the power heuristic. `None` counts them fully.
    pub fn radiance_from_hit(
        &self,
        dir: DVec3,
        hit: Option<Hit>,
        dir_pdf: Option<f64>,
        rng: &mut PathRng,
        rays: &mut RayCounts,
    ) -> [f64; 3] {
        let mut l = Total([0.0; 3]);
        self.trace_path(dir, hit, dir_pdf, rng, rays, &mut l);
        l.0
    }

    /// [`Self::radiance_from_hit`], also split by light group: returns the same total (the
    /// same arithmetic, bit for bit) and writes each group's share to `per_group` (one entry
    /// per group of [`Self::groups`]; zeroed first). The shares sum to the total up to
    /// rounding, and come from the same random numbers and rays.
    ///
    /// # Panics
    /// If the engine has no groups or `per_group` has the wrong length.
    pub fn radiance_from_hit_grouped(
        &self,
        dir: DVec3,
        hit: Option<Hit>,
        dir_pdf: Option<f64>,
        rng: &mut PathRng,
        rays: &mut RayCounts,
        per_group: &mut [[f64; 3]],
    ) -> [f64; 3] {
        let groups = self.groups.as_ref().expect("a transport with light groups");
        assert_eq!(per_group.len(), groups.len(), "one entry per light group");
        per_group.fill([0.0; 3]);
        let mut l = Grouped { total: [0.0; 3], groups, per_group };
        self.trace_path(dir, hit, dir_pdf, rng, rays, &mut l);
        l.total
    }

    fn trace_path(
        &self,
        dir: DVec3,
        hit: Option<Hit>,
        dir_pdf: Option<f64>,
        rng: &mut PathRng,
        rays: &mut RayCounts,
        l: &mut impl Terms,
    ) {
        let scene = self.scene;
        let mut beta = [1.0; 3];
        let (mut d, mut hit, mut prev_pdf) = (dir, hit, dir_pdf);
        for depth in 0..=self.settings.max_depth {
            // The first segment arrives at the receiver directly.
            let direct = if depth == 0 { self.settings.direct } else { DirectLight::All };
            let Some(h) = hit else {
                self.add_escaped(l, beta, d, prev_pdf, direct);
                break;
            };
            if h.back_face {
                break;
            }
            let tri = h.triangle;
            let t = scene.triangle(tri);
            let m = &scene.materials[t.material as usize];
            // Shading normal: the geometric normal on the side the ray came from.
            let n = if h.from_behind { -h.normal } else { h.normal };
            let x = t.point(h.bary[0], h.bary[1]);
            if m.is_emissive() && direct.allows(LightSource::Emitter) {
                let w = match prev_pdf {
                    Some(p) => power_heuristic(p, self.lights.pdf_emitter(scene, tri, d, h.t)),
                    None => 1.0,
                };
                l.add(LightKey::Emitter(t.material), mul(beta, m.emission), w);
            }
            if depth == self.settings.max_depth {
                break;
            }
            if depth >= self.settings.bounces {
                if !self.settings.russian_roulette {
                    // Truncated: the last surface still gets its direct light below.
                    self.add_direct(l, beta, x, n, scene.albedo(tri, h.bary[0], h.bary[1]), false, rng, rays);
                    break;
                }
                let q = beta.iter().copied().fold(0.0, f64::max).clamp(0.05, 0.95);
                if rng.next() >= q {
                    break;
                }
                beta = beta.map(|b| b / q);
            }
            let albedo = scene.albedo(tri, h.bary[0], h.bary[1]);
            if albedo.iter().all(|&a| a <= 0.0) {
                break;
            }
            self.add_direct(l, beta, x, n, albedo, true, rng, rays);
            // Cosine-weighted bounce: f cos / pdf = albedo.
            let local = sample_cosine_hemisphere(rng.next2());
            let nd = DVec3::from_array(Frame::from_normal(n.to_array()).to_world(local));
            beta = mul(beta, albedo);
            prev_pdf = Some(local[2].max(0.0) / PI);
            d = nd;
            rays.bounce += 1;
            hit = self.tracer.closest_hit(x + n * self.eps, d, 0.0, f64::INFINITY);
        }
    }

    /// Environment and sun radiance for an escaped ray, MIS-weighted against light sampling.
    fn add_escaped(
        &self,
        l: &mut impl Terms,
        beta: [f64; 3],
        d: DVec3,
        prev_pdf: Option<f64>,
        direct: DirectLight,
    ) {
        let scene = self.scene;
        if direct.allows(LightSource::Environment) {
            let env = scene.environment.radiance(d);
            let w_env = prev_pdf.map_or(1.0, |p| power_heuristic(p, self.lights.pdf_env(scene, d)));
            l.add_sky(d, beta, env, w_env);
        }
        if let Some(sun) = scene.sun
            && direct.allows(LightSource::Sun)
        {
            let ls = sun.radiance_along(d);
            if ls.iter().any(|&v| v > 0.0) {
                let w = prev_pdf.map_or(1.0, |p| power_heuristic(p, self.lights.pdf_sun(scene, d)));
                l.add(LightKey::Sun, mul(beta, ls), w);
            }
        }
    }

    /// Next-event estimation at a diffuse surface point `x` with normal `n`. When no BSDF
    /// sample follows (`bsdf_follows = false`, a truncated path) the light sample takes
    /// full weight.
    #[allow(clippy::too_many_arguments)]
    fn add_direct(
        &self,
        l: &mut impl Terms,
        beta: [f64; 3],
        x: DVec3,
        n: DVec3,
        albedo: [f64; 3],
        bsdf_follows: bool,
        rng: &mut PathRng,
        rays: &mut RayCounts,
    ) {
        let u = rng.next3();
        // Sample from the offset origin the shadow ray starts at, so the ray ends exactly on
        // the sampled point: sampling from the surface and tracing from the offset point
        // lets grazing shadow rays hit the emitter's own plane early (a 0.2 % furnace bias).
        let x = x + n * self.eps;
        let Some(s) = self.lights.sample(self.scene, x, u) else { return };
        let cos = n.dot(s.dir);
        if cos <= 0.0 {
            return;
        }
        if !self.visible(x, &s, rays) {
            return;
        }
        let w = if s.delta || !bsdf_follows { 1.0 } else { power_heuristic(s.pdf, cos / PI) };
        // f = albedo / π.
        let k = cos * w / (PI * s.pdf);
        if s.key == LightKey::Sky {
            l.add_sky(s.dir, mul(beta, albedo), s.radiance, k);
        } else {
            l.add(s.key, mul(mul(beta, albedo), s.radiance), k);
        }
    }

    fn visible(&self, from: DVec3, s: &crate::light_sampler::LightSample, rays: &mut RayCounts) -> bool {
        rays.shadow += 1;
        // Stop short of the sampled point by a relative margin (f32 intersection error).
        let tmax = if s.dist.is_finite() { s.dist * (1.0 - SHADOW_MARGIN) } else { f64::INFINITY };
        tmax > 0.0 && !self.tracer.occluded(from, s.dir, 0.0, tmax)
    }

    /// One light-sampling term at a free-space point `x` for projecting incident radiance
    /// (no cosine): the direction and `radiance × weight / pdf`, MIS-weighted against a
    /// direction technique of density `dir_pdf` (e.g. `1/4π` for uniform sphere sampling).
    /// `None` when the sample carries nothing (no lights, occluded, facing away).
    pub fn light_sample(
        &self,
        x: DVec3,
        dir_pdf: f64,
        u: [f64; 3],
        rays: &mut RayCounts,
    ) -> Option<(DVec3, [f64; 3])> {
        self.light_sample_keyed(x, dir_pdf, u, rays).map(|(d, r, _, _)| (d, r))
    }

    /// Writes a light sample's term (from [`Self::light_sample_keyed`]: direction, term,
    /// light and factor) into `per_group` the way a path's terms are split: to its light's
    /// group, or with a sky transfer and a sky sample, `Y_j(dir) · factor` to each of the
    /// sky's SH groups.
    ///
    /// # Panics
    /// If the engine has no groups or `per_group` has the wrong length.
    pub fn split_light_sample(
        &self,
        dir: DVec3,
        term: [f64; 3],
        key: LightKey,
        factor: f64,
        per_group: &mut [[f64; 3]],
    ) {
        let groups = self.groups.as_ref().expect("a transport with light groups");
        assert_eq!(per_group.len(), groups.len(), "one entry per light group");
        match groups.sky_transfer() {
            Some((base, coeffs)) if key == LightKey::Sky => {
                let mut y = [0.0; 16];
                lightvol_sh::eval::eval_into(bands(coeffs), dir.to_array(), &mut y[..coeffs]);
                for (j, &yj) in y[..coeffs].iter().enumerate() {
                    per_group[base + j] = [yj * factor; 3];
                }
            }
            _ => per_group[groups.group_of(key)] = term,
        }
    }

    /// [`Self::light_sample`] with the light the sample came from and the factor `w / pdf`
    /// its radiance was scaled by (`radiance × factor` is the term returned).
    pub fn light_sample_keyed(
        &self,
        x: DVec3,
        dir_pdf: f64,
        u: [f64; 3],
        rays: &mut RayCounts,
    ) -> Option<(DVec3, [f64; 3], LightKey, f64)> {
        let s = self.lights.sample(self.scene, x, u)?;
        // The receiver's own light sample is direct light.
        if !self.settings.direct.allows(s.source) || !self.visible(x, &s, rays) {
            return None;
        }
        let w = if s.delta { 1.0 } else { power_heuristic(s.pdf, dir_pdf) };
        let k = w / s.pdf;
        Some((s.dir, s.radiance.map(|v| v * k), s.key, k))
    }

    /// One estimate of irradiance `E(x, n) = ∫ L cos θ dω` at a free-space point `x` for a
    /// receiver normal `n`: a cosine-sampled direction (from `u_dir`) MIS-combined with a
    /// light sample (from `u_light`).
    pub fn irradiance_sample(
        &self,
        x: DVec3,
        n: DVec3,
        u_dir: [f64; 2],
        u_light: [f64; 3],
        rng: &mut PathRng,
        rays: &mut RayCounts,
    ) -> [f64; 3] {
        let local = sample_cosine_hemisphere(u_dir);
        let d = DVec3::from_array(Frame::from_normal(n.to_array()).to_world(local));
        let pdf = local[2] / PI;
        let mut e = [0.0; 3];
        if pdf > 0.0 {
            rays.sampling += 1;
            let hit = self.tracer.closest_hit(x, d, 0.0, f64::INFINITY);
            let l = self.radiance_from_hit(d, hit, Some(pdf), rng, rays);
            // L cos / pdf = π L.
            add_scaled(&mut e, l, PI);
        }
        if let Some(s) = self.lights.sample(self.scene, x, u_light)
            && self.settings.direct.allows(s.source)
        {
            let cos = n.dot(s.dir);
            if cos > 0.0 && self.visible(x, &s, rays) {
                let w = if s.delta { 1.0 } else { power_heuristic(s.pdf, cos / PI) };
                add_scaled(&mut e, s.radiance, cos * w / s.pdf);
            }
        }
        e
    }
}
