//! Command-line definitions (clap derive).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// lightvol: precomputed volumetric lighting (irradiance volumes baked by domain-of-interest
/// sampling, Kontkanen & Laine 2006).
#[derive(Debug, Parser)]
#[command(name = "lightvol", version, about, long_about = None, propagate_version = true)]
pub(crate) struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub(crate) command: Command,
}

/// The verbs.
#[derive(Debug, Subcommand)]
pub(crate) enum Command {
    /// Measure ray, lookup and bake throughput (JSON).
    Bench(crate::cmd_bench::BenchArgs),
    /// Bake an irradiance volume from a glTF/OBJ scene or a built-in scene.
    Bake(crate::bake_args::BakeArgs),
    /// Bake coefficient maps for lightmapped, normal-mapped surfaces in a hemispherical basis
    /// (Ishmukhametov 2011 §2.2), with optional 8-bit / BC1 / BC7 textures.
    BakeSurface(crate::cmd_bake_surface::BakeSurfaceArgs),
    /// Bake every method at equal sample budget and measure leakage on a plate against a
    /// path-traced reference (Kontkanen & Laine 2006 Fig. 6).
    Compare(crate::cmd_compare::CompareArgs),
    /// The main job: compare the methods on the built-in city, interior and maze scenes,
    /// sweep the grid resolution, and write an index.html with every panel and metric.
    Demo(crate::cmd_demo::DemoArgs),
    /// Geometry diagnostics: reversed polygons and inconsistent winding (exit status 2 when
    /// suspects are found).
    Lint(crate::cmd_lint::LintArgs),
    /// Merge shard bakes (`bake --shard K/N`) into one volume; refuses mismatched grids.
    Merge(crate::cmd_merge::MergeArgs),
    /// Soft shadows and bounce light from a sphere-proxy character, compared with a
    /// path-traced reference (Sloan et al. 2007).
    Proxies(crate::cmd_proxies::ProxiesArgs),
    /// Render a view shaded by a baked volume (or path-traced with --reference): the
    /// "helicopter" view that shows leaking; with --surface DIR, lightmapped surfaces shaded
    /// from bake-surface's coefficient maps next to a path-traced reference.
    Render(crate::render_args::RenderArgs),
    /// List the Vulkan devices the GPU evaluator can use, and the one it selects.
    GpuInfo(crate::cmd_gpu::GpuInfoArgs),
    /// Reproduce the IMSE comparison of hemispherical bases (Ishmukhametov 2011, Table 3.1
    /// and Fig. 3.1).
    Imse(crate::cmd_imse::ImseArgs),
    /// Print a volume file's grid, conventions, bake metadata and zero-weight node count.
    Info(InfoArgs),
    /// Scale and sum the light groups of a volume baked with --light-groups: the volume of
    /// other light intensities and colours, without baking again.
    Relight(crate::cmd_relight::RelightArgs),
    /// The scene × method Markdown table of `compare` reports: relative RMSE, too dark
    /// near geometry, too bright, rays and seconds, each method's mean over the scenes and
    /// its ratio to the best engine baseline's mean.
    Table(crate::cmd_table::TableArgs),
    /// Describe what the loader understood of a scene file: triangles (unique and
    /// instanced), objects, materials with alpha mode and sidedness, extensions and their
    /// treatment, lights, cameras, bounds in the file's and the internal frame, warnings.
    Inspect(crate::cmd_inspect::InspectArgs),
    /// Repeat a glTF scene on a grid of tiles (instanced meshes, shared binary data): a
    /// large world to bake and stream from one room.
    Layout(crate::cmd_layout::LayoutArgs),
    /// A sharded bake as a Slurm job array plus a merge job that depends on it (afterok);
    /// --submit submits both, --wait waits for the merge and exits with its status.
    Slurm(crate::cmd_cluster::SlurmArgs),
    /// A sharded bake as a Kubernetes Indexed Job plus a merge Job (YAML files).
    K8s(crate::cmd_cluster::K8sArgs),
    /// Export a volume to an engine format (KTX2, DDS, Bevy irradiance volume, three.js,
    /// sparse bricks, JSON).
    Export(ExportArgs),
    /// Shader functions that sample a volume (world position to texel, trilinear, SH
    /// irradiance) in WGSL, HLSL or GLSL, for the KTX2 or the native layout.
    Shader(crate::cmd_shader::ShaderArgs),
}

/// `lightvol info`.
#[derive(Debug, Args)]
pub(crate) struct InfoArgs {
    /// The native EXR volume to describe.
    pub(crate) volume: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub(crate) json: bool,
}

/// Engine export formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum ExportFormat {
    /// KTX2 3D texture, RGBA16F, coefficient slabs along z, weight in alpha (+ JSON sidecar),
    /// in the scene file's frame.
    Ktx2,
    /// DDS volume texture, RGBA16F (+ JSON sidecar), in the scene file's frame.
    Dds,
    /// Bevy irradiance volume: ambient cube per voxel in Bevy's units (E/π), in the scene
    /// file's frame (KTX2, RGBA16F or --bevy-format rgb9e5, + JSON with the Transform and
    /// intensity to use).
    Bevy,
    /// three.js LightProbeGrid: its probe atlas as an RGBA16F 3D KTX2 that three's
    /// KTX2Loader reads, with the grid's resolution, position and size (+ JSON), in the scene
    /// file's frame; read as three reads it by `render --lookup three`.
    Three,
    /// The JSON sidecar alone (grid transform, SH convention, encoding, units).
    Json,
    /// Adaptive volumes: sparse bricks of probes behind an indirection texture, stored by
    /// stream cell (an RGBA16F KTX2 atlas, STEM.indirection.ktx2 and a JSON description
    /// with the map from the file's positions and normals).
    Bricks,
}

/// `lightvol export`.
#[derive(Debug, Args)]
pub(crate) struct ExportArgs {
    /// The native EXR volume to export.
    pub(crate) volume: PathBuf,
    /// Target format.
    #[arg(long, value_enum)]
    pub(crate) format: ExportFormat,
    /// Output file (a `.json` sidecar is written beside texture outputs).
    #[arg(short, long)]
    pub(crate) output: PathBuf,
    /// Adaptive volumes only: the uniform resolution `NX,NY,NZ` that KTX2, DDS and Bevy
    /// exports resample the octree to (default: the finest level's resolution, which
    /// reproduces every finest-level node exactly). The resolution used is printed.
    #[arg(long, value_name = "NX,NY,NZ")]
    pub(crate) res: Option<String>,
    /// Texel format of `--format bevy`: `rgba16f` (default) or `rgb9e5` (shared exponent,
    /// half the memory, as Bevy's example volume; negative values clamp to 0).
    #[arg(long, value_enum, default_value = "rgba16f")]
    pub(crate) bevy_format: BevyFormatArg,
    /// `--format bricks`: cells per brick and axis (2 to 8; a brick stores one more probe
    /// per axis).
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub(crate) brick_cells: u32,
    /// `--format bricks`: the most memory the bricks' probes may take, in MiB; sibling
    /// bricks are merged into their parent, least useful first, until they fit, and the
    /// export says what was dropped.
    #[arg(long, value_name = "MIB")]
    pub(crate) max_probe_memory: Option<f64>,
}

/// `--bevy-format`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum BevyFormatArg {
    /// RGBA16F.
    Rgba16f,
    /// RGB9E5 (E5B9G9R9_UFLOAT_PACK32).
    Rgb9e5,
}
