//! Engine export: a KTX2 3D texture in RGBA16F (`VK_FORMAT_R16G16B16A16_SFLOAT`), written
//! with the `ktx2` crate's header, level-index and data-format-descriptor types.
//!
//! ## Layout
//! Width `nx`, height `ny`, depth `coeffs · nz`: the coefficients are slabs along z.
//! Texel `(x, y, j·nz + z)` holds coefficient `j` of node `(x, y, z)` in RGB and the node's
//! weight (its domain-of-interest fraction, 0 for filled nodes) in A. One mip level, no
//! supercompression. A shader samples coefficient `j` at normalised z
//! `(j + (z_grid + 0.5)/nz) / coeffs`, i.e. with hardware filtering *within* a slab
//! (clamp z to half a texel inside the slab to avoid bleeding across slabs).
//!
//! The key/value data holds `KTXwriter` and the JSON sidecar under [`KTX2_SIDECAR_KEY`]
//! (grid transform, SH convention, encoding, units, bake metadata and, when the volume has
//! one, its validity mask; see [`crate::io::sidecar`]). The reader validates the header against the sidecar and the data
//! length against the dimensions and rejects non-finite texels.

use std::path::Path;

use ktx2::Format;

use crate::checksum::{through_f16, to_hex, verify, volume_checksum};
use crate::encode::Encoding;
use crate::error::{FileFormat, VolumeError};
use crate::io::sidecar::Sidecar;
use crate::io::util::{guard, read_bounded, write_atomic};
use crate::slab::{SLAB_LAYOUT, slab_texels, volume_from_slab_texels};
use crate::volume::IrradianceVolume;

/// Key of the embedded JSON sidecar in the KTX2 key/value data.
pub const KTX2_SIDECAR_KEY: &str = "lightvol.sidecar";
/// Key of a light-group texture's description ([`crate::io::ktx2_groups`]): a texture that
/// carries it holds light groups stacked, not one volume.
pub const KTX2_GROUPS_KEY: &str = "lightvol.light_groups";
/// Value of the `KTXwriter` key.
pub const KTX2_WRITER: &str = concat!("lightvol-volume ", env!("CARGO_PKG_VERSION"));
use crate::slab::TEXEL_BYTES;

/// Bytes per texel of the uncompressed formats lightvol writes (RGBA16F 8, RGB9E5 and the
/// brick indirection's RGBA8 unsigned 4).
pub(crate) fn texel_bytes(format: Format) -> usize {
    if format == Format::E5B9G9R9_UFLOAT_PACK32 || format == Format::R8G8B8A8_UINT { 4 } else { TEXEL_BYTES }
}

/// The KTX2 `typeSize` of the formats lightvol writes (the size of one component, or of
/// the packed word).
fn type_size(format: Format) -> u32 {
    match format {
        Format::E5B9G9R9_UFLOAT_PACK32 => 4,
        Format::R8G8B8A8_UINT => 1,
        _ => 2,
    }
}

/// Assembles a single-level, uncompressed RGBA16F 3D KTX2 file. `texels` is the level data
/// (x fastest, then y, then z); `kvd` the key/value pairs, which must be sorted by key.
pub(crate) fn ktx2_rgba16f_bytes(dims: [u32; 3], texels: &[u8], kvd: &[(&str, &str)]) -> Vec<u8> {
    ktx2_bytes(Format::R16G16B16A16_SFLOAT, dims, texels, kvd)
}

/// [`ktx2_rgba16f_bytes`] for `format` (RGBA16F or RGB9E5, whose data-format descriptors the
/// `ktx2` crate generates).
pub(crate) fn ktx2_bytes(format: Format, dims: [u32; 3], texels: &[u8], kvd: &[(&str, &str)]) -> Vec<u8> {
    debug_assert_eq!(texels.len(), dims.iter().map(|&d| d as usize).product::<usize>() * texel_bytes(format));
    // Level data aligned to lcm(texel size 8, 4) = 8.
    lightvol_core::ktx2::container_bytes(format, dims, texels, kvd, 8)
}

/// `(dims, key/value pairs, level data)` of a parsed KTX2 file.
pub(crate) type ParsedKtx2 = ([u32; 3], Vec<(String, Vec<u8>)>, Vec<u8>);

/// Parses an RGBA16F 3D KTX2 file: checks the header (format, type size, one face, no
/// layers, one level, no supercompression), the level length against the dimensions, and
/// returns `(dims, key/value pairs, level data)`.
pub(crate) fn parse_ktx2_rgba16f(bytes: &[u8], format_tag: FileFormat) -> Result<ParsedKtx2, VolumeError> {
    parse_ktx2(bytes, format_tag, &[Format::R16G16B16A16_SFLOAT]).map(|(_, p)| p)
}

/// [`parse_ktx2_rgba16f`] for any of `formats` (RGBA16F, RGB9E5), also returning which.
pub(crate) fn parse_ktx2(
    bytes: &[u8],
    format_tag: FileFormat,
    formats: &[Format],
) -> Result<(Format, ParsedKtx2), VolumeError> {
    let bad = |r: String| VolumeError::malformed(format_tag, r);
    let reader = ktx2::Reader::new(bytes).map_err(|e| bad(e.to_string()))?;
    let h = reader.header();
    let Some(format) = h.format.filter(|f| formats.contains(f)) else {
        return Err(VolumeError::unsupported(
            format_tag,
            format!("pixel format {:?} (expected one of {formats:?})", h.format),
        ));
    };
    let type_size = type_size(format);
    if h.type_size != type_size {
        return Err(bad(format!("type size {} ({format:?} needs {type_size})", h.type_size)));
    }
    if h.supercompression_scheme.is_some() {
        return Err(VolumeError::unsupported(format_tag, "supercompressed data"));
    }
    if h.face_count != 1 || h.layer_count != 0 || h.level_count > 1 {
        return Err(VolumeError::unsupported(
            format_tag,
            format!(
                "{} faces, {} layers, {} levels (expected 1, 0, 1)",
                h.face_count, h.layer_count, h.level_count
            ),
        ));
    }
    if h.pixel_height == 0 || h.pixel_depth == 0 {
        return Err(bad("not a 3D texture (zero height or depth)".into()));
    }
    let dims = [h.pixel_width, h.pixel_height, h.pixel_depth];
    let want = dims
        .iter()
        .try_fold(texel_bytes(format), |acc, &d| acc.checked_mul(d as usize))
        .ok_or_else(|| bad("dimensions overflow".into()))?;
    let level = reader.levels().next().ok_or_else(|| bad("no mip level".into()))?;
    if level.data.len() != want || level.uncompressed_byte_length != want as u64 {
        return Err(bad(format!("level 0 has {} bytes, dimensions need {want}", level.data.len())));
    }
    let kvd = reader.key_value_data().map(|(k, v)| (k.to_string(), v.to_vec())).collect();
    Ok((format, (dims, kvd, level.data.to_vec())))
}

/// Serialises `vol` as an RGBA16F KTX2 3D texture in memory, in its scene file's frame
/// ([`crate::frame::to_file_frame`]; the sidecar's `frame` says which), so that engine
/// positions and normals need no conversion.
pub fn ktx2_to_bytes(vol: &IrradianceVolume) -> Result<Vec<u8>, VolumeError> {
    let frame = vol.metadata().frame;
    let vol = &crate::frame::to_file_frame(vol, frame)?;
    let [nx, ny, nz] = vol.spec().res();
    let depth = (vol.coeffs() as u32)
        .checked_mul(nz)
        .ok_or_else(|| VolumeError::InvalidData("texture depth overflows u32".into()))?;
    let mut sidecar = Sidecar::describe(
        vol,
        Encoding::F16,
        None,
        &format!("KTX2 R16G16B16A16_SFLOAT 3D texture; {SLAB_LAYOUT}"),
    )
    .in_frame(frame);
    sidecar.checksum = Some(to_hex(volume_checksum(&through_f16(vol, true)?)));
    let json = sidecar.to_json();
    Ok(ktx2_rgba16f_bytes(
        [nx, ny, depth],
        &slab_texels(vol)?,
        &[("KTXwriter", KTX2_WRITER), (KTX2_SIDECAR_KEY, &json)],
    ))
}

/// Writes `vol` as a KTX2 3D texture and its JSON sidecar beside it (`PATH.json`, the same
/// description the texture embeds), each by temporary file and rename.
pub fn write_ktx2(path: &Path, vol: &IrradianceVolume) -> Result<(), VolumeError> {
    let bytes = ktx2_to_bytes(vol)?;
    let mut sidecar = embedded_sidecar(&bytes)?;
    sidecar.storage.file = path.file_name().map(|n| n.to_string_lossy().into_owned());
    write_atomic(path, &bytes)?;
    crate::io::sidecar::write_sidecar(&crate::io::sidecar::sidecar_path(path), &sidecar)
}

/// The JSON sidecar a KTX2 volume embeds under [`KTX2_SIDECAR_KEY`].
pub fn embedded_sidecar(bytes: &[u8]) -> Result<Sidecar, VolumeError> {
    let f = FileFormat::Ktx2;
    let (_, kvd, _) = parse_ktx2_rgba16f(bytes, f)?;
    sidecar_of(&kvd)
}

/// The value of `key` in parsed key/value data, without the terminating NUL the KTX2
/// format allows; a missing key is a malformed `f` file.
pub(crate) fn kvd_value<'a>(
    kvd: &'a [(String, Vec<u8>)],
    key: &str,
    f: FileFormat,
) -> Result<&'a [u8], VolumeError> {
    let raw = kvd
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_slice())
        .ok_or_else(|| VolumeError::malformed(f, format!("missing key {key}")))?;
    Ok(raw.strip_suffix(&[0]).unwrap_or(raw))
}

fn sidecar_of(kvd: &[(String, Vec<u8>)]) -> Result<Sidecar, VolumeError> {
    let f = FileFormat::Ktx2;
    let raw = kvd_value(kvd, KTX2_SIDECAR_KEY, f)?;
    let text = std::str::from_utf8(raw).map_err(|e| VolumeError::malformed(f, e.to_string()))?;
    Sidecar::from_json(text)
}

/// Reads a volume written by [`write_ktx2`].
pub fn read_ktx2(path: &Path) -> Result<IrradianceVolume, VolumeError> {
    ktx2_from_bytes(&read_bounded(path)?)
}

/// Parses a KTX2 volume from memory (see the module docs for what is checked), returned in
/// lightvol's internal frame like the native file ([`crate::frame::to_internal_frame`] of
/// the texture's file-frame data).
pub fn ktx2_from_bytes(bytes: &[u8]) -> Result<IrradianceVolume, VolumeError> {
    let f = FileFormat::Ktx2;
    guard(f, || {
        let (dims, kvd, data) = parse_ktx2_rgba16f(bytes, f)?;
        if let Ok(groups) = kvd_value(&kvd, KTX2_GROUPS_KEY, f) {
            let names = serde_json::from_slice::<serde_json::Value>(groups)
                .ok()
                .and_then(|g| {
                    g["names"]
                        .as_array()
                        .map(|n| n.iter().filter_map(|x| x.as_str()).collect::<Vec<_>>().join(", "))
                })
                .unwrap_or_default();
            return Err(VolumeError::unsupported(
                f,
                format!(
                    "this is the stacked light-group texture of a grouped export (groups {names}), which the generated sampling code reads; open the whole volume or a group's file (the export's STEM.light_groups.json names them)"
                ),
            ));
        }
        let sidecar = sidecar_of(&kvd)?;
        if sidecar.encoding != Encoding::F16 {
            return Err(VolumeError::malformed(f, "sidecar encoding is not f16"));
        }
        let spec = sidecar.grid_spec()?;
        let coeffs = sidecar.sh.coeffs;
        let [nx, ny, nz] = spec.res();
        if [dims[0], dims[1]] != [nx, ny] || u64::from(dims[2]) != u64::from(nz) * coeffs as u64 {
            return Err(VolumeError::malformed(
                f,
                format!(
                    "texture is {dims:?}, the sidecar's grid needs [{nx}, {ny}, {}]",
                    nz as usize * coeffs
                ),
            ));
        }
        let (values, weights) = volume_from_slab_texels(spec.node_count(), coeffs, &data, f)?;
        let mut vol = IrradianceVolume::new(spec, coeffs, values, weights)?.with_metadata(sidecar.metadata());
        vol.set_validity(sidecar.validity_mask()?)?;
        vol.set_reach(sidecar.node_reach()?)?;
        verify(f, sidecar.checksum.as_deref(), &vol)?;
        // Back from the file's axes to the internal frame the native file and the lookups use.
        crate::frame::to_internal_frame(&vol, sidecar.frame)
    })
}
