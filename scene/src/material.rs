//! Materials: Lambertian albedo (a factor times an optional base-colour texture), emission,
//! sidedness and alpha (glTF 2.0 §3.9).

/// How a material's base-colour alpha affects rays (glTF 2.0 §3.9.4 `alphaMode`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored: every hit is a surface.
    #[default]
    Opaque,
    /// Alpha-tested: a hit whose base-colour alpha (factor × texture at the hit's UV) is
    /// below `cutoff` is no surface, for every ray query (closest hit, occlusion, and so the
    /// domain-of-interest back-face test).
    Mask {
        /// `alphaCutoff` (glTF default 0.5).
        cutoff: f64,
    },
    /// Stochastic transparency: a hit is a surface with probability alpha, decided by a
    /// hash of the triangle and the ray, so results stay bit-identical across runs and
    /// thread counts (see [`crate::alpha`]).
    Blend,
}

impl AlphaMode {
    /// The glTF name (`OPAQUE`, `MASK`, `BLEND`).
    #[must_use]
    pub fn gltf_name(self) -> &'static str {
        match self {
            Self::Opaque => "OPAQUE",
            Self::Mask { .. } => "MASK",
            Self::Blend => "BLEND",
        }
    }
}

/// A diffuse material (Kontkanen & Laine 2006 Algorithm 2's `brdf`, Lambertian only).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name from the file (for reports).
    pub name: String,
    /// Diffuse albedo factor, linear RGB in [0, 1].
    pub albedo: [f64; 3],
    /// Optional base-colour texture (index into [`Scene::textures`](crate::Scene::textures)), multiplied by
    /// `albedo` at the hit's texture coordinates.
    pub albedo_texture: Option<u32>,
    /// Emitted radiance, linear RGB (W·sr⁻¹·m⁻² in scene units), from the front face (both
    /// faces if `double_sided`).
    pub emission: [f64; 3],
    /// Double-sided materials have no back face: both sides reflect and emit, and hitting
    /// them never marks a point as outside the domain of interest.
    pub double_sided: bool,
    /// Alpha handling of ray hits.
    pub alpha_mode: AlphaMode,
    /// Base-colour alpha factor (`baseColorFactor[3]`), multiplied by the texture's alpha.
    pub alpha: f64,
}

impl Material {
    /// A single-sided diffuse material.
    #[must_use]
    pub fn diffuse(name: &str, albedo: [f64; 3]) -> Self {
        Self {
            name: name.to_owned(),
            albedo,
            albedo_texture: None,
            emission: [0.0; 3],
            double_sided: false,
            alpha_mode: AlphaMode::Opaque,
            alpha: 1.0,
        }
    }

    /// A single-sided emitter with the given albedo.
    #[must_use]
    pub fn emitter(name: &str, albedo: [f64; 3], emission: [f64; 3]) -> Self {
        Self { emission, ..Self::diffuse(name, albedo) }
    }

    /// The same material, double-sided.
    #[must_use]
    pub fn two_sided(mut self) -> Self {
        self.double_sided = true;
        self
    }

    /// True when any emission channel is positive.
    #[must_use]
    pub fn is_emissive(&self) -> bool {
        self.emission.iter().any(|&e| e > 0.0)
    }
}
