//! A volume's light groups as one KTX2 3D texture (`STEM.groups.ktx2` beside a grouped KTX2
//! export), for sampling code that relights on the device (lightvol-gpu's engine shader,
//! `lightvol_irradiance_groups`): RGBA16F, the groups stacked along y
//! ([`crate::slab::STACKED_LAYOUT`]), so the texture is as deep as one group's and a shader
//! binds one texture for any number of groups.
//!
//! The key/value data holds the whole bake's JSON sidecar (grid, frame, SH convention,
//! validity and reach, which the groups share) under [`crate::io::ktx2::KTX2_SIDECAR_KEY`]
//! and, under [`GROUPS_KEY`], the group names and, for a sky transfer, the baked sky's
//! coefficients, in the file frame ([`GroupedVolume::sky_in_frame`]).

use std::path::Path;

use crate::encode::Encoding;
use crate::error::{FileFormat, VolumeError};
use crate::io::ktx2::{KTX2_SIDECAR_KEY, KTX2_WRITER, ktx2_rgba16f_bytes, kvd_value, parse_ktx2_rgba16f};
use crate::io::sidecar::Sidecar;
use crate::io::util::{guard, read_bounded, write_atomic};
use crate::light_groups::GroupedVolume;
use crate::slab::{STACKED_LAYOUT, layers_from_stacked_texels, stacked_slab_texels};

/// Key of the groups' description in the key/value data.
pub const GROUPS_KEY: &str = crate::io::ktx2::KTX2_GROUPS_KEY;

/// The groups' description ([`GROUPS_KEY`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StackedGroups {
    /// Group names, in stacking order (group `g` at rows `g·ny ..`).
    pub names: Vec<String>,
    /// A sky transfer's baked sky coefficients per channel, in the file frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baked_sky: Option<Vec<[f64; 3]>>,
}

/// The groups of `grouped` as the stacked KTX2 texture, in the scene file's frame (every
/// layer rotated as [`crate::frame::to_file_frame`] rotates a volume, the sky transfer
/// mixed by [`GroupedVolume::sky_in_frame`]).
///
/// # Errors
/// A value beyond the f16 range, or a texture taller than `u32`.
pub fn groups_ktx2_to_bytes(grouped: &GroupedVolume) -> Result<Vec<u8>, VolumeError> {
    let frame = grouped.total().metadata().frame;
    let framed = grouped.sky_in_frame(frame)?;
    let total = crate::frame::to_file_frame(framed.total(), frame)?;
    let layers = (0..framed.names().len())
        .map(|g| crate::frame::to_file_frame(&framed.group(g), frame).map(|v| v.data().to_vec()))
        .collect::<Result<Vec<_>, _>>()?;
    let [nx, ny, nz] = total.spec().res();
    let too_big = || VolumeError::InvalidData("the stacked light-group texture's size overflows u32".into());
    let height = u32::try_from(layers.len()).ok().and_then(|g| g.checked_mul(ny)).ok_or_else(too_big)?;
    let depth = (total.coeffs() as u32).checked_mul(nz).ok_or_else(too_big)?;
    let refs: Vec<&[f32]> = layers.iter().map(Vec::as_slice).collect();
    let texels = stacked_slab_texels(&total, &refs)?;
    let sidecar = Sidecar::describe(
        &total,
        Encoding::F16,
        None,
        &format!("KTX2 R16G16B16A16_SFLOAT 3D texture of light groups; {STACKED_LAYOUT}"),
    )
    .in_frame(frame);
    let groups =
        StackedGroups { names: framed.names().to_vec(), baked_sky: framed.baked_sky().map(<[_]>::to_vec) };
    let groups_json = serde_json::to_string(&groups).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
    Ok(ktx2_rgba16f_bytes(
        [nx, height, depth],
        &texels,
        &[("KTXwriter", KTX2_WRITER), (GROUPS_KEY, &groups_json), (KTX2_SIDECAR_KEY, &sidecar.to_json())],
    ))
}

/// Writes [`groups_ktx2_to_bytes`] to `path` atomically.
///
/// # Errors
/// As [`groups_ktx2_to_bytes`], or the write.
pub fn write_groups_ktx2(path: &Path, grouped: &GroupedVolume) -> Result<(), VolumeError> {
    write_atomic(path, &groups_ktx2_to_bytes(grouped)?)
}

/// The file-frame grid and groups of a stacked texture: the whole bake's sidecar, the
/// groups' description and each group's coefficients (`[node][coeff][rgb]`, f16 values as
/// f32, in the file frame, the order the texture holds them).
///
/// # Errors
/// A malformed texture: a missing or unreadable description, or dimensions that do not
/// fit the sidecar's grid and the group count.
pub fn groups_ktx2_from_bytes(bytes: &[u8]) -> Result<(Sidecar, StackedGroups, Vec<Vec<f32>>), VolumeError> {
    let f = FileFormat::Ktx2;
    guard(f, || {
        let (dims, kvd, data) = parse_ktx2_rgba16f(bytes, f)?;
        let text = |key: &str| -> Result<String, VolumeError> {
            let raw = kvd_value(&kvd, key, f)?;
            String::from_utf8(raw.to_vec()).map_err(|e| VolumeError::malformed(f, e.to_string()))
        };
        let sidecar = Sidecar::from_json(&text(KTX2_SIDECAR_KEY)?)?;
        let groups: StackedGroups = serde_json::from_str(&text(GROUPS_KEY)?)
            .map_err(|e| VolumeError::malformed(f, format!("{GROUPS_KEY}: {e}")))?;
        let spec = sidecar.grid_spec()?;
        let coeffs = sidecar.sh.coeffs;
        let [nx, ny, nz] = spec.res();
        let g = groups.names.len();
        if g == 0
            || u64::from(dims[0]) != u64::from(nx)
            || u64::from(dims[1]) != u64::from(ny) * g as u64
            || u64::from(dims[2]) != u64::from(nz) * coeffs as u64
        {
            return Err(VolumeError::malformed(
                f,
                format!(
                    "texture is {dims:?}, {g} groups of the sidecar's grid [{nx}, {ny}, {nz}] need [{nx}, {}, {}]",
                    g * ny as usize,
                    coeffs * nz as usize
                ),
            ));
        }
        let layers = layers_from_stacked_texels(spec.res(), coeffs, g, &data, f)?;
        Ok((sidecar, groups, layers))
    })
}

/// Reads [`groups_ktx2_from_bytes`] from `path`.
///
/// # Errors
/// As [`groups_ktx2_from_bytes`], or the read.
pub fn read_groups_ktx2(path: &Path) -> Result<(Sidecar, StackedGroups, Vec<Vec<f32>>), VolumeError> {
    groups_ktx2_from_bytes(&read_bounded(path)?)
}
