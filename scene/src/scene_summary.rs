//! # Scene summary: what the loader understood of a scene file
//!
//! Unique and instanced triangles, objects, materials with alpha mode and sidedness,
//! extensions and how each was treated, lights, cameras, bounds in the file's axes and in
//! lightvol's internal +Z-up frame, the memory estimate and every warning
//! ([`summarize`]; [`text`] is the human-readable form). The first place to look when a bake
//! looks wrong.

use serde::Serialize;

use crate::{AlphaMode, DVec3, Environment, PunctualLight, Scene, UpAxis};

/// Axis-aligned bounds.
#[derive(Debug, Serialize)]
pub struct Bounds {
    /// Minimum corner.
    pub min: [f64; 3],
    /// Maximum corner.
    pub max: [f64; 3],
}

/// One material as loaded.
#[derive(Debug, Serialize)]
pub struct MaterialInfo {
    /// Name.
    pub name: String,
    /// `OPAQUE`, `MASK` or `BLEND`.
    pub alpha_mode: &'static str,
    /// `alphaCutoff` of a `MASK` material.
    pub alpha_cutoff: Option<f64>,
    /// Base-colour alpha factor.
    pub alpha: f64,
    /// Both sides reflect (no back faces for the domain of interest).
    pub double_sided: bool,
    /// Diffuse albedo factor (linear RGB).
    pub albedo: [f64; 3],
    /// Size of the base-colour texture in use, if any.
    pub texture: Option<[u32; 2]>,
    /// The texture has an alpha channel.
    pub texture_alpha: bool,
    /// Emitted radiance (linear RGB).
    pub emission: [f64; 3],
    /// Triangles that use it.
    pub triangles: usize,
}

/// One extension and its treatment.
#[derive(Debug, Serialize)]
pub struct ExtensionInfo {
    /// Name.
    pub name: String,
    /// Listed in `extensionsRequired`.
    pub required: bool,
    /// Where the file uses it.
    pub used_in: Vec<String>,
    /// What the loader did.
    pub treatment: String,
}

/// One camera, in both frames.
#[derive(Debug, Serialize)]
pub struct CameraInfo {
    /// Index for `render --camera gltf:INDEX`.
    pub index: usize,
    /// Name for `render --camera gltf:NAME`.
    pub name: String,
    /// Eye position in the file's frame.
    pub position: [f64; 3],
    /// View direction in the file's frame.
    pub forward: [f64; 3],
    /// Eye position in lightvol's internal +Z-up frame.
    pub position_internal: [f64; 3],
    /// Vertical field of view in degrees.
    pub yfov_deg: f64,
    /// Width / height, if the file gives one.
    pub aspect: Option<f64>,
}

/// What the loader understood.
#[derive(Debug, Serialize)]
pub struct SceneSummary {
    /// The scene argument.
    pub scene: String,
    /// The file's frame (`y-up` or `z-up`, as in reports and sidecars); the internal frame is
    /// +Z up.
    pub up: &'static str,
    /// Triangles after instancing (what is traced), without degenerate ones.
    pub instanced_triangles: usize,
    /// Triangles of the unique meshes.
    pub unique_triangles: usize,
    /// Degenerate triangles dropped.
    pub degenerate_skipped: usize,
    /// Mesh instances placed.
    pub instances: usize,
    /// Lightmap objects (one per mesh instance).
    pub objects: usize,
    /// Triangles whose material is `MASK` or `BLEND` (alpha-tested in every ray query).
    pub alpha_triangles: usize,
    /// Materials.
    pub materials: Vec<MaterialInfo>,
    /// Extensions.
    pub extensions: Vec<ExtensionInfo>,
    /// Punctual lights (glTF `KHR_lights_punctual`), described in the file's frame.
    pub lights: Vec<String>,
    /// The names `--light-groups` patterns match ([`crate::light_groups::scene_lights`]).
    pub light_names: Vec<String>,
    /// The sun, if any (direction towards it, file frame).
    pub sun: Option<String>,
    /// The environment.
    pub environment: String,
    /// Cameras.
    pub cameras: Vec<CameraInfo>,
    /// Bounds in the file's axes (in scene units, after `--scale`).
    pub bounds_file: Bounds,
    /// Bounds in the internal +Z-up frame.
    pub bounds_internal: Bounds,
    /// Loader warnings.
    pub warnings: Vec<String>,
    /// The memory estimate made before loading (`crate::estimate`), bytes.
    pub memory: MemorySummary,
}

/// The scene-memory estimate in a summary.
#[derive(Debug, Clone, Serialize)]
pub struct MemorySummary {
    /// Triangles placed (every instance counted) the estimate counted.
    pub triangles: u64,
    /// Triangles stored (each instanced mesh once).
    pub unique_triangles: u64,
    /// Instances (placements of meshes placed more than once).
    pub instances: u64,
    /// Triangles and vertex attributes.
    pub geometry_bytes: u64,
    /// The ray tracer (BVH build peak and its arrays).
    pub tracer_bytes: u64,
    /// Decoded textures.
    pub texture_bytes: u64,
    /// All three.
    pub total_bytes: u64,
}

fn bounds_to_file(up: UpAxis, lo: DVec3, hi: DVec3) -> Bounds {
    let (min, max) = up.box_to_file(lo.to_array(), hi.to_array());
    Bounds { min, max }
}

/// Summarises a loaded scene in the file's frame `up`, with the memory estimate made
/// before loading.
#[must_use]
pub fn summarize(
    label: &str,
    scene: &Scene,
    up: UpAxis,
    memory: &crate::estimate::SceneMemory,
) -> SceneSummary {
    let mut per_material = vec![0usize; scene.materials.len()];
    for (_, t, _) in scene.stored_triangles() {
        per_material[t.material as usize] += 1;
    }
    let materials: Vec<MaterialInfo> = scene
        .materials
        .iter()
        .zip(&per_material)
        .map(|(m, &n)| {
            let tex = m.albedo_texture.and_then(|i| scene.textures.get(i as usize));
            MaterialInfo {
                name: m.name.clone(),
                alpha_mode: m.alpha_mode.gltf_name(),
                alpha_cutoff: match m.alpha_mode {
                    AlphaMode::Mask { cutoff } => Some(cutoff),
                    _ => None,
                },
                alpha: m.alpha,
                double_sided: m.double_sided,
                albedo: m.albedo,
                texture: tex.map(|t| [t.width(), t.height()]),
                texture_alpha: tex.is_some_and(crate::base_color::Texture::has_alpha),
                emission: m.emission,
                triangles: n,
            }
        })
        .collect();
    let alpha_triangles = scene
        .materials
        .iter()
        .zip(&per_material)
        .filter(|(m, _)| m.alpha_mode != AlphaMode::Opaque)
        .map(|(_, &n)| n)
        .sum();
    let f = |p: DVec3| up.to_file(p.to_array());
    let v = |p: [f64; 3]| format!("({:.4}, {:.4}, {:.4})", p[0], p[1], p[2]);
    let lights = scene
        .punctual
        .iter()
        .enumerate()
        .map(|(i, l)| (scene.punctual_name(i), l))
        .map(|(name, l)| match l {
            PunctualLight::Point { position, intensity } => {
                format!("{name}: point at {} intensity {}", v(f(*position)), v(*intensity))
            }
            PunctualLight::Spot { position, axis, intensity, inner, outer } => format!(
                "{name}: spot at {} along {} intensity {} cone {:.1}°..{:.1}°",
                v(f(*position)),
                v(f(*axis)),
                v(*intensity),
                inner.to_degrees(),
                outer.to_degrees()
            ),
            PunctualLight::Directional { to_light, irradiance } => {
                format!("{name}: directional towards {} irradiance {}", v(f(*to_light)), v(*irradiance))
            }
        })
        .collect();
    let environment = match &scene.environment {
        Environment::Black => "black".to_owned(),
        Environment::UniformSky { sky, ground } => {
            format!("uniform sky {} ground {}", v(*sky), v(ground.unwrap_or([0.0; 3])))
        }
        Environment::Map(_) => "latitude-longitude map".to_owned(),
    };
    let (lo, hi) = scene.bounds();
    SceneSummary {
        scene: label.to_owned(),
        up: up.name(),
        instanced_triangles: scene.triangle_count(),
        unique_triangles: scene.report.unique_triangles,
        degenerate_skipped: scene.report.degenerate_skipped,
        instances: scene.report.instances,
        objects: scene.meshes.len(),
        alpha_triangles,
        materials,
        extensions: scene
            .report
            .extensions
            .iter()
            .map(|e| ExtensionInfo {
                name: e.name.clone(),
                required: e.required,
                used_in: e.used_in.clone(),
                treatment: e.treatment.clone(),
            })
            .collect(),
        lights,
        light_names: crate::light_groups::scene_lights(scene).into_iter().map(|l| l.name).collect(),
        sun: scene
            .sun
            .as_ref()
            .map(|s| format!("towards {} irradiance {}", v(f(s.direction)), v(s.irradiance))),
        environment,
        cameras: scene
            .cameras
            .iter()
            .enumerate()
            .map(|(index, c)| CameraInfo {
                index,
                name: c.name.clone(),
                position: f(c.position),
                forward: f(c.forward),
                position_internal: c.position.to_array(),
                yfov_deg: c.yfov.to_degrees(),
                aspect: c.aspect,
            })
            .collect(),
        bounds_file: bounds_to_file(up, lo, hi),
        bounds_internal: Bounds { min: lo.to_array(), max: hi.to_array() },
        warnings: scene.report.warnings.clone(),
        memory: MemorySummary {
            triangles: memory.triangles,
            unique_triangles: memory.unique_triangles,
            instances: memory.instances,
            geometry_bytes: memory.geometry_bytes,
            tracer_bytes: memory.tracer_bytes,
            texture_bytes: memory.texture_bytes,
            total_bytes: memory.total(),
        },
    }
}

/// The summary as the text `lightvol inspect` prints: one topic per line, materials,
/// extensions, lights, cameras and warnings one per indented line.
#[must_use]
pub fn text(s: &SceneSummary) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    // Writing to a String cannot fail.
    macro_rules! println {
        ($($t:tt)*) => { let _ = writeln!(out, $($t)*); };
    }
    let v = |p: [f64; 3]| format!("({:.4}, {:.4}, {:.4})", p[0], p[1], p[2]);
    println!(
        "scene: {} (+{} up in the file; lightvol works +Z up)",
        s.scene,
        s.up.trim_end_matches("-up").to_uppercase()
    );
    println!(
        "triangles: {} traced (after instancing, degenerate ones dropped), {} in the file's unique meshes, {} degenerate dropped; {} instances, {} objects",
        s.instanced_triangles, s.unique_triangles, s.degenerate_skipped, s.instances, s.objects
    );
    println!("alpha-tested triangles: {}", s.alpha_triangles);
    let mib = |b: u64| b as f64 / f64::from(1u32 << 20);
    println!(
        "memory estimate: {:.1} MiB (geometry {:.1}, ray tracer {:.1}, textures {:.1}; a bake adds its grid)",
        mib(s.memory.total_bytes),
        mib(s.memory.geometry_bytes),
        mib(s.memory.tracer_bytes),
        mib(s.memory.texture_bytes)
    );
    println!("bounds (file frame):     {} .. {}", v(s.bounds_file.min), v(s.bounds_file.max));
    println!("bounds (internal +Z up): {} .. {}", v(s.bounds_internal.min), v(s.bounds_internal.max));
    println!("materials: {}", s.materials.len());
    for m in &s.materials {
        let alpha = match m.alpha_cutoff {
            Some(c) => format!("MASK cutoff {c}"),
            None => m.alpha_mode.to_owned(),
        };
        let tex = m.texture.map_or_else(
            || "no texture".to_owned(),
            |t| format!("texture {}x{}{}", t[0], t[1], if m.texture_alpha { " with alpha" } else { "" }),
        );
        println!(
            "  {:<24} {:>9} tris  {}  {}  albedo {}  alpha {}  {}{}",
            m.name,
            m.triangles,
            alpha,
            if m.double_sided { "double-sided" } else { "single-sided" },
            v(m.albedo),
            m.alpha,
            tex,
            if m.emission.iter().any(|&e| e > 0.0) {
                format!("  emits {}", v(m.emission))
            } else {
                String::new()
            }
        );
    }
    println!("extensions: {}", s.extensions.len());
    for e in &s.extensions {
        println!(
            "  {}{} in [{}]: {}",
            e.name,
            if e.required { " (required)" } else { "" },
            e.used_in.join(", "),
            e.treatment
        );
    }
    println!("lights: {}", s.lights.len());
    for l in &s.lights {
        println!("  {l}");
    }
    if let Some(sun) = &s.sun {
        println!("sun: {sun}");
    }
    println!("light names (for --light-groups): {}", s.light_names.join(", "));
    println!("environment: {}", s.environment);
    println!("cameras: {}", s.cameras.len());
    for c in &s.cameras {
        println!(
            "  gltf:{} '{}' at {} looking {} yfov {:.1}°{}",
            c.index,
            c.name,
            v(c.position),
            v(c.forward),
            c.yfov_deg,
            c.aspect.map_or_else(String::new, |a| format!(" aspect {a:.4}"))
        );
    }
    println!("warnings: {}", s.warnings.len());
    for w in &s.warnings {
        println!("  {w}");
    }
    out
}
