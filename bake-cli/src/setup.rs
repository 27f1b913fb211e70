//! Scene, light, grid and bake options shared by `bake`, `compare`, `render`, `lint` and
//! `bench`, and their validation (every problem is one clear error before any heavy work).

use lightvol_core::samples::{Samples, parse_samples, samples};
use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_sampler::Method;
pub(crate) use lightvol_sampler::scene_setup::LoadedScene;
use lightvol_sampler::{
    scene_setup,
    scene_setup::{GridChoice, GridError, LightOverrides, SceneSource, SetupError},
};
use lightvol_scene::TransportSettings;
use lightvol_scene::{DVec3, LoadOptions, Sun, UpAxis};
use lightvol_volume::GridSpec;

/// Where the scene comes from and how to light it.
#[derive(Debug, Clone, Args)]
pub(crate) struct SceneArgs {
    /// A glTF (.gltf/.glb) or OBJ file, or `builtin:NAME` (city, interior, maze).
    pub(crate) scene: String,
    /// Up axis of the file: glTF is +Y up by specification; many scenes are +Z up. lightvol
    /// works +Z up internally.
    #[arg(long, value_parser = ["y", "z"], default_value = "y")]
    pub(crate) up: String,
    /// Uniform scale applied to file positions (e.g. 0.001 for millimetres).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) scale: f64,
    /// Sky radiance R,G,B over the upper hemisphere (replaces the scene's environment).
    #[arg(long, value_name = "R,G,B")]
    pub(crate) sky: Option<String>,
    /// Ground radiance R,G,B below the horizon (with --sky).
    #[arg(long, value_name = "R,G,B")]
    pub(crate) ground: Option<String>,
    /// A sun: direction towards it (in the scene file's frame), irradiance on a facing
    /// surface, optional angular radius in degrees (0 = directional light).
    #[arg(long, value_name = "DX,DY,DZ:INTENSITY[:ANGLE_DEG]", allow_hyphen_values = true)]
    pub(crate) sun: Option<String>,
    /// Remove the scene's sun (e.g. to bake sky and bounce light only and add the sun at run
    /// time, as many engines do).
    #[arg(long, conflicts_with = "sun")]
    pub(crate) no_sun: bool,
    /// A latitude-longitude EXR environment map (replaces the scene's environment).
    #[arg(long, value_name = "FILE.exr")]
    pub(crate) env: Option<PathBuf>,
}

/// The grid: bounds and resolution (or spacing), and the SH order.
#[derive(Debug, Clone, Args)]
pub(crate) struct GridArgs {
    /// Grid bounds `MINX,MINY,MINZ,MAXX,MAXY,MAXZ` in the scene file's frame (glTF: +Y up;
    /// OBJ: per --up) (default: the built-in scene's recommended grid, or the scene bounds
    /// grown by 5%).
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true)]
    pub(crate) bounds: Option<String>,
    /// Nodes per axis `NX,NY,NZ` along the scene file's axes (each at least 2).
    #[arg(long, value_name = "NX,NY,NZ", conflicts_with = "spacing", allow_hyphen_values = true)]
    pub(crate) res: Option<String>,
    /// Node spacing (sets the resolution from the bounds).
    #[arg(long)]
    pub(crate) spacing: Option<f64>,
    /// SH order: 2, 3 or 4 bands (4, 9 or 16 coefficients per channel).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(2..=4))]
    pub(crate) order: u32,
    /// Refuse bakes that would need more memory than this many MiB — the scene's geometry,
    /// ray tracer and textures, estimated before the scene is loaded, plus the grid's sums
    /// (default: half of the available memory).
    #[arg(long)]
    pub(crate) max_memory_mib: Option<u64>,
}

/// How far paths go and which light counts directly (bake, surface bake and the path-traced
/// references alike).
#[derive(Debug, Clone, Args)]
pub(crate) struct PathArgs {
    /// At most N diffuse bounces (0: the first surface's direct light only). Without it,
    /// paths are unbiased: 2 bounces, then Russian roulette.
    #[arg(long, value_name = "N")]
    bounces: Option<u32>,
    /// With --bounces N: continue after the N bounces under Russian roulette (unbiased)
    /// instead of stopping.
    #[arg(long, requires = "bounces")]
    russian_roulette: bool,
    /// Which light counts when it reaches a probe or surface directly: `all`, `sky+indirect`
    /// (not the sun nor punctual lights, which engines often add at run time) or `indirect`
    /// (only light that bounced). Applies to the bake and to the reference alike.
    #[arg(long, default_value = "all", value_parser = ["all", "sky+indirect", "indirect"])]
    pub(crate) light: String,
}

impl Default for PathArgs {
    /// Unbiased paths and all light: what no option gives.
    fn default() -> Self {
        Self { bounces: None, russian_roulette: false, light: "all".into() }
    }
}

impl PathArgs {
    /// The path settings (module docs of lightvol-scene's `transport`): unbiased by
    /// default, else at most N bounces.
    #[must_use]
    pub(crate) fn transport(&self) -> TransportSettings {
        let direct = lightvol_scene::transport::DirectLight::parse(&self.light).unwrap_or_default();
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
    pub(crate) fn is_default(&self) -> bool {
        self.bounces.is_none() && self.light == "all"
    }
}

/// Sampling options.
#[derive(Debug, Clone, Args)]
pub(crate) struct SampleArgs {
    /// Samples per cell (prefilter, doi-paper), per node (doi-node) or directions per node
    /// (point, doi).
    #[arg(long, value_parser = parse_samples, default_value_t = samples(256))]
    pub(crate) samples: Samples,
    /// Path length and direct light.
    #[command(flatten)]
    pub(crate) path: PathArgs,
    /// Seed of every random stream (results are bit-identical for a seed).
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub(crate) threads: Option<usize>,
    /// How prefilter/doi-paper node values come from their samples: `average` (Kontkanen & Laine
    /// Eq. 6) or `lsq[:LAMBDA]` (least squares over the domain of interest, regularised
    /// toward Eq. 6 with weight LAMBDA; see lightvol-sampler's `fit` module).
    #[arg(long, default_value = "average")]
    pub(crate) fit: lightvol_sampler::node_fit::Fit,
    /// Bake until converged: sample each node (cell for prefilter and doi-paper) in rounds
    /// growing from --samples (at least doubling) until the estimated relative error of its
    /// estimate is at most N (e.g. 0.01), or it has --max-samples. The error is estimated
    /// from how far the mean of the unit's first half and first quarter of samples lie from
    /// the mean of all of them. Each unit's count depends only on its own
    /// samples, so results stay bit-identical for any thread or shard count; the report
    /// says how many samples were spent and how many units stopped at the cap. Every `doi`
    /// bake reports how noisy its nodes came out (median, 90th percentile, worst), with or
    /// without it, to choose N from.
    #[arg(long, value_name = "N")]
    pub(crate) noise: Option<f64>,
    /// The most samples a unit gets under --noise.
    #[arg(long, value_parser = parse_samples, default_value_t = samples(lightvol_sampler::noise::DEFAULT_MAX_SAMPLES))]
    pub(crate) max_samples: Samples,
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
/// Parses `--scenario NAME=LIGHTS` (LIGHTS: `sky:R,G,B[:R,G,B]`, `env:FILE.exr`,
/// `sun:DX,DY,DZ:INTENSITY[:ANGLE_DEG]`, `no-sun`, separated by `;`).
pub(crate) fn parse_scenario(spec: &str) -> anyhow::Result<lightvol_sampler::scenarios::Scenario> {
    let (name, lights) =
        spec.split_once('=').with_context(|| format!("--scenario: '{spec}' is not NAME=LIGHTS"))?;
    let name = name.trim();
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || "-_".contains(c)) {
        bail!("--scenario: name '{name}' must be letters, digits, '-' or '_'");
    }
    let mut l = LightOverrides::default();
    for item in lights.split(';').map(str::trim).filter(|i| !i.is_empty()) {
        let (kind, value) = item.split_once(':').unwrap_or((item, ""));
        match kind {
            "sky" => {
                let (sky, ground) = match value.split_once(':') {
                    Some((s, g)) => {
                        (parse_rgb("--scenario sky", s)?, Some(parse_rgb("--scenario ground", g)?))
                    }
                    None => (parse_rgb("--scenario sky", value)?, None),
                };
                l.sky = Some((sky, ground));
            }
            "env" => l.environment_map = Some(PathBuf::from(value)),
            "sun" => l.sun = Some(parse_sun(value)?),
            "no-sun" if value.is_empty() => l.no_sun = true,
            _ => bail!("--scenario {name}: '{item}' is not sky:R,G,B[:R,G,B], env:FILE, sun:... or no-sun"),
        }
    }
    if l.sun.is_some() && l.no_sun {
        bail!("--scenario {name}: sun and no-sun together");
    }
    Ok(lightvol_sampler::scenarios::Scenario { name: name.to_owned(), lights: l })
}

fn parse_sun(s: &str) -> anyhow::Result<Sun> {
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
    pub(crate) fn load(&self) -> anyhow::Result<LoadedScene> {
        self.load_within(scene_setup::memory_limit(None))
    }

    /// [`load`](Self::load) with every placement of an instanced mesh written out as its
    /// own triangles and lightmap object (the surface bake and its renders).
    pub(crate) fn load_flattened(&self) -> anyhow::Result<LoadedScene> {
        let loaded = self.load_quiet_with(scene_setup::memory_limit(None), true)?;
        for w in &loaded.scene.report.warnings {
            eprintln!("warning: {w}");
        }
        Ok(loaded)
    }

    /// [`load`](Self::load), refusing a scene whose estimated memory
    /// (`lightvol_scene::estimate`: geometry, ray tracer, textures) exceeds `limit` bytes
    /// before its geometry is read.
    pub(crate) fn load_within(&self, limit: u128) -> anyhow::Result<LoadedScene> {
        let loaded = self.load_quiet_within(limit)?;
        for w in &loaded.scene.report.warnings {
            eprintln!("warning: {w}");
        }
        Ok(loaded)
    }

    /// As [`load`](Self::load), leaving the warnings in the scene's report only.
    pub(crate) fn load_quiet(&self) -> anyhow::Result<LoadedScene> {
        self.load_quiet_within(scene_setup::memory_limit(None))
    }

    fn load_quiet_within(&self, limit: u128) -> anyhow::Result<LoadedScene> {
        self.load_quiet_with(limit, false)
    }

    fn load_quiet_with(&self, limit: u128, flatten_instances: bool) -> anyhow::Result<LoadedScene> {
        let up = if self.up == "z" { UpAxis::Z } else { UpAxis::Y };
        let options = LoadOptions { up, scale: self.scale, flatten_instances, ..LoadOptions::default() };
        let sky = match (&self.sky, &self.ground) {
            (Some(sky), ground) => Some((
                parse_rgb("--sky", sky)?,
                ground.as_deref().map(|g| parse_rgb("--ground", g)).transpose()?,
            )),
            (None, Some(_)) => bail!("--ground needs --sky"),
            (None, None) => None,
        };
        let lights = LightOverrides {
            sky,
            environment_map: self.env.clone(),
            sun: self.sun.as_deref().map(parse_sun).transpose()?,
            no_sun: self.no_sun,
        };
        let loaded = scene_setup::load(&SceneSource::parse(&self.scene, options), limit, &lights).map_err(
            |e| match e {
                SetupError::BadScale => anyhow::anyhow!("--scale must be a positive finite number"),
                e @ SetupError::SceneTooLarge { .. } => anyhow::anyhow!("{e} (--max-memory-mib)"),
                e => e.into(),
            },
        )?;
        if loaded.defaulted_sky {
            eprintln!("note: the scene has no lights; using a uniform white sky (radiance 1)");
        }
        Ok(loaded)
    }
}

impl GridArgs {
    /// The bake's memory limit in bytes (scene, ray tracer and grid together).
    #[must_use]
    pub(crate) fn memory_limit(&self) -> u128 {
        scene_setup::memory_limit(self.max_memory_mib)
    }

    /// SH coefficients per channel.
    #[must_use]
    pub(crate) fn coeffs(&self) -> usize {
        (self.order * self.order) as usize
    }

    /// The grid from the options, the built-in recommendation, or the scene bounds; refuses
    /// invalid or oversized grids before anything is allocated (counting the node reach
    /// when the bake records one, `node_reach`).
    pub(crate) fn grid(&self, scene: &LoadedScene, node_reach: bool) -> anyhow::Result<GridSpec> {
        self.grid_split(scene, node_reach, 0)
    }

    /// [`Self::grid`] for a bake split into `light_groups` light groups (their memory
    /// counted).
    pub(crate) fn grid_split(
        &self,
        scene: &LoadedScene,
        node_reach: bool,
        light_groups: usize,
    ) -> anyhow::Result<GridSpec> {
        let bounds = match &self.bounds {
            Some(b) => {
                let v = parse_floats::<6>("--bounds", b)?;
                Some(([v[0], v[1], v[2]], [v[3], v[4], v[5]]))
            }
            None => None,
        };
        let res = self.res.as_deref().map(|r| parse_floats::<3>("--res", r)).transpose()?;
        let choice = GridChoice {
            bounds,
            res,
            spacing: self.spacing,
            coeffs: self.coeffs(),
            memory_limit: self.memory_limit(),
            node_reach,
            light_groups,
        };
        choice.resolve(scene).map_err(|e| match e {
            GridError::EmptyBounds { .. } => anyhow::anyhow!("--{e}"),
            GridError::BadResolution(_) => anyhow::anyhow!(
                "--res: each axis needs a whole number of at least 2 nodes, got {}",
                self.res.as_deref().unwrap_or_default()
            ),
            GridError::BadSpacing => anyhow::anyhow!("--spacing must be a positive finite number"),
            e @ GridError::TooLarge { .. } => anyhow::anyhow!("{e} (lower --res or raise --max-memory-mib)"),
            e => e.into(),
        })
    }
}

impl SampleArgs {
    /// The path settings ([`PathArgs::transport`]).
    #[must_use]
    pub(crate) fn transport(&self) -> TransportSettings {
        self.path.transport()
    }

    /// Refuses a sample count whose units would not fit in `limit` bytes on the threads
    /// the bake runs (the cap under `--noise`), in one line, before anything is loaded.
    pub(crate) fn check_memory(&self, limit: u128) -> anyhow::Result<()> {
        let most = if self.noise.is_some() { self.max_samples.max(self.samples) } else { self.samples };
        let threads = resolve_threads(self.threads)?.unwrap_or_else(rayon::current_num_threads);
        scene_setup::check_sample_memory(u64::from(most.get()), threads, scene_setup::SAMPLE_BYTES, limit)
            .map_err(|e| anyhow::anyhow!("{e} (lower --samples or raise --max-memory-mib)"))
    }

    /// The noise target of `--noise` and `--max-samples`, checked: a positive, finite
    /// error and a cap no lower than `--samples`.
    pub(crate) fn noise_target(&self) -> anyhow::Result<Option<lightvol_sampler::noise::NoiseTarget>> {
        let Some(relative_error) = self.noise else { return Ok(None) };
        if !(relative_error > 0.0 && relative_error.is_finite()) {
            bail!("--noise must be a relative error > 0, e.g. 0.01 (got {relative_error})");
        }
        if self.max_samples < self.samples {
            bail!("--max-samples {} is below --samples {}", self.max_samples, self.samples);
        }
        Ok(Some(lightvol_sampler::noise::NoiseTarget { relative_error, max_samples: self.max_samples }))
    }
}

/// The shard of `--shard K/N|auto` and `--shards N` (`auto`: from the scheduler's
/// environment, `lightvol_core::shard::resolve_shard`), or `None` without `--shard`.
pub(crate) fn shard_option(shard: Option<&str>, shards: Option<u32>) -> anyhow::Result<Option<(u32, u32)>> {
    let resolved = lightvol_core::shard::resolve_shard(shard, shards, |k| std::env::var(k).ok())?;
    Ok(shard.is_some().then_some(resolved))
}

/// Parses a method name.
pub(crate) fn parse_method(s: &str) -> anyhow::Result<Method> {
    Ok(lightvol_eval::entries::parse_method(s)?)
}

/// The worker threads to use: `threads` (`--threads`), else `SLURM_CPUS_PER_TASK` when the
/// scheduler sets it, else `None` (the global pool, all cores).
pub(crate) fn resolve_threads(threads: Option<usize>) -> anyhow::Result<Option<usize>> {
    match threads.or_else(|| lightvol_core::shard::threads_from_env(|k| std::env::var(k).ok())) {
        Some(0) => bail!("--threads must be at least 1"),
        t => Ok(t),
    }
}

/// Runs `f` on a rayon pool of [`resolve_threads`] threads, or on the global pool (all
/// cores).
pub(crate) fn with_threads<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> T + Send,
) -> anyhow::Result<T> {
    match resolve_threads(threads)? {
        None => Ok(f()),
        Some(n) => {
            let pool =
                rayon::ThreadPoolBuilder::new().num_threads(n).build().context("creating the thread pool")?;
            Ok(pool.install(f))
        }
    }
}
