//! `lightvol merge`: combine shard bakes into one volume.
//!
//! Each input is a shard's exact accumulator (`.lvacc`, written by `bake --shard` or
//! `bake --keep-accumulator`) or an EXR whose sibling `.lvacc` exists. The Eq. 6 sums are
//! added as exact fixed-point integers (any order gives the same bits), then finalized; the
//! result is the unsharded bake's file byte for byte (a set baked with `--target lightvol`
//! smoothed under the per-node errors its shards carry). The merge is lightvol-sampler's
//! `merge` (`merge_shards`, `finish_merged`); this verb words its errors and writes the
//! files.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_sampler::merge::{
    MergeShardsError, MergedShards, ShardInputError, accumulator_path, finish_merged, merge_shards,
};
use lightvol_volume::io::exr::{ExrOptions, write_exr};

/// `lightvol merge`.
#[derive(Debug, Args)]
pub(crate) struct MergeArgs {
    /// Shard files (`.lvacc`, or `.exr` with a sibling `.lvacc`).
    #[arg(required = true, num_args = 1..)]
    pub(crate) inputs: Vec<PathBuf>,
    /// Merged volume (native EXR).
    #[arg(short, long)]
    pub(crate) output: PathBuf,
    /// Also write the merged accumulator (`<stem>.lvacc`) for further merging.
    #[arg(long)]
    pub(crate) keep_accumulator: bool,
    /// Merge an incomplete set (missing shards leave their cells unsampled) instead of
    /// refusing it.
    #[arg(long)]
    allow_partial: bool,
}

/// A refused shard set, in this verb's words.
fn merge_error(e: MergeShardsError) -> anyhow::Error {
    match e {
        MergeShardsError::Input(ShardInputError::LevelFile(p)) => anyhow::anyhow!(
            "{} is a refinement level of a sharded adaptive bake; assemble those with `lightvol bake SCENE --adaptive ... --from-shards FILES`",
            p.display()
        ),
        MergeShardsError::Input(ShardInputError::Octree(p)) => anyhow::anyhow!(
            "{} is an adaptive (octree) volume; merge combines uniform shard bakes only (sharded adaptive bakes are assembled by `bake --adaptive --from-shards`)",
            p.display()
        ),
        MergeShardsError::Input(ShardInputError::NoAccumulator { volume, accumulator }) => anyhow::anyhow!(
            "{} has no accumulator beside it ({}); bake with --shard K/N or --keep-accumulator to get mergeable output",
            volume.display(),
            accumulator.display()
        ),
        MergeShardsError::OctreeBase(p) => anyhow::anyhow!(
            "{} is a level-0 shard of an adaptive bake; assemble its levels with `lightvol bake SCENE --adaptive ... --from-shards FILES`",
            p.display()
        ),
        MergeShardsError::Incomplete { missing, count, merged } => anyhow::anyhow!(
            "incomplete set: shards {} of {count} are missing (have {}); nothing written (--allow-partial merges what is there)",
            list(&missing),
            list(&merged)
        ),
        e => e.into(),
    }
}

/// Runs `lightvol merge`.
pub(crate) fn run(args: &MergeArgs) -> anyhow::Result<ExitCode> {
    if args.allow_partial && args.keep_accumulator {
        bail!(
            "--keep-accumulator cannot be combined with --allow-partial: a partial merge's sums would carry one shard index for several shards"
        );
    }
    // Headers first: the whole set is checked before any sum is read or anything written.
    let MergedShards { accumulator: acc, metadata: meta, merged: have, missing } =
        merge_shards(&args.inputs, args.allow_partial).map_err(merge_error)?;
    if !missing.is_empty() {
        eprintln!(
            "warning: shards {} of {} are missing; the volume covers only part of the grid's cells",
            list(&missing),
            meta.shard_count
        );
    }
    if args.keep_accumulator {
        let ap = accumulator_path(&args.output);
        lightvol_volume::io::accumulator::write_accumulator(&ap, &acc, &meta)
            .with_context(|| format!("writing {}", ap.display()))?;
    }
    // A least-squares bake's shards carry the mass matrix: the fit is solved over the whole
    // set. A gradient bake's carry the basis estimator's systems (solved on the merged
    // volume) or the central differences of their nodes.
    let merged = finish_merged(&acc, meta)?;
    drop(acc);
    if let Some((lambda, solve)) = &merged.least_squares {
        eprintln!(
            "least-squares fit (λ = {lambda}): {} nodes, {} CG iterations, residual {:.1e}",
            solve.active_nodes, solve.max_iterations, solve.max_relative_residual
        );
    }
    if let (Some(r), Some(record)) =
        (&merged.target, merged.volume.metadata().settings.as_ref().and_then(|s| s.target.as_ref()))
        && let Some(lookup) = lightvol_volume::EngineLookup::parse(&record.lookup)
    {
        crate::cmd_bake::print_target(lookup, record.lambda, r);
    }
    let (vol, fill) = (&merged.volume, merged.fill);
    match &merged.gradients {
        None => match &merged.groups {
            Some(g) => {
                lightvol_volume::io::groups::write_grouped_exr(&args.output, g, &ExrOptions::default())
            }
            None => write_exr(&args.output, vol, &ExrOptions::default()),
        },
        Some((grads, rep)) => {
            eprintln!("gradients: {} nodes solved, {} singular", rep.solved, rep.singular);
            lightvol_volume::io::exr::write_exr_with_gradients(
                &args.output,
                vol,
                grads,
                &ExrOptions::default(),
            )
        }
    }
    .with_context(|| format!("writing {}", args.output.display()))?;
    eprintln!(
        "merged {} shard(s) into {} ({} zero-weight nodes filled)",
        have.len(),
        args.output.display(),
        fill.filled
    );
    Ok(ExitCode::SUCCESS)
}

/// `0, 3, 5`.
fn list(v: &[u32]) -> String {
    v.iter().map(u32::to_string).collect::<Vec<_>>().join(", ")
}
