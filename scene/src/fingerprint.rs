//! The fingerprints of a scene: its geometry hash ([`scene_hash`]), which every baked file's
//! key is hashed with, and the lighting fingerprint, a canonical text of everything that
//! lights it, stored with every coefficient map so that a renderer can tell whether the maps
//! were baked under the scene's current lighting, and part of every bake's key.
//!
//! The geometry hash is FNV-1a ([`lightvol_core::hash`]) over the triangle vertices, the
//! instance placements and the caller's settings text. It identifies a bake; it is not a
//! checksum of the file.
//!
//! The text is deterministic (the same scene and bounce count give the same bytes on every
//! machine and thread count) and lists, separated by `"; "`:
//! - `lighting=1`: the format version of this text;
//! - `environment=black`, `environment=uniform_sky sky=[r, g, b] ground=none|[r, g, b]`, or
//!   `environment=map WxH fnv1a64=HEX` (FNV-1a of the map's texels, see [`env_map_hash`];
//!   the scene keeps no file path, so the pixels identify the map);
//! - `sun=none` or `sun direction=[x, y, z] irradiance=[r, g, b] angular_radius=a`;
//! - `punctual=N` followed by one entry per light (`point position=… intensity=…`,
//!   `spot position=… axis=… intensity=… inner=… outer=…`, `directional to_light=…
//!   irradiance=…`), in scene order; beyond [`MAX_LISTED_PUNCTUAL`] lights only the count and
//!   an FNV-1a hash of the full list;
//! - `emissive materials=M triangles=T emission_area=[r, g, b]`: the emissive materials used
//!   by some triangle, the emissive triangles, and `Σ area · emission · sides` over them
//!   (emitted flux / π, W/π in scene units; sides = 2 for double-sided materials);
//! - `bounces=B`: the path length, `TransportSettings::label` (`N`, truncated after N
//!   bounces, or `N+roulette`).
//!
//! Numbers are Rust's shortest round-trip `f64` text (`-0` written as `0`), so two scenes
//! share a fingerprint exactly when these values are bit-identical.

use std::fmt;
use std::str::FromStr;

use glam::DVec3;
use lightvol_core::hash::{FNV_OFFSET, Fnv1a, fnv1a, fnv1a_from};

use crate::lights::{Environment, PunctualLight};
use crate::scene::Scene;

/// The lightvol version written into every key: a file baked by another version is
/// another bake.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// FNV-1a over the geometry of `scene` (every stored triangle's vertices, every instance's
/// prototype and placement, as little-endian f64) followed by `extra`, as 16 hex digits.
#[must_use]
pub fn scene_hash(scene: &Scene, extra: &str) -> String {
    let mut h = Fnv1a::default();
    for t in scene.triangles.iter().chain(scene.prototypes.iter().flat_map(|p| &p.triangles)) {
        for v in t.v {
            for c in v.to_array() {
                h.write(&c.to_le_bytes());
            }
        }
    }
    for i in &scene.instances {
        h.write(&i.prototype.to_le_bytes());
        for c in i.to_world.to_cols_array() {
            h.write(&c.to_le_bytes());
        }
    }
    h.write(extra.as_bytes());
    format!("{:016x}", h.finish())
}

/// Punctual lights listed one by one in the fingerprint; more are summarised by count and
/// hash (keeps the EXR attribute small for scenes with thousands of lights).
pub const MAX_LISTED_PUNCTUAL: usize = 16;

/// `f64` as canonical text (shortest round trip, negative zero as zero).
fn num(x: f64) -> String {
    format!("{:?}", x + 0.0)
}

fn vec3(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", num(v[0]), num(v[1]), num(v[2]))
}

fn dvec(v: DVec3) -> String {
    vec3(v.to_array())
}

/// FNV-1a 64 of an environment map's texels: width and height (u64 little endian), then
/// every texel row by row (row 0 at the zenith), R, G, B as little-endian `f32` bits. The
/// texels are read through [`EnvMap::radiance`](crate::envmap::EnvMap::radiance) at texel
/// centres (the map is piecewise constant, nearest texel).
#[must_use]
pub fn env_map_hash(map: &crate::envmap::EnvMap) -> u64 {
    let (w, h) = (map.width(), map.height());
    let mut hash = fnv1a(&(w as u64).to_le_bytes());
    hash = fnv1a_from(hash, &(h as u64).to_le_bytes());
    for y in 0..h {
        let theta = std::f64::consts::PI * (y as f64 + 0.5) / h as f64;
        for x in 0..w {
            let phi = 2.0 * std::f64::consts::PI * (x as f64 + 0.5) / w as f64;
            let dir = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            for c in map.radiance(dir) {
                // Exact: the map stores f32.
                hash = fnv1a_from(hash, &(c as f32).to_bits().to_le_bytes());
            }
        }
    }
    hash
}

fn punctual(l: &PunctualLight) -> String {
    match *l {
        PunctualLight::Point { position, intensity } => {
            format!("point position={} intensity={}", dvec(position), vec3(intensity))
        }
        PunctualLight::Spot { position, axis, intensity, inner, outer } => format!(
            "spot position={} axis={} intensity={} inner={} outer={}",
            dvec(position),
            dvec(axis),
            vec3(intensity),
            num(inner),
            num(outer)
        ),
        PunctualLight::Directional { to_light, irradiance } => {
            format!("directional to_light={} irradiance={}", dvec(to_light), vec3(irradiance))
        }
    }
}

/// The lighting fingerprint of `scene` baked with the path settings `transport` (format in the
/// module docs). Stored in every coefficient map of lightvol-surface as `lighting` and
/// in the EXR part attribute `lightvol.lighting`.
#[must_use]
pub fn lighting_fingerprint(scene: &Scene, transport: &crate::transport::TransportSettings) -> String {
    LightingRecord::of(scene, transport).to_string()
}

/// The lighting fingerprint as a typed record: one field per part of the text (module docs),
/// each the part's canonical text. [`Display`](fmt::Display) writes the fingerprint,
/// [`FromStr`] reads it back, [`Self::diff`] names the first part in which two differ.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LightingRecord {
    /// `environment=…` (the sky, its ground colour, or the map's size and hash).
    pub environment: String,
    /// `sun=none` or `sun direction=… irradiance=… angular_radius=…`.
    pub sun: String,
    /// `punctual=N | …` (each light) or `punctual=N fnv1a64=HEX`.
    pub punctual: String,
    /// `emissive materials=M triangles=T emission_area=[…]`.
    pub emissive: String,
    /// The path length, `TransportSettings::label`.
    pub bounces: String,
}

/// The format version written as the fingerprint's first part, `lighting=1`.
pub const LIGHTING_RECORD_VERSION: u32 = 1;

impl LightingRecord {
    /// The record of `scene` baked with `transport` (module docs).
    #[must_use]
    pub fn of(scene: &Scene, transport: &crate::transport::TransportSettings) -> Self {
        let mut parts = Vec::new();
        parts.push(match &scene.environment {
            Environment::Black => "environment=black".to_owned(),
            Environment::UniformSky { sky, ground } => format!(
                "environment=uniform_sky sky={} ground={}",
                vec3(*sky),
                ground.map_or_else(|| "none".to_owned(), vec3)
            ),
            Environment::Map(m) => {
                format!("environment=map {}x{} fnv1a64={:016x}", m.width(), m.height(), env_map_hash(m))
            }
        });
        parts.push(match &scene.sun {
            None => "sun=none".to_owned(),
            Some(s) => format!(
                "sun direction={} irradiance={} angular_radius={}",
                dvec(s.direction),
                vec3(s.irradiance),
                num(s.angular_radius)
            ),
        });
        let lights: Vec<String> = scene.punctual.iter().map(punctual).collect();
        if lights.len() <= MAX_LISTED_PUNCTUAL {
            let mut p = format!("punctual={}", lights.len());
            for l in &lights {
                p.push_str(" | ");
                p.push_str(l);
            }
            parts.push(p);
        } else {
            let hash = lights.iter().fold(FNV_OFFSET, |h, l| fnv1a_from(fnv1a_from(h, l.as_bytes()), b"\n"));
            parts.push(format!("punctual={} fnv1a64={hash:016x}", lights.len()));
        }
        let mut used = vec![false; scene.materials.len()];
        let mut triangles = 0u64;
        let mut total = [0.0f64; 3];
        for (_, stored, inst) in scene.stored_triangles() {
            let Some(m) = scene.materials.get(stored.material as usize) else { continue };
            if !m.is_emissive() {
                continue;
            }
            let t = inst.map_or(*stored, |i| i.place(stored));
            used[t.material as usize] = true;
            triangles += 1;
            let sides = if m.double_sided { 2.0 } else { 1.0 };
            for (acc, e) in total.iter_mut().zip(m.emission) {
                *acc += t.area() * e * sides;
            }
        }
        let materials = used.iter().filter(|&&u| u).count();
        parts.push(format!(
            "emissive materials={materials} triangles={triangles} emission_area={}",
            vec3(total)
        ));
        let [environment, sun, punctual, emissive]: [String; 4] =
            parts.try_into().expect("four parts, pushed above");
        Self { environment, sun, punctual, emissive, bounces: transport.label() }
    }

    /// The path settings the record names (`None` for a label this version cannot read).
    #[must_use]
    pub fn transport(&self) -> Option<crate::transport::TransportSettings> {
        crate::transport::TransportSettings::from_label(&self.bounces)
    }

    /// The parts as `(name, text)`, in the fingerprint's order.
    fn parts(&self) -> [(&'static str, String); 5] {
        [
            ("environment", self.environment.clone()),
            ("sun", self.sun.clone()),
            ("punctual lights", self.punctual.clone()),
            ("emission", self.emissive.clone()),
            ("bounces", format!("bounces={}", self.bounces)),
        ]
    }

    /// The first part in which `self` and `other` differ, as `"NAME: A vs B"`, or `None`
    /// when they are equal.
    #[must_use]
    pub fn diff(&self, other: &Self) -> Option<String> {
        self.parts()
            .into_iter()
            .zip(other.parts())
            .find(|(a, b)| a.1 != b.1)
            .map(|((name, a), (_, b))| format!("{name}: {a} vs {b}"))
    }
}

/// The fingerprint text (module docs).
impl fmt::Display for LightingRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "lighting={LIGHTING_RECORD_VERSION}")?;
        for (_, p) in self.parts() {
            write!(f, "; {p}")?;
        }
        Ok(())
    }
}

/// Reads a fingerprint back: its version and five parts, each by its prefix.
impl FromStr for LightingRecord {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let parts: Vec<&str> = s.split("; ").collect();
        let [version, environment, sun, punctual, emissive, bounces] = parts[..] else {
            return Err(format!("{} parts, expected 6", parts.len()));
        };
        if version != format!("lighting={LIGHTING_RECORD_VERSION}") {
            return Err(format!("version {version:?}, expected lighting={LIGHTING_RECORD_VERSION}"));
        }
        for (p, prefix) in
            [(environment, "environment="), (sun, "sun"), (punctual, "punctual="), (emissive, "emissive ")]
        {
            if !p.starts_with(prefix) {
                return Err(format!("{p:?} where {prefix}… was expected"));
            }
        }
        let bounces = bounces
            .strip_prefix("bounces=")
            .ok_or_else(|| format!("{bounces:?} where bounces=… was expected"))?;
        Ok(Self {
            environment: environment.to_owned(),
            sun: sun.to_owned(),
            punctual: punctual.to_owned(),
            emissive: emissive.to_owned(),
            bounces: bounces.to_owned(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hash_is_fnv1a_of_the_vertices_then_the_text() {
        // The same bytes laid out in one buffer and hashed at once.
        let maze = crate::builtin("maze").unwrap().scene;
        assert!(maze.instances.is_empty() && maze.prototypes.is_empty());
        let mut bytes: Vec<u8> = maze
            .triangles
            .iter()
            .flat_map(|t| t.v)
            .flat_map(|v| v.to_array())
            .flat_map(f64::to_le_bytes)
            .collect();
        bytes.extend_from_slice(b"key");
        assert_eq!(scene_hash(&maze, "key"), format!("{:016x}", fnv1a(&bytes)));
        assert_ne!(scene_hash(&maze, "key"), scene_hash(&maze, "kez"));
    }
    use crate::builder::SceneBuilder;
    use crate::envmap::EnvMap;
    use crate::lights::Sun;
    use crate::material::Material;
    use glam::DVec2;

    /// The environment-map hash equals FNV-1a of the texels written out independently (so
    /// every texel is read once, at its own centre), and changes with one texel.
    #[test]
    fn env_map_hash_reads_every_texel() {
        let (w, h) = (7usize, 5usize);
        let texels: Vec<[f32; 3]> =
            (0..w * h).map(|i| [i as f32 * 0.5, 1.0 / (1.0 + i as f32), (i % 3) as f32]).collect();
        let mut bytes = Vec::new();
        bytes.extend_from_slice(&(w as u64).to_le_bytes());
        bytes.extend_from_slice(&(h as u64).to_le_bytes());
        for t in &texels {
            for c in t {
                bytes.extend_from_slice(&c.to_bits().to_le_bytes());
            }
        }
        let map = EnvMap::from_linear(w, h, texels.clone()).unwrap();
        assert_eq!(env_map_hash(&map), fnv1a(&bytes));
        let mut other = texels;
        other[w * h - 1][1] += 1e-3;
        assert_ne!(env_map_hash(&EnvMap::from_linear(w, h, other).unwrap()), env_map_hash(&map));
    }

    fn scene() -> SceneBuilder {
        let mut b = SceneBuilder::new("l");
        let m = b.add_material(Material::diffuse("d", [0.5; 3])).unwrap();
        let e = b.add_material(Material::emitter("e", [0.5; 3], [2.0, 1.0, 0.5]).two_sided()).unwrap();
        let _unused = b.add_material(Material::emitter("u", [0.5; 3], [9.0; 3])).unwrap();
        b.add_triangle([DVec3::ZERO, DVec3::X, DVec3::Y], [DVec2::ZERO; 3], m).unwrap();
        // Area 2 (legs 2): emission_area = 2 · (2, 1, 0.5) · 2 sides = (8, 4, 2).
        b.add_triangle([DVec3::Z, DVec3::Z + 2.0 * DVec3::X, DVec3::Z + 2.0 * DVec3::Y], [DVec2::ZERO; 3], e)
            .unwrap();
        b
    }

    fn rr(bounces: u32) -> crate::transport::TransportSettings {
        crate::transport::TransportSettings { bounces, ..crate::transport::TransportSettings::default() }
    }

    /// The text of a known scene, written out by hand; each lighting input changes it, the
    /// geometry's albedo alone does not.
    #[test]
    fn fingerprint_text_and_sensitivity() {
        let mut b = scene();
        b.environment = Environment::UniformSky { sky: [1.0, 0.5, 0.25], ground: None };
        b.sun = Some(Sun { direction: DVec3::Z, irradiance: [3.0; 3], angular_radius: 0.0 });
        let s = b.build().unwrap();
        let f = lighting_fingerprint(&s, &rr(2));
        assert_eq!(
            f,
            "lighting=1; environment=uniform_sky sky=[1.0, 0.5, 0.25] ground=none; \
             sun direction=[0.0, 0.0, 1.0] irradiance=[3.0, 3.0, 3.0] angular_radius=0.0; punctual=0; \
             emissive materials=1 triangles=1 emission_area=[8.0, 4.0, 2.0]; bounces=2+roulette"
        );
        assert_eq!(lighting_fingerprint(&s, &rr(2)), f, "deterministic");
        assert_ne!(lighting_fingerprint(&s, &rr(3)), f);
        // Truncated paths are another lighting; the label reads back.
        let cut = crate::transport::TransportSettings::truncated(2);
        assert!(lighting_fingerprint(&s, &cut).ends_with("bounces=2"));
        for t in [cut, rr(2), crate::transport::TransportSettings::truncated(0)] {
            assert_eq!(crate::transport::TransportSettings::from_label(&t.label()), Some(t));
        }
        let mut s2 = s.clone();
        s2.sun.as_mut().unwrap().angular_radius = 0.01;
        assert_ne!(lighting_fingerprint(&s2, &rr(2)), f);
        let mut s3 = s.clone();
        s3.punctual.push(PunctualLight::Point { position: DVec3::new(1.0, -0.0, 2.0), intensity: [1.0; 3] });
        let f3 = lighting_fingerprint(&s3, &rr(2));
        assert!(f3.contains("punctual=1 | point position=[1.0, 0.0, 2.0] intensity=[1.0, 1.0, 1.0]"), "{f3}");
        let mut s4 = s.clone();
        s4.materials[1].emission[0] = 2.5;
        assert_ne!(lighting_fingerprint(&s4, &rr(2)), f);
        let mut s5 = s.clone();
        s5.materials[0].albedo = [0.9; 3];
        assert_eq!(lighting_fingerprint(&s5, &rr(2)), f);
        // Many punctual lights: count and hash, and the hash sees each one.
        let mut s6 = s.clone();
        for i in 0..=MAX_LISTED_PUNCTUAL {
            s6.punctual.push(PunctualLight::Directional { to_light: DVec3::Z, irradiance: [i as f64; 3] });
        }
        let f6 = lighting_fingerprint(&s6, &rr(2));
        assert!(f6.contains(&format!("punctual={} fnv1a64=", MAX_LISTED_PUNCTUAL + 1)), "{f6}");
        s6.punctual[3] = PunctualLight::Directional { to_light: DVec3::Z, irradiance: [0.5; 3] };
        assert_ne!(lighting_fingerprint(&s6, &rr(2)), f6);
    }

    /// The record reads its own text back, names the part that differs (by hand: the sun's),
    /// and refuses texts that are not fingerprints.
    #[test]
    fn record_round_trips_and_names_differences() {
        let mut b = scene();
        b.sun = Some(Sun { direction: DVec3::Z, irradiance: [3.0; 3], angular_radius: 0.0 });
        let s = b.build().unwrap();
        let r = LightingRecord::of(&s, &rr(2));
        let text = r.to_string();
        assert_eq!(text, lighting_fingerprint(&s, &rr(2)));
        assert_eq!(text.parse::<LightingRecord>().unwrap(), r);
        assert_eq!(r.transport(), Some(rr(2)));
        assert_eq!(r.diff(&r), None);
        let mut s2 = s.clone();
        s2.sun.as_mut().unwrap().irradiance = [4.0; 3];
        let d = r.diff(&LightingRecord::of(&s2, &rr(2))).unwrap();
        assert_eq!(
            d,
            "sun: sun direction=[0.0, 0.0, 1.0] irradiance=[3.0, 3.0, 3.0] angular_radius=0.0 vs \
             sun direction=[0.0, 0.0, 1.0] irradiance=[4.0, 4.0, 4.0] angular_radius=0.0"
        );
        assert!(
            r.diff(&LightingRecord::of(&s, &rr(3))).unwrap().starts_with("bounces: bounces=2+roulette vs")
        );
        for bad in ["", "lighting=2; a; b; c; d; bounces=1", "lighting=1; environment=black; sun=none"] {
            assert!(bad.parse::<LightingRecord>().is_err(), "{bad:?}");
        }
        let swapped = text.replace("; sun", "; moon");
        assert!(swapped.parse::<LightingRecord>().is_err());
    }
}
