//! Scene, light, grid and bake options shared by `bake`, `compare`, `render`, `lint` and
//! `bench`, and their validation (every problem is one clear error before any heavy work).

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Args;
use lightvol_sampler::TransportSettings;
use lightvol_sampler::builtin::{BUILTIN_NAMES, builtin};
use lightvol_sampler::envmap::EnvMap;
use lightvol_sampler::estimate::SceneMemory;
use lightvol_sampler::{DVec3, Environment, LoadOptions, Method, Scene, Sun, UpAxis, load_scene};
use lightvol_volume::GridSpec;

/// Where the scene comes from and how to light it.
#[derive(Debug, Clone, Args)]
pub struct SceneArgs {
    /// A glTF (.gltf/.glb) or OBJ file, or `builtin:NAME` (city, interior, maze).
    pub scene: String,
    /// Up axis of the file: glTF is +Y up by specification; many scenes are +Z up. lightvol
    /// works +Z up internally.
    #[arg(long, value_parser = ["y", "z"], default_value = "y")]
    pub up: String,
    /// Uniform scale applied to file positions (e.g. 0.001 for millimetres).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Sky radiance R,G,B over the upper hemisphere (replaces the scene's environment).
    #[arg(long, value_name = "R,G,B")]
    pub sky: Option<String>,
    /// Ground radiance R,G,B below the horizon (with --sky).
    #[arg(long, value_name = "R,G,B")]
    pub ground: Option<String>,
    /// A sun: direction towards it (in the scene file's frame), irradiance on a facing
    /// surface, optional angular radius in degrees (0 = directional light).
    #[arg(long, value_name = "DX,DY,DZ:INTENSITY[:ANGLE_DEG]", allow_hyphen_values = true)]
    pub sun: Option<String>,
    /// Remove the scene's sun (e.g. to bake sky and bounce light only and add the sun at run
    /// time, as many engines do).
    #[arg(long, conflicts_with = "sun")]
    pub no_sun: bool,
    /// A latitude-longitude EXR environment map (replaces the scene's environment).
    #[arg(long, value_name = "FILE.exr")]
    pub env: Option<PathBuf>,
}

/// The grid: bounds and resolution (or spacing), and the SH order.
#[derive(Debug, Clone, Args)]
pub struct GridArgs {
    /// Grid bounds `MINX,MINY,MINZ,MAXX,MAXY,MAXZ` in the scene file's frame (glTF: +Y up;
    /// OBJ: per --up) (default: the built-in scene's recommended grid, or the scene bounds
    /// grown by 5%).
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true)]
    pub bounds: Option<String>,
    /// Nodes per axis `NX,NY,NZ` along the scene file's axes (each at least 2).
    #[arg(long, value_name = "NX,NY,NZ", conflicts_with = "spacing", allow_hyphen_values = true)]
    pub res: Option<String>,
    /// Node spacing (sets the resolution from the bounds).
    #[arg(long)]
    pub spacing: Option<f64>,
    /// SH order: 2, 3 or 4 bands (4, 9 or 16 coefficients per channel).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(2..=4))]
    pub order: u32,
    /// Refuse bakes that would need more memory than this many MiB — the scene's geometry,
    /// ray tracer and textures, estimated before the scene is loaded, plus the grid's sums
    /// (default: half of the available memory).
    #[arg(long)]
    pub max_memory_mib: Option<u64>,
}

/// How far paths go and which light counts directly (bake, surface bake and the path-traced
/// references alike).
#[derive(Debug, Clone, Args)]
pub struct PathArgs {
    /// At most N diffuse bounces (0: the first surface's direct light only). Without it,
    /// paths are unbiased: 2 bounces, then Russian roulette.
    #[arg(long, value_name = "N")]
    pub bounces: Option<u32>,
    /// With --bounces N: continue after the N bounces under Russian roulette (unbiased)
    /// instead of stopping.
    #[arg(long, requires = "bounces")]
    pub russian_roulette: bool,
    /// Which light counts when it reaches a probe or surface directly: `all`, `sky+indirect`
    /// (not the sun nor punctual lights, which engines often add at run time) or `indirect`
    /// (only light that bounced). Applies to the bake and to the reference alike.
    #[arg(long, default_value = "all", value_parser = ["all", "sky+indirect", "indirect"])]
    pub light: String,
}

impl Default for PathArgs {
    /// Unbiased paths and all light: what no option gives.
    fn default() -> Self {
        Self { bounces: None, russian_roulette: false, light: "all".into() }
    }
}

impl PathArgs {
    /// The path settings (module docs of lightvol-sampler's `transport`): unbiased by
    /// default, else at most N bounces.
    #[must_use]
    pub fn transport(&self) -> TransportSettings {
        let direct = lightvol_sampler::transport::DirectLight::parse(&self.light).unwrap_or_default();
        match self.bounces {
            None => TransportSettings { direct, ..TransportSettings::default() },
            Some(n) => TransportSettings {
                bounces: n,
                russian_roulette: self.russian_roulette,
                direct,
                ..TransportSettings::default()
            },
        }
    }

    /// Whether no path option was given.
    #[must_use]
    pub fn is_default(&self) -> bool {
        self.bounces.is_none() && self.light == "all"
    }
}

/// Sampling options.
#[derive(Debug, Clone, Args)]
pub struct SampleArgs {
    /// Samples per cell (prefilter, doi-paper), per node (doi-node) or directions per node
    /// (point, doi).
    #[arg(long, default_value_t = 256)]
    pub samples: u32,
    /// Path length and direct light.
    #[command(flatten)]
    pub path: PathArgs,
    /// Seed of every random stream (results are bit-identical for a seed).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// How prefilter/doi-paper node values come from their samples: `average` (Kontkanen & Laine
    /// Eq. 6) or `lsq[:LAMBDA]` (least squares over the domain of interest, regularised
    /// toward Eq. 6 with weight LAMBDA; see lightvol-sampler's `fit` module).
    #[arg(long, default_value = "average")]
    pub fit: lightvol_sampler::node_fit::Fit,
}

/// A loaded scene with its recommended grid (built-ins) and plate heights.
pub struct LoadedScene {
    /// The scene with lights applied.
    pub scene: Scene,
    /// Recommended grid (built-in scenes).
    pub grid: Option<GridSpec>,
    /// Recommended plate heights (built-in scenes).
    pub plate_heights: Vec<f64>,
    /// Label for reports.
    pub label: String,
    /// The source file's frame (built-in scenes: the internal +Z-up frame). Coordinates on
    /// the command line and in reports are in it.
    pub frame: UpAxis,
    /// The scene's estimated memory (geometry, ray tracer, textures), checked before load.
    pub memory: SceneMemory,
}

fn parse_floats<const N: usize>(what: &str, s: &str) -> anyhow::Result<[f64; N]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>().with_context(|| format!("{what}: '{t}' is not a number")))
        .collect::<anyhow::Result<_>>()?;
    let arr: [f64; N] = v
        .try_into()
        .map_err(|v: Vec<f64>| anyhow::anyhow!("{what}: expected {N} numbers, got {}", v.len()))?;
    if let Some(x) = arr.iter().find(|x| !x.is_finite()) {
        bail!("{what}: {x} is not finite");
    }
    Ok(arr)
}

fn parse_rgb(what: &str, s: &str) -> anyhow::Result<[f64; 3]> {
    let c = parse_floats::<3>(what, s)?;
    if c.iter().any(|&v| v < 0.0) {
        bail!("{what}: radiance must not be negative");
    }
    Ok(c)
}

/// Parses `DX,DY,DZ:INTENSITY[:ANGLE_DEG]`.
pub fn parse_sun(s: &str) -> anyhow::Result<Sun> {
    let parts: Vec<&str> = s.split(':').collect();
    if !(2..=3).contains(&parts.len()) {
        bail!("--sun: expected DX,DY,DZ:INTENSITY[:ANGLE_DEG], got '{s}'");
    }
    let d = parse_floats::<3>("--sun direction", parts[0])?;
    let dir = DVec3::from(d);
    if dir.length() < 1e-12 {
        bail!("--sun: direction must not be zero");
    }
    let intensity: f64 = parts[1]
        .trim()
        .parse()
        .with_context(|| format!("--sun: intensity '{}' is not a number", parts[1]))?;
    if !intensity.is_finite() || intensity < 0.0 {
        bail!("--sun: intensity must be finite and non-negative, got {intensity}");
    }
    let angle = match parts.get(2) {
        Some(a) => a.trim().parse::<f64>().with_context(|| format!("--sun: angle '{a}' is not a number"))?,
        None => 0.27,
    };
    if !angle.is_finite() || !(0.0..90.0).contains(&angle) {
        bail!("--sun: angular radius must be in [0, 90) degrees, got {angle}");
    }
    Ok(Sun { direction: dir.normalize(), irradiance: [intensity; 3], angular_radius: angle.to_radians() })
}

impl SceneArgs {
    /// Loads (or builds) the scene and applies the light options; loader warnings go to
    /// standard error.
    pub fn load(&self) -> anyhow::Result<LoadedScene> {
        self.load_within(memory_limit(None))
    }

    /// [`load`](Self::load) with every placement of an instanced mesh written out as its
    /// own triangles and lightmap object (the surface bake and its renders).
    pub fn load_flattened(&self) -> anyhow::Result<LoadedScene> {
        let loaded = self.load_quiet_with(memory_limit(None), true)?;
        for w in &loaded.scene.report.warnings {
            eprintln!("warning: {w}");
        }
        Ok(loaded)
    }

    /// [`load`](Self::load), refusing a scene whose estimated memory
    /// (`lightvol_sampler::estimate`: geometry, ray tracer, textures) exceeds `limit` bytes
    /// before its geometry is read.
    pub fn load_within(&self, limit: u128) -> anyhow::Result<LoadedScene> {
        let loaded = self.load_quiet_within(limit)?;
        for w in &loaded.scene.report.warnings {
            eprintln!("warning: {w}");
        }
        Ok(loaded)
    }

    /// As [`load`](Self::load), leaving the warnings in the scene's report only.
    pub fn load_quiet(&self) -> anyhow::Result<LoadedScene> {
        self.load_quiet_within(memory_limit(None))
    }

    fn load_quiet_within(&self, limit: u128) -> anyhow::Result<LoadedScene> {
        self.load_quiet_with(limit, false)
    }

    fn load_quiet_with(&self, limit: u128, flatten_instances: bool) -> anyhow::Result<LoadedScene> {
        let up = if self.up == "z" { UpAxis::Z } else { UpAxis::Y };
        let mut loaded = if let Some(name) = self.scene.strip_prefix("builtin:") {
            let b = builtin(name).with_context(|| {
                format!("unknown built-in scene '{name}' (choose from {})", BUILTIN_NAMES.join(", "))
            })?;
            let memory = SceneMemory::from_counts(b.scene.triangle_count() as u64, 0, 0);
            LoadedScene {
                scene: b.scene,
                grid: Some(b.grid),
                plate_heights: b.plate_heights,
                label: format!("builtin:{name}"),
                frame: UpAxis::Z,
                memory,
            }
        } else {
            if !(self.scale.is_finite() && self.scale > 0.0) {
                bail!("--scale must be a positive finite number");
            }
            let path = Path::new(&self.scene);
            let opts = LoadOptions { up, scale: self.scale, flatten_instances, ..LoadOptions::default() };
            // Estimate first: a scene too large for memory is one line, not an abort mid-load.
            let memory = lightvol_sampler::estimate::estimate_scene(path, flatten_instances)
                .with_context(|| format!("loading {}", path.display()))?;
            if u128::from(memory.total()) > limit {
                let (what, bytes) = memory.biggest();
                bail!(
                    "{} needs about {} ({} triangles placed, {} stored; the {what} alone {}), more than the {} allowed (--max-memory-mib)",
                    path.display(),
                    gib(u128::from(memory.total())),
                    memory.triangles,
                    memory.unique_triangles,
                    gib(u128::from(bytes)),
                    gib(limit)
                );
            }
            let scene = load_scene(path, &opts).with_context(|| format!("loading {}", path.display()))?;
            LoadedScene {
                scene,
                grid: None,
                plate_heights: Vec::new(),
                label: self.scene.clone(),
                frame: up,
                memory,
            }
        };
        let s = &mut loaded.scene;
        if let Some(sky) = &self.sky {
            let ground = self.ground.as_deref().map(|g| parse_rgb("--ground", g)).transpose()?;
            s.environment = Environment::UniformSky { sky: parse_rgb("--sky", sky)?, ground };
        } else if self.ground.is_some() {
            bail!("--ground needs --sky");
        }
        if let Some(env) = &self.env {
            let map =
                EnvMap::from_exr(env).with_context(|| format!("loading environment {}", env.display()))?;
            s.environment = Environment::Map(map);
        }
        if let Some(sun) = &self.sun {
            // The direction is in the file's frame, like every coordinate on the command line.
            let mut parsed = parse_sun(sun)?;
            parsed.direction = DVec3::from_array(loaded.frame.to_world(parsed.direction.to_array()));
            s.sun = Some(parsed);
        }
        if self.no_sun {
            s.sun = None;
        }
        let has_emitter = s.materials.iter().any(|m| m.is_emissive());
        if matches!(s.environment, Environment::Black)
            && s.sun.is_none()
            && s.punctual.is_empty()
            && !has_emitter
        {
            eprintln!("note: the scene has no lights; using a uniform white sky (radiance 1)");
            s.environment = Environment::UniformSky { sky: [1.0; 3], ground: None };
        }
        Ok(loaded)
    }
}

/// Bytes a bake of this grid needs: the exact accumulator (numerators, denominators,
/// outside sums; 16-byte fixed-point values plus a 1-byte poison flag each, see
/// `lightvol_volume::fixed`), the f64 estimates the finalizer divides into, and the
/// finalized f32 volume and weights.
#[must_use]
pub fn bake_memory_bytes(res: [u64; 3], coeffs: usize) -> u128 {
    let nodes = u128::from(res[0]) * u128::from(res[1]) * u128::from(res[2]);
    let k = coeffs as u128 * 3;
    nodes * ((k + 2) * 17 + (k + 1) * 8 + (k + 1) * 4)
}

fn available_memory_bytes() -> u128 {
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

/// The memory limit: `--max-memory-mib`, or half of the available memory.
#[must_use]
pub fn memory_limit(mib: Option<u64>) -> u128 {
    mib.map_or_else(|| available_memory_bytes() / 2, |m| u128::from(m) << 20)
}

/// Bytes as `1.23 GiB`.
fn gib(b: u128) -> String {
    format!("{:.2} GiB", b as f64 / f64::from(1u32 << 30))
}

impl GridArgs {
    /// The bake's memory limit in bytes (scene, ray tracer and grid together).
    #[must_use]
    pub fn memory_limit(&self) -> u128 {
        memory_limit(self.max_memory_mib)
    }

    /// SH coefficients per channel.
    #[must_use]
    pub fn coeffs(&self) -> usize {
        (self.order * self.order) as usize
    }

    /// The grid from the options, the built-in recommendation, or the scene bounds; refuses
    /// invalid or oversized grids before anything is allocated.
    pub fn grid(&self, scene: &LoadedScene) -> anyhow::Result<GridSpec> {
        let (min, max) = match &self.bounds {
            Some(b) => {
                let v = parse_floats::<6>("--bounds", b)?;
                let (min, max) = ([v[0], v[1], v[2]], [v[3], v[4], v[5]]);
                if (0..3).any(|i| min[i] >= max[i]) {
                    bail!("--bounds: min {min:?} must be below max {max:?} on every axis");
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
        let res: [u64; 3] = if let Some(r) = &self.res {
            let v = parse_floats::<3>("--res", r)?;
            if v.iter().any(|&x| x < 2.0 || x.fract() != 0.0 || x > f64::from(u32::MAX)) {
                bail!("--res: each axis needs a whole number of at least 2 nodes, got {r}");
            }
            // NX,NY,NZ count nodes along the file's axes.
            res_to_world(scene.frame, v.map(|x| x as u64))
        } else if let Some(s) = self.spacing {
            if !(s.is_finite() && s > 0.0) {
                bail!("--spacing must be a positive finite number");
            }
            core::array::from_fn(|i| (((max[i] - min[i]) / s).ceil() as u64 + 1).max(2))
        } else if let (Some(g), None) = (&scene.grid, &self.bounds) {
            g.res().map(u64::from)
        } else {
            // Default: about 16 cells along the longest axis.
            let longest = (0..3).map(|i| max[i] - min[i]).fold(0.0, f64::max);
            core::array::from_fn(|i| (((max[i] - min[i]) / longest * 16.0).ceil() as u64 + 1).max(2))
        };
        let coeffs = self.coeffs();
        let grid_bytes = bake_memory_bytes(res, coeffs);
        let scene_bytes = u128::from(scene.memory.total());
        let need = grid_bytes.saturating_add(scene_bytes);
        let limit = self.memory_limit();
        if need > limit {
            let (what, bytes) = if grid_bytes >= scene_bytes {
                (format!("grid {}x{}x{} with {coeffs} coefficients", res[0], res[1], res[2]), grid_bytes)
            } else {
                (format!("scene ({})", scene.memory.biggest().0), scene_bytes)
            };
            bail!(
                "the bake needs about {} (the {what} {} of it), more than the {} allowed (lower --res or raise --max-memory-mib)",
                gib(need),
                gib(bytes),
                gib(limit)
            );
        }
        let res32 = res.map(|r| u32::try_from(r).expect("bounded by the memory check"));
        let mut spec = GridSpec::new(min, max, res32).context("invalid grid")?;
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

/// A per-axis count along the file's axes (`--res`) as the count along the internal axes.
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

impl SampleArgs {
    /// The path settings ([`PathArgs::transport`]).
    #[must_use]
    pub fn transport(&self) -> TransportSettings {
        self.path.transport()
    }
}

/// Parses a method name.
pub fn parse_method(s: &str) -> anyhow::Result<Method> {
    Ok(lightvol_sampler::eval::entries::parse_method(s)?)
}

/// The worker threads to use: `threads` (`--threads`), else `SLURM_CPUS_PER_TASK` when the
/// scheduler sets it, else `None` (the global pool, all cores).
pub fn resolve_threads(threads: Option<usize>) -> anyhow::Result<Option<usize>> {
    match threads.or_else(|| lightvol_sampler::shard::threads_from_env(|k| std::env::var(k).ok())) {
        Some(0) => bail!("--threads must be at least 1"),
        t => Ok(t),
    }
}

/// Runs `f` on a rayon pool of [`resolve_threads`] threads, or on the global pool (all
/// cores).
pub fn with_threads<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> anyhow::Result<T> {
    match resolve_threads(threads)? {
        None => Ok(f()),
        Some(n) => {
            let pool =
                rayon::ThreadPoolBuilder::new().num_threads(n).build().context("creating the thread pool")?;
            Ok(pool.install(f))
        }
    }
}
