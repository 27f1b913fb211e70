//! `lightvol bench`: measured throughput as JSON, each figure beside its baseline from the
//! same run: closest-hit rays per second (1 thread and all threads), volume lookups per
//! second (scalar and batched, coherent and random order), and the cost of doi against
//! point sampling at equal samples on a built-in scene.

use lightvol_core::samples::{Samples, parse_samples, samples};
use std::hint::black_box;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use lightvol_core::progress::BakeControl;
use lightvol_sampler::{BakeSettings, Method};
use lightvol_scene::builtin::builtin;
use lightvol_scene::{DVec3, Tracer, Transport, TransportSettings};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::{GridSpec, IrradianceVolume};
use serde_json::json;

/// `lightvol bench`.
#[derive(Debug, Args)]
pub(crate) struct BenchArgs {
    /// Built-in scene for the ray and bake figures.
    #[arg(long, default_value = "city")]
    pub(crate) scene: String,
    /// Rays per throughput measurement.
    #[arg(long, default_value_t = 1_000_000)]
    pub(crate) rays: usize,
    /// Lookups per throughput measurement.
    #[arg(long, default_value_t = 2_000_000)]
    pub(crate) lookups: usize,
    /// Samples per cell/node for the doi vs point bakes.
    #[arg(long, value_parser = parse_samples, default_value_t = samples(64))]
    pub(crate) samples: Samples,
    /// Also measure the Vulkan evaluator (volume lookups and proxy frame passes; needs a
    /// Vulkan device, see `lightvol gpu-info`).
    #[arg(long)]
    pub(crate) gpu: bool,
    /// Instead: lightvol's tracer against Embree 3 on the same triangles and rays (closest
    /// hit and occlusion, 1 and 2 threads, with ray-by-ray agreement). `--scene` may then
    /// also be a glTF/OBJ file (+Y up). Needs Debian's `libembree-dev` and a C compiler.
    #[arg(long)]
    embree: bool,
    /// Instead: bake wall time and peak memory (each bake its own process) for the vendored
    /// scenes under `--data`, grid layouts of the occlusion room up to 32 x 32 rooms (65 M
    /// placed triangles, 63,720 stored) and the built-in scenes.
    #[arg(long, conflicts_with = "embree")]
    bakes: bool,
    /// Instead: the wall time of a whole bake as users run it (the Breakfast Room under
    /// `--data` at 0.2 m spacing and 256 samples, the default method), `--bake-runs` times,
    /// each run its own process, timed from outside; with `--vs` beside another lightvol
    /// executable's.
    #[arg(long, conflicts_with_all = ["embree", "bakes"])]
    whole_bake: bool,
    /// With --whole-bake: another lightvol executable (an earlier build) that bakes the
    /// same scene alternately with this one; reports both medians, the speed-up and
    /// whether both wrote the same bytes.
    #[arg(long, requires = "whole_bake")]
    vs: Option<std::path::PathBuf>,
    /// With --whole-bake: runs of each executable.
    #[arg(long, default_value_t = 3)]
    bake_runs: u32,
    /// With --bakes or --whole-bake: the folder holding the vendored scenes.
    #[arg(long, default_value = "data/scenes")]
    pub(crate) data: std::path::PathBuf,
    /// With --bakes: samples per cell of each doi bake.
    #[arg(long, value_parser = parse_samples, default_value_t = samples(16))]
    bake_samples: Samples,
    /// With --embree: how lightvol traces an instanced scene: `auto` (one level up to 2^20
    /// placed triangles), `one` (instances written out), `two` (a BVH per mesh under a
    /// top-level BVH). Embree always gets the triangles written out.
    #[arg(long, default_value = "auto", value_parser = ["auto", "one", "two"])]
    pub(crate) levels: String,
    /// With --embree: lightvol's BVH build quality (`fast`, `medium`, `slow`: spatial splits).
    #[arg(long, default_value = "medium", value_parser = ["fast", "medium", "slow"])]
    bvh_quality: String,
}

fn rays_per_second(tracer: &Tracer, origins: &[(DVec3, DVec3)], pool: &rayon::ThreadPool) -> f64 {
    use rayon::prelude::*;
    let t0 = Instant::now();
    let hits: usize = pool.install(|| {
        origins
            .par_chunks(4096)
            .map(|c| {
                c.iter().filter(|(o, d)| tracer.closest_hit(*o, *d, 0.0, f64::INFINITY).is_some()).count()
            })
            .sum()
    });
    black_box(hits);
    origins.len() as f64 / t0.elapsed().as_secs_f64()
}

fn pool(threads: usize) -> anyhow::Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("thread pool")
}

/// A 64³ volume with 9 smooth random coefficients per channel (the lookup figure does not
/// depend on the values).
fn lookup_volume() -> anyhow::Result<IrradianceVolume> {
    let spec = GridSpec::new([0.0; 3], [1.0; 3], [64, 64, 64])?;
    Ok(IrradianceVolume::from_fn(spec, 9, |p| {
        (0..9).map(|j| [p[0] + j as f64 * 0.1, p[1], p[2] * 0.5 + 0.2]).collect()
    })?)
}

fn lookups_per_second(
    vol: &IrradianceVolume,
    pts: &[[f32; 3]],
    nrm: &[[f32; 3]],
    batched: bool,
    pool: &rayon::ThreadPool,
) -> anyhow::Result<f64> {
    let mut out = vec![[0.0f32; 3]; pts.len()];
    let t0 = Instant::now();
    if batched {
        pool.install(|| vol.irradiance_batch(pts, nrm, &mut out))?;
    } else {
        for (o, (p, n)) in out.iter_mut().zip(pts.iter().zip(nrm)) {
            *o = vol.irradiance(*p, *n);
        }
    }
    black_box(&out);
    Ok(pts.len() as f64 / t0.elapsed().as_secs_f64())
}

/// The most rays or lookups one measurement takes: 2^26 (67,108,864; the rays alone are
/// 3 GiB as f64 origins and directions). More is refused in one line, not allocated.
const MAX_PER_MEASUREMENT: usize = 1 << 26;

/// Runs `lightvol bench`.
pub(crate) fn run(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    for (flag, n) in [("--rays", args.rays), ("--lookups", args.lookups)] {
        if n == 0 || n > MAX_PER_MEASUREMENT {
            anyhow::bail!("{flag} must be between 1 and {MAX_PER_MEASUREMENT}, got {n}");
        }
    }
    if args.bakes {
        let report = crate::bench_scale::run(&args.data, args.bake_samples.get())?;
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    if args.whole_bake {
        let report = crate::bench_scale::whole_bake(&args.data, args.vs.as_deref(), args.bake_runs)?;
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    if args.embree {
        let scene = match builtin(args.scene.trim_start_matches("builtin:")) {
            Some(b) => b.scene,
            None => {
                let path = std::path::Path::new(&args.scene);
                lightvol_scene::load_scene(path, &lightvol_scene::LoadOptions::default())
                    .with_context(|| format!("loading {} (not a built-in scene either)", path.display()))?
            }
        };
        let quality = match args.bvh_quality.as_str() {
            "fast" => lightvol_scene::BuildQuality::Fast,
            "slow" => lightvol_scene::BuildQuality::Slow,
            _ => lightvol_scene::BuildQuality::Medium,
        };
        let levels = match args.levels.as_str() {
            "one" => lightvol_scene::Levels::One,
            "two" => lightvol_scene::Levels::Two,
            _ => lightvol_scene::Levels::Auto,
        };
        let mut report = crate::embree_baseline::compare(&scene, args.rays, 42, quality, levels)?;
        report["scene"] = json!(args.scene);
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    let b = builtin(&args.scene).with_context(|| format!("unknown built-in scene '{}'", args.scene))?;
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    let (one, all) = (pool(1)?, pool(cores)?);

    // Rays: origins uniform in the recommended grid, uniform directions (seeded).
    let tracer = Tracer::new(&b.scene);
    let (lo, hi) = b.grid.bounds();
    let mut rng = SplitMix64::new(42);
    let rays: Vec<(DVec3, DVec3)> = (0..args.rays)
        .map(|_| {
            let o = DVec3::new(rng.range(lo[0], hi[0]), rng.range(lo[1], hi[1]), rng.range(lo[2], hi[2]));
            (o, DVec3::from(sample_uniform_sphere([rng.next_f64(), rng.next_f64()])))
        })
        .collect();
    let r1 = rays_per_second(&tracer, &rays, &one);
    let rn = rays_per_second(&tracer, &rays, &all);

    // Lookups: coherent (x fastest, a slab sweep) and random order.
    let vol = lookup_volume()?;
    let n = args.lookups;
    let side = (n as f64).cbrt().ceil() as usize;
    let coherent: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            [
                (i % side) as f32 / side as f32,
                ((i / side) % side) as f32 / side as f32,
                (i / (side * side)) as f32 / side as f32,
            ]
        })
        .collect();
    let random: Vec<[f32; 3]> =
        (0..n).map(|_| [rng.next_f64() as f32, rng.next_f64() as f32, rng.next_f64() as f32]).collect();
    let normals: Vec<[f32; 3]> =
        (0..n).map(|_| sample_uniform_sphere([rng.next_f64(), rng.next_f64()]).map(|v| v as f32)).collect();
    let gpu = if args.gpu {
        Some(crate::cmd_gpu::bench_section(&vol, &coherent, &random, &normals)?)
    } else {
        None
    };
    let lookups = json!({
        "volume": "64^3 nodes, 9 RGB coefficients",
        "scalar_coherent": lookups_per_second(&vol, &coherent, &normals, false, &one)?,
        "scalar_random": lookups_per_second(&vol, &random, &normals, false, &one)?,
        "batched_coherent_1_thread": lookups_per_second(&vol, &coherent, &normals, true, &one)?,
        "batched_random_1_thread": lookups_per_second(&vol, &random, &normals, true, &one)?,
        "batched_coherent_all_threads": lookups_per_second(&vol, &coherent, &normals, true, &all)?,
        "batched_random_all_threads": lookups_per_second(&vol, &random, &normals, true, &all)?,
    });

    // doi vs point at equal samples on the scene's recommended grid.
    let transport = Transport::new(&b.scene, &tracer, TransportSettings::default());
    let bake = |method: Method| -> anyhow::Result<(u64, f64)> {
        let s = BakeSettings { method, samples: args.samples, seed: 1, ..BakeSettings::default() };
        let out = all.install(|| lightvol_sampler::bake(&transport, &b.grid, &s, &BakeControl::default()))?;
        Ok((out.stats.rays.total(), out.stats.wall_time.as_secs_f64()))
    };
    let (point_rays, point_s) = bake(Method::Point)?;
    let (doi_rays, doi_s) = bake(Method::Doi)?;

    let mut report = json!({
        "scene": args.scene,
        "triangles": b.scene.triangle_count(),
        "threads": cores,
        "rays": { "count": args.rays, "closest_hit_per_second_1_thread": r1, "closest_hit_per_second_all_threads": rn, "thread_scaling": rn / r1 },
        "lookups_per_second": lookups,
        "bake": {
            "samples": args.samples,
            "grid": b.grid.res(),
            "point": { "rays": point_rays, "seconds": point_s, "mrays_per_second": point_rays as f64 / point_s / 1e6 },
            "doi": { "rays": doi_rays, "seconds": doi_s, "mrays_per_second": doi_rays as f64 / doi_s / 1e6 },
            "doi_over_point_rays": doi_rays as f64 / point_rays as f64,
            "doi_over_point_seconds": doi_s / point_s,
        },
    });
    if let Some(g) = gpu {
        report["gpu"] = g;
    }
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(ExitCode::SUCCESS)
}
