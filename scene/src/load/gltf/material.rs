//! glTF materials (glTF 2.0 §3.9) as lightvol's diffuse [`Material`]s: base colour factor ×
//! texture (with `KHR_texture_transform` and the sampler's wrap modes), emission with
//! `KHR_materials_emissive_strength`, `doubleSided`, and `alphaMode`/`alphaCutoff`.
//!
//! Images are never all-or-nothing: a texture without `source`, an image this build cannot
//! decode (DDS, KTX2, WebP) or a missing file leaves the material on its factor, with one
//! warning per material naming it and the reason.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec2;
use serde_json::Value;

use super::container::read_uri;
use crate::base_color::{Texture, Wrap};
use crate::builder::SceneBuilder;
use crate::load::image::decode_texture;
use crate::load::options::{DEFAULT_ALBEDO, LoadOptions};
use crate::material::{AlphaMode, Material};

/// A 2×3 affine map of texture coordinates, `uv' = [a b c; d e f] · (u, v, 1)`.
pub(crate) type UvTransform = [[f64; 3]; 2];

/// `KHR_texture_transform`'s matrix `T · R · S` (the extension's GLSL definition, with
/// `R = mat3(cos, sin, 0, -sin, cos, 0, 0, 0, 1)` in GLSL's column-major order).
pub(crate) fn texture_transform(offset: [f64; 2], rotation: f64, scale: [f64; 2]) -> UvTransform {
    let (s, c) = rotation.sin_cos();
    [[c * scale[0], -s * scale[1], offset[0]], [s * scale[0], c * scale[1], offset[1]]]
}

/// Applies a [`UvTransform`].
pub(crate) fn apply(m: &UvTransform, uv: DVec2) -> DVec2 {
    DVec2::new(m[0][0] * uv.x + m[0][1] * uv.y + m[0][2], m[1][0] * uv.x + m[1][1] * uv.y + m[1][2])
}

/// A converted material and how its base-colour texture reads texture coordinates.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MaterialUse {
    /// Index into the scene's materials.
    pub id: u32,
    /// The `TEXCOORD_n` set the base-colour texture reads.
    pub uv_set: u32,
    /// Its texture transform, if any.
    pub uv_transform: Option<UvTransform>,
}

fn num(v: Option<&Value>, default: f64) -> f64 {
    v.and_then(Value::as_f64).unwrap_or(default)
}

fn nums<const N: usize>(v: Option<&Value>, default: [f64; N]) -> [f64; N] {
    let mut out = default;
    if let Some(a) = v.and_then(Value::as_array) {
        for (o, x) in out.iter_mut().zip(a) {
            if let Some(x) = x.as_f64() {
                *o = x;
            }
        }
    }
    out
}

/// Converts and caches materials and their textures.
pub(crate) struct Materials<'a> {
    json: &'a Value,
    buffers: &'a [Vec<u8>],
    base: Option<&'a Path>,
    opts: LoadOptions,
    /// (image, wrap) → scene texture id, or why it could not be read.
    textures: HashMap<(u64, [Wrap; 2]), Result<u32, String>>,
    by_index: HashMap<Option<u64>, MaterialUse>,
    /// Base-colour images decoded ahead ([`Self::decode_all`]), taken on first use.
    decoded: HashMap<u64, Result<Texture, String>>,
}

impl<'a> Materials<'a> {
    pub(crate) fn new(
        json: &'a Value,
        buffers: &'a [Vec<u8>],
        base: Option<&'a Path>,
        opts: LoadOptions,
    ) -> Self {
        Self {
            json,
            buffers,
            base,
            opts,
            textures: HashMap::new(),
            by_index: HashMap::new(),
            decoded: HashMap::new(),
        }
    }

    /// Decodes every image that a material's base-colour texture names, in parallel:
    /// decoding is most of the time it takes to load a textured scene, and each image
    /// decodes on its own, so the textures are the same on any thread count. Materials
    /// then take their image from here; an image that fails keeps its reason for the
    /// warning of the material that uses it.
    pub(crate) fn decode_all(&mut self) {
        use rayon::prelude::*;
        let textures = self.json.get("textures");
        let mut sources: Vec<u64> = self
            .json
            .get("materials")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
            .filter_map(|m| m.pointer("/pbrMetallicRoughness/baseColorTexture/index")?.as_u64())
            .filter_map(|t| textures?.get(t as usize)?.get("source")?.as_u64())
            .collect();
        sources.sort_unstable();
        sources.dedup();
        let this = &*self;
        let decoded: Vec<(u64, Result<Texture, String>)> =
            sources.par_iter().map(|&source| (source, this.decode(source))).collect();
        self.decoded = decoded.into_iter().collect();
    }

    /// The material `index` (`None`: the primitive has none), converted on first use.
    pub(crate) fn get(&mut self, b: &mut SceneBuilder, index: Option<u64>) -> Result<MaterialUse, String> {
        if let Some(m) = self.by_index.get(&index) {
            return Ok(*m);
        }
        let m = match index {
            None => {
                let mut m = Material::diffuse("default", DEFAULT_ALBEDO);
                m.double_sided = self.opts.force_double_sided;
                b.warn(format!("a primitive has no material: default albedo {} used", DEFAULT_ALBEDO[0]));
                MaterialUse {
                    id: b.add_material(m).map_err(|e| e.to_string())?,
                    uv_set: 0,
                    uv_transform: None,
                }
            }
            Some(i) => {
                let gm = self
                    .json
                    .get("materials")
                    .and_then(|a| a.get(i as usize))
                    .ok_or_else(|| format!("material {i} does not exist"))?;
                self.convert(b, i, gm)?
            }
        };
        self.by_index.insert(index, m);
        Ok(m)
    }

    fn convert(&mut self, b: &mut SceneBuilder, index: u64, gm: &Value) -> Result<MaterialUse, String> {
        let name =
            gm.get("name").and_then(Value::as_str).map_or_else(|| format!("material{index}"), str::to_owned);
        let pbr = gm.get("pbrMetallicRoughness");
        let f = nums(pbr.and_then(|p| p.get("baseColorFactor")), [1.0; 4]);
        let mut m = Material::diffuse(&name, [f[0], f[1], f[2]]);
        m.alpha = f[3];
        let strength = num(gm.pointer("/extensions/KHR_materials_emissive_strength/emissiveStrength"), 1.0);
        m.emission = nums(gm.get("emissiveFactor"), [0.0; 3]).map(|e| e * strength);
        m.double_sided =
            gm.get("doubleSided").and_then(Value::as_bool).unwrap_or(false) || self.opts.force_double_sided;
        m.alpha_mode = match gm.get("alphaMode").and_then(Value::as_str).unwrap_or("OPAQUE") {
            "MASK" => AlphaMode::Mask { cutoff: num(gm.get("alphaCutoff"), 0.5) },
            "BLEND" => AlphaMode::Blend,
            "OPAQUE" => AlphaMode::Opaque,
            other => {
                b.warn(format!("material '{name}': unknown alphaMode {other:?}, OPAQUE used"));
                AlphaMode::Opaque
            }
        };
        if let AlphaMode::Mask { cutoff } = m.alpha_mode
            && !cutoff.is_finite()
        {
            return Err(format!("material '{name}': alphaCutoff is not finite"));
        }
        if !m.alpha.is_finite() {
            return Err(format!("material '{name}': baseColorFactor alpha is not finite"));
        }
        if gm.get("emissiveTexture").is_some() {
            b.warn(format!("material '{name}': emissive texture ignored, using emissiveFactor"));
        }
        let mut uv_set = 0;
        let mut uv_transform = None;
        if let Some(info) = pbr.and_then(|p| p.get("baseColorTexture")) {
            uv_set = info.get("texCoord").and_then(Value::as_u64).unwrap_or(0) as u32;
            if let Some(t) = info.pointer("/extensions/KHR_texture_transform") {
                let tr = texture_transform(
                    nums(t.get("offset"), [0.0; 2]),
                    num(t.get("rotation"), 0.0),
                    nums(t.get("scale"), [1.0; 2]),
                );
                if tr.iter().flatten().all(|x| x.is_finite()) {
                    uv_transform = Some(tr);
                } else {
                    b.warn(format!("material '{name}': non-finite KHR_texture_transform ignored"));
                }
                if let Some(s) = t.get("texCoord").and_then(Value::as_u64) {
                    uv_set = s as u32;
                }
            }
            let tex = info.get("index").and_then(Value::as_u64).unwrap_or(u64::MAX);
            match self.texture(b, tex) {
                Ok(id) => m.albedo_texture = Some(id),
                Err(why) => b.warn(format!(
                    "material '{name}': base colour texture {tex} not used ({why}); factor used"
                )),
            }
        }
        let id = b.add_material(m).map_err(|e| e.to_string())?;
        Ok(MaterialUse { id, uv_set, uv_transform })
    }

    /// The scene texture of glTF texture `index`, decoded once per (image, wrap modes).
    fn texture(&mut self, b: &mut SceneBuilder, index: u64) -> Result<u32, String> {
        let t = self
            .json
            .get("textures")
            .and_then(|a| a.get(index as usize))
            .ok_or_else(|| "the texture does not exist".to_owned())?;
        let Some(source) = t.get("source").and_then(Value::as_u64) else {
            let alt: Vec<&str> = t
                .get("extensions")
                .and_then(Value::as_object)
                .map(|o| o.keys().map(String::as_str).collect())
                .unwrap_or_default();
            return Err(if alt.is_empty() {
                "it has no source image".to_owned()
            } else {
                format!("it has no PNG/JPEG source, only {}", alt.join(", "))
            });
        };
        let sampler =
            t.get("sampler").and_then(Value::as_u64).and_then(|s| self.json.get("samplers")?.get(s as usize));
        let wrap =
            |k: &str| Wrap::from_gl(sampler.and_then(|s| s.get(k)).and_then(Value::as_u64).unwrap_or(10497));
        let wrap = [wrap("wrapS"), wrap("wrapT")];
        let key = (source, wrap);
        if let Some(r) = self.textures.get(&key) {
            return r.clone();
        }
        let decoded = self.decoded.remove(&source).unwrap_or_else(|| self.decode(source));
        let r = decoded.map(|t| b.add_texture(t.with_wrap(wrap)));
        self.textures.insert(key, r.clone());
        r
    }

    /// Decodes image `index` (PNG or JPEG, from a file, a data URI or a buffer view).
    fn decode(&self, index: u64) -> Result<Texture, String> {
        let img = self
            .json
            .get("images")
            .and_then(|a| a.get(index as usize))
            .ok_or_else(|| format!("image {index} does not exist"))?;
        let bytes = if let Some(uri) = img.get("uri").and_then(Value::as_str) {
            read_uri(uri, self.base).map_err(|e| format!("image {index}: {e}"))?
        } else if let Some(view) = img.get("bufferView").and_then(Value::as_u64) {
            let v = self
                .json
                .get("bufferViews")
                .and_then(|a| a.get(view as usize))
                .ok_or("its buffer view does not exist")?;
            let buf = v
                .get("buffer")
                .and_then(Value::as_u64)
                .and_then(|i| self.buffers.get(i as usize))
                .ok_or("its buffer does not exist")?;
            let off = v.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
            let len = v.get("byteLength").and_then(Value::as_u64).unwrap_or(0) as usize;
            buf.get(off..off.saturating_add(len)).ok_or("its buffer view runs past the buffer")?.to_vec()
        } else {
            return Err(format!("image {index} has neither uri nor bufferView"));
        };
        decode_texture(&bytes, &format!("image {index}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The transform against the extension's definition worked by hand: a quarter turn
    /// maps (1, 0) to (0, 1) and (0, 1) to (-1, 0); scale acts before the rotation and the
    /// offset last.
    #[test]
    fn texture_transform_matches_the_extension() {
        let q = texture_transform([0.0; 2], std::f64::consts::FRAC_PI_2, [1.0; 2]);
        let close = |a: DVec2, b: DVec2| (a - b).length() < 1e-15;
        assert!(close(apply(&q, DVec2::X), DVec2::Y));
        assert!(close(apply(&q, DVec2::Y), -DVec2::X));
        let m = texture_transform([0.5, 0.25], std::f64::consts::FRAC_PI_2, [2.0, 3.0]);
        // S(1, 1) = (2, 3); R → (-3, 2); T → (-2.5, 2.25).
        assert!(close(apply(&m, DVec2::ONE), DVec2::new(-2.5, 2.25)));
    }
}
