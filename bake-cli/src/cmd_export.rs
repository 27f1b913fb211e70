//! `lightvol export`: engine formats (lightvol-volume's `export`; JSON describes an
//! octree, KTX2, DDS and Bevy resample it to a uniform grid, bricks resample it sparsely).

use std::process::ExitCode;

use anyhow::{Context, bail};
use lightvol_volume::AnyVolume;
use lightvol_volume::bricks::BrickParams;
use lightvol_volume::export::{ExportError, ExportFormat, export};
use lightvol_volume::io::bevy::BevyFormat;
use lightvol_volume::io::sidecar::sidecar_path;

use crate::cli::{BevyFormatArg, ExportArgs, ExportFormat as CliFormat};

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

/// MiB (`--max-probe-memory`) as bytes: finite and positive.
fn mib_to_bytes(mib: f64) -> anyhow::Result<usize> {
    if !(mib.is_finite() && mib > 0.0 && mib < 1e9) {
        bail!("--max-probe-memory: expected a positive number of MiB below 1e9, got {mib}");
    }
    Ok((mib * 1024.0 * 1024.0) as usize)
}

/// Runs `lightvol export`.
pub(crate) fn run(args: &ExportArgs) -> anyhow::Result<ExitCode> {
    let res = args.res.as_deref().map(parse_res).transpose()?;
    let out = &args.output;
    let opened =
        lightvol_volume::open(&args.volume).with_context(|| format!("reading {}", args.volume.display()))?;
    let format = match args.format {
        CliFormat::Ktx2 => ExportFormat::Ktx2,
        CliFormat::Dds => ExportFormat::Dds,
        CliFormat::Json => ExportFormat::Json,
        CliFormat::Three => ExportFormat::Three,
        CliFormat::Bevy => ExportFormat::Bevy(match args.bevy_format {
            BevyFormatArg::Rgba16f => BevyFormat::Rgba16f,
            BevyFormatArg::Rgb9e5 => BevyFormat::Rgb9e5,
        }),
        CliFormat::Bricks => ExportFormat::Bricks(BrickParams {
            cells: args.brick_cells,
            max_probe_bytes: args.max_probe_memory.map(mib_to_bytes).transpose()?,
            ..BrickParams::default()
        }),
    };
    if args.format != CliFormat::Bricks && (args.max_probe_memory.is_some() || args.brick_cells != 4) {
        bail!("--brick-cells and --max-probe-memory apply to --format bricks");
    }
    let grouped = grouped_volume(&args.volume)?;
    let exported = match &grouped {
        Some(g) if res.is_none() && args.format != CliFormat::Bricks => {
            lightvol_volume::export::export_grouped(g, &args.volume, format, out)
        }
        _ => export(&opened, &args.volume, format, res, out).map(|r| (r, Vec::new())),
    };
    let (report, group_files) = exported.map_err(|e| match e {
        ExportError::ResolutionForUniform => {
            anyhow::anyhow!(
                "--res resamples adaptive volumes only; {} is a uniform volume",
                args.volume.display()
            )
        }
        ExportError::ResolutionForJson => anyhow::anyhow!(
            "--res applies to KTX2, DDS, Bevy and three.js exports; the JSON export describes the octree itself"
        ),
        e @ (ExportError::Resample(_) | ExportError::BricksNeedOctree(_)) => e.into(),
        ExportError::Volume(e) => anyhow::Error::new(e).context(format!("writing {}", out.display())),
    })?;
    if let (Some((used, finest)), AnyVolume::Adaptive(vol)) = (report.resampled, &opened) {
        eprintln!(
            "resampled the adaptive volume (levels 0..{}) to a uniform {}x{}x{} grid{}",
            vol.max_level(),
            used[0],
            used[1],
            used[2],
            if finest { " (its finest level)" } else { "" }
        );
    }
    if let Some(b) = &report.bricks {
        eprintln!("{}", b.summary());
        eprintln!("wrote {}", lightvol_volume::io::bricks::indirection_path(out).display());
    }
    // The engine whose export drops what it cannot read, and its `render --lookup` name.
    let (engine, lookup) =
        if args.format == CliFormat::Three { ("three.js", "three") } else { ("Bevy", "bevy") };
    if let Some(n) = report.dropped_mask_nodes {
        eprintln!(
            "note: {engine} interpolates its probes plainly; the validity mask ({n} invalid nodes) is not in the {engine} export"
        );
    }
    if let Some(n) = report.dropped_reach_nodes {
        eprintln!(
            "note: {engine} interpolates its probes plainly; the node reach ({n} limited nodes) is not in the {engine} export, so its lookups read nodes through thin walls (lightvol render --lookup {lookup} shows what it draws)"
        );
    }
    let reads = match args.format {
        CliFormat::Three => Some("three"),
        CliFormat::Bevy => Some("bevy"),
        _ => None,
    };
    if let Some(w) = opened.field().metadata().settings.as_ref().and_then(|r| target_warning(r, reads)) {
        eprintln!("{w}");
    }
    eprintln!("wrote {}", out.display());
    if let Some(g) = &grouped {
        eprintln!(
            "the volume's {} light groups ({}): each written beside it in the same format, listed in the manifest",
            g.names().len(),
            g.names().join(", ")
        );
        for f in group_files.iter().skip(1) {
            eprintln!("wrote {}", f.display());
        }
    }
    if args.format != CliFormat::Json {
        let sc = sidecar_path(out);
        if sc.exists() {
            eprintln!("wrote {}", sc.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The volume's light groups, when it is a native EXR file baked with them.
fn grouped_volume(path: &std::path::Path) -> anyhow::Result<Option<lightvol_volume::GroupedVolume>> {
    let is_exr = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if !is_exr {
        return Ok(None);
    }
    let bytes = lightvol_volume::io::util::read_bounded(path)?;
    if !lightvol_volume::io::groups::has_groups(&bytes)? {
        return Ok(None);
    }
    let g = lightvol_volume::io::groups::grouped_exr_from_bytes(&bytes)
        .with_context(|| format!("reading the light groups of {}", path.display()))?;
    Ok(Some(g))
}

/// The warning for exporting a volume fitted for one engine's lookup (`bake --target`) to a
/// format read by another (`reads`: the engine's lookup name, `None` for the textures that
/// lightvol's own lookup and shader code read); `None` when they agree or there is no target.
fn target_warning(record: &lightvol_volume::BakeRecord, reads: Option<&str>) -> Option<String> {
    let t = record.target.as_ref()?;
    (reads.unwrap_or("lightvol") != t.lookup.as_str()).then(|| {
        format!(
            "warning: the volume's node values were chosen for the {} lookup (bake --target {}); {} reads them differently, so the fit's gain is lost there: bake again with --target {} for it",
            t.lookup,
            t.lookup,
            reads.map_or("a texture read by lightvol's lookup".to_owned(), |r| format!("the {r} lookup")),
            reads.unwrap_or("lightvol")
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A volume fitted for three.js warns when exported for Bevy or as a plain texture, not
    /// for three.js; one chosen for lightvol's lookup warns for an engine, not as a plain
    /// texture; a volume without a target never warns.
    #[test]
    fn exports_for_another_engine_warn() {
        let mut r = lightvol_volume::BakeRecord {
            method: "doi".into(),
            samples_per_unit: 16,
            coeffs: 9,
            fit: lightvol_volume::FitRecord::Average,
            gradients: None,
            bounces: 2,
            russian_roulette: true,
            direct_light: "all".into(),
            octree: None,
            target: None,
            noise: None,
        };
        assert_eq!(target_warning(&r, Some("bevy")), None);
        r.target =
            Some(lightvol_volume::TargetRecord { lookup: "three".into(), lambda: 0.5, smoothing: None });
        assert_eq!(target_warning(&r, Some("three")), None);
        let w = target_warning(&r, Some("bevy")).unwrap();
        assert!(w.contains("chosen for the three lookup") && w.contains("--target bevy"), "{w}");
        let w = target_warning(&r, None).unwrap();
        assert!(w.contains("lightvol's lookup") && w.contains("--target lightvol"), "{w}");
        // Smoothed for lightvol's own lookup: the plain textures read it as chosen.
        r.target = Some(lightvol_volume::TargetRecord {
            lookup: "lightvol".into(),
            lambda: 0.5,
            smoothing: Some(0.5),
        });
        assert_eq!(target_warning(&r, None), None);
        let w = target_warning(&r, Some("three")).unwrap();
        assert!(w.contains("chosen for the lightvol lookup") && w.contains("--target three"), "{w}");
    }
}
