//! `lightvol merge`: combine shard bakes into one volume.
//!
//! Each input is a shard's exact accumulator (`.lvacc`, written by `bake --shard` or
//! `bake --keep-accumulator`) or an EXR whose sibling `.lvacc` exists. The Eq. 6 sums are
//! added in shard order (deterministic), then finalized; the result equals the unsharded
//! bake to f64 rounding.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_volume::accumulator_io::read_accumulator;
use lightvol_volume::exr_io::{ExrOptions, write_exr};
use lightvol_volume::{Accumulator, BakeMetadata};

/// `lightvol merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Shard files (`.lvacc`, or `.exr` with a sibling `.lvacc`).
    #[arg(required = true, num_args = 1..)]
    pub inputs: Vec<PathBuf>,
    /// Merged volume (native EXR).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also write the merged accumulator (`<stem>.lvacc`) for further merging.
    #[arg(long)]
    pub keep_accumulator: bool,
}

fn accumulator_path(p: &Path) -> anyhow::Result<PathBuf> {
    if p.extension().is_some_and(|e| e == "lvacc") {
        return Ok(p.to_owned());
    }
    if crate::adaptive_files::is_adaptive(p) {
        bail!(
            "{} is an adaptive (octree) volume; merge combines uniform shard bakes only (bake --adaptive is never sharded)",
            p.display()
        );
    }
    let sibling = p.with_extension("lvacc");
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
pub fn run(args: &MergeArgs) -> anyhow::Result<ExitCode> {
    let mut parts: Vec<(Accumulator, BakeMetadata, PathBuf)> = Vec::new();
    for p in &args.inputs {
        let ap = accumulator_path(p)?;
        let (acc, meta) = read_accumulator(&ap).with_context(|| format!("reading {}", ap.display()))?;
        parts.push((acc, meta, ap));
    }
    // Deterministic order: by shard index, then by input order.
    parts.sort_by_key(|(_, m, _)| m.shard_index);
    let first = &parts[0].1;
    for (_, m, p) in &parts[1..] {
        if m.method != first.method
            || m.shard_count != first.shard_count
            || m.seed != first.seed
            || m.scene_hash != first.scene_hash
        {
            bail!(
                "{} does not belong to the same bake as {} (method {} vs {}, seed {} vs {}, shards {} vs {}, scene {} vs {})",
                p.display(),
                parts[0].2.display(),
                m.method,
                first.method,
                m.seed,
                first.seed,
                m.shard_count,
                first.shard_count,
                m.scene_hash,
                first.scene_hash
            );
        }
    }
    for w in parts.windows(2) {
        if w[0].1.shard_index == w[1].1.shard_index && first.shard_count > 1 {
            bail!(
                "shard {} of {} given twice ({} and {})",
                w[0].1.shard_index,
                first.shard_count,
                w[0].2.display(),
                w[1].2.display()
            );
        }
    }
    let mut iter = parts.into_iter();
    let (mut acc, mut meta, p0) = iter.next().context("no inputs")?;
    let mut have = vec![meta.shard_index];
    for (a, m, p) in iter {
        acc.merge(&a).with_context(|| format!("merging {} into {}", p.display(), p0.display()))?;
        meta.samples += m.samples;
        have.push(m.shard_index);
    }
    let missing: Vec<u32> = (0..meta.shard_count).filter(|k| !have.contains(k)).collect();
    if !missing.is_empty() {
        eprintln!(
            "warning: shards {missing:?} of {} are missing; the volume covers only part of the grid's cells",
            meta.shard_count
        );
    } else {
        meta.shard_index = 0;
        meta.shard_count = 1;
    }
    if args.keep_accumulator {
        let ap = args.output.with_extension("lvacc");
        lightvol_volume::accumulator_io::write_accumulator(&ap, &acc, &meta)
            .with_context(|| format!("writing {}", ap.display()))?;
    }
    let (vol, fill) = acc.finalize();
    let vol = vol.with_metadata(meta);
    write_exr(&args.output, &vol, &ExrOptions::default())
        .with_context(|| format!("writing {}", args.output.display()))?;
    eprintln!(
        "merged {} shard(s) into {} ({} zero-weight nodes filled)",
        have.len(),
        args.output.display(),
        fill.filled
    );
    Ok(ExitCode::SUCCESS)
}
