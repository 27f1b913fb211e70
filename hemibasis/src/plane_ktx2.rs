//! KTX2 containers for coefficient planes: one 2D texture per coefficient, as \[Ish11\]
//! Listing 2.2 samples them (`h1 … h6`).
//!
//! The DC plane is tagged sRGB (`R8G8B8A8_SRGB`, `BC1_RGB_SRGB_BLOCK`, `BC7_SRGB_BLOCK`) so
//! the hardware decodes the transfer on sampling; use it with
//! [`crate::encode::DcTransfer::Srgb`], the curve GPUs implement exactly. The other planes
//! are `*_UNORM` and are decoded in the shader with `2 r v - r`. Files are assembled in
//! memory with the `ktx2` crate's header, level-index and data-format-descriptor types:
//! one level, one face, no layers, no supercompression. A key/value entry
//! [`KTX2_PLANE_KEY`] carries a caller-supplied description (for example JSON naming the
//! basis, the coefficient and the encoding). [`read_ktx2_plane`] parses such a file back
//! and checks it.

use ktx2::Format;

use crate::map::Plane;

/// Key of the plane description in the KTX2 key/value data.
pub const KTX2_PLANE_KEY: &str = "lightvol.plane";
/// Value of the `KTXwriter` key.
pub const KTX2_WRITER: &str = concat!("lightvol-hemibasis ", env!("CARGO_PKG_VERSION"));

/// The payloads this module writes and reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PlaneFormat {
    /// Uncompressed RGBA8.
    Rgba8,
    /// BC1 (DXT1) blocks.
    Bc1,
    /// BC7 blocks.
    Bc7,
}

impl PlaneFormat {
    fn vk(self, srgb: bool) -> Format {
        match (self, srgb) {
            (Self::Rgba8, false) => Format::R8G8B8A8_UNORM,
            (Self::Rgba8, true) => Format::R8G8B8A8_SRGB,
            (Self::Bc1, false) => Format::BC1_RGB_UNORM_BLOCK,
            (Self::Bc1, true) => Format::BC1_RGB_SRGB_BLOCK,
            (Self::Bc7, false) => Format::BC7_UNORM_BLOCK,
            (Self::Bc7, true) => Format::BC7_SRGB_BLOCK,
        }
    }

    fn from_vk(f: Format) -> Option<(Self, bool)> {
        [Self::Rgba8, Self::Bc1, Self::Bc7]
            .into_iter()
            .flat_map(|p| [(p, false), (p, true)])
            .find(|&(p, s)| p.vk(s) == f)
    }

    /// Bytes of level data for a `width × height` plane.
    #[must_use]
    pub fn data_len(self, width: usize, height: usize) -> usize {
        match self {
            Self::Rgba8 => width * height * 4,
            Self::Bc1 => width.div_ceil(4) * height.div_ceil(4) * 8,
            Self::Bc7 => width.div_ceil(4) * height.div_ceil(4) * 16,
        }
    }
}

/// A parsed plane texture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Ktx2Plane {
    /// Payload format.
    pub format: PlaneFormat,
    /// True when the texture is tagged sRGB.
    pub srgb: bool,
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Level-0 data (RGBA8 texels or blocks).
    pub data: Vec<u8>,
    /// The [`KTX2_PLANE_KEY`] value, if present.
    pub description: Option<String>,
}

/// Why a KTX2 plane could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// Not a KTX2 file, or a broken one.
    #[error("malformed KTX2 plane: {0}")]
    Malformed(String),
    /// A valid KTX2 file this module does not write (3D, arrays, mips, other formats).
    #[error("unsupported KTX2 plane: {0}")]
    Unsupported(String),
}

/// A single-level 2D KTX2 texture holding `data` in `format`.
///
/// # Panics
/// If `data.len()` does not match the format and size.
#[must_use]
pub fn ktx2_plane_bytes(
    format: PlaneFormat,
    srgb: bool,
    width: usize,
    height: usize,
    data: &[u8],
    description: &str,
) -> Vec<u8> {
    assert_eq!(data.len(), format.data_len(width, height), "level data does not match the size");
    let dims = [width as u32, height as u32, 0];
    // Key/value data sorted by key ('K' < 'l'); level data aligned to lcm(texel or block
    // size, 4) = 16, which covers every format here.
    lightvol_core::ktx2::container_bytes(
        format.vk(srgb),
        dims,
        data,
        &[("KTXwriter", KTX2_WRITER), (KTX2_PLANE_KEY, description)],
        16,
    )
}

/// [`ktx2_plane_bytes`] for an uncompressed plane.
#[must_use]
pub fn ktx2_rgba8(plane: &Plane, srgb: bool, description: &str) -> Vec<u8> {
    ktx2_plane_bytes(PlaneFormat::Rgba8, srgb, plane.width, plane.height, &plane.rgba_bytes(), description)
}

/// [`ktx2_plane_bytes`] for a block-compressed plane.
#[cfg(feature = "bc")]
#[must_use]
pub fn ktx2_compressed(plane: &crate::bc::CompressedPlane, srgb: bool, description: &str) -> Vec<u8> {
    let format = match plane.format {
        crate::bc::BlockFormat::Bc1 => PlaneFormat::Bc1,
        crate::bc::BlockFormat::Bc7 => PlaneFormat::Bc7,
    };
    ktx2_plane_bytes(format, srgb, plane.width, plane.height, &plane.blocks, description)
}

/// Parses a plane written by [`ktx2_plane_bytes`] (or any single-level 2D RGBA8/BC1/BC7
/// KTX2 file without supercompression).
///
/// # Errors
/// [`TextureError`] for anything else, naming what was found.
pub fn read_ktx2_plane(bytes: &[u8]) -> Result<Ktx2Plane, TextureError> {
    let reader = ktx2::Reader::new(bytes).map_err(|e| TextureError::Malformed(e.to_string()))?;
    let h = reader.header();
    let (format, srgb) = h
        .format
        .and_then(PlaneFormat::from_vk)
        .ok_or_else(|| TextureError::Unsupported(format!("pixel format {:?}", h.format)))?;
    if h.supercompression_scheme.is_some()
        || h.face_count != 1
        || h.layer_count != 0
        || h.level_count > 1
        || h.pixel_depth != 0
        || h.pixel_height == 0
    {
        return Err(TextureError::Unsupported(format!(
            "{}×{}×{}, {} faces, {} layers, {} levels, supercompression {:?} (expected one 2D level)",
            h.pixel_width,
            h.pixel_height,
            h.pixel_depth,
            h.face_count,
            h.layer_count,
            h.level_count,
            h.supercompression_scheme
        )));
    }
    let (width, height) = (h.pixel_width as usize, h.pixel_height as usize);
    let level = reader.levels().next().ok_or_else(|| TextureError::Malformed("no mip level".into()))?;
    let want = format.data_len(width, height);
    if level.data.len() != want {
        return Err(TextureError::Malformed(format!(
            "level 0 has {} bytes, {want} expected",
            level.data.len()
        )));
    }
    let description = reader
        .key_value_data()
        .find(|(k, _)| *k == KTX2_PLANE_KEY)
        .map(|(_, v)| String::from_utf8_lossy(v.strip_suffix(&[0]).unwrap_or(v)).into_owned());
    Ok(Ktx2Plane { format, srgb, width, height, data: level.data.to_vec(), description })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgba8_plane_round_trips_through_ktx2() {
        let plane = Plane { width: 3, height: 2, texels: (0..6).map(|i| [i, 2 * i, 3 * i, 255]).collect() };
        let bytes = ktx2_rgba8(&plane, true, "{\"coefficient\":0}");
        let back = read_ktx2_plane(&bytes).unwrap();
        assert_eq!((back.format, back.srgb, back.width, back.height), (PlaneFormat::Rgba8, true, 3, 2));
        assert_eq!(back.data, plane.rgba_bytes());
        assert_eq!(back.description.as_deref(), Some("{\"coefficient\":0}"));
    }

    #[cfg(feature = "bc")]
    #[test]
    fn compressed_plane_round_trips_through_ktx2() {
        use crate::bc::{BlockFormat, compress, decompress};
        let plane =
            Plane { width: 5, height: 6, texels: (0..30).map(|i| [8 * i, 100, 255 - 8 * i, 255]).collect() };
        for f in [BlockFormat::Bc1, BlockFormat::Bc7] {
            let c = compress(&plane, f);
            let back = read_ktx2_plane(&ktx2_compressed(&c, false, "x")).unwrap();
            assert!(!back.srgb);
            assert_eq!(back.data, c.blocks);
            let again = crate::bc::CompressedPlane {
                format: f,
                width: back.width,
                height: back.height,
                blocks: back.data,
            };
            assert_eq!(decompress(&again), decompress(&c));
        }
    }

    #[test]
    fn garbage_is_a_clear_error() {
        let e = read_ktx2_plane(b"not a texture").unwrap_err();
        assert!(e.to_string().starts_with("malformed KTX2 plane"), "{e}");
    }
}
