//! Engine export: a DDS volume texture (`ddsfile`), RGBA16F with a DX10 header
//! (`DXGI_FORMAT_R16G16B16A16_FLOAT`, `D3D10_RESOURCE_DIMENSION_TEXTURE3D`), in the
//! coefficient-slab layout of [`crate::slab`] (width `nx`, height `ny`, depth `coeffs·nz`,
//! weight in alpha) — the 3D-texture route of \[Ish11\] §2.3.
//!
//! DDS has no room for metadata, so [`write_dds`] also writes the JSON sidecar (with the
//! validity mask, if the volume has one) beside the texture (`name.dds.json`, [`crate::io::sidecar::sidecar_path`]) and [`read_dds`] requires it;
//! the reader checks the DDS header (DX10 extension, format, 3D dimension, one array
//! element, one mip level) and the data length against the sidecar's grid.

use std::io::Cursor;
use std::path::Path;

use ddsfile::{AlphaMode, Caps2, D3D10ResourceDimension, Dds, DxgiFormat, NewDxgiParams};

use crate::checksum::{through_f16, to_hex, verify, volume_checksum};
use crate::encode::Encoding;
use crate::error::{FileFormat, VolumeError};
use crate::io::sidecar::{Sidecar, read_sidecar, sidecar_path, write_sidecar};
use crate::io::util::{guard, read_bounded, write_atomic};
use crate::slab::{SLAB_LAYOUT, slab_texels, volume_from_slab_texels};
use crate::volume::IrradianceVolume;

const F: FileFormat = FileFormat::Dds;

/// Both the texture and the sidecar are in the scene file's frame
/// ([`crate::frame::to_file_frame`]).
///
/// The sidecar that [`write_dds`] writes beside a DDS file named `file` (with the checksum
/// of the volume as the DDS decodes to); errors if a value exceeds the f16 range.
pub fn dds_sidecar(vol: &IrradianceVolume, file: Option<String>) -> Result<Sidecar, VolumeError> {
    let vol = &crate::frame::to_file_frame(vol, vol.metadata().frame)?;
    let mut s = Sidecar::describe(
        vol,
        Encoding::F16,
        file,
        &format!("DDS DXGI_FORMAT_R16G16B16A16_FLOAT volume texture; {SLAB_LAYOUT}"),
    )
    .in_frame(vol.metadata().frame);
    s.checksum = Some(to_hex(volume_checksum(&through_f16(vol, true)?)));
    Ok(s)
}

/// Serialises `vol` as an RGBA16F DDS volume texture in memory (the texture only).
pub fn dds_to_bytes(vol: &IrradianceVolume) -> Result<Vec<u8>, VolumeError> {
    let vol = &crate::frame::to_file_frame(vol, vol.metadata().frame)?;
    let [nx, ny, nz] = vol.spec().res();
    let depth = (vol.coeffs() as u32)
        .checked_mul(nz)
        .ok_or_else(|| VolumeError::InvalidData("texture depth overflows u32".into()))?;
    let mut dds = Dds::new_dxgi(NewDxgiParams {
        height: ny,
        width: nx,
        depth: Some(depth),
        format: DxgiFormat::R16G16B16A16_Float,
        mipmap_levels: Some(1),
        array_layers: None,
        caps2: Some(Caps2::VOLUME),
        is_cubemap: false,
        resource_dimension: D3D10ResourceDimension::Texture3D,
        alpha_mode: AlphaMode::Straight,
    })
    .map_err(|e| VolumeError::InvalidData(format!("DDS header: {e}")))?;
    let texels = slab_texels(vol)?;
    if dds.data.len() != texels.len() {
        return Err(VolumeError::InvalidData(format!(
            "ddsfile sized the volume at {} bytes, the slabs have {}",
            dds.data.len(),
            texels.len()
        )));
    }
    dds.data = texels;
    let mut out = Vec::new();
    dds.write(&mut out).map_err(|e| VolumeError::InvalidData(format!("DDS writer: {e}")))?;
    Ok(out)
}

/// Parses a DDS volume written by [`dds_to_bytes`], with its sidecar.
pub fn dds_from_bytes(bytes: &[u8], sidecar: &Sidecar) -> Result<IrradianceVolume, VolumeError> {
    sidecar.validate()?;
    if sidecar.encoding != Encoding::F16 {
        return Err(VolumeError::malformed(F, "sidecar encoding is not f16"));
    }
    let spec = sidecar.grid_spec()?;
    let coeffs = sidecar.sh.coeffs;
    guard(F, || {
        let dds = Dds::read(Cursor::new(bytes)).map_err(|e| VolumeError::malformed(F, e.to_string()))?;
        let h10 = dds.header10.as_ref().ok_or_else(|| VolumeError::unsupported(F, "no DX10 header"))?;
        if h10.dxgi_format != DxgiFormat::R16G16B16A16_Float {
            return Err(VolumeError::unsupported(
                F,
                format!("format {:?} (expected RGBA16F)", h10.dxgi_format),
            ));
        }
        if h10.resource_dimension != D3D10ResourceDimension::Texture3D || h10.array_size > 1 {
            return Err(VolumeError::unsupported(
                F,
                format!(
                    "{:?} with {} array elements (expected one 3D texture)",
                    h10.resource_dimension, h10.array_size
                ),
            ));
        }
        if dds.header.mip_map_count.unwrap_or(1) > 1 {
            return Err(VolumeError::unsupported(F, "mip maps"));
        }
        let [nx, ny, nz] = spec.res();
        let dims = [dds.header.width, dds.header.height, dds.header.depth.unwrap_or(0)];
        if [dims[0], dims[1]] != [nx, ny] || u64::from(dims[2]) != u64::from(nz) * coeffs as u64 {
            return Err(VolumeError::malformed(
                F,
                format!(
                    "texture is {dims:?}, the sidecar's grid needs [{nx}, {ny}, {}]",
                    nz as usize * coeffs
                ),
            ));
        }
        let (values, weights) = volume_from_slab_texels(spec.node_count(), coeffs, &dds.data, F)?;
        let mut vol =
            IrradianceVolume::new(spec.clone(), coeffs, values, weights)?.with_metadata(sidecar.metadata());
        vol.set_validity(sidecar.validity_mask()?)?;
        vol.set_reach(sidecar.node_reach()?)?;
        verify(F, sidecar.checksum.as_deref(), &vol)?;
        // Back from the file's axes to the internal frame the native file and the lookups use.
        crate::frame::to_internal_frame(&vol, sidecar.frame)
    })
}

/// Writes `path` (the DDS texture) and `path.json` (its sidecar), each atomically.
pub fn write_dds(path: &Path, vol: &IrradianceVolume) -> Result<(), VolumeError> {
    let bytes = dds_to_bytes(vol)?;
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    write_atomic(path, &bytes)?;
    write_sidecar(&sidecar_path(path), &dds_sidecar(vol, name)?)
}

/// Reads a DDS volume and the sidecar beside it.
pub fn read_dds(path: &Path) -> Result<IrradianceVolume, VolumeError> {
    let sidecar = read_sidecar(&sidecar_path(path))?;
    dds_from_bytes(&read_bounded(path)?, &sidecar)
}
