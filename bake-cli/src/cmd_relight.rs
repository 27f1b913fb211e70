//! `lightvol relight`: a volume baked with light groups, its groups scaled and summed
//! (lightvol-volume's `light_groups`), written as a plain volume.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;
use lightvol_volume::io::exr::{ExrOptions, write_exr};
use lightvol_volume::io::groups::read_grouped_exr;

/// `lightvol relight`.
#[derive(Debug, Args)]
pub(crate) struct RelightArgs {
    /// A volume baked with `--light-groups`.
    pub(crate) volume: PathBuf,
    /// Scales per group, `NAME=S` or `NAME=R,G,B`, separated by `;` (groups not named keep
    /// 1): for example `sun=0;lamps=1,0.8,0.6` turns the sun off and warms the lamps.
    #[arg(long, value_name = "NAME=S;...", default_value = "")]
    pub(crate) scale: String,
    /// Write this group alone instead (its scale, if given, applies).
    #[arg(long, value_name = "NAME", conflicts_with = "list")]
    pub(crate) group: Option<String>,
    /// List the groups and exit.
    #[arg(long)]
    pub(crate) list: bool,
    /// Output volume (native EXR, without groups).
    #[arg(short, long, required_unless_present = "list")]
    pub(crate) output: Option<PathBuf>,
}

/// Runs `lightvol relight`.
pub(crate) fn run(args: &RelightArgs) -> anyhow::Result<ExitCode> {
    let path = &args.volume;
    let grouped = read_grouped_exr(path).with_context(|| format!("reading {}", path.display()))?;
    if args.list {
        for n in grouped.names() {
            println!("{n}");
        }
        return Ok(ExitCode::SUCCESS);
    }
    let mut scales = grouped.parse_scales(&args.scale).context("--scale")?;
    if let Some(name) = &args.group {
        let g = grouped.find(name).ok_or_else(|| {
            anyhow::anyhow!(
                "--group: no light group {name:?} (the volume has {})",
                grouped.names().join(", ")
            )
        })?;
        for (i, s) in scales.iter_mut().enumerate() {
            if i != g {
                *s = [0.0; 3];
            }
        }
    }
    let relit = grouped.relit(&scales).context("relighting")?;
    let out = args.output.as_ref().expect("clap requires --output without --list");
    write_exr(out, &relit, &ExrOptions::default()).with_context(|| format!("writing {}", out.display()))?;
    eprintln!("wrote {}", out.display());
    Ok(ExitCode::SUCCESS)
}
