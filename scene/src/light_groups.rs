//! Light groups: which light each contribution of a path comes from, and how the lights of
//! a scene are gathered into named groups.
//!
//! Light transport is linear in the emitters: the radiance a path carries is a sum of terms,
//! each the product of the path's throughput and the radiance of one light (the sky, the
//! sun, an emissive material, a punctual light). Tagging each term with its light and adding
//! it to that light's group splits one path's estimate into per-group estimates that sum to
//! the whole, from the same rays ([`crate::transport::Transport::radiance_from_hit_grouped`]).
//! Scaling group `g` by `k` and summing then gives the estimate for a scene whose lights of
//! group `g` are `k` times brighter, without tracing again.
//!
//! A scene's lights ([`scene_lights`]) are named `sky` (the environment, sky and ground or
//! map, when it is not black), `sun`, each emissive material by its material name, and each
//! punctual light by its glTF name (`lightN` when it has none). A group specification
//! ([`LightGroups::parse`]) is `NAME=PATTERN,PATTERN;NAME=…`, where a pattern is a light's
//! name with `*` matching any run of characters; `each` puts every light in its own group.
//! Lights that no pattern names are gathered in a group called `other`, so the groups
//! always sum to the whole bake.

use crate::lights::Environment;
use crate::scene::Scene;

/// The light a term of a path's radiance comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LightKey {
    /// The environment: the uniform sky and ground, or the environment map.
    Sky,
    /// The sun.
    Sun,
    /// An emissive surface of this material (index into [`Scene::materials`]).
    Emitter(u32),
    /// The punctual light of this index (into [`Scene::punctual`]).
    Punctual(u32),
}

/// One light of a scene and its name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneLight {
    /// The name patterns match (module docs).
    pub name: String,
    /// Which light it is.
    pub key: LightKey,
}

/// The lights of `scene` that can carry light, in a fixed order: `sky`, `sun`, the emissive
/// materials in material order, the punctual lights in scene order (module docs).
#[must_use]
pub fn scene_lights(scene: &Scene) -> Vec<SceneLight> {
    let mut out = Vec::new();
    let sky = match &scene.environment {
        Environment::Black => false,
        Environment::UniformSky { sky, ground } => {
            sky.iter().chain(ground.iter().flatten()).any(|&v| v > 0.0)
        }
        Environment::Map(m) => !m.is_black(),
    };
    if sky {
        out.push(SceneLight { name: "sky".into(), key: LightKey::Sky });
    }
    if scene.sun.is_some_and(|s| s.irradiance.iter().any(|&e| e > 0.0)) {
        out.push(SceneLight { name: "sun".into(), key: LightKey::Sun });
    }
    for (i, m) in scene.materials.iter().enumerate() {
        if m.is_emissive() {
            out.push(SceneLight { name: m.name.clone(), key: LightKey::Emitter(i as u32) });
        }
    }
    for i in 0..scene.punctual.len() {
        out.push(SceneLight { name: scene.punctual_name(i), key: LightKey::Punctual(i as u32) });
    }
    out
}

/// The SH coefficients `l_j = ∫ L(ω) Y_j(ω) dω` of `env`'s radiance over the whole sphere,
/// per channel, for the first `coeffs` (4, 9 or 16) functions: the sky a sky transfer's
/// groups are scaled by to relight with `env` (Sloan, Kautz & Snyder 2002, Eq. 3's
/// projection). Integrated by a Gauss-Legendre product rule on each hemisphere, which is
/// exact up to rounding for the uniform sky and ground (constant on each, times polynomials
/// of degree ≤ 3); a map is integrated at 128 × 256 nodes per hemisphere, far finer than the
/// band limit it is projected to.
#[must_use]
pub fn sky_coefficients(env: &Environment, coeffs: usize) -> Vec<[f64; 3]> {
    use lightvol_sh::quadrature::SphereQuadrature;
    let bands = (coeffs as f64).sqrt().round() as usize;
    let (n_theta, n_phi) = match env {
        Environment::Map(_) => (128, 256),
        _ => (8, 16),
    };
    let upper = SphereQuadrature::hemisphere(n_theta, n_phi);
    let mut out = vec![[0.0; 3]; coeffs];
    let mut y = vec![0.0; coeffs];
    for node in upper.nodes() {
        for d in [node.dir, [node.dir[0], node.dir[1], -node.dir[2]]] {
            // The horizon (z = 0) is no Gauss-Legendre node, so each node lies strictly on
            // one side.
            let l = env.radiance(glam::DVec3::from_array(d));
            lightvol_sh::eval::eval_into(bands, d, &mut y);
            for (o, &yj) in out.iter_mut().zip(&y) {
                for c in 0..3 {
                    o[c] += node.weight * l[c] * yj;
                }
            }
        }
    }
    out
}

/// The name of the group that gathers the lights no pattern names.
pub const OTHER_GROUP: &str = "other";

/// The most groups a bake carries: each group stores a whole volume's coefficients.
pub const MAX_GROUPS: usize = 64;

/// A partition of a scene's lights into named groups (module docs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LightGroups {
    names: Vec<String>,
    /// Per light of [`scene_lights`]: its key and its group.
    members: Vec<(SceneLight, usize)>,
    sky: usize,
    sun: usize,
    /// Per material: its group (materials that emit nothing map to 0, never used).
    material: Vec<usize>,
    /// Per punctual light: its group.
    punctual: Vec<usize>,
    /// A sky transfer: its first group and its SH coefficient count.
    transfer: Option<(usize, usize)>,
}

/// The name prefix of a sky transfer's groups: `sky.sh00`, `sky.sh01`, ….
pub const SKY_TRANSFER_PREFIX: &str = "sky.sh";

/// Parses `NAME=PATTERN,PATTERN;NAME=…` (module docs).
fn parse_spec(spec: &str) -> Result<Vec<(String, Vec<String>)>, String> {
    let mut groups: Vec<(String, Vec<String>)> = Vec::new();
    for part in spec.split(';').map(str::trim).filter(|p| !p.is_empty()) {
        let Some((name, pats)) = part.split_once('=') else {
            return Err(format!("light group '{part}' is not NAME=PATTERN,…"));
        };
        let name = name.trim();
        if name.is_empty() || name == OTHER_GROUP || name.starts_with(SKY_TRANSFER_PREFIX) {
            return Err(format!("light group name '{name}' is empty or reserved"));
        }
        if groups.iter().any(|g| g.0 == name) {
            return Err(format!("light group '{name}' is named twice"));
        }
        let pats: Vec<String> =
            pats.split(',').map(str::trim).filter(|p| !p.is_empty()).map(str::to_owned).collect();
        if pats.is_empty() {
            return Err(format!("light group '{name}' has no patterns"));
        }
        groups.push((name.to_owned(), pats));
    }
    if groups.is_empty() {
        return Err("no light groups given (each, or NAME=PATTERN,…;NAME=…)".into());
    }
    Ok(groups)
}

/// Whether `name` matches `pattern`, where `*` matches any run of characters (also empty)
/// and every other character matches itself.
#[must_use]
pub fn matches(pattern: &str, name: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let s: Vec<char> = name.chars().collect();
    // Greedy matching with backtracking to the last star: linear in practice.
    let (mut i, mut j) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while j < s.len() {
        if i < p.len() && p[i] != '*' && p[i] == s[j] {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == '*' {
            star = Some((i, j));
            i += 1;
        } else if let Some((si, sj)) = star {
            i = si + 1;
            j = sj + 1;
            star = Some((si, sj + 1));
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == '*')
}

impl LightGroups {
    /// Every light of `scene` in a group of its own, named after it.
    ///
    /// # Errors
    /// When the scene has no lights, more than [`MAX_GROUPS`], or two lights share a name.
    pub fn each(scene: &Scene) -> Result<Self, String> {
        let lights = scene_lights(scene);
        let spec: Vec<(String, Vec<String>)> =
            lights.iter().map(|l| (l.name.clone(), vec![l.name.clone()])).collect();
        let mut seen = std::collections::HashSet::new();
        if let Some(l) = lights.iter().find(|l| !seen.insert(l.name.as_str())) {
            return Err(format!(
                "two lights are named '{}': name the groups with patterns (NAME=PATTERN,…)",
                l.name
            ));
        }
        Self::from_patterns(scene, &spec)
    }

    /// Groups from a specification (module docs): `each`, or `NAME=PATTERN,PATTERN;NAME=…`.
    ///
    /// # Errors
    /// A malformed specification, a group without patterns or named twice, a pattern that
    /// matches no light, a light that two groups claim, a scene without lights, or more
    /// than [`MAX_GROUPS`] groups, each in one line naming the culprit.
    pub fn parse(scene: &Scene, spec: &str) -> Result<Self, String> {
        if spec.trim() == "each" {
            return Self::each(scene);
        }
        Self::from_patterns(scene, &parse_spec(spec)?)
    }

    /// Groups for a bake with a sky transfer (module docs): the lights other than the sky
    /// grouped by `spec` (as [`Self::parse`]; `None`: all in `other`, if there are any),
    /// then one group per SH coefficient of the sky's radiance, `sky.sh00` … (`coeffs`:
    /// 4, 9 or 16), whose terms are the path's throughput times `Y_j` of the direction the
    /// sky is seen in.
    ///
    /// # Errors
    /// As [`Self::parse`], a pattern that names the sky, or an unsupported `coeffs`.
    pub fn with_sky_transfer(scene: &Scene, spec: Option<&str>, coeffs: usize) -> Result<Self, String> {
        if ![4, 9, 16].contains(&coeffs) {
            return Err(format!("a sky transfer has 4, 9 or 16 SH coefficients, not {coeffs}"));
        }
        let lights: Vec<SceneLight> =
            scene_lights(scene).into_iter().filter(|l| l.key != LightKey::Sky).collect();
        let groups = match spec.map(str::trim) {
            None => Vec::new(),
            Some("each") => lights.iter().map(|l| (l.name.clone(), vec![l.name.clone()])).collect(),
            Some(s) => parse_spec(s)?,
        };
        if let Some(p) = groups
            .iter()
            .flat_map(|g| &g.1)
            .find(|p| matches(p, "sky") && !lights.iter().any(|l| matches(p, &l.name)))
        {
            return Err(format!(
                "light pattern '{p}' names the sky, which a sky transfer relights by itself; leave it out of the groups"
            ));
        }
        let mut g = Self::partition(scene, lights, &groups)?;
        let base = g.names.len();
        g.names.extend((0..coeffs).map(|j| format!("{SKY_TRANSFER_PREFIX}{j:02}")));
        if g.names.len() > MAX_GROUPS {
            return Err(format!(
                "{} light groups with the sky transfer; at most {MAX_GROUPS}",
                g.names.len()
            ));
        }
        g.sky = base;
        g.transfer = Some((base, coeffs));
        Ok(g)
    }

    fn from_patterns(scene: &Scene, groups: &[(String, Vec<String>)]) -> Result<Self, String> {
        let lights = scene_lights(scene);
        if lights.is_empty() {
            return Err(format!("scene '{}' has no lights to group", scene.name));
        }
        Self::partition(scene, lights, groups)
    }

    fn partition(
        scene: &Scene,
        lights: Vec<SceneLight>,
        groups: &[(String, Vec<String>)],
    ) -> Result<Self, String> {
        let listing = || lights.iter().map(|l| l.name.as_str()).collect::<Vec<_>>().join(", ");
        let mut names: Vec<String> = groups.iter().map(|g| g.0.clone()).collect();
        let mut members = Vec::with_capacity(lights.len());
        for (_, pats) in groups {
            if let Some(p) = pats.iter().find(|p| !lights.iter().any(|l| matches(p, &l.name))) {
                return Err(format!(
                    "light pattern '{p}' matches none of the scene's lights ({})",
                    listing()
                ));
            }
        }
        let mut other = None;
        for l in lights {
            let claim: Vec<usize> =
                (0..groups.len()).filter(|&g| groups[g].1.iter().any(|p| matches(p, &l.name))).collect();
            let g = match claim[..] {
                [g] => g,
                [] => *other.get_or_insert_with(|| {
                    names.push(OTHER_GROUP.to_owned());
                    names.len() - 1
                }),
                _ => {
                    return Err(format!(
                        "light '{}' is in groups '{}' and '{}'",
                        l.name, groups[claim[0]].0, groups[claim[1]].0
                    ));
                }
            };
            members.push((l, g));
        }
        if names.len() > MAX_GROUPS {
            return Err(format!("{} light groups; at most {MAX_GROUPS}", names.len()));
        }
        let find = |key: LightKey| members.iter().find(|m| m.0.key == key).map_or(0, |m| m.1);
        let sky = find(LightKey::Sky);
        let sun = find(LightKey::Sun);
        let material = (0..scene.materials.len()).map(|i| find(LightKey::Emitter(i as u32))).collect();
        let punctual = (0..scene.punctual.len()).map(|i| find(LightKey::Punctual(i as u32))).collect();
        Ok(Self { names, members, sky, sun, material, punctual, transfer: None })
    }

    /// The group names, in group order.
    #[must_use]
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The number of groups.
    #[must_use]
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Never true: a partition of at least one light has a group.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Each light and the index of its group.
    #[must_use]
    pub fn members(&self) -> &[(SceneLight, usize)] {
        &self.members
    }

    /// The group of the light `key` (0 for a light the scene does not have, which carries
    /// no radiance).
    #[inline]
    #[must_use]
    pub fn group_of(&self, key: LightKey) -> usize {
        match key {
            LightKey::Sky => self.sky,
            LightKey::Sun => self.sun,
            LightKey::Emitter(m) => self.material.get(m as usize).copied().unwrap_or(0),
            LightKey::Punctual(i) => self.punctual.get(i as usize).copied().unwrap_or(0),
        }
    }

    /// The sky transfer, if any: its first group and its SH coefficient count.
    #[must_use]
    pub fn sky_transfer(&self) -> Option<(usize, usize)> {
        self.transfer
    }

    /// One line per group: its name and its lights.
    #[must_use]
    pub fn describe(&self) -> String {
        (0..self.len())
            .map(|g| {
                let lights: Vec<&str> =
                    self.members.iter().filter(|m| m.1 == g).map(|m| m.0.name.as_str()).collect();
                match self.transfer {
                    Some((base, _)) if g >= base => {
                        format!("{}: the sky's radiance along Y_{}", self.names[g], g - base)
                    }
                    _ => format!("{}: {}", self.names[g], lights.join(", ")),
                }
            })
            .collect::<Vec<_>>()
            .join("\n")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builder::SceneBuilder;
    use crate::lights::{PunctualLight, Sun};
    use crate::material::Material;
    use glam::DVec3;

    fn scene() -> Scene {
        let mut b = SceneBuilder::new("lit");
        let grey = b.add_material(Material::diffuse("grey", [0.5; 3])).unwrap();
        let two_sided = |m: Material| Material { double_sided: true, ..m };
        let lamp = b.add_material(two_sided(Material::emitter("LampShade", [0.3; 3], [2.0; 3]))).unwrap();
        let bulb = b.add_material(two_sided(Material::emitter("LampBulb", [0.0; 3], [9.0; 3]))).unwrap();
        let q = |z: f64| {
            [DVec3::new(0., 0., z), DVec3::new(1., 0., z), DVec3::new(1., 1., z), DVec3::new(0., 1., z)]
        };
        b.add_quad(q(0.0), grey).unwrap();
        b.add_quad(q(1.0), lamp).unwrap();
        b.add_quad(q(2.0), bulb).unwrap();
        b.environment = Environment::UniformSky { sky: [1.0; 3], ground: None };
        b.sun = Some(Sun { direction: DVec3::Z, irradiance: [3.0; 3], angular_radius: 0.0 });
        b.punctual.push(PunctualLight::Point { position: DVec3::ZERO, intensity: [1.0; 3] });
        b.punctual_names.push("desk".into());
        b.build().unwrap()
    }

    #[test]
    fn lights_are_named_and_ordered() {
        let names: Vec<String> = scene_lights(&scene()).into_iter().map(|l| l.name).collect();
        assert_eq!(names, ["sky", "sun", "LampShade", "LampBulb", "desk"]);
    }

    #[test]
    fn patterns_match_like_shell_stars() {
        for (p, s, m) in [
            ("Lamp*", "LampShade", true),
            ("*Bulb", "LampBulb", true),
            ("L*p*b", "LampBulb", true),
            ("*", "", true),
            ("sun", "sunset", false),
            ("a*a", "a", false),
            ("**x", "yx", true),
        ] {
            assert_eq!(matches(p, s), m, "{p} {s}");
        }
    }

    #[test]
    fn groups_partition_the_lights_with_the_rest_in_other() {
        let s = scene();
        let g = LightGroups::parse(&s, "day=sky,sun; lamps=Lamp*").unwrap();
        assert_eq!(g.names(), ["day", "lamps", "other"]);
        assert_eq!(g.group_of(LightKey::Sky), 0);
        assert_eq!(g.group_of(LightKey::Sun), 0);
        assert_eq!(g.group_of(LightKey::Emitter(1)), 1);
        assert_eq!(g.group_of(LightKey::Emitter(2)), 1);
        assert_eq!(g.group_of(LightKey::Punctual(0)), 2);
        assert_eq!(g.describe(), "day: sky, sun\nlamps: LampShade, LampBulb\nother: desk");
        let e = LightGroups::each(&s).unwrap();
        assert_eq!(e.names(), ["sky", "sun", "LampShade", "LampBulb", "desk"]);
        assert_eq!(e.group_of(LightKey::Punctual(0)), 4);
    }

    /// Every path split by group: the total is the ungrouped radiance bit for bit, the
    /// groups sum to it, and a scene whose lights of one group are twice as bright gives
    /// that group twice the radiance, path for path (the same random numbers).
    #[test]
    fn grouped_paths_sum_to_the_path_and_scale_with_their_lights() {
        use crate::transport::{PathRng, Transport, TransportSettings};
        use crate::{RayCounts, Tracer};
        // A floor and a ceiling lamp and a bulb, lit by everything: every kind of light reaches
        // the receiver through bounces and light samples.
        let s = scene();
        let groups = LightGroups::parse(&s, "day=sky,sun;lamps=Lamp*").unwrap();
        let tracer = Tracer::new(&s);
        let plain = Transport::new(&s, &tracer, TransportSettings::default());
        let grouped = Transport::new(&s, &tracer, TransportSettings::default()).with_groups(groups.clone());
        let mut brighter = s.clone();
        for m in &mut brighter.materials {
            m.emission = m.emission.map(|e| 2.0 * e);
        }
        let tracer2 = Tracer::new(&brighter);
        let bright = Transport::new(&brighter, &tracer2, TransportSettings::default());
        let mut rays = RayCounts::default();
        let mut per = vec![[0.0; 3]; 3];
        let mut bright_per = vec![[0.0; 3]; 3];
        let bright = bright.with_groups(groups);
        let mut lamp_paths = 0;
        for i in 0..2000u64 {
            let origin = DVec3::new(0.5, 0.5, 0.5);
            let dir = DVec3::from_array(lightvol_sh::sampling::sample_uniform_sphere([
                (i as f64 + 0.5) / 2000.0,
                (i as f64 * 0.618_034) % 1.0,
            ]));
            let hit = tracer.closest_hit(origin, dir, 0.0, f64::INFINITY);
            let a = plain.radiance_from_hit(dir, hit, Some(0.25), &mut PathRng::new(7, 1, i), &mut rays);
            let b = grouped.radiance_from_hit_grouped(
                dir,
                hit,
                Some(0.25),
                &mut PathRng::new(7, 1, i),
                &mut rays,
                &mut per,
            );
            assert_eq!(a, b, "path {i}: the total is the ungrouped radiance");
            for c in 0..3 {
                let sum: f64 = per.iter().map(|g| g[c]).sum();
                // Three partial sums of the same terms in another order: a few ulps of the
                // largest term, far below 1e-12 of the total.
                assert!((sum - a[c]).abs() <= 1e-12 * a[c].abs().max(1e-300), "path {i}: {sum} vs {}", a[c]);
            }
            bright.radiance_from_hit_grouped(
                dir,
                hit,
                Some(0.25),
                &mut PathRng::new(7, 1, i),
                &mut rays,
                &mut bright_per,
            );
            for c in 0..3 {
                // Doubling the emission doubles each term exactly (a power of two), and the
                // other groups' terms are untouched.
                assert_eq!(bright_per[1][c], 2.0 * per[1][c], "path {i}");
                assert_eq!(bright_per[0][c], per[0][c], "path {i}");
                assert_eq!(bright_per[2][c], per[2][c], "path {i}");
            }
            lamp_paths += usize::from(per[1][0] > 0.0);
        }
        // The test has teeth: the lamps light a good share of the paths.
        assert!(lamp_paths > 200, "{lamp_paths}");
    }

    /// The projection of a uniform sky and ground: `l_0 = √π (sky + ground)` (`Y_0 = 1/√(4π)`
    /// over two hemispheres of 2π), `l_2 = √(3π)/2 · (sky − ground)` (`∫_upper Y_{1,0} =
    /// √(3/4π) · π`), the other band-1 terms 0 by symmetry; and a sky equal to its ground is
    /// `Y_0` alone.
    #[test]
    fn sky_coefficients_of_a_uniform_sky_are_closed_forms() {
        let env = Environment::UniformSky { sky: [2.0, 1.0, 0.5], ground: Some([0.5, 0.25, 0.0]) };
        let l = sky_coefficients(&env, 9);
        let pi = std::f64::consts::PI;
        for c in 0..3 {
            let (s, g) = ([2.0, 1.0, 0.5][c], [0.5, 0.25, 0.0][c]);
            // Sums of 2·8·16 products of rounded values: 1e-12.
            assert!((l[0][c] - pi.sqrt() * (s + g)).abs() < 1e-12, "{:?}", l[0]);
            assert!((l[2][c] - (3.0 * pi).sqrt() / 2.0 * (s - g)).abs() < 1e-12, "{:?}", l[2]);
            for j in [1, 3, 4, 5, 7] {
                assert!(l[j][c].abs() < 1e-12, "{j}: {:?}", l[j]);
            }
        }
        let flat = sky_coefficients(&Environment::UniformSky { sky: [1.0; 3], ground: Some([1.0; 3]) }, 4);
        assert!(
            (flat[0][0] - (4.0 * pi).sqrt()).abs() < 1e-12 && flat[1..].iter().all(|v| v[0].abs() < 1e-12)
        );
    }

    /// A sky transfer, path by path: with a sky equal to its ground (radiance `L`, exactly
    /// `L √(4π) Y_0`), the sky groups scaled by the sky's coefficients plus the other group
    /// give the path's radiance; and relit with another uniform colour, what a transport
    /// of that sky gives on the same random numbers.
    #[test]
    fn sky_transfer_paths_relight_to_the_sky_they_are_given() {
        use crate::transport::{PathRng, Transport, TransportSettings};
        use crate::{RayCounts, Tracer};
        let mut s = scene();
        s.environment = Environment::UniformSky { sky: [1.0, 0.8, 0.6], ground: Some([1.0, 0.8, 0.6]) };
        let g = LightGroups::with_sky_transfer(&s, None, 9).unwrap();
        assert_eq!(g.names()[0], "other");
        assert_eq!(g.names()[1], "sky.sh00");
        assert_eq!(g.sky_transfer(), Some((1, 9)));
        let tracer = Tracer::new(&s);
        let t = Transport::new(&s, &tracer, TransportSettings::default()).with_groups(g);
        let mut other = s.clone();
        other.environment = Environment::UniformSky { sky: [0.2, 0.5, 3.0], ground: Some([0.2, 0.5, 3.0]) };
        let t2 = Transport::new(&other, &tracer, TransportSettings::default());
        let (baked, new) = (sky_coefficients(&s.environment, 9), sky_coefficients(&other.environment, 9));
        let mut per = vec![[0.0; 3]; 10];
        let mut rays = RayCounts::default();
        let mut sky_paths = 0;
        for i in 0..2000u64 {
            let origin = DVec3::new(0.5, 0.5, 0.5);
            let dir = DVec3::from_array(lightvol_sh::sampling::sample_uniform_sphere([
                (i as f64 + 0.5) / 2000.0,
                (i as f64 * 0.618_034) % 1.0,
            ]));
            let hit = tracer.closest_hit(origin, dir, 0.0, f64::INFINITY);
            let total = t.radiance_from_hit_grouped(
                dir,
                hit,
                Some(0.25),
                &mut PathRng::new(3, 1, i),
                &mut rays,
                &mut per,
            );
            let fresh = t2.radiance_from_hit(dir, hit, Some(0.25), &mut PathRng::new(3, 1, i), &mut rays);
            for c in 0..3 {
                let relit = |l: &[[f64; 3]]| per[0][c] + (0..9).map(|j| l[j][c] * per[1 + j][c]).sum::<f64>();
                // Sums of a few terms, each relit through nine products: 1e-12 relative.
                let tol = 1e-12 * total[c].abs().max(fresh[c].abs()).max(1e-9);
                assert!(
                    (relit(&baked) - total[c]).abs() <= tol,
                    "path {i}: {} vs {}",
                    relit(&baked),
                    total[c]
                );
                assert!((relit(&new) - fresh[c]).abs() <= tol, "path {i}: {} vs {}", relit(&new), fresh[c]);
            }
            sky_paths += usize::from(per[1][2] != 0.0);
        }
        assert!(sky_paths > 200, "{sky_paths}");
        assert!(LightGroups::with_sky_transfer(&s, Some("a=sky"), 9).unwrap_err().contains("names the sky"));
        assert!(LightGroups::with_sky_transfer(&s, None, 5).is_err());
    }

    #[test]
    fn bad_specifications_are_one_line_errors() {
        let s = scene();
        for (spec, says) in [
            ("day", "is not NAME=PATTERN"),
            ("a=sky;a=sun", "named twice"),
            ("a=", "has no patterns"),
            ("a=moon", "matches none"),
            ("a=sky;b=s*", "is in groups 'a' and 'b'"),
            ("other=sky", "reserved"),
            ("", "no light groups"),
        ] {
            let e = LightGroups::parse(&s, spec).unwrap_err();
            assert!(e.contains(says) && !e.contains('\n'), "{spec}: {e}");
        }
    }
}
