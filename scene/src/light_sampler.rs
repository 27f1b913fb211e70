//! Next-event estimation: choosing a light and a direction towards it, and the matching
//! densities that multiple importance sampling needs (Veach 1997, ch. 9).
//!
//! Strategies, chosen uniformly: the sun (a cone, or a delta direction), the environment
//! map (∝ luminance · sin θ), the emissive triangles (one triangle ∝ emitted power, then a
//! uniform point on it), and each punctual light. A uniform sky is not a strategy: cosine
//! sampling already matches it, so escaped rays see it with full weight.

use glam::DVec3;
use lightvol_sh::sampling::{Frame, sample_uniform_cone};

use crate::envmap::luminance;
use crate::light_groups::LightKey;
use crate::lights::Environment;
use crate::scene::Scene;

/// One light sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the receiver towards the light.
    pub dir: DVec3,
    /// Distance to the sampled point (infinite for distant lights).
    pub dist: f64,
    /// Radiance arriving along `dir` (for delta lights: irradiance on a surface facing the
    /// light).
    pub radiance: [f64; 3],
    /// Density of this direction: selection probability × solid-angle density (for delta
    /// lights the selection probability alone).
    pub pdf: f64,
    /// Delta light (no other technique can find it: weight 1).
    pub delta: bool,
    /// The emissive triangle sampled, if any (shadow rays must stop short of it).
    pub emitter: Option<u32>,
    /// Which kind of light it is.
    pub source: LightSource,
    /// Which light it is ([`crate::light_groups`]).
    pub key: LightKey,
}

/// The kinds of light a sample can come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightSource {
    /// The sun.
    Sun,
    /// The environment (sky or map).
    Environment,
    /// An emissive surface.
    Emitter,
    /// A punctual light (point, spot, directional).
    Punctual,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Strategy {
    Sun,
    EnvMap,
    Emitters,
    Punctual(usize),
}

/// Light selection and sampling for one scene.
#[derive(Clone, Debug)]
pub struct LightSampler {
    strategies: Vec<Strategy>,
    /// Emissive triangles and their cumulative power.
    emitters: Vec<u32>,
    emitter_cdf: Vec<f64>,
    /// Per emitter (parallel to `emitters`, which is in increasing scene index order): the
    /// probability of choosing it / its area.
    emitter_pdf_area: Vec<f64>,
}

impl LightSampler {
    /// Collects the lights of `scene`.
    #[must_use]
    pub fn new(scene: &Scene) -> Self {
        let mut strategies = Vec::new();
        if let Some(sun) = scene.sun
            && sun.irradiance.iter().any(|&e| e > 0.0)
        {
            strategies.push(Strategy::Sun);
        }
        if let Environment::Map(m) = &scene.environment
            && !m.is_black()
        {
            strategies.push(Strategy::EnvMap);
        }
        let mut emitters = Vec::new();
        let mut emitter_cdf = vec![0.0];
        for (i, stored, inst) in scene.stored_triangles() {
            let m = &scene.materials[stored.material as usize];
            if m.is_emissive() {
                let t = inst.map_or(*stored, |x| x.place(stored));
                let sides = if m.double_sided { 2.0 } else { 1.0 };
                let power =
                    t.area() * luminance(m.emission).max(1e-12 * m.emission.iter().sum::<f64>()) * sides;
                if power > 0.0 {
                    emitters.push(i);
                    emitter_cdf.push(emitter_cdf.last().unwrap() + power);
                }
            }
        }
        let total = *emitter_cdf.last().unwrap();
        let emitter_pdf_area = emitters
            .iter()
            .enumerate()
            .map(|(k, &tri)| (emitter_cdf[k + 1] - emitter_cdf[k]) / total / scene.triangle(tri).area())
            .collect();
        if !emitters.is_empty() {
            strategies.push(Strategy::Emitters);
        }
        strategies.extend((0..scene.punctual.len()).map(Strategy::Punctual));
        Self { strategies, emitters, emitter_cdf, emitter_pdf_area }
    }

    /// True when there is nothing to sample.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.strategies.is_empty()
    }

    fn selection(&self) -> f64 {
        1.0 / self.strategies.len() as f64
    }

    /// Samples a light as seen from `x` with three uniform numbers.
    #[must_use]
    pub fn sample(&self, scene: &Scene, x: DVec3, u: [f64; 3]) -> Option<LightSample> {
        if self.strategies.is_empty() {
            return None;
        }
        let n = self.strategies.len();
        let k = ((u[0] * n as f64) as usize).min(n - 1);
        // Reuse the rest of u[0] for the emitter choice.
        let u0 = u[0] * n as f64 - k as f64;
        let sel = self.selection();
        match self.strategies[k] {
            Strategy::Sun => {
                let sun = scene.sun?;
                if sun.is_delta() {
                    return Some(LightSample {
                        dir: sun.direction,
                        dist: f64::INFINITY,
                        radiance: sun.irradiance,
                        pdf: sel,
                        delta: true,
                        emitter: None,
                        source: LightSource::Sun,
                        key: LightKey::Sun,
                    });
                }
                let local = sample_uniform_cone([u[1], u[2]], sun.cos_max());
                let dir = DVec3::from_array(Frame::from_normal(sun.direction.to_array()).to_world(local));
                Some(LightSample {
                    dir,
                    dist: f64::INFINITY,
                    radiance: sun.radiance(),
                    pdf: sel / sun.solid_angle(),
                    delta: false,
                    emitter: None,
                    source: LightSource::Sun,
                    key: LightKey::Sun,
                })
            }
            Strategy::EnvMap => {
                let Environment::Map(m) = &scene.environment else { return None };
                let (dir, pdf) = m.sample([u[1], u[2]])?;
                Some(LightSample {
                    dir,
                    dist: f64::INFINITY,
                    radiance: m.radiance(dir),
                    pdf: sel * pdf,
                    delta: false,
                    emitter: None,
                    source: LightSource::Environment,
                    key: LightKey::Sky,
                })
            }
            Strategy::Emitters => {
                let total = *self.emitter_cdf.last()?;
                let target = u0 * total;
                let i = self.emitter_cdf[1..].partition_point(|&c| c <= target).min(self.emitters.len() - 1);
                let tri = self.emitters[i];
                let t = scene.triangle(tri);
                let s = u[1].sqrt();
                let (b1, b2) = (u[2] * s, 1.0 - s);
                // Uniform on the triangle (Shirley's square-root warp): weights
                // (√u1 (1 - u2), u2 √u1, 1 - √u1).
                let p = t.point(b1, b2);
                let d = p - x;
                let dist2 = d.length_squared();
                if !(dist2 > 0.0) {
                    return None;
                }
                let dist = dist2.sqrt();
                let dir = d / dist;
                let m = scene.material_of(tri);
                let cos_l = -t.normal().dot(dir);
                if cos_l <= 0.0 && !m.double_sided || cos_l == 0.0 {
                    return None;
                }
                let pdf = sel * self.emitter_pdf_area[i] * dist2 / cos_l.abs();
                Some(LightSample {
                    dir,
                    dist,
                    radiance: m.emission,
                    pdf,
                    delta: false,
                    emitter: Some(tri),
                    source: LightSource::Emitter,
                    key: LightKey::Emitter(scene.stored_triangle(tri).material),
                })
            }
            Strategy::Punctual(i) => {
                let (dir, dist, e) = scene.punctual[i].incident(x)?;
                Some(LightSample {
                    dir,
                    dist,
                    radiance: e,
                    pdf: sel,
                    delta: true,
                    emitter: None,
                    source: LightSource::Punctual,
                    key: LightKey::Punctual(i as u32),
                })
            }
        }
    }

    /// Density with which [`sample`](Self::sample) produces escaped direction `dir` for the
    /// sun (if it contains `dir`).
    #[must_use]
    pub fn pdf_sun(&self, scene: &Scene, dir: DVec3) -> f64 {
        match scene.sun {
            Some(sun)
                if !sun.is_delta()
                    && self.strategies.contains(&Strategy::Sun)
                    && dir.dot(sun.direction) >= sun.cos_max() =>
            {
                self.selection() / sun.solid_angle()
            }
            _ => 0.0,
        }
    }

    /// Density with which [`sample`](Self::sample) produces escaped direction `dir` from the
    /// environment map.
    #[must_use]
    pub fn pdf_env(&self, scene: &Scene, dir: DVec3) -> f64 {
        match &scene.environment {
            Environment::Map(m) if self.strategies.contains(&Strategy::EnvMap) => {
                self.selection() * m.pdf(dir)
            }
            _ => 0.0,
        }
    }

    /// Density with which [`sample`](Self::sample) from `x` picks the point where the ray
    /// `x + t·dir` meets emissive triangle `tri` (per steradian).
    #[must_use]
    pub fn pdf_emitter(&self, scene: &Scene, tri: u32, dir: DVec3, t: f64) -> f64 {
        let Ok(k) = self.emitters.binary_search(&tri) else { return 0.0 };
        let pa = self.emitter_pdf_area[k];
        if pa == 0.0 {
            return 0.0;
        }
        let cos_l = scene.triangle(tri).normal().dot(dir).abs();
        if cos_l == 0.0 { 0.0 } else { self.selection() * pa * t * t / cos_l }
    }
}

/// Veach's power heuristic (β = 2) for a sample of technique `a` against technique `b`.
#[must_use]
#[inline]
pub fn power_heuristic(a: f64, b: f64) -> f64 {
    if a.is_infinite() {
        return 1.0;
    }
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 { a2 / (a2 + b2) } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builder::SceneBuilder;
    use crate::material::Material;
    use lightvol_sh::lowdisc::Halton;

    /// Light-sampled estimate of the solid angle subtended by an emitter quad equals the
    /// closed form for a square seen on axis (Σ 1/pdf over samples that hit it).
    #[test]
    fn emitter_pdf_matches_solid_angle() {
        let mut b = SceneBuilder::new("quad");
        let m = b.add_material(Material::emitter("e", [0.0; 3], [1.0; 3])).unwrap();
        // Unit square at z = 1 facing down, centred above the origin.
        let q = [
            DVec3::new(-0.5, -0.5, 1.0),
            DVec3::new(-0.5, 0.5, 1.0),
            DVec3::new(0.5, 0.5, 1.0),
            DVec3::new(0.5, -0.5, 1.0),
        ];
        b.add_quad(q, m).unwrap();
        let s = b.build().unwrap();
        let ls = LightSampler::new(&s);
        let h = Halton::new(9, 3);
        let n = 1 << 14;
        let est: f64 = (0..n)
            .map(|i| ls.sample(&s, DVec3::ZERO, h.point::<3>(i)).map_or(0.0, |l| 1.0 / l.pdf))
            .sum::<f64>()
            / n as f64;
        // Solid angle of an a×a square at distance d on axis: 4 asin(a² / (a² + 4d²)).
        let exact = 4.0 * (1.0f64 / (1.0 + 4.0)).asin();
        assert!((est - exact).abs() < 2e-3 * exact, "{est} {exact}");
        // The density matches pdf_emitter for the same direction.
        let l = ls.sample(&s, DVec3::ZERO, [0.3, 0.6, 0.2]).unwrap();
        let pe = ls.pdf_emitter(&s, l.emitter.unwrap(), l.dir, l.dist);
        assert!((pe - l.pdf).abs() < 1e-12 * l.pdf);
    }

    #[test]
    fn power_heuristic_sums_to_one() {
        for (a, b) in [(1.0, 2.0), (0.3, 0.0), (5.0, 5.0)] {
            assert!((power_heuristic(a, b) + power_heuristic(b, a) - 1.0).abs() < 1e-15);
        }
    }
}
