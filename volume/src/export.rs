//! One export of any volume ([`AnyVolume`]) to an engine format: KTX2, DDS, Bevy, or the
//! JSON sidecar describing the native file. The uniform-only formats resample an octree
//! ([`AdaptiveVolume::to_uniform`](crate::AdaptiveVolume::to_uniform): the exact f64 lookup
//! at every node, rounded to f32) at a chosen resolution, by default its finest level's,
//! which reproduces every finest-level node exactly. Every file is written atomically.

use std::path::Path;

use crate::encode::Encoding;
use crate::error::VolumeError;
use crate::field::{AnyVolume, GradientField};
use crate::io::bevy::BevyFormat;
use crate::io::sidecar::{Sidecar, write_sidecar};
use crate::reach::NodeReach;
use crate::validity::ValidityMask;
use crate::volume::IrradianceVolume;

/// An engine format.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ExportFormat {
    /// KTX2 3D textures ([`crate::io::ktx2`]).
    Ktx2,
    /// DDS 3D textures ([`crate::io::dds`]).
    Dds,
    /// Bevy's irradiance volume ([`crate::io::bevy`]).
    Bevy(BevyFormat),
    /// three.js's `LightProbeGrid` atlas ([`crate::io::three`]).
    Three,
    /// The JSON sidecar describing the native file (and an octree's levels).
    Json,
    /// An octree resampled into bricks behind an indirection texture
    /// ([`crate::bricks`], [`crate::io::bricks`]).
    Bricks(crate::bricks::BrickParams),
}

/// What an export did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExportReport {
    /// An octree resampled to this uniform resolution, with whether it is the finest
    /// level's.
    pub resampled: Option<([u32; 3], bool)>,
    /// Invalid nodes of a validity mask the format cannot carry (Bevy, three.js).
    pub dropped_mask_nodes: Option<usize>,
    /// Limited nodes of a node reach the format cannot carry (Bevy, three.js).
    pub dropped_reach_nodes: Option<usize>,
    /// What the brick export made and what its budget dropped.
    pub bricks: Option<crate::bricks::BrickReport>,
}

/// Why an export was refused.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A resolution was given for a uniform volume.
    #[error("a resampling resolution applies to adaptive volumes only")]
    ResolutionForUniform,
    /// A resolution was given for the JSON description of an octree.
    #[error(
        "the JSON export describes the octree itself; a resampling resolution applies to KTX2, DDS and Bevy"
    )]
    ResolutionForJson,
    /// Bricks were asked of a volume that is not an octree.
    #[error(
        "the brick export resamples an adaptive volume (bake with --adaptive); this volume is {0}, which the KTX2 export writes whole"
    )]
    BricksNeedOctree(&'static str),
    /// Resampling the octree failed.
    #[error("resampling the adaptive volume")]
    Resample(#[source] VolumeError),
    /// Writing failed.
    #[error(transparent)]
    Volume(#[from] VolumeError),
}

/// Writes `vol`, read from `source`, to `out` in `format`; `res` resamples an octree for the
/// uniform-only formats.
///
/// # Errors
/// [`ExportError`]: a resolution where none applies, a failed resampling or write.
pub fn export(
    vol: &AnyVolume,
    source: &Path,
    format: ExportFormat,
    res: Option<[u32; 3]>,
    out: &Path,
) -> Result<ExportReport, ExportError> {
    if let ExportFormat::Bricks(params) = format {
        if res.is_some() {
            return Err(ExportError::ResolutionForUniform);
        }
        let AnyVolume::Adaptive(oct) = vol else { return Err(ExportError::BricksNeedOctree(vol.kind())) };
        let (bricks, report) = crate::bricks::bricks_from_octree(oct, &params)?;
        crate::io::bricks::write_bricks(out, &bricks)?;
        return Ok(ExportReport { bricks: Some(report), ..ExportReport::default() });
    }
    match vol {
        AnyVolume::Bricks(_) => Err(ExportError::Volume(VolumeError::InvalidData(
            "a brick volume is already an engine export; export the octree it was made from".into(),
        ))),
        AnyVolume::Uniform(v) | AnyVolume::Gradient(GradientField { volume: v, .. }) => {
            if res.is_some() {
                return Err(ExportError::ResolutionForUniform);
            }
            Ok(write_uniform(v, source, format, out)?)
        }
        AnyVolume::Adaptive(v) if format == ExportFormat::Json => {
            if res.is_some() {
                return Err(ExportError::ResolutionForJson);
            }
            let json = crate::info::adaptive_export_json(v, source)?;
            let text =
                serde_json::to_string_pretty(&json).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
            crate::io::util::write_atomic(out, text.as_bytes())?;
            Ok(ExportReport::default())
        }
        AnyVolume::Adaptive(v) => {
            let used = res.unwrap_or_else(|| v.finest_res());
            let uniform = v.to_uniform(Some(used)).map_err(ExportError::Resample)?;
            let mut report = write_uniform(&uniform, source, format, out)?;
            report.resampled = Some((used, used == v.finest_res()));
            Ok(report)
        }
    }
}

/// The file of light group `g` beside the export `out`: `STEM.groupGG.EXT` (by index, so
/// that any group name makes a safe file name; the manifest gives the names).
#[must_use]
pub fn group_export_path(out: &Path, g: usize) -> std::path::PathBuf {
    let stem = out.file_stem().map_or_else(|| "volume".into(), |s| s.to_string_lossy().into_owned());
    let name = match out.extension() {
        Some(e) => format!("{stem}.group{g:02}.{}", e.to_string_lossy()),
        None => format!("{stem}.group{g:02}"),
    };
    out.with_file_name(name)
}

/// The stacked light-group texture beside a KTX2 export `out`: `STEM.groups.ktx2`.
#[must_use]
pub fn stacked_groups_path(out: &Path) -> std::path::PathBuf {
    let stem = out.file_stem().map_or_else(|| "volume".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}.groups.ktx2"))
}

/// The manifest of a grouped export beside `out`: `STEM.light_groups.json`.
#[must_use]
pub fn group_manifest_path(out: &Path) -> std::path::PathBuf {
    let stem = out.file_stem().map_or_else(|| "volume".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}.light_groups.json"))
}

/// What the manifest of a grouped export says (module docs of
/// [`crate::light_groups`]): the whole bake's file, each group's name and file, and how
/// they combine.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GroupManifest {
    /// How the files combine.
    pub convention: String,
    /// The whole bake's file (name only, beside the manifest).
    pub whole: String,
    /// Each group: its name and file (name only), in group order.
    pub groups: Vec<GroupFile>,
    /// The KTX2 export's texture of every group stacked along y
    /// ([`crate::io::ktx2_groups`]), which the generated sampling code relights from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stacked: Option<String>,
}

/// One light group's exported file.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GroupFile {
    /// The group's name.
    pub name: String,
    /// Its file, beside the manifest.
    pub file: String,
}

/// How a grouped export's files combine, in words (the manifest's `convention`).
pub const GROUP_CONVENTION: &str = "each group file holds the coefficients that group's lights alone contribute, \
     in the whole file's layout and frame (weights, validity and reach are the whole bake's); \
     relit = sum over groups of scale_g * group_g (per colour channel); \
     with every scale 1 the sum is the whole file up to f16/f32 rounding; \
     groups sky.shJJ are a sky transfer: their scales are the new sky's SH radiance coefficients \
     (lightvol's real SH, no Condon-Shortley phase) in the file's frame";

/// How a scenario export's files combine (the manifest's `convention` for lighting
/// scenarios, [`crate::light_groups`]).
pub const SCENARIO_CONVENTION: &str = "each group file is one lighting scenario's whole bake, \
     in the whole file's layout and frame (weights, validity and reach are shared); \
     a blend is sum over scenarios of w_s * scenario_s with weights summing to 1; \
     the whole file is the first scenario";

/// Writes a volume baked with light groups in `format`: the whole bake to `out` as
/// [`export`] does, each group to [`group_export_path`] in the same format, and the
/// manifest ([`GroupManifest`]) to [`group_manifest_path`]; a KTX2 export also writes every
/// group in one stacked texture ([`stacked_groups_path`], [`crate::io::ktx2_groups`]). In
/// the engine formats a sky transfer's groups answer sky coefficients in the file's frame
/// ([`crate::light_groups::GroupedVolume::sky_in_frame`]). Returns the report of the
/// whole bake's export and the files written.
///
/// # Errors
/// As [`export`]; the JSON format describes the native file, which carries the groups
/// already, so it writes the whole bake's sidecar and the manifest names the native file.
pub fn export_grouped(
    grouped: &crate::light_groups::GroupedVolume,
    source: &Path,
    format: ExportFormat,
    out: &Path,
) -> Result<(ExportReport, Vec<std::path::PathBuf>), ExportError> {
    let report = write_uniform(grouped.total(), source, format, out)?;
    // The engine formats are in the scene file's frame: a sky transfer answers that frame's
    // sky coefficients there. The JSON sidecar describes the native file, in lightvol's.
    let framed = if format == ExportFormat::Json {
        grouped.clone()
    } else {
        grouped.sky_in_frame(grouped.total().metadata().frame)?
    };
    let name = |p: &Path| p.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let mut files = vec![out.to_path_buf()];
    let mut groups = Vec::with_capacity(grouped.names().len());
    for (g, group_name) in grouped.names().iter().enumerate() {
        let file = if format == ExportFormat::Json {
            name(source)
        } else {
            let path = group_export_path(out, g);
            write_uniform(&framed.group(g), source, format, &path)?;
            files.push(path.clone());
            name(&path)
        };
        groups.push(GroupFile { name: group_name.clone(), file });
    }
    let stacked = if format == ExportFormat::Ktx2 {
        let path = stacked_groups_path(out);
        crate::io::ktx2_groups::write_groups_ktx2(&path, grouped)?;
        files.push(path.clone());
        Some(name(&path))
    } else {
        None
    };
    let convention = if grouped.is_scenarios() { SCENARIO_CONVENTION } else { GROUP_CONVENTION };
    let manifest = GroupManifest { convention: convention.into(), whole: name(out), groups, stacked };
    let text =
        serde_json::to_string_pretty(&manifest).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
    let path = group_manifest_path(out);
    crate::io::util::write_atomic(&path, text.as_bytes())?;
    files.push(path);
    Ok((report, files))
}

fn write_uniform(
    vol: &IrradianceVolume,
    source: &Path,
    format: ExportFormat,
    out: &Path,
) -> Result<ExportReport, VolumeError> {
    let mut report = ExportReport::default();
    match format {
        ExportFormat::Ktx2 => crate::io::ktx2::write_ktx2(out, vol)?,
        ExportFormat::Dds => crate::io::dds::write_dds(out, vol)?,
        ExportFormat::Three | ExportFormat::Bevy(_) => {
            match format {
                ExportFormat::Bevy(f) => crate::io::bevy::write_bevy(out, vol, f)?,
                _ => crate::io::three::write_three(out, vol)?,
            }
            // Both engines interpolate their probes plainly.
            report.dropped_mask_nodes = vol.validity().map(ValidityMask::invalid_count);
            report.dropped_reach_nodes = vol.reach().map(NodeReach::limited_count);
        }
        ExportFormat::Bricks(_) => {
            return Err(VolumeError::InvalidData("the brick export resamples an adaptive volume".into()));
        }
        ExportFormat::Json => {
            let file = crate::info::described_file_name(source);
            write_sidecar(out, &Sidecar::describe(vol, Encoding::F32, file, "native-exr"))?;
        }
    }
    Ok(report)
}
