//! `lightvol merge`: combine shard bakes into one volume.
//!
//! Each input is a shard's exact accumulator (`.lvacc`, written by `bake --shard` or
//! `bake --keep-accumulator`) or an EXR whose sibling `.lvacc` exists. The Eq. 6 sums are
//! added as exact fixed-point integers (any order gives the same bits), then finalized; the
//! result is the unsharded bake's file byte for byte.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_sampler::adaptive_shard::LEVEL_EXTENSION;
use lightvol_sampler::request::{accumulator_path, finish_merged};
use lightvol_volume::BakeMetadata;
use lightvol_volume::io::accumulator::{
    ACC_EXTENSION, check_shard_set, merge_accumulator_file, read_accumulator_metadata,
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
    pub(crate) allow_partial: bool,
}

/// The accumulator file of the input `p`: itself, or the one beside a volume file.
fn input_accumulator(p: &Path) -> anyhow::Result<PathBuf> {
    if p.extension().is_some_and(|e| e == ACC_EXTENSION) {
        return Ok(p.to_owned());
    }
    if p.extension().is_some_and(|e| e == LEVEL_EXTENSION) {
        bail!(
            "{} is a refinement level of a sharded adaptive bake; assemble those with `lightvol bake SCENE --adaptive ... --from-shards FILES`",
            p.display()
        );
    }
    if lightvol_volume::io::adaptive::is_adaptive_exr(p).unwrap_or(false) {
        bail!(
            "{} is an adaptive (octree) volume; merge combines uniform shard bakes only (sharded adaptive bakes are assembled by `bake --adaptive --from-shards`)",
            p.display()
        );
    }
    let sibling = accumulator_path(p);
    if sibling.is_file() {
        Ok(sibling)
    } else if p.is_file() {
        bail!(
            "{} has no accumulator beside it ({}); bake with --shard K/N or --keep-accumulator to get mergeable output",
            p.display(),
            sibling.display()
        )
    } else {
        bail!("{}: no such file", p.display())
    }
}

/// Runs `lightvol merge`.
pub(crate) fn run(args: &MergeArgs) -> anyhow::Result<ExitCode> {
    // Headers first: the whole set is checked before any sum is read or anything written.
    if args.allow_partial && args.keep_accumulator {
        bail!(
            "--keep-accumulator cannot be combined with --allow-partial: a partial merge's sums would carry one shard index for several shards"
        );
    }
    let mut parts: Vec<(BakeMetadata, PathBuf)> = Vec::new();
    let mut seen: Vec<PathBuf> = Vec::new();
    for p in &args.inputs {
        let ap = input_accumulator(p)?;
        let canon = std::fs::canonicalize(&ap).unwrap_or_else(|_| ap.clone());
        if seen.contains(&canon) {
            bail!("{} is given twice (its samples would count twice)", ap.display());
        }
        seen.push(canon);
        let meta = read_accumulator_metadata(&ap).with_context(|| format!("reading {}", ap.display()))?;
        parts.push((meta, ap));
    }
    let missing = check_shard_set(&mut parts)?;
    let (first, p0) = (&parts[0].0, &parts[0].1);
    if first.method.ends_with(lightvol_sampler::adaptive_shard::BASE_SUFFIX) {
        bail!(
            "{} is a level-0 shard of an adaptive bake; assemble its levels with `lightvol bake SCENE --adaptive ... --from-shards FILES`",
            p0.display()
        );
    }
    let have: Vec<u32> = parts.iter().map(|(m, _)| m.shard_index).collect();
    if !missing.is_empty() && !args.allow_partial {
        bail!(
            "incomplete set: shards {} of {} are missing (have {}); nothing written (--allow-partial merges what is there)",
            list(&missing),
            first.shard_count,
            list(&have)
        );
    }
    // Stream the sums in: one accumulator in memory whatever the number of shards.
    let mut acc = None;
    let mut meta = first.clone();
    meta.samples = 0;
    for (m, p) in &parts {
        let (a, _) =
            merge_accumulator_file(acc.take(), p).with_context(|| format!("merging {}", p.display()))?;
        acc = Some(a);
        meta.samples += m.samples;
    }
    let acc = acc.context("no inputs")?;
    if missing.is_empty() {
        meta.shard_index = 0;
        meta.shard_count = 1;
    } else {
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
    let lambda = lsq_lambda(&meta);
    let merged = finish_merged(&acc, meta, lambda)?;
    drop(acc);
    if let Some((lambda, solve)) = &merged.least_squares {
        eprintln!(
            "least-squares fit (λ = {lambda}): {} nodes, {} CG iterations, residual {:.1e}",
            solve.active_nodes, solve.max_iterations, solve.max_relative_residual
        );
    }
    let (vol, fill) = (&merged.volume, merged.fill);
    match &merged.gradients {
        None => write_exr(&args.output, vol, &ExrOptions::default()),
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

/// λ of a least-squares bake: from the typed settings record, or, in files written
/// before it, from the method label `METHOD fit=lsq:λ`.
fn lsq_lambda(meta: &BakeMetadata) -> Option<f64> {
    use lightvol_sampler::node_fit::Fit;
    use lightvol_volume::FitRecord;
    if let Some(record) = &meta.settings {
        return match record.fit {
            FitRecord::LeastSquares { lambda } => Some(lambda),
            FitRecord::Average => None,
        };
    }
    let fit: Fit = meta.method.split_whitespace().find_map(|w| w.strip_prefix("fit="))?.parse().ok()?;
    match fit {
        Fit::LeastSquares { lambda } => Some(lambda),
        Fit::Average => None,
    }
}

/// `0, 3, 5`.
fn list(v: &[u32]) -> String {
    v.iter().map(u32::to_string).collect::<Vec<_>>().join(", ")
}
