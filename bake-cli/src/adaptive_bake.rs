//! `lightvol bake --adaptive`: an adaptive octree volume (\[Oat05\], "Adaptive Octree
//! Subdivision", "Subdivision Heuristics"), baked by lightvol-sampler's `bake_adaptive`
//! over the grid options' grid as level 0, written to the native EXR's adaptive extension.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use std::path::PathBuf;

use lightvol_sampler::BakeSettings;
use lightvol_sampler::adaptive::{assemble_adaptive, bake_adaptive, bake_adaptive_level_shard};
use lightvol_sampler::adaptive_shard::{ShardSet, ShardSetError, level_shard_path, write_level};
use lightvol_sampler::report::AdaptiveReport;
use lightvol_scene::{Tracer, Transport};
use lightvol_volume::io::accumulator::write_accumulator;
use lightvol_volume::io::adaptive::write_adaptive_exr;

use crate::bake_args::{BakeArgs, request};
use crate::progress::{run_bake, with_bar, with_progress};
use crate::setup::with_threads;
use lightvol_sampler::request::AdaptiveRequest;
use lightvol_scene::fingerprint::scene_hash;

/// The shard set of `--from-shards`, read and checked ([`ShardSet::load`]).
fn load_inputs(files: &[PathBuf], hash: &str, method: &str) -> anyhow::Result<ShardSet> {
    ShardSet::load(files, hash, method).map_err(|e| match e {
        ShardSetError::Extension(p) => {
            anyhow::anyhow!("{}: --from-shards takes level-0 .lvacc and level .lvref files", p.display())
        }
        ShardSetError::NoBase => {
            anyhow::anyhow!(
                "--from-shards has no level-0 .lvacc shard (bake them with --adaptive --shard K/N)"
            )
        }
        ShardSetError::LevelGap { top, level } => {
            anyhow::anyhow!("--from-shards has level-{top} shards but none of level {level}")
        }
        e => e.into(),
    })
}

/// `lightvol bake --adaptive`: whole, one shard of one level, or the assembly of shards.
pub(crate) fn run(args: &BakeArgs) -> anyhow::Result<ExitCode> {
    let a = &args.adaptive;
    let coeffs = args.grid.coeffs();
    let mut adaptive = a.settings(coeffs)?;
    let mut request = request(
        args,
        Some(AdaptiveRequest {
            settings: adaptive.clone(),
            level: a.level,
            from_shards: !a.from_shards.is_empty(),
        }),
    )?;
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    // The placement boxes are given in the scene file's frame.
    adaptive.regions = a.regions(adaptive.max_level, loaded.frame)?;
    adaptive.regions.extend(a.mesh_regions(&loaded.scene, adaptive.max_level)?);
    if let Some(r) = request.adaptive.as_mut() {
        r.settings.regions.clone_from(&adaptive.regions);
    }
    let grid = args.grid.grid(&loaded, request.records_node_reach())?;
    let settings = BakeSettings { shard: (0, 1), ..request.settings() };
    let ts = request.transport;
    let key = request.key(&loaded.scene, &grid);
    // The shard sets' hash, only where shard files are read or written (the volume's own
    // metadata hashes the scene itself).
    let hash = || scene_hash(&loaded.scene, &key);
    let shard = request.shard;
    if let Some(shard) = shard {
        let level = a.level.unwrap_or(0);
        return with_threads(args.sampling.threads, || -> anyhow::Result<ExitCode> {
            let tracer = Tracer::new(&loaded.scene);
            if level == 0 {
                let s = BakeSettings { shard, ..settings };
                let out = run_bake(&loaded, &tracer, &grid, &s, ts, args.quiet, &args.method)?;
                let meta = request.metadata(&loaded.scene, loaded.frame, &key, out.stats.rays.sampling);
                let path = level_shard_path(&args.output, 0);
                write_accumulator(&path, &out.accumulator, &meta)
                    .with_context(|| format!("writing {}", path.display()))?;
                eprintln!("wrote {} (adaptive level 0, shard {} of {})", path.display(), shard.0, shard.1);
                return Ok(ExitCode::SUCCESS);
            }
            let hash = hash();
            let inputs = load_inputs(&a.from_shards, &hash, &args.method)?;
            if inputs.levels.len() != level as usize - 1 {
                bail!(
                    "--level {level} needs the complete shard sets of levels 1..{level} and no others; --from-shards has levels 1..={}",
                    inputs.levels.len()
                );
            }
            let part = with_progress(&loaded, &tracer, ts, args.quiet, &args.method, |t, c| {
                bake_adaptive_level_shard(
                    t,
                    &grid,
                    &settings,
                    &adaptive,
                    &inputs.base,
                    &inputs.levels,
                    level,
                    shard,
                    c,
                )
            })?;
            let path = level_shard_path(&args.output, level);
            write_level(&path, &part, shard, &hash).with_context(|| format!("writing {}", path.display()))?;
            if part.units == 0 {
                eprintln!("wrote {} (level {level}: nothing to refine)", path.display());
            } else {
                eprintln!(
                    "wrote {} (adaptive level {level}, shard {} of {}: {} of the level's {} units)",
                    path.display(),
                    shard.0,
                    shard.1,
                    lightvol_core::shard::shard_range(part.units as usize, shard).len(),
                    part.units
                );
            }
            Ok(ExitCode::SUCCESS)
        })?;
    }
    let (vol, stats, bvh_seconds) = with_threads(args.sampling.threads, || -> anyhow::Result<_> {
        let t0 = Instant::now();
        let tracer = Tracer::new(&loaded.scene);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let (v, s) = if a.from_shards.is_empty() {
            let transport = Transport::new(&loaded.scene, &tracer, ts);
            with_bar(args.quiet, &args.method, |c| bake_adaptive(&transport, &grid, &settings, &adaptive, c))
                .context("adaptive bake")?
        } else {
            let inputs = load_inputs(&a.from_shards, &hash(), &args.method)?;
            let base_stats = inputs.base_stats();
            with_progress(&loaded, &tracer, ts, args.quiet, &args.method, |t, c| {
                assemble_adaptive(t, &grid, &settings, &adaptive, &inputs.base, base_stats, &inputs.levels, c)
            })?
        };
        Ok((v, s, bvh_seconds))
    })??;
    let meta = request.metadata(&loaded.scene, loaded.frame, &key, stats.rays.sampling);
    let vol = vol.with_metadata(meta);
    write_adaptive_exr(&args.output, &vol).with_context(|| format!("writing {}", args.output.display()))?;
    let report = AdaptiveReport::new(
        &loaded,
        &grid,
        &request,
        &vol,
        &stats,
        bvh_seconds,
        args.output.display().to_string(),
    );
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.to_json()?)?);
        return Ok(ExitCode::SUCCESS);
    }
    let [nx, ny, nz] = grid.res();
    let f = vol.finest_res();
    eprintln!(
        "baked {} ({}, adaptive) on {nx}x{ny}x{nz} base nodes, levels 0..{} (finest {}x{}x{}): {} rays in {:.2} s",
        report.scene,
        report.method,
        vol.max_level(),
        f[0],
        f[1],
        f[2],
        report.rays.total(),
        report.seconds
    );
    let votes = report.split_votes;
    eprintln!("split votes: gradient {}, geometry {}, depth {}", votes.gradient, votes.geometry, votes.depth);
    for l in vol.level_stats() {
        eprintln!(
            "level {}: {} cells ({} leaves, {} split), {} nodes stored of {} baked",
            l.level, l.cells, l.leaves, l.split, l.stored_nodes, l.created_nodes
        );
    }
    eprintln!("memory {} bytes ({} stored nodes)", vol.memory_bytes(), vol.stored_nodes());
    eprintln!("wrote {}", args.output.display());
    Ok(ExitCode::SUCCESS)
}
