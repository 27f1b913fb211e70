//! `lightvol export`: engine formats.

use std::process::ExitCode;

use anyhow::Context;
use lightvol_volume::encode::Encoding;
use lightvol_volume::exr_io::read_exr;
use lightvol_volume::sidecar::{Sidecar, sidecar_path, write_sidecar};

use crate::cli::{ExportArgs, ExportFormat};

/// Runs `lightvol export`.
pub fn run(args: &ExportArgs) -> anyhow::Result<ExitCode> {
    let vol = read_exr(&args.volume).with_context(|| format!("reading {}", args.volume.display()))?;
    let out = &args.output;
    let ctx = || format!("writing {}", out.display());
    match args.format {
        ExportFormat::Ktx2 => lightvol_volume::ktx2_io::write_ktx2(out, &vol).with_context(ctx)?,
        ExportFormat::Dds => lightvol_volume::dds_io::write_dds(out, &vol).with_context(ctx)?,
        ExportFormat::Bevy => lightvol_volume::bevy::write_bevy(out, &vol).with_context(ctx)?,
        ExportFormat::Json => {
            let sc =
                Sidecar::describe(&vol, Encoding::F32, Some(args.volume.display().to_string()), "native-exr");
            write_sidecar(out, &sc).with_context(ctx)?;
        }
    }
    eprintln!("wrote {}", out.display());
    if args.format != ExportFormat::Json {
        let sc = sidecar_path(out);
        if sc.exists() {
            eprintln!("wrote {}", sc.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
