//! Alpha in ray queries: alpha-tested (`MASK`) and stochastically transparent (`BLEND`)
//! materials (glTF 2.0 §3.9.4).
//!
//! The [`Tracer`](crate::Tracer) asks [`AlphaTable::is_surface`] about every candidate hit
//! on such a triangle, inside its traversal, so a masked-out texel is no surface for closest
//! hits, for occlusion, and therefore for the domain-of-interest back-face test
//! (Kontkanen & Laine 2006 §5): a leaf's transparent texels neither shade, nor shadow, nor
//! mark a point as inside geometry.
//!
//! - `MASK`: the hit is a surface when the base-colour alpha (factor × bilinear texture
//!   alpha at the hit's UV) is at least `alphaCutoff`.
//! - `BLEND`: the hit is a surface with probability alpha. The decision is a hash of the
//!   triangle and the ray's bits ([`ray_key`]), not a random stream, so a query gives the
//!   same answer on every run and thread count, and the closest-hit and occlusion queries of
//!   one ray agree. Averaged over many rays, a pane of alpha `a` passes `1 - a` of the light
//!   (tested in `blend_passes_one_minus_alpha`).
//!
//! Cost: opaque triangles pay one table read per candidate hit; alpha triangles add a
//! barycentric computation and a bilinear texture lookup per candidate (measured by the
//! `alpha` case of `cargo bench -p lightvol-scene --bench trace`).

use glam::{DVec2, DVec3};

use crate::base_color::Texture;
use crate::material::AlphaMode;
use crate::scene::Scene;
use crate::triangle::Triangle;

/// `slot` value of an opaque triangle.
const OPAQUE: u32 = u32::MAX;

#[derive(Clone, Debug)]
struct AlphaMaterial {
    mode: AlphaMode,
    factor: f64,
    /// Index into [`AlphaTable::textures`].
    texture: Option<u32>,
}

/// Per-triangle alpha data of a scene, detached from it so the tracer owns what it reads.
///
/// Triangles are numbered as *stored* ([`AlphaTable::new`]): the scene's directly placed
/// triangles, then each prototype's once, so instancing costs the table nothing per
/// instance. For a scene without instances that is the scene index.
#[derive(Clone, Debug, Default)]
pub struct AlphaTable {
    /// Per stored triangle: [`OPAQUE`] or an index into `uvs` / `material`.
    slot: Vec<u32>,
    uvs: Vec<[DVec2; 3]>,
    material: Vec<u32>,
    materials: Vec<AlphaMaterial>,
    textures: Vec<Texture>,
}

impl AlphaTable {
    /// Collects the `MASK` and `BLEND` triangles of `scene`, numbered as stored:
    /// [`Scene::triangles`](crate::Scene::triangles), then every prototype's triangles in
    /// prototype order. Materials whose alpha can
    /// never fail (`MASK` with factor ≥ cutoff and no alpha texture, `BLEND` with alpha 1
    /// and no alpha texture) are treated as opaque.
    #[must_use]
    pub fn new(scene: &Scene) -> Self {
        Self::from_triangles(
            scene,
            scene.triangles.iter().chain(scene.prototypes.iter().flat_map(|p| &p.triangles)),
        )
    }

    /// The table of `triangles` (their materials and UVs), numbered in the iterator's order,
    /// with `scene`'s materials and textures: e.g. a scene's placed triangles, for a tracer
    /// that flattens its instances.
    #[must_use]
    pub fn from_triangles<'a>(scene: &Scene, triangles: impl Iterator<Item = &'a Triangle>) -> Self {
        let mut t = Self::default();
        let mut mat_map: Vec<Option<u32>> = vec![None; scene.materials.len()];
        let mut tex_map: Vec<Option<u32>> = vec![None; scene.textures.len()];
        for (mi, m) in scene.materials.iter().enumerate() {
            let tex =
                m.albedo_texture.filter(|&i| scene.textures.get(i as usize).is_some_and(Texture::has_alpha));
            let trivially_opaque = match m.alpha_mode {
                AlphaMode::Opaque => true,
                AlphaMode::Mask { cutoff } => tex.is_none() && m.alpha >= cutoff,
                AlphaMode::Blend => tex.is_none() && m.alpha >= 1.0,
            };
            if trivially_opaque {
                continue;
            }
            let texture = tex.map(|i| {
                *tex_map[i as usize].get_or_insert_with(|| {
                    t.textures.push(scene.textures[i as usize].clone());
                    t.textures.len() as u32 - 1
                })
            });
            t.materials.push(AlphaMaterial { mode: m.alpha_mode, factor: m.alpha, texture });
            mat_map[mi] = Some(t.materials.len() as u32 - 1);
        }
        if t.materials.is_empty() {
            return t;
        }
        t.slot = triangles
            .map(|tri| match mat_map[tri.material as usize] {
                Some(am) => {
                    t.uvs.push(tri.uv);
                    t.material.push(am);
                    t.uvs.len() as u32 - 1
                }
                None => OPAQUE,
            })
            .collect();
        t
    }

    /// True when no triangle needs an alpha decision.
    #[must_use]
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.materials.is_empty()
    }

    /// Number of triangles with `MASK` or `BLEND` alpha.
    #[must_use]
    pub fn len(&self) -> usize {
        self.uvs.len()
    }

    /// True when stored triangle `tri` needs an alpha decision.
    #[must_use]
    #[inline]
    pub fn needs_test(&self, tri: u32) -> bool {
        self.slot.get(tri as usize).is_some_and(|&s| s != OPAQUE)
    }

    /// Base-colour alpha of stored triangle `tri` at barycentrics `(u, v)` of its stored
    /// vertex order (1 for opaque ones).
    #[must_use]
    pub fn alpha(&self, tri: u32, u: f64, v: f64) -> f64 {
        let Some(&s) = self.slot.get(tri as usize).filter(|&&s| s != OPAQUE) else { return 1.0 };
        let m = &self.materials[self.material[s as usize] as usize];
        match m.texture {
            Some(ti) => {
                let uv = self.uvs[s as usize];
                let p = uv[0] * (1.0 - u - v) + uv[1] * u + uv[2] * v;
                m.factor * self.textures[ti as usize].sample_alpha([p.x, p.y])
            }
            None => m.factor,
        }
    }

    /// Whether a hit on stored triangle `stored` at barycentrics `(u, v)` (of its stored
    /// vertex order) is a surface for the ray whose [`ray_key`] is `key`. The `BLEND`
    /// decision hashes the scene index `tri`, so instances of one pane decide apart, and an
    /// instanced scene decides as its flattened copy does.
    #[must_use]
    #[inline]
    pub fn is_surface(&self, stored: u32, tri: u32, u: f64, v: f64, key: u64) -> bool {
        let Some(&s) = self.slot.get(stored as usize).filter(|&&s| s != OPAQUE) else { return true };
        let a = self.alpha(stored, u, v);
        match self.materials[self.material[s as usize] as usize].mode {
            AlphaMode::Opaque => true,
            AlphaMode::Mask { cutoff } => a >= cutoff,
            AlphaMode::Blend => unit_hash(key ^ u64::from(tri).wrapping_mul(0x9e37_79b9_7f4a_7c15)) < a,
        }
    }
}

/// The SplitMix64 finaliser (Steele, Lea & Flood 2014): a bijective 64-bit mix.
#[must_use]
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A uniform number in [0, 1) from a hash (its top 53 bits).
#[inline]
fn unit_hash(key: u64) -> f64 {
    (mix64(key) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A key identifying a ray by the f32 bits the tracer intersects with: equal rays get equal
/// keys, and so equal `BLEND` decisions, whichever query or thread traces them.
#[must_use]
#[inline]
pub fn ray_key(origin: DVec3, dir: DVec3) -> u64 {
    let bits = |x: f64| u64::from((x as f32).to_bits());
    let mut h = 0x243f_6a88_85a3_08d3_u64;
    for c in [origin.x, origin.y, origin.z, dir.x, dir.y, dir.z] {
        h = mix64(h ^ bits(c));
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hash's uniform numbers have the mean and spread of U[0, 1): over 2^16 keys the
    /// mean is within 4σ = 4/√(12·65536) ≈ 0.0045 of 1/2, and every tenth of [0, 1) holds
    /// within 4σ of its expected count.
    #[test]
    fn unit_hash_is_uniform() {
        let n: u32 = 1 << 16;
        let mut bins = [0u32; 10];
        let mut mean = 0.0;
        for k in 0..n {
            let x = unit_hash(u64::from(k));
            assert!((0.0..1.0).contains(&x));
            mean += x / f64::from(n);
            bins[(x * 10.0) as usize] += 1;
        }
        assert!((mean - 0.5).abs() < 4.0 / (12.0 * f64::from(n)).sqrt(), "{mean}");
        let expect = f64::from(n) / 10.0;
        let sigma = (expect * 0.9).sqrt();
        for b in bins {
            assert!((f64::from(b) - expect).abs() < 4.0 * sigma, "{bins:?}");
        }
    }

    /// The tracer's detached table gives the alpha that [`Scene::alpha`] (the reference,
    /// read straight from the scene's materials and textures) gives, at every barycentric
    /// of a grid, for a textured MASK material, an untextured BLEND one and an opaque one.
    #[test]
    fn table_alpha_equals_the_scene_reference() {
        use crate::builder::SceneBuilder;
        use crate::material::Material;
        use glam::DVec2;
        let mut b = SceneBuilder::new("alpha");
        let tex = Texture::from_linear(2, 2, vec![[1.0; 3]; 4])
            .unwrap()
            .with_alpha(vec![0.0, 0.25, 0.75, 1.0])
            .unwrap();
        let t = b.add_texture(tex);
        let mut leaf = Material::diffuse("leaf", [0.5; 3]);
        leaf.albedo_texture = Some(t);
        leaf.alpha_mode = AlphaMode::Mask { cutoff: 0.5 };
        leaf.alpha = 0.8;
        let mut pane = Material::diffuse("pane", [0.5; 3]);
        pane.alpha_mode = AlphaMode::Blend;
        pane.alpha = 0.3;
        let ms = [
            b.add_material(leaf).unwrap(),
            b.add_material(pane).unwrap(),
            b.add_material(Material::diffuse("wall", [0.5; 3])).unwrap(),
        ];
        let uv = [DVec2::new(0.1, 0.2), DVec2::new(0.9, 0.3), DVec2::new(0.4, 0.95)];
        for (i, &m) in ms.iter().enumerate() {
            let z = i as f64;
            b.add_triangle(
                [DVec3::new(0.0, 0.0, z), DVec3::new(1.0, 0.0, z), DVec3::new(0.0, 1.0, z)],
                uv,
                m,
            )
            .unwrap();
        }
        let scene = b.build().unwrap();
        let table = AlphaTable::new(&scene);
        assert_eq!(table.len(), 2);
        for tri in 0..3u32 {
            for (u, v) in
                (0..=10).flat_map(|i| (0..=10 - i).map(move |j| (f64::from(i) / 10.0, f64::from(j) / 10.0)))
            {
                assert_eq!(table.alpha(tri, u, v), scene.alpha(tri, u, v), "triangle {tri} at ({u}, {v})");
            }
        }
    }

    /// Ray keys depend on every component and nothing else.
    #[test]
    fn ray_keys_are_stable_and_distinct() {
        let o = DVec3::new(1.0, 2.0, 3.0);
        let d = DVec3::new(0.0, 0.6, 0.8);
        assert_eq!(ray_key(o, d), ray_key(o, d));
        let mut keys = vec![ray_key(o, d)];
        for i in 0..6 {
            let mut c = [o.x, o.y, o.z, d.x, d.y, d.z];
            c[i] += 0.125;
            keys.push(ray_key(DVec3::new(c[0], c[1], c[2]), DVec3::new(c[3], c[4], c[5])));
        }
        keys.sort_unstable();
        keys.dedup();
        assert_eq!(keys.len(), 7);
    }
}
