//! A scene made ready to bake: read from a file (its memory estimated and checked before
//! any geometry is read, [`lightvol_scene::estimate`]) or built in ([`lightvol_scene::builtin`](mod@lightvol_scene::builtin)), with its
//! lights replaced as asked, and the grid a bake uses on it ([`GridChoice`]).
//!
//! This is what `lightvol bake`, `compare`, `render` and `lint` do before their own work;
//! a program that bakes does the same through [`load`] and [`GridChoice::resolve`].

use std::path::{Path, PathBuf};

use lightvol_volume::GridSpec;

use lightvol_scene::builtin::{BUILTIN_NAMES, builtin};
use lightvol_scene::envmap::EnvMap;
use lightvol_scene::estimate::SceneMemory;
use lightvol_scene::{DVec3, Environment, LoadOptions, Scene, SceneError, Sun, UpAxis, load_scene};

/// Where a scene comes from.
#[derive(Clone, Debug)]
pub enum SceneSource {
    /// A built-in scene by name ([`BUILTIN_NAMES`]), with its recommended grid and plates.
    Builtin(String),
    /// A glTF (`.gltf`/`.glb`) or OBJ file read with these options.
    File {
        /// The file.
        path: PathBuf,
        /// Up axis, scale, instancing.
        options: LoadOptions,
    },
}

impl SceneSource {
    /// `builtin:NAME` as a built-in scene, anything else as a file read with `options`.
    #[must_use]
    pub fn parse(spec: &str, options: LoadOptions) -> Self {
        match spec.strip_prefix("builtin:") {
            Some(name) => Self::Builtin(name.to_owned()),
            None => Self::File { path: PathBuf::from(spec), options },
        }
    }
}

/// Lights that replace the scene's own (each `None` keeps what the scene has).
#[derive(Clone, Debug, Default)]
pub struct LightOverrides {
    /// A uniform sky radiance over the upper hemisphere, and optionally the ground's below.
    pub sky: Option<([f64; 3], Option<[f64; 3]>)>,
    /// A latitude-longitude EXR environment map (applied after `sky`, so it wins).
    pub environment_map: Option<PathBuf>,
    /// A sun whose direction is in the scene file's frame (converted to the internal one).
    pub sun: Option<Sun>,
    /// Remove the scene's sun (applied last).
    pub no_sun: bool,
}

/// Applies `lights` to `s`, whose file frame is `frame` (a sun's direction is given in it):
/// a uniform sky, then an environment map, a sun, no sun; then, if the scene has no light at
/// all, a uniform white sky (returns `true` when it did that).
///
/// # Errors
/// [`SetupError::Environment`] for an unreadable map.
pub fn apply_lights(s: &mut Scene, frame: UpAxis, lights: &LightOverrides) -> Result<bool, SetupError> {
    if let Some((sky, ground)) = lights.sky {
        s.environment = Environment::UniformSky { sky, ground };
    }
    if let Some(env) = &lights.environment_map {
        let map =
            EnvMap::from_exr(env).map_err(|source| SetupError::Environment { path: env.clone(), source })?;
        s.environment = Environment::Map(map);
    }
    if let Some(sun) = &lights.sun {
        let mut sun = *sun;
        sun.direction = DVec3::from_array(frame.to_world(sun.direction.to_array()));
        s.sun = Some(sun);
    }
    if lights.no_sun {
        s.sun = None;
    }
    let has_emitter = s.materials.iter().any(|m| m.is_emissive());
    if matches!(s.environment, Environment::Black) && s.sun.is_none() && s.punctual.is_empty() && !has_emitter
    {
        s.environment = Environment::UniformSky { sky: [1.0; 3], ground: None };
        return Ok(true);
    }
    Ok(false)
}

/// A loaded scene with what a bake on it needs besides the geometry.
pub struct LoadedScene {
    /// The scene with lights applied.
    pub scene: Scene,
    /// Recommended grid (built-in scenes).
    pub grid: Option<GridSpec>,
    /// Recommended plate heights (built-in scenes).
    pub plate_heights: Vec<f64>,
    /// Label for reports: `builtin:NAME` or the file path as given.
    pub label: String,
    /// The source file's frame (built-in scenes: the internal +Z-up frame). Coordinates
    /// given by users and shown in reports are in it.
    pub frame: UpAxis,
    /// The scene's estimated memory (geometry, ray tracer, textures), checked before load.
    pub memory: SceneMemory,
    /// The scene had no light at all, so a uniform white sky (radiance 1) was put in.
    pub defaulted_sky: bool,
}

impl LoadedScene {
    /// Bytes a bake of this scene on a grid of `res` nodes with `coeffs` coefficients per
    /// channel needs, the node reach counted or not (`node_reach`): the scene's own
    /// (geometry, ray tracer, textures) and the grid's ([`bake_memory_bytes`]). The memory
    /// limit is checked against it ([`GridChoice::resolve`]).
    #[must_use]
    pub fn bake_memory_bytes(&self, res: [u64; 3], coeffs: usize, node_reach: bool) -> u128 {
        bake_memory_bytes(res, coeffs, node_reach).saturating_add(u128::from(self.memory.total()))
    }
}

/// Why a scene could not be made ready.
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    /// No built-in scene has this name.
    #[error("unknown built-in scene '{0}' (choose from {names})", names = BUILTIN_NAMES.join(", "))]
    UnknownBuiltin(String),
    /// The load scale is zero, negative or not finite.
    #[error("the scale must be a positive finite number")]
    BadScale,
    /// The scene file could not be estimated or read.
    #[error("loading {}", path.display())]
    Load {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: SceneError,
    },
    /// The scene's estimated memory is over the limit.
    #[error(
        "{} needs about {} ({} triangles placed, {} stored; the {what} alone {}), more than the {} allowed",
        path.display(), gib(u128::from(memory.total())), memory.triangles, memory.unique_triangles,
        gib(u128::from(*bytes)), gib(*limit)
    )]
    SceneTooLarge {
        /// The file.
        path: PathBuf,
        /// Its estimate (boxed: the error stays small).
        memory: Box<SceneMemory>,
        /// Its largest consumer.
        what: &'static str,
        /// That consumer's bytes.
        bytes: u64,
        /// The limit in bytes.
        limit: u128,
    },
    /// The environment map could not be read.
    #[error("loading environment {}", path.display())]
    Environment {
        /// The map.
        path: PathBuf,
        /// Why.
        #[source]
        source: SceneError,
    },
}

/// Bytes as `1.23 GiB` (the unit of every memory message).
#[must_use]
pub fn gib(b: u128) -> String {
    format!("{:.2} GiB", b as f64 / f64::from(1u32 << 30))
}

/// Loads (or builds) the scene of `source`, refusing a file whose estimated memory exceeds
/// `limit` bytes before its geometry is read, and applies `lights`. Loader warnings stay in
/// the scene's report.
///
/// # Errors
/// [`SetupError`]: an unknown built-in, a bad scale, a file that cannot be read or is too
/// large, an unreadable environment map.
pub fn load(source: &SceneSource, limit: u128, lights: &LightOverrides) -> Result<LoadedScene, SetupError> {
    let mut loaded = match source {
        SceneSource::Builtin(name) => {
            let b = builtin(name).ok_or_else(|| SetupError::UnknownBuiltin(name.clone()))?;
            let memory = SceneMemory::from_counts(b.scene.triangle_count() as u64, 0, 0);
            LoadedScene {
                scene: b.scene,
                grid: Some(b.grid),
                plate_heights: b.plate_heights,
                label: format!("builtin:{name}"),
                frame: UpAxis::Z,
                memory,
                defaulted_sky: false,
            }
        }
        SceneSource::File { path, options } => load_file(path, options, limit)?,
    };
    loaded.defaulted_sky = apply_lights(&mut loaded.scene, loaded.frame, lights)?;
    Ok(loaded)
}

fn load_file(path: &Path, options: &LoadOptions, limit: u128) -> Result<LoadedScene, SetupError> {
    if !(options.scale.is_finite() && options.scale > 0.0) {
        return Err(SetupError::BadScale);
    }
    let failed = |source| SetupError::Load { path: path.to_owned(), source };
    // Estimate first: a scene too large for memory is one error, not an abort mid-load.
    let memory = lightvol_scene::estimate::estimate_scene(path, options.flatten_instances).map_err(failed)?;
    if u128::from(memory.total()) > limit {
        let (what, bytes) = memory.biggest();
        return Err(SetupError::SceneTooLarge {
            path: path.to_owned(),
            memory: Box::new(memory),
            what,
            bytes,
            limit,
        });
    }
    let scene = load_scene(path, options).map_err(failed)?;
    Ok(LoadedScene {
        scene,
        grid: None,
        plate_heights: Vec::new(),
        label: path.display().to_string(),
        frame: options.up,
        memory,
        defaulted_sky: false,
    })
}

/// Bytes of one exact sum of the accumulator: a 16-byte fixed-point value plus a 1-byte
/// poison flag (`lightvol_volume::fixed`).
pub const SUM_BYTES: u128 = 17;

/// Bytes per node that a bake recording the node reach
/// ([`crate::method::Method::Doi`], [`crate::reach`]) needs on top of
/// [`bake_memory_bytes`]'s arrays: the accumulator's six reach sums, the relocated
/// capture point (`Option<DVec3>`, 32 bytes), the reach rays' results before they are
/// recorded (`([f32; 6], u64)`, 32 bytes) and the finalized volume's six f32 reaches.
/// Measured on a 120 × 120 × 40 grid of the built-in maze at one sample per node
/// (`lightvol bake builtin:maze --res 120,120,40 --samples 1 --json --method M`, its
/// `peak_memory_bytes`): 439 MiB for `point`, 518 MiB for `doi`, 143 bytes per node more, as
/// the relocated points and the reach rays' results are freed before the volume's reach
/// is made.
pub const NODE_REACH_BYTES: u128 = 6 * SUM_BYTES + 32 + 32 + 6 * 4;

/// Bytes a bake of this grid needs: the exact accumulator (numerators, denominators,
/// outside sums; [`SUM_BYTES`] each), the f64 estimates the finalizer divides into, and
/// the finalized f32 volume and weights; plus [`NODE_REACH_BYTES`] per node when the bake
/// records the node reach (`node_reach`).
#[must_use]
pub fn bake_memory_bytes(res: [u64; 3], coeffs: usize, node_reach: bool) -> u128 {
    let nodes = u128::from(res[0]) * u128::from(res[1]) * u128::from(res[2]);
    let k = coeffs as u128 * 3;
    let reach = if node_reach { NODE_REACH_BYTES } else { 0 };
    nodes * ((k + 2) * SUM_BYTES + (k + 1) * 8 + (k + 1) * 4 + reach)
}

/// Bytes a bake's unit (node or cell) holds per sample while it is traced: each sample's
/// direction and first hit.
pub const SAMPLE_BYTES: u128 = crate::probe::TRACED_BYTES;

/// Bytes the units traced at once hold for their samples: `samples` (a unit's most, the
/// cap under `--noise`) records of `bytes_per_sample` ([`SAMPLE_BYTES`] for a volume bake),
/// on each of `threads` threads.
#[must_use]
pub fn sample_memory_bytes(samples: u64, threads: usize, bytes_per_sample: u128) -> u128 {
    u128::from(samples) * threads as u128 * bytes_per_sample
}

/// Refuses a sample count whose units would not fit in `limit` bytes
/// ([`sample_memory_bytes`]), before anything is allocated.
///
/// # Errors
/// A one-line reason with the bytes needed and allowed.
pub fn check_sample_memory(
    samples: u64,
    threads: usize,
    bytes_per_sample: u128,
    limit: u128,
) -> Result<(), String> {
    let need = sample_memory_bytes(samples, threads, bytes_per_sample);
    if need > limit {
        return Err(format!(
            "{samples} samples per unit on {threads} threads hold about {} of directions and hits, more than the {} allowed",
            gib(need),
            gib(limit)
        ));
    }
    Ok(())
}

/// Bytes that splitting a bake of this grid into `groups` light groups adds
/// ([`lightvol_volume::accumulator`]'s light-group numerators): per group and node, `3 ·
/// coeffs` exact sums ([`SUM_BYTES`]) and the finalized f32 layer; once, the f64 values,
/// the f32 volume and its copy that each group passes through when it is finalized.
#[must_use]
pub fn light_group_bytes(res: [u64; 3], coeffs: usize, groups: usize) -> u128 {
    if groups == 0 {
        return 0;
    }
    let nodes = u128::from(res[0]) * u128::from(res[1]) * u128::from(res[2]);
    let k = coeffs as u128 * 3;
    nodes * k * (groups as u128 * (SUM_BYTES + 4) + 8 + 4 + 4)
}

/// Bytes the system reports available (`MemAvailable`), or 8 GiB where it does not say.
#[must_use]
pub fn available_memory_bytes() -> u128 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|m| {
            m.lines()
                .find(|l| l.starts_with("MemAvailable:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<u128>().ok())
        })
        .map_or(8 << 30, |kib| kib * 1024)
}

/// The memory limit of a bake: `mib` MiB, or half of the available memory.
#[must_use]
pub fn memory_limit(mib: Option<u64>) -> u128 {
    mib.map_or_else(|| available_memory_bytes() / 2, |m| u128::from(m) << 20)
}

/// How a bake's grid is chosen: each field `None` falls back to the scene's recommended
/// grid (built-ins), else to the scene bounds grown by 5% with about 16 cells along the
/// longest axis.
#[derive(Clone, Debug)]
pub struct GridChoice {
    /// Min and max corners in the scene file's frame.
    pub bounds: Option<([f64; 3], [f64; 3])>,
    /// Nodes per axis along the scene file's axes (each a whole number of at least 2).
    pub res: Option<[f64; 3]>,
    /// Node spacing (sets the resolution from the bounds); `res` wins over it.
    pub spacing: Option<f64>,
    /// SH coefficients per channel.
    pub coeffs: usize,
    /// The bake's memory limit in bytes: scene, ray tracer and grid together.
    pub memory_limit: u128,
    /// The bake records the node reach ([`NODE_REACH_BYTES`]).
    pub node_reach: bool,
    /// Light groups the bake is split into (0: none; [`light_group_bytes`]).
    pub light_groups: usize,
}

/// Why a grid could not be chosen.
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    /// A bounds minimum is not below its maximum.
    #[error("bounds: min {min:?} must be below max {max:?} on every axis")]
    EmptyBounds {
        /// Min corner (file frame).
        min: [f64; 3],
        /// Max corner (file frame).
        max: [f64; 3],
    },
    /// A resolution is not a whole number of at least 2.
    #[error("each axis needs a whole number of at least 2 nodes, got {0:?}")]
    BadResolution([f64; 3]),
    /// The spacing is zero, negative or not finite.
    #[error("the spacing must be a positive finite number")]
    BadSpacing,
    /// Scene and grid together are over the memory limit.
    #[error("the bake needs about {} (the {what} {} of it), more than the {} allowed", gib(*need), gib(*bytes), gib(*limit))]
    TooLarge {
        /// Bytes needed.
        need: u128,
        /// The larger part: the grid or the scene.
        what: String,
        /// Its bytes.
        bytes: u128,
        /// The limit.
        limit: u128,
    },
    /// The grid itself is invalid.
    #[error("invalid grid")]
    Grid(#[source] lightvol_volume::VolumeError),
}

impl GridChoice {
    /// The grid on `scene`; refuses invalid or oversized grids before anything is allocated.
    ///
    /// # Errors
    /// [`GridError`].
    pub fn resolve(&self, scene: &LoadedScene) -> Result<GridSpec, GridError> {
        let (min, max) = match self.bounds {
            Some((min, max)) => {
                if (0..3).any(|i| min[i] >= max[i]) {
                    return Err(GridError::EmptyBounds { min, max });
                }
                // Given in the file's frame; the grid is built in the internal one.
                scene.frame.box_to_world(min, max)
            }
            None => match &scene.grid {
                Some(g) => g.bounds(),
                None => {
                    let (lo, hi) = scene.scene.bounds();
                    let pad = (hi - lo) * 0.05 + DVec3::splat(1e-3);
                    ((lo - pad).to_array(), (hi + pad).to_array())
                }
            },
        };
        let res: [u64; 3] = if let Some(v) = self.res {
            if v.iter().any(|&x| x < 2.0 || x.fract() != 0.0 || x > f64::from(u32::MAX)) {
                return Err(GridError::BadResolution(v));
            }
            // NX,NY,NZ count nodes along the file's axes.
            res_to_world(scene.frame, v.map(|x| x as u64))
        } else if let Some(s) = self.spacing {
            if !(s.is_finite() && s > 0.0) {
                return Err(GridError::BadSpacing);
            }
            core::array::from_fn(|i| (((max[i] - min[i]) / s).ceil() as u64 + 1).max(2))
        } else if let (Some(g), None) = (&scene.grid, &self.bounds) {
            g.res().map(u64::from)
        } else {
            // Default: about 16 cells along the longest axis.
            let longest = (0..3).map(|i| max[i] - min[i]).fold(0.0, f64::max);
            core::array::from_fn(|i| (((max[i] - min[i]) / longest * 16.0).ceil() as u64 + 1).max(2))
        };
        let coeffs = self.coeffs;
        let groups = light_group_bytes(res, coeffs, self.light_groups);
        let grid_bytes = bake_memory_bytes(res, coeffs, self.node_reach).saturating_add(groups);
        let scene_bytes = u128::from(scene.memory.total());
        let need = scene.bake_memory_bytes(res, coeffs, self.node_reach).saturating_add(groups);
        let limit = self.memory_limit;
        if need > limit {
            let (what, bytes) = if grid_bytes >= scene_bytes {
                let split = match self.light_groups {
                    0 => String::new(),
                    g => format!(" in {g} light groups"),
                };
                (
                    format!("grid {}x{}x{} with {coeffs} coefficients{split}", res[0], res[1], res[2]),
                    grid_bytes,
                )
            } else {
                (format!("scene ({})", scene.memory.biggest().0), scene_bytes)
            };
            return Err(GridError::TooLarge { need, what, bytes, limit });
        }
        let res32 = res.map(|r| u32::try_from(r).expect("bounded by the memory check"));
        let mut spec = GridSpec::new(min, max, res32).map_err(GridError::Grid)?;
        if self.bounds.is_none()
            && self.res.is_none()
            && self.spacing.is_none()
            && let Some(g) = &scene.grid
            && let Some(p) = g.placement()
        {
            spec = spec.with_placement(*p);
        }
        Ok(spec)
    }
}

/// A per-axis count along the file's axes as the count along the internal axes.
#[must_use]
pub fn res_to_world(up: UpAxis, file: [u64; 3]) -> [u64; 3] {
    let mut out = [0; 3];
    for (a, (axis, _)) in up.file_axes().into_iter().enumerate() {
        out[axis] = file[a];
    }
    out
}

/// An internal per-axis count as the count along the file's axes (for reports).
#[must_use]
pub fn res_to_file(up: UpAxis, internal: [u32; 3]) -> [u32; 3] {
    up.file_axes().map(|(axis, _)| internal[axis])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn maze() -> LoadedScene {
        load(&SceneSource::Builtin("maze".into()), u128::MAX, &LightOverrides::default()).unwrap()
    }

    #[test]
    fn bake_memory_counts_each_array() {
        // One node, 9 coefficients: 27 numerators + denominator + outside sum at 17 bytes,
        // 28 f64 estimates, 28 f32 values.
        assert_eq!(bake_memory_bytes([1, 1, 1], 9, false), 29 * 17 + 28 * 8 + 28 * 4);
        assert_eq!(bake_memory_bytes([2, 3, 4], 4, false), 24 * (14 * 17 + 13 * 12));
        assert_eq!(bake_memory_bytes([2, 3, 4], 4, true), 24 * (14 * 17 + 13 * 12 + 190));
        // A bake adds the scene's own bytes.
        let m = maze();
        let scene = u128::from(m.memory.total());
        assert!(scene > 0);
        assert_eq!(m.bake_memory_bytes([2, 3, 4], 4, true), 24 * (14 * 17 + 13 * 12 + 190) + scene);
        assert_eq!(m.bake_memory_bytes([1, 1, 1], 9, false), 29 * 17 + 28 * 8 + 28 * 4 + scene);
    }

    #[test]
    fn node_reach_bytes_are_the_sizes_of_its_arrays() {
        use std::mem::size_of;
        let fixed = size_of::<i128>() + size_of::<bool>();
        let per_node =
            6 * fixed + size_of::<Option<DVec3>>() + size_of::<([f32; 6], u64)>() + size_of::<[f32; 6]>();
        assert_eq!(NODE_REACH_BYTES, per_node as u128);
    }

    /// The scene's recommended grid, 9 coefficients, no memory limit, no node reach.
    fn recommended() -> GridChoice {
        GridChoice {
            light_groups: 0,
            bounds: None,
            res: None,
            spacing: None,
            coeffs: 9,
            memory_limit: u128::MAX,
            node_reach: false,
        }
    }

    #[test]
    fn builtin_grid_is_the_recommended_one() {
        let m = maze();
        let g = recommended().resolve(&m).unwrap();
        assert_eq!(g.res(), m.grid.as_ref().unwrap().res());
        assert!(!m.defaulted_sky);
    }

    #[test]
    fn grid_choices_are_checked() {
        let m = maze();
        let base = recommended();
        let bad = |c: GridChoice| c.resolve(&m).unwrap_err().to_string();
        assert!(bad(GridChoice { res: Some([1.0, 4.0, 4.0]), ..base.clone() }).contains("at least 2"));
        // The samples units hold: 4e9 on 2 threads is far beyond 1 GiB; 4096 is not.
        let e = check_sample_memory(4_000_000_000, 2, SAMPLE_BYTES, 1 << 30).unwrap_err();
        assert!(e.contains("4000000000 samples per unit on 2 threads") && !e.contains('\n'), "{e}");
        assert!(check_sample_memory(4096, 2, SAMPLE_BYTES, 1 << 30).is_ok());
        assert_eq!(sample_memory_bytes(10, 3, SAMPLE_BYTES), 30 * crate::probe::TRACED_BYTES);
        assert!(bad(GridChoice { res: Some([2.5, 4.0, 4.0]), ..base.clone() }).contains("whole number"));
        assert!(bad(GridChoice { spacing: Some(0.0), ..base.clone() }).contains("spacing"));
        assert!(
            bad(GridChoice { bounds: Some(([0.0; 3], [1.0, 0.0, 1.0])), ..base.clone() })
                .contains("below max")
        );
        let e = bad(GridChoice { res: Some([100.0; 3]), memory_limit: 1 << 20, ..base.clone() });
        assert!(e.starts_with("the bake needs about") && e.contains("grid 100x100x100"), "{e}");
        // Spacing 1 over a box of 4 gives 5 nodes.
        let g = GridChoice { bounds: Some(([0.0; 3], [4.0; 3])), spacing: Some(1.0), ..base.clone() }
            .resolve(&m)
            .unwrap();
        assert_eq!(g.res(), [5, 5, 5]);
        // A limit that fits a 50³ grid only without the node reach refuses a doi bake of it.
        let res = Some([50.0; 3]);
        let fits = bake_memory_bytes([50; 3], 9, false) + u128::from(m.memory.total());
        let plain = GridChoice { res, memory_limit: fits, ..base.clone() };
        assert_eq!(plain.resolve(&m).unwrap().res(), [50; 3]);
        let e = bad(GridChoice { node_reach: true, ..plain });
        assert!(e.starts_with("the bake needs about") && e.contains("grid 50x50x50"), "{e}");
    }

    #[test]
    fn unknown_builtins_list_the_names() {
        let e = load(&SceneSource::Builtin("nope".into()), u128::MAX, &LightOverrides::default())
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("'nope'") && BUILTIN_NAMES.iter().all(|n| e.contains(n)), "{e}");
    }

    #[test]
    fn lights_are_replaced_in_order() {
        let lights = LightOverrides {
            sky: Some(([0.5; 3], Some([0.1; 3]))),
            sun: Some(Sun { direction: DVec3::Z, irradiance: [2.0; 3], angular_radius: 0.0 }),
            no_sun: true,
            ..LightOverrides::default()
        };
        let m = load(&SceneSource::Builtin("maze".into()), u128::MAX, &lights).unwrap();
        assert!(m.scene.sun.is_none());
        assert!(matches!(
            m.scene.environment,
            Environment::UniformSky { sky: [0.5, 0.5, 0.5], ground: Some(_) }
        ));
    }
}
