//! `lightvol bake`: bake an irradiance volume.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use lightvol_sampler::baselines::bake_baseline;
use lightvol_sampler::merge::accumulator_path;
use lightvol_sampler::method::BakeMethod;
use lightvol_sampler::method::Baseline;
use lightvol_sampler::report::{BakeReport, RunFigures};
use lightvol_sampler::request::{BakeRequest, Provenance, bake_uniform};
use lightvol_sampler::scenarios::{bake_scenarios, scenario_accumulator};
use lightvol_scene::light_groups::LightGroups;
use lightvol_scene::{Tracer, Transport};
use lightvol_volume::io::accumulator::write_accumulator;
use lightvol_volume::io::exr::{ExrOptions, write_exr, write_exr_with_gradients};
use lightvol_volume::io::groups::write_grouped_exr;

use crate::bake_args::{BakeArgs, request};
use crate::progress::with_bar;
use crate::setup::with_threads;

/// Runs `lightvol bake`.
pub(crate) fn run(args: &BakeArgs) -> anyhow::Result<ExitCode> {
    args.sampling.check_memory(args.grid.memory_limit())?;
    if args.adaptive.adaptive {
        return crate::adaptive_bake::run(args);
    }
    let request = request(args, None)?;
    if let Some(first) = args.adaptive.stray_options().first() {
        bail!("{first} needs --adaptive");
    }
    if let BakeMethod::Baseline(b) = request.method {
        return run_baseline(args, &request, b);
    }
    if request.scenarios {
        return run_scenarios(args, &request);
    }
    let started = Instant::now();
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    let groups = match (&args.light_groups, args.sky_transfer) {
        (spec, Some(order)) => Some(
            LightGroups::with_sky_transfer(&loaded.scene, spec.as_deref(), (order * order) as usize)
                .map_err(|e| anyhow::anyhow!("--sky-transfer: {e}"))?,
        ),
        (Some(spec), None) => Some(
            LightGroups::parse(&loaded.scene, spec).map_err(|e| anyhow::anyhow!("--light-groups: {e}"))?,
        ),
        (None, None) => None,
    };
    // A checkpointed bake holds a piece's sums beside the running total: about one more
    // light group's worth.
    let grid = args.grid.grid_split(
        &loaded,
        request.records_node_reach(),
        groups.as_ref().map_or(0, LightGroups::len) + usize::from(args.checkpoint.is_some()),
    )?;
    if let (Some(g), false) = (&groups, args.quiet || args.json) {
        eprintln!("light groups:\n{}", g.describe());
    }
    let key = request.key(&loaded.scene, &grid);
    let provenance = Provenance { frame: loaded.frame, key: &key };
    if let Some(dir) = &args.checkpoint {
        if request.shard.is_some() {
            bail!("--checkpoint cannot be combined with --shard (a checkpointed bake is its own shards)");
        }
        return run_checkpointed(args, &request, &loaded, &grid, groups, provenance, dir, started);
    }
    let (bake, bvh_seconds) = with_transport(args, &loaded, &request, groups, |transport| {
        Ok(with_bar(args.quiet, &args.method, |c| {
            bake_uniform(transport, &loaded.scene, &grid, &request, provenance, c)
        })?)
    })?;
    if request.writes_accumulator() {
        let acc_path = accumulator_path(&args.output);
        write_accumulator(&acc_path, &bake.output.accumulator, bake.volume.metadata())
            .with_context(|| format!("writing {}", acc_path.display()))?;
        if !args.json {
            eprintln!("wrote {}", acc_path.display());
        }
    }
    if let (Some((lambda, solve)), false) = (&bake.least_squares, args.json) {
        eprintln!(
            "least-squares fit (λ = {lambda}): {} nodes, {} CG iterations, residual {:.1e}",
            solve.active_nodes, solve.max_iterations, solve.max_relative_residual
        );
    }
    if let (Some(t), Some(r), false) = (request.effective_target(), &bake.target, args.json) {
        print_target(t.lookup, t.lambda, r);
    }
    if let (Some(_), Some(_), false) = (request.effective_target(), request.shard, args.json || args.quiet) {
        eprintln!(
            "note: the shard carries its nodes' error estimates; `lightvol merge` smooths the merged set for lightvol's lookup"
        );
    }
    let vol = &bake.volume;
    match (&bake.gradients, &bake.groups) {
        (_, Some(g)) => write_grouped_exr(&args.output, g, &ExrOptions::default()),
        (None, None) => write_exr(&args.output, vol, &ExrOptions::default()),
        (Some(g), None) => write_exr_with_gradients(&args.output, vol, &g.gradients, &ExrOptions::default()),
    }
    .with_context(|| format!("writing {}", args.output.display()))?;
    let report =
        BakeReport::uniform(&loaded, &grid, &request, &bake, run_figures(args, bvh_seconds, started));
    print_report(args, &report)?;
    Ok(ExitCode::SUCCESS)
}

/// Runs `bake` on `args`' threads with the light transport over `loaded` (split by
/// `groups` when given), returning its result and the ray tracer's build time.
fn with_transport<T>(
    args: &BakeArgs,
    loaded: &lightvol_sampler::scene_setup::LoadedScene,
    request: &BakeRequest,
    groups: Option<LightGroups>,
    bake: impl FnOnce(&Transport<'_>) -> anyhow::Result<T> + Send,
) -> anyhow::Result<(T, f64)>
where
    T: Send,
{
    with_threads(args.sampling.threads, || -> anyhow::Result<_> {
        let t0 = Instant::now();
        let tracer = Tracer::new(&loaded.scene);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let mut transport = Transport::new(&loaded.scene, &tracer, request.transport);
        if let Some(g) = groups {
            transport = transport.with_groups(g);
        }
        Ok((bake(&transport)?, bvh_seconds))
    })?
}

/// `lightvol bake --checkpoint DIR [--resume]`: the bake in pieces, checkpointed after each
/// ([`lightvol_sampler::checkpoint`]), written as `merge` writes a whole shard set.
#[allow(clippy::too_many_arguments, reason = "the bake's set-up, passed on from `run`")]
fn run_checkpointed(
    args: &BakeArgs,
    request: &BakeRequest,
    loaded: &lightvol_sampler::scene_setup::LoadedScene,
    grid: &lightvol_volume::GridSpec,
    groups: Option<LightGroups>,
    provenance: Provenance<'_>,
    dir: &std::path::Path,
    started: Instant,
) -> anyhow::Result<ExitCode> {
    use lightvol_sampler::checkpoint::bake_checkpointed;
    let pieces = args.checkpoint_pieces;
    let quiet = args.quiet || args.json;
    let (done, bvh_seconds) = with_transport(args, loaded, request, groups, |transport| {
        Ok(with_bar(args.quiet, &args.method, |c| {
            bake_checkpointed(
                transport,
                &loaded.scene,
                grid,
                request,
                provenance,
                dir,
                pieces,
                args.resume,
                c,
                |k, n| {
                    if !quiet {
                        eprintln!("checkpoint: {k} of {n} pieces done ({})", dir.display());
                    }
                },
            )
        })?)
    })?;
    if request.keep_accumulator {
        let acc_path = accumulator_path(&args.output);
        write_accumulator(&acc_path, &done.accumulator, &done.metadata)
            .with_context(|| format!("writing {}", acc_path.display()))?;
    }
    let merged = &done.merged;
    if let (Some(t), Some(r), false) = (request.effective_target(), &merged.target, quiet) {
        print_target(t.lookup, t.lambda, r);
    }
    match (&merged.gradients, &merged.groups) {
        (_, Some(g)) => write_grouped_exr(&args.output, g, &ExrOptions::default()),
        (None, None) => write_exr(&args.output, &merged.volume, &ExrOptions::default()),
        (Some((g, _)), None) => {
            write_exr_with_gradients(&args.output, &merged.volume, g, &ExrOptions::default())
        }
    }
    .with_context(|| format!("writing {}", args.output.display()))?;
    let report = serde_json::json!({
        "scene": loaded.scene.name,
        "output": args.output.display().to_string(),
        "grid": { "res": grid.res() },
        "pieces": pieces,
        "resumed_pieces": done.resumed,
        "rays_this_run": done.rays_this_run.total(),
        "rays_total": done.rays_total,
        "bvh_seconds": bvh_seconds,
        "total_seconds": started.elapsed().as_secs_f64(),
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        eprintln!(
            "baked {} in {pieces} pieces ({} resumed from {}): {} rays this run, {} in all; wrote {}",
            loaded.scene.name,
            done.resumed.len(),
            dir.display(),
            done.rays_this_run.total(),
            done.rays_total,
            args.output.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `lightvol bake --scenario …`: the bake once per lighting scenario
/// ([`lightvol_sampler::scenarios`]), written as one grouped EXR; one report line per
/// scenario (with `--json`, a JSON array of the reports).
fn run_scenarios(args: &BakeArgs, request: &BakeRequest) -> anyhow::Result<ExitCode> {
    let started = Instant::now();
    let scenarios =
        args.scenario.iter().map(|s| crate::setup::parse_scenario(s)).collect::<anyhow::Result<Vec<_>>>()?;
    let mut loaded = args.scene.load_within(args.grid.memory_limit())?;
    // Every scenario's sums stay in memory until the file is written: one light group's
    // worth each.
    let grid = args.grid.grid_split(&loaded, request.records_node_reach(), scenarios.len())?;
    let frame = loaded.frame;
    let ((grouped, bakes), bvh_seconds) = with_threads(args.sampling.threads, || -> anyhow::Result<_> {
        let t0 = Instant::now();
        let tracer = Tracer::new(&loaded.scene);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let out = with_bar(args.quiet, &args.method, |c| {
            bake_scenarios(&mut loaded.scene, &tracer, frame, &grid, request, &scenarios, c)
        })?;
        Ok((out, bvh_seconds))
    })??;
    if request.writes_accumulator() {
        let acc = scenario_accumulator(&scenarios, &bakes)?;
        let acc_path = accumulator_path(&args.output);
        write_accumulator(&acc_path, &acc, grouped.total().metadata())
            .with_context(|| format!("writing {}", acc_path.display()))?;
        if !args.json {
            eprintln!("wrote {}", acc_path.display());
        }
    }
    write_grouped_exr(&args.output, &grouped, &ExrOptions::default())
        .with_context(|| format!("writing {}", args.output.display()))?;
    let reports: Vec<BakeReport> = bakes
        .iter()
        .map(|b| BakeReport::uniform(&loaded, &grid, request, b, run_figures(args, bvh_seconds, started)))
        .collect();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&reports)?);
    } else {
        for (s, r) in scenarios.iter().zip(&reports) {
            eprint!("scenario {}: ", s.name);
            print_report(args, r)?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `lightvol bake --method point+…`: an engine baseline ([`lightvol_sampler::baselines`]),
/// whole (no shards, gradients or octree), written as the native EXR (`point+apv` with its
/// validity mask).
fn run_baseline(args: &BakeArgs, request: &BakeRequest, baseline: Baseline) -> anyhow::Result<ExitCode> {
    let started = Instant::now();
    let loaded = args.scene.load_within(args.grid.memory_limit())?;
    let grid = args.grid.grid(&loaded, false)?;
    let settings = request.settings();
    let (bake, bvh_seconds) = with_threads(args.sampling.threads, || -> anyhow::Result<_> {
        let t0 = Instant::now();
        let tracer = Tracer::new(&loaded.scene);
        let bvh_seconds = t0.elapsed().as_secs_f64();
        let transport = Transport::new(&loaded.scene, &tracer, request.transport);
        let bake = bake_baseline(&transport, &grid, &settings, baseline).context("baking")?;
        Ok((bake, bvh_seconds))
    })??;
    let key = request.key(&loaded.scene, &grid);
    let meta = request.metadata(&loaded.scene, loaded.frame, &key, bake.rays.sampling);
    let vol = bake.volume.clone().with_metadata(meta);
    write_exr(&args.output, &vol, &ExrOptions::default())
        .with_context(|| format!("writing {}", args.output.display()))?;
    let report =
        BakeReport::baseline(&loaded, &grid, request, &bake, run_figures(args, bvh_seconds, started));
    print_report(args, &report)?;
    Ok(ExitCode::SUCCESS)
}

/// What only the command knows of its run: the ray tracer's build time, the time since it
/// `started`, and the output path.
fn run_figures(args: &BakeArgs, bvh_seconds: f64, started: Instant) -> RunFigures {
    RunFigures {
        bvh_seconds,
        total_seconds: started.elapsed().as_secs_f64(),
        output: args.output.display().to_string(),
    }
}

/// Prints `report`: JSON on stdout with `--json`, else lines on stderr.
fn print_report(args: &BakeArgs, report: &BakeReport) -> anyhow::Result<()> {
    if args.json {
        println!("{}", serde_json::to_string_pretty(report)?);
    } else {
        eprintln!(
            "baked {} ({}) on {}x{}x{} nodes: {} rays ({} sampling, {} query, {} bounce, {} shadow) in {:.2} s = {:.2} Mrays/s",
            report.scene,
            report.method,
            report.grid.res[0],
            report.grid.res[1],
            report.grid.res[2],
            report.rays.total(),
            report.rays.sampling,
            report.rays.query,
            report.rays.bounce,
            report.rays.shadow,
            report.seconds,
            report.mrays_per_second
        );
        if let Some(b) = &report.baseline {
            eprintln!(
                "invalid nodes {} (filled {}), moved nodes {}, validity mask {}",
                b.invalid_nodes,
                report.filled_nodes,
                b.moved_nodes,
                if b.validity_mask { "written (validity-weighted lookups)" } else { "none" }
            );
        } else {
            eprintln!(
                "cells with back faces {}, samples kept {} / rejected {}, zero-weight nodes {} (filled {})",
                report.cells_with_back_faces,
                report.samples_kept,
                report.samples_rejected,
                report.zero_weight_nodes,
                report.filled_nodes
            );
        }
        if let Some(n) = &report.node_noise {
            eprintln!(
                "noise of the {} sampled nodes (estimated relative error of each one's mean): median {:.1}%, 90% at most {:.1}%, worst {:.1}% (--noise N samples each until it is below N)",
                n.nodes,
                100.0 * n.median,
                100.0 * n.p90,
                100.0 * n.max
            );
        }
        if let Some(n) = &report.noise {
            eprintln!(
                "until converged: {} units to a relative error of {} with {} samples in their final rounds (mean {:.0} per unit), {} stopped at --max-samples {}",
                n.units,
                n.relative_error,
                n.final_samples,
                n.final_samples as f64 / n.units.max(1) as f64,
                n.capped_units,
                n.max_samples
            );
        }
        if let Some(g) = &report.gradients {
            eprintln!(
                "gradients ({}) in {:.2} s: {} extra directions, {} singular nodes (zero gradient), {} bytes",
                g.estimator.name(),
                g.seconds,
                g.extra_directions,
                g.singular_nodes,
                g.memory_bytes
            );
        }
        eprintln!("wrote {}", args.output.display());
    }
    Ok(())
}

/// The plain report's lines on a `--target` bake: the fit (none for lightvol's own lookup)
/// and the smoothing before it.
pub(crate) fn print_target(
    lookup: lightvol_volume::EngineLookup,
    lambda: f64,
    r: &lightvol_sampler::target::TargetReport,
) {
    let own = lookup == lightvol_volume::EngineLookup::Lightvol;
    if !own {
        eprintln!(
            "fitted for the {} lookup (λ = {}): {} nodes from {} surface and {} free-space samples ({} rays, {} CG iterations); the engine's reading differs from lightvol's by {:.4} relative RMS before the fit, {:.4} after",
            lookup,
            lambda,
            r.nodes_fitted,
            r.surface_samples,
            r.free_samples,
            r.rays,
            r.iterations,
            r.relative_rms_before,
            r.relative_rms_after
        );
    }
    if let Some(m) = r.smoothing {
        eprintln!(
            "smoothed {} noisy nodes{} (median estimated error {:.3}, {} edges, {} CG iterations)",
            m.nodes,
            if own { " for lightvol's lookup" } else { " first" },
            m.median_error,
            m.edges,
            m.iterations
        );
    }
}
