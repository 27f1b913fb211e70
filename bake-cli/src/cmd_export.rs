//! `lightvol export`: engine formats. Adaptive volumes: see [`crate::adaptive_files`]
//! (JSON describes the octree; KTX2, DDS and Bevy resample it to a uniform grid).

use std::process::ExitCode;

use anyhow::{Context, bail};
use lightvol_volume::IrradianceVolume;
use lightvol_volume::encode::Encoding;
use lightvol_volume::io::sidecar::{Sidecar, sidecar_path, write_sidecar};
use lightvol_volume::{AnyVolume, GradientField};

use crate::adaptive_files;
use crate::cli::{ExportArgs, ExportFormat};
use crate::imaging::write_atomic;

/// Parses `--res NX,NY,NZ` (each a whole number of at least 2).
fn parse_res(s: &str) -> anyhow::Result<[u32; 3]> {
    let v: Vec<u32> = s
        .split(',')
        .map(|t| t.trim().parse::<u32>().with_context(|| format!("--res: '{t}' is not a whole number")))
        .collect::<anyhow::Result<_>>()?;
    match v[..] {
        [x, y, z] if x >= 2 && y >= 2 && z >= 2 => Ok([x, y, z]),
        _ => bail!("--res: expected NX,NY,NZ with each at least 2, got '{s}'"),
    }
}

fn write_uniform(args: &ExportArgs, vol: &IrradianceVolume) -> anyhow::Result<()> {
    let out = &args.output;
    let ctx = || format!("writing {}", out.display());
    match args.format {
        ExportFormat::Ktx2 => lightvol_volume::io::ktx2::write_ktx2(out, vol).with_context(ctx)?,
        ExportFormat::Dds => lightvol_volume::io::dds::write_dds(out, vol).with_context(ctx)?,
        ExportFormat::Bevy => {
            let format = match args.bevy_format {
                crate::cli::BevyFormatArg::Rgba16f => lightvol_volume::io::bevy::BevyFormat::Rgba16f,
                crate::cli::BevyFormatArg::Rgb9e5 => lightvol_volume::io::bevy::BevyFormat::Rgb9e5,
            };
            lightvol_volume::io::bevy::write_bevy(out, vol, format).with_context(ctx)?;
            if let Some(mask) = vol.validity() {
                eprintln!(
                    "note: Bevy interpolates its voxels plainly; the validity mask ({} invalid nodes) is not in the Bevy export",
                    mask.invalid_count()
                );
            }
        }
        ExportFormat::Json => {
            let file = adaptive_files::described_file_name(&args.volume);
            let sc = Sidecar::describe(vol, Encoding::F32, file, "native-exr");
            write_sidecar(out, &sc).with_context(ctx)?;
        }
    }
    Ok(())
}

/// Runs `lightvol export`.
pub fn run(args: &ExportArgs) -> anyhow::Result<ExitCode> {
    let res = args.res.as_deref().map(parse_res).transpose()?;
    let out = &args.output;
    let opened =
        lightvol_volume::open(&args.volume).with_context(|| format!("reading {}", args.volume.display()))?;
    match &opened {
        AnyVolume::Uniform(vol) | AnyVolume::Gradient(GradientField { volume: vol, .. }) => {
            if res.is_some() {
                bail!("--res resamples adaptive volumes only; {} is a uniform volume", args.volume.display());
            }
            write_uniform(args, vol)?;
        }
        AnyVolume::Adaptive(vol) if args.format == ExportFormat::Json => {
            if res.is_some() {
                bail!(
                    "--res applies to KTX2, DDS and Bevy exports; the JSON export describes the octree itself"
                );
            }
            let v = adaptive_files::export_json(vol, &args.volume)?;
            write_atomic(out, serde_json::to_string_pretty(&v)?.as_bytes())?;
        }
        AnyVolume::Adaptive(vol) => {
            let (uniform, used) = adaptive_files::resample(vol, res)?;
            let finest = vol.finest_res();
            eprintln!(
                "resampled the adaptive volume (levels 0..{}) to a uniform {}x{}x{} grid{}",
                vol.max_level(),
                used[0],
                used[1],
                used[2],
                if used == finest { " (its finest level)" } else { "" }
            );
            write_uniform(args, &uniform)?;
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
