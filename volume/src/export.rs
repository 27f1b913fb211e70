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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
    match vol {
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
        ExportFormat::Json => {
            let file = crate::info::described_file_name(source);
            write_sidecar(out, &Sidecar::describe(vol, Encoding::F32, file, "native-exr"))?;
        }
    }
    Ok(report)
}
