//! The options of `lightvol bake` (its octree options among them) and the validated
//! lightvol-sampler `BakeRequest` they give, with the request's errors in the options' words.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_sampler::adaptive::{AdaptiveSettings, node_budget_bytes};
use lightvol_sampler::method::BakeMethod;
use lightvol_sampler::request::{AdaptiveRequest, BakeRequest, Conflict, GradientChoice, RequestError};
use lightvol_sampler::target::TargetSettings;
use lightvol_volume::up_axis::UpAxis;
use lightvol_volume::{OctreeRegion, RegionKind};

use crate::gradient_args::GradientEstimatorArg;
use crate::setup::{GridArgs, SampleArgs, SceneArgs, shard_option};

/// `lightvol bake`.
#[derive(Debug, Args)]
pub(crate) struct BakeArgs {
    /// Scene and lights.
    #[command(flatten)]
    pub(crate) scene: SceneArgs,
    /// Grid.
    #[command(flatten)]
    pub(crate) grid: GridArgs,
    /// Sampling.
    #[command(flatten)]
    pub(crate) sampling: SampleArgs,
    /// Sampling method: `doi` (default: each node point-sampled where it is in the domain of
    /// interest, at a point relocated through its closest back face where it is not, filled
    /// from its neighbours where neither is, and a node reach in the file so that lookups
    /// leave out nodes on the far side of a thin wall), `doi-paper` (Kontkanen & Laine 2006: Eq. 5-6
    /// restricted to the domain of interest, Algorithm 2), `doi-node` (Algorithm 2 over each node's own cell),
    /// `point` (Eq. 4 at each node), `prefilter` (Eq. 5-6, no domain test); or point
    /// sampling with an engine's leak fix: `point+validity` (invalid probes dilated),
    /// `point+apv` (Unity APV: virtual offset, dilation, and a validity mask in the file for
    /// validity-weighted lookups), `point+vlm` (Unreal) or `point+ddgi` (DDGI relocation).
    #[arg(long, default_value = "doi")]
    /// Method name.
    pub(crate) method: String,
    /// Bake only shard K of N (by cells, or nodes for point sampling), or `auto`: the shard
    /// from the job scheduler (Slurm array variables, Kubernetes `JOB_COMPLETION_INDEX` or
    /// AWS Batch `AWS_BATCH_JOB_ARRAY_INDEX` with --shards, or `LIGHTVOL_SHARD=K/N`). The
    /// shard's exact sums are written beside the output as `<stem>.lvacc`; `lightvol merge`
    /// combines shards into the volume the whole bake gives, bit for bit.
    #[arg(long, value_name = "K/N|auto")]
    pub(crate) shard: Option<String>,
    /// Number of shards, for `--shard auto` with Kubernetes or AWS Batch indices (checked
    /// against the Slurm array or `LIGHTVOL_SHARD` where those give it).
    #[arg(long, value_name = "N")]
    pub(crate) shards: Option<u32>,
    /// Bake in pieces (--checkpoint-pieces) and save the exact sums to this directory after
    /// each one, so that a bake that is killed can be finished with --resume: the resumed
    /// bake traces only the pieces not yet done and writes the same bytes as an
    /// uninterrupted bake. The directory's checkpoint files are removed when the bake is
    /// done. Uniform bakes, not combined with --shard.
    #[arg(long, value_name = "DIR")]
    pub(crate) checkpoint: Option<PathBuf>,
    /// Finish the bake checkpointed in --checkpoint DIR (the same scene, grid and settings).
    #[arg(long, requires = "checkpoint")]
    pub(crate) resume: bool,
    /// Pieces of a checkpointed bake: a kill loses at most one piece's work.
    #[arg(long, value_name = "N", requires = "checkpoint", default_value_t = lightvol_sampler::checkpoint::DEFAULT_PIECES)]
    pub(crate) checkpoint_pieces: u32,
    /// Also write the exact accumulator (`<stem>.lvacc`) of an unsharded bake: its Eq. 6
    /// sums as `merge` reads them (for example to finalize it again with `merge`).
    #[arg(long)]
    pub(crate) keep_accumulator: bool,
    /// Also bake per-node SH irradiance gradients (Oat 2005) and store them in the EXR:
    /// `basis` (from the bake's own samples, no extra rays; prefilter/doi-paper) or
    /// `central` (six extra point projections per node at 1/16 cell). Without a value, the
    /// method's own: `basis` for prefilter and doi-paper, `central` for the others.
    #[arg(long, value_enum, value_name = "ESTIMATOR", num_args = 0..=1)]
    pub(crate) gradients: Option<Option<GradientEstimatorArg>>,
    /// Choose the node values for this engine's lookup: `three` (three.js
    /// LightProbeGrid), `bevy` (Bevy's irradiance volume), `apv` (Unity APV's lookup; the
    /// file gets a validity mask), `trilinear` (any engine that filters the texture
    /// trilinearly, Godot) or `lightvol` (lightvol's own lookup and shaders). After the bake,
    /// the `doi` bake's noisy nodes are smoothed (--target-smoothing) and, for an engine,
    /// a least-squares fit makes the engine's reconstruction match lightvol's own reading
    /// of the bake over points near surfaces and in free space in the domain of interest,
    /// held to the baked values by --target-lambda (12 extra rays per node find the points;
    /// no light path is traced; `lightvol` fits nothing and traces no extra ray). Without
    /// --target the bake's values are written as sampled. The file records the target, and
    /// `export` warns when it writes the volume for another engine. Uniform bakes only. With
    /// --checkpoint any target runs on the finished bake; shards (and --keep-accumulator)
    /// take `lightvol` only: they carry their nodes' error estimates and `merge` smooths the
    /// merged set, while an engine's fit traces rays in the scene, which a merge has not.
    #[arg(long, value_name = "ENGINE")]
    pub(crate) target: Option<lightvol_volume::EngineLookup>,
    /// The --target fit's weight toward the baked values (0: a pure least-squares fit).
    /// Default: 0.1 for three and apv (they read the grid away from the shading point, so
    /// the fit needs room to move the values), 0.15 for bevy and trilinear.
    #[arg(long, value_name = "LAMBDA", requires = "target")]
    pub(crate) target_lambda: Option<f64>,
    /// With --target, smooth the `doi` bake's node values where their own samples say
    /// they are noisy (before the fit, if any): TAU is the relative difference between neighbouring nodes'
    /// light the smoothing expects (smaller smooths more); `off`: no smoothing.
    #[arg(long, value_name = "TAU|off", requires = "target", default_value_t = lightvol_sampler::denoise::DEFAULT_SMOOTHING.to_string())]
    pub(crate) target_smoothing: String,
    /// Split the bake by light group, from the same paths (no extra rays): the file keeps
    /// the whole bake and one volume per group, and scaling and summing the groups (`lightvol
    /// relight`) gives the volume of any brightness and colour per group. `each` gives every
    /// light a group of its own; `NAME=PATTERN,PATTERN;NAME=...` names groups of lights,
    /// where the lights are `sky`, `sun`, each emissive material and each glTF punctual
    /// light by name (`lightvol inspect` lists them) and `*` matches any run of characters.
    /// Lights no pattern names form the group `other`. Uniform bakes with the average fit.
    #[arg(long, value_name = "each|NAME=PATTERN,...;...")]
    pub(crate) light_groups: Option<String>,
    /// Also store each node's transfer from the sky's SH radiance of this order (2: 4
    /// coefficients, 3: 9, 4: 16) to its own coefficients, every bounce included (a precomputed
    /// radiance transfer volume, Sloan, Kautz & Snyder 2002), from the same paths: `lightvol
    /// relight --sky R,G,B[:R,G,B] | --env FILE.exr` then relights the volume with any sky
    /// without baking again, exactly for skies of that order and to the sky's band limit
    /// otherwise. Stored as light groups `sky.sh00`, … after those of --light-groups (which
    /// then must not name the sky; without it, the other lights form the group `other`).
    #[arg(long, value_name = "ORDER", value_parser = clap::value_parser!(u32).range(2..=4))]
    pub(crate) sky_transfer: Option<u32>,
    /// A lighting scenario, `NAME=LIGHTS` (give two or more): the bake is repeated under
    /// each one's lights, over the scene's own and the options', into one file whose whole
    /// bake is the first scenario's; `lightvol relight --blend NAME=W;NAME=W` blends them.
    /// LIGHTS is `;`-separated: `sky:R,G,B[:R,G,B]` (sky and ground), `env:FILE.exr`,
    /// `sun:DX,DY,DZ:INTENSITY[:ANGLE_DEG]` (as --sun), `no-sun`; for example
    /// `--scenario noon=sun:0.3,1,0.2:6 --scenario "dusk=sun:1,0.08,0:2;sky:0.3,0.25,0.4"`.
    #[arg(long, value_name = "NAME=LIGHTS")]
    pub(crate) scenario: Vec<String>,
    /// Adaptive octree (Oat 2005, "Adaptive Octree Subdivision").
    #[command(flatten)]
    pub(crate) adaptive: AdaptiveArgs,
    /// Output volume (native multi-part EXR).
    #[arg(short, long, default_value = "volume.exr")]
    pub(crate) output: PathBuf,
    /// Print the bake statistics as JSON on stdout.
    #[arg(long)]
    pub(crate) json: bool,
    /// No progress bar.
    #[arg(long)]
    pub(crate) quiet: bool,
}

/// Options of `bake --adaptive` (each heuristic with its threshold, Oat 2005, "Subdivision
/// Heuristics"). Defaults are lightvol-sampler's `AdaptiveSettings::default()`; giving any
/// of them without `--adaptive` is an error.
#[derive(Debug, Clone, Args)]
pub(crate) struct AdaptiveArgs {
    /// Bake an adaptive octree volume: the grid options give level 0, cells split by the
    /// heuristics below down to --max-level, redundant nodes are culled.
    #[arg(long)]
    pub(crate) adaptive: bool,
    /// Every cell of the levels below this one is split (nodes of levels up to it are never
    /// culled). Default 0.
    #[arg(long, value_name = "L")]
    min_level: Option<u32>,
    /// The finest level (level l has cells 2^l times smaller than the grid's); at most 8.
    /// Default 2.
    #[arg(long, value_name = "L")]
    pub(crate) max_level: Option<u32>,
    /// Split a cell when the largest coefficient change along its edges, relative to the
    /// volume's mean DC value, is at least T (`off` disables the heuristic). Default 0.25.
    #[arg(long, value_name = "T|off", allow_hyphen_values = true)]
    gradient_threshold: Option<String>,
    /// Do not split cells because scene geometry lies inside them.
    #[arg(long)]
    no_geometry_split: bool,
    /// Split a cell when its edge exceeds R times the harmonic-mean scene depth at a corner
    /// (`off` disables the heuristic). Default 1.
    #[arg(long, value_name = "R|off", allow_hyphen_values = true)]
    depth_ratio: Option<String>,
    /// Rays per node for the harmonic-mean depth. Default 32.
    #[arg(long, value_name = "N")]
    depth_rays: Option<u32>,
    /// Cull a node whose difference from the coarser levels' interpolation is within this
    /// fraction of the volume's mean DC value. Default 0.01.
    #[arg(long, value_name = "TOL", allow_hyphen_values = true)]
    cull_tolerance: Option<f64>,
    /// Memory budget, stated as the node count of a uniform grid of the same memory: the
    /// octree's bytes (coefficients, base weights, 8-byte keys, split bitmaps) stay within
    /// N × (3·coeffs + 1) × 4 bytes, the bytes of N uniform nodes with their weights.
    #[arg(long, value_name = "N")]
    node_budget: Option<u64>,
    /// A density volume `X0,Y0,Z0,X1,Y1,Z1[:LEVEL]` (a box in the scene file's frame):
    /// cells that overlap it are split down to LEVEL (default --max-level) and keep their
    /// nodes. Repeatable.
    #[arg(long, value_name = "BOX[:LEVEL]", allow_hyphen_values = true)]
    density: Vec<String>,
    /// An exclusion volume `X0,Y0,Z0,X1,Y1,Z1`: cells inside it are not split. Repeatable.
    #[arg(long, value_name = "BOX", allow_hyphen_values = true)]
    exclude: Vec<String>,
    /// Where the player can go, `X0,Y0,Z0,X1,Y1,Z1`: with one or more, only cells that
    /// overlap one are split (density volumes still apply). Repeatable.
    #[arg(long, value_name = "BOX", allow_hyphen_values = true)]
    walkable: Vec<String>,
    /// A density volume from the scene: the bounds of every placement of the instanced mesh
    /// NAME and of every triangle of the material NAME, split down to LEVEL (default
    /// --max-level). Repeatable.
    #[arg(long, value_name = "NAME[:LEVEL]")]
    density_mesh: Vec<String>,
    /// An exclusion volume from the scene's mesh or material NAME (its bounds, as
    /// --density-mesh). Repeatable.
    #[arg(long, value_name = "NAME")]
    exclude_mesh: Vec<String>,
    /// Where the player can go, from the scene: the mesh or material NAME (a floor), each
    /// triangle's bounds raised by --walkable-height. Repeatable.
    #[arg(long, value_name = "NAME")]
    walkable_mesh: Vec<String>,
    /// The height above a --walkable-mesh that the player occupies, in the scene's units.
    #[arg(long, value_name = "H", default_value_t = 2.0)]
    walkable_height: f64,
    /// With --shard: bake shard K/N of refinement level L (1..=--max-level) from the
    /// complete shard sets of the levels below (--from-shards), writing `<stem>.lvref`.
    /// Without --level, --shard bakes level 0 (the base grid) and writes `<stem>.lvacc`.
    #[arg(long, value_name = "L")]
    pub(crate) level: Option<u32>,
    /// Shard files of a level-by-level adaptive bake: the level-0 `.lvacc` set and the
    /// `.lvref` sets of levels 1, 2, … (each complete). With --shard and --level, the levels
    /// below L; without --shard, every level: the shards are assembled into the volume the
    /// whole bake gives, byte for byte.
    #[arg(long, value_name = "FILE", num_args = 1..)]
    pub(crate) from_shards: Vec<PathBuf>,
}

fn threshold(name: &str, s: Option<&str>, default: Option<f64>) -> anyhow::Result<Option<f64>> {
    let Some(s) = s else { return Ok(default) };
    if s.trim() == "off" {
        return Ok(None);
    }
    let t: f64 = s.trim().parse().with_context(|| format!("{name}: '{s}' is not a number or 'off'"))?;
    if !(t.is_finite() && t > 0.0) {
        bail!("{name} must be a positive finite number or 'off', got {s}");
    }
    Ok(Some(t))
}

impl AdaptiveArgs {
    /// The options given without `--adaptive`, if any.
    #[must_use]
    pub(crate) fn stray_options(&self) -> Vec<&'static str> {
        let given = [
            ("--min-level", self.min_level.is_some()),
            ("--max-level", self.max_level.is_some()),
            ("--gradient-threshold", self.gradient_threshold.is_some()),
            ("--no-geometry-split", self.no_geometry_split),
            ("--depth-ratio", self.depth_ratio.is_some()),
            ("--depth-rays", self.depth_rays.is_some()),
            ("--cull-tolerance", self.cull_tolerance.is_some()),
            ("--node-budget", self.node_budget.is_some()),
            ("--level", self.level.is_some()),
            ("--density", !self.density.is_empty()),
            ("--exclude", !self.exclude.is_empty()),
            ("--walkable", !self.walkable.is_empty()),
            ("--density-mesh", !self.density_mesh.is_empty()),
            ("--exclude-mesh", !self.exclude_mesh.is_empty()),
            ("--walkable-mesh", !self.walkable_mesh.is_empty()),
            ("--from-shards", !self.from_shards.is_empty()),
        ];
        if self.adaptive { Vec::new() } else { given.iter().filter(|g| g.1).map(|g| g.0).collect() }
    }

    /// The sampler's settings, validated (one clear error each).
    pub(crate) fn settings(&self, coeffs: usize) -> anyhow::Result<AdaptiveSettings> {
        let d = AdaptiveSettings::default();
        let cull_tolerance = self.cull_tolerance.unwrap_or(d.cull_tolerance);
        if !(cull_tolerance.is_finite() && cull_tolerance >= 0.0) {
            bail!("--cull-tolerance must be finite and >= 0, got {cull_tolerance}");
        }
        let max = lightvol_volume::adaptive::MAX_LEVEL;
        let (min_level, max_level) =
            (self.min_level.unwrap_or(d.min_level), self.max_level.unwrap_or(d.max_level));
        if max_level > max || min_level > max_level {
            bail!("--min-level {min_level} and --max-level {max_level} need min <= max <= {max}");
        }
        let memory_budget = match self.node_budget {
            None => None,
            Some(0) => bail!("--node-budget must be at least 1"),
            Some(n) => Some(
                usize::try_from(node_budget_bytes(n, coeffs))
                    .map_err(|_| anyhow::anyhow!("--node-budget {n} is too large"))?,
            ),
        };
        let depth_ratio_threshold =
            threshold("--depth-ratio", self.depth_ratio.as_deref(), d.depth_ratio_threshold)?;
        let depth_rays = self.depth_rays.unwrap_or(d.depth_rays);
        if depth_ratio_threshold.is_some() && depth_rays == 0 {
            bail!("--depth-rays must be at least 1 with the depth heuristic on");
        }
        let s = AdaptiveSettings {
            min_level,
            max_level,
            gradient_threshold: threshold(
                "--gradient-threshold",
                self.gradient_threshold.as_deref(),
                d.gradient_threshold,
            )?,
            geometry: !self.no_geometry_split,
            depth_ratio_threshold,
            depth_rays,
            cull_tolerance,
            memory_budget,
            regions: Vec::new(),
        };
        s.validate().map_err(|e| anyhow::anyhow!("{e}"))?;
        // Checked now (before the scene loads), placed in the file's frame once it has.
        self.regions(max_level, UpAxis::INTERNAL)?;
        Ok(s)
    }

    /// The placement boxes named by mesh or material (`--density-mesh`, `--exclude-mesh`,
    /// `--walkable-mesh`), from the loaded scene (internal frame).
    pub(crate) fn mesh_regions(
        &self,
        scene: &lightvol_scene::Scene,
        max_level: u32,
    ) -> anyhow::Result<Vec<OctreeRegion>> {
        if !(self.walkable_height.is_finite() && self.walkable_height >= 0.0) {
            bail!("--walkable-height must be finite and >= 0, got {}", self.walkable_height);
        }
        let mut out = Vec::new();
        let mut add = |flag: &str, name: &str, kind: RegionKind| -> anyhow::Result<()> {
            let r = lightvol_sampler::adaptive_regions::mesh_regions(scene, name, kind, self.walkable_height)
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "{flag}: the scene has no instanced mesh or material named '{name}' (lightvol inspect lists the materials)"
                    )
                })?;
            out.extend(r);
            Ok(())
        };
        for d in &self.density_mesh {
            let (name, level) = match d.rsplit_once(':') {
                Some((n, l)) if l.trim().parse::<u32>().is_ok() => {
                    let l: u32 = l.trim().parse()?;
                    if l == 0 || l > max_level {
                        bail!("--density-mesh: level {l} must be between 1 and --max-level {max_level}");
                    }
                    (n, l)
                }
                _ => (d.as_str(), max_level),
            };
            add("--density-mesh", name, RegionKind::Density(level))?;
        }
        for n in &self.exclude_mesh {
            add("--exclude-mesh", n, RegionKind::Exclude)?;
        }
        for n in &self.walkable_mesh {
            add("--walkable-mesh", n, RegionKind::Walkable)?;
        }
        Ok(out)
    }

    /// The placement boxes (`--density`, `--exclude`, `--walkable`), given in the frame
    /// `up` of the scene file, in lightvol's internal frame.
    pub(crate) fn regions(&self, max_level: u32, up: UpAxis) -> anyhow::Result<Vec<OctreeRegion>> {
        let mut out = Vec::new();
        let parse_box = |name: &str, s: &str| -> anyhow::Result<([f64; 3], [f64; 3])> {
            let v: Vec<f64> = s
                .split(',')
                .map(|t| t.trim().parse::<f64>().with_context(|| format!("{name}: '{t}' is not a number")))
                .collect::<anyhow::Result<_>>()?;
            let [x0, y0, z0, x1, y1, z1] = v[..] else {
                bail!("{name}: expected X0,Y0,Z0,X1,Y1,Z1 (six numbers), got '{s}'")
            };
            let (lo, hi) = ([x0, y0, z0], [x1, y1, z1]);
            if lo.iter().chain(&hi).any(|x| !x.is_finite()) || (0..3).any(|a| lo[a] >= hi[a]) {
                bail!("{name}: '{s}' is not a box (finite, each minimum below its maximum)");
            }
            Ok(up.box_to_world(lo, hi))
        };
        for d in &self.density {
            let (b, level) = match d.split_once(':') {
                Some((b, l)) => {
                    let l: u32 = l
                        .trim()
                        .parse()
                        .with_context(|| format!("--density: level '{l}' is not a whole number"))?;
                    if l == 0 || l > max_level {
                        bail!("--density: level {l} must be between 1 and --max-level {max_level}");
                    }
                    (b, l)
                }
                None => (d.as_str(), max_level),
            };
            let (min, max) = parse_box("--density", b)?;
            out.push(OctreeRegion { kind: RegionKind::Density(level), min, max });
        }
        for (name, list, kind) in [
            ("--exclude", &self.exclude, RegionKind::Exclude),
            ("--walkable", &self.walkable, RegionKind::Walkable),
        ] {
            for b in list {
                let (min, max) = parse_box(name, b)?;
                out.push(OctreeRegion { kind, min, max });
            }
        }
        Ok(out)
    }
}

/// The bake request of the options (the shard resolved from `--shard`, `--shards` and the
/// scheduler's environment), validated.
pub(crate) fn request(args: &BakeArgs, adaptive: Option<AdaptiveRequest>) -> anyhow::Result<BakeRequest> {
    let shard = shard_option(args.shard.as_deref(), args.shards)?;
    request_for_shard(args, adaptive, shard)
}

/// [`request`] for shard `shard` of the bake (`None`: the whole), whatever `--shard` says:
/// the cluster verbs check what their jobs' shards will refuse.
pub(crate) fn request_for_shard(
    args: &BakeArgs,
    adaptive: Option<AdaptiveRequest>,
    shard: Option<(u32, u32)>,
) -> anyhow::Result<BakeRequest> {
    let request = BakeRequest {
        method: args.method.parse::<BakeMethod>().map_err(anyhow::Error::msg)?,
        samples: args.sampling.samples,
        coeffs: args.grid.coeffs(),
        seed: args.sampling.seed,
        transport: args.sampling.transport(),
        fit: args.sampling.fit,
        gradients: args
            .gradients
            .map(|g| g.map_or(GradientChoice::MethodDefault, |e| GradientChoice::Estimator(e.into()))),
        shard,
        keep_accumulator: args.keep_accumulator,
        adaptive,
        noise: args.sampling.noise_target()?,
        light_groups: args.light_groups.is_some() || args.sky_transfer.is_some(),
        scenarios: !args.scenario.is_empty(),
        target: match args.target {
            Some(lookup) => Some(TargetSettings {
                lambda: args
                    .target_lambda
                    .unwrap_or_else(|| lightvol_sampler::target::default_target_lambda(lookup)),
                smoothing: threshold("--target-smoothing", Some(&args.target_smoothing), None)?,
                ..TargetSettings::new(lookup, args.sampling.seed)
            }),
            None => None,
        },
    };
    if let Some(lambda) = args.target_lambda.filter(|l| !(*l >= 0.0 && l.is_finite())) {
        bail!("--target-lambda must be a number >= 0 (got {lambda})");
    }
    request.validate().map_err(request_error)?;
    Ok(request)
}

/// A refused request, in the options' words.
fn request_error(e: RequestError) -> anyhow::Error {
    let option = |c: Conflict| match c {
        Conflict::Adaptive => "--adaptive".to_owned(),
        Conflict::Shard => "--shard".to_owned(),
        Conflict::KeepAccumulator => "--keep-accumulator".to_owned(),
        Conflict::Gradients => "--gradients".to_owned(),
        Conflict::Fit(fit) => format!("--fit {fit}"),
    };
    match e {
        RequestError::Baseline { baseline, with } => anyhow::anyhow!(
            "{} cannot be combined with --method {} (the engine baselines bake a whole uniform grid)",
            option(with),
            baseline.name()
        ),
        RequestError::Adaptive(c @ Conflict::KeepAccumulator) => anyhow::anyhow!(
            "--adaptive cannot be combined with {} (shard an octree bake with --shard and --level)",
            option(c)
        ),
        RequestError::Adaptive(c @ Conflict::Gradients) => {
            anyhow::anyhow!(
                "--adaptive cannot be combined with {} (the octree stores no gradients)",
                option(c)
            )
        }
        RequestError::Adaptive(c) => {
            anyhow::anyhow!(
                "--adaptive cannot be combined with {} (the octree levels use Eq. 6's average)",
                option(c)
            )
        }
        RequestError::LevelNeedsShard => anyhow::anyhow!("--level needs --shard K/N (or --shard auto)"),
        RequestError::BaseLevelFromShards => anyhow::anyhow!(
            "level 0 is baked from the scene alone: drop --from-shards, or bake a level >= 1 with --level L"
        ),
        RequestError::LevelNeedsShards(l) => {
            anyhow::anyhow!("--level {l} needs the shard files of levels 0..{l} (--from-shards)")
        }
        RequestError::FitNeedsCells { fit, method } => anyhow::anyhow!(
            "--fit {fit} needs cell samples (--method prefilter or doi-paper); {} samples per node",
            method.name()
        ),
        RequestError::FitWithGradients(fit) => anyhow::anyhow!(
            "--fit {fit} cannot be combined with --gradients (the gradient estimators assume --fit average)"
        ),
        e @ (RequestError::NotUniform(_)
        | RequestError::Target(_)
        | RequestError::Noise(_)
        | RequestError::LightGroups(_)
        | RequestError::Scenarios(_)
        | RequestError::NoLightGroups) => e.into(),
        RequestError::BasisNeedsCells(_) => anyhow::anyhow!(
            "--gradients basis needs cell samples (--method prefilter or doi-paper); use --gradients central with point, doi or doi-node"
        ),
    }
}
