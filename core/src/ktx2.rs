//! The KTX 2.0 container (Khronos, "KTX File Format Specification", version 2.0): one
//! level, one face, no layers, no supercompression; the header, level index and
//! data-format descriptor come from the `ktx2` crate's types. Volume exports (3D RGBA16F,
//! RGB9E5) and hemispherical-basis planes (2D RGBA8, BC1, BC7) are written by this one
//! function.

use ktx2::{Format, Header, Index, LevelIndex, SupercompressionScheme};

/// A single-level KTX2 file holding `data` in `format`, `dims` = width, height, depth
/// (depth 0 for a 2D texture), with the key/value pairs `kvd` (which KTX2 requires sorted
/// by key; each stored as a u32 length of `key\0value\0`, padded to 4 bytes). The level
/// data starts at a multiple of `align` (at least the texel or block size, and 4).
///
/// # Panics
/// If `format` has no data-format descriptor in the `ktx2` crate (every format lightvol
/// writes has one), or, in debug builds, if `kvd` is not sorted.
#[must_use]
pub fn container_bytes(
    format: Format,
    dims: [u32; 3],
    data: &[u8],
    kvd: &[(&str, &str)],
    align: usize,
) -> Vec<u8> {
    // A fixed order also keeps the bytes reproducible.
    debug_assert!(kvd.windows(2).all(|w| w[0].0.as_bytes() < w[1].0.as_bytes()), "unsorted KTX2 keys");
    let (dfd, type_size) =
        ktx2::dfd::Basic::from_format(format).expect("lightvol's formats have generated DFDs");
    let dfd_block = ktx2::dfd::Block::Basic(dfd).to_vec();
    let mut dfd_bytes = Vec::with_capacity(4 + dfd_block.len());
    dfd_bytes.extend_from_slice(&((4 + dfd_block.len()) as u32).to_le_bytes());
    dfd_bytes.extend_from_slice(&dfd_block);

    let mut kvd_bytes = Vec::new();
    for (k, v) in kvd {
        let len = k.len() + 1 + v.len() + 1;
        kvd_bytes.extend_from_slice(&(len as u32).to_le_bytes());
        kvd_bytes.extend_from_slice(k.as_bytes());
        kvd_bytes.push(0);
        kvd_bytes.extend_from_slice(v.as_bytes());
        kvd_bytes.push(0);
        while kvd_bytes.len() % 4 != 0 {
            kvd_bytes.push(0);
        }
    }

    let dfd_offset = Header::LENGTH + LevelIndex::LENGTH;
    let kvd_offset = dfd_offset + dfd_bytes.len();
    let data_offset = (kvd_offset + kvd_bytes.len()).next_multiple_of(align.max(4));
    let header = Header {
        format: Some(format),
        type_size,
        pixel_width: dims[0],
        pixel_height: dims[1],
        pixel_depth: dims[2],
        layer_count: 0,
        face_count: 1,
        level_count: 1,
        supercompression_scheme: None::<SupercompressionScheme>,
        index: Index {
            dfd_byte_offset: dfd_offset as u32,
            dfd_byte_length: dfd_bytes.len() as u32,
            kvd_byte_offset: if kvd_bytes.is_empty() { 0 } else { kvd_offset as u32 },
            kvd_byte_length: kvd_bytes.len() as u32,
            sgd_byte_offset: 0,
            sgd_byte_length: 0,
        },
    };
    let level = LevelIndex {
        byte_offset: data_offset as u64,
        byte_length: data.len() as u64,
        uncompressed_byte_length: data.len() as u64,
    };
    let mut out = Vec::with_capacity(data_offset + data.len());
    out.extend_from_slice(&header.as_bytes());
    out.extend_from_slice(&level.as_bytes());
    out.extend_from_slice(&dfd_bytes);
    out.extend_from_slice(&kvd_bytes);
    out.resize(data_offset, 0);
    out.extend_from_slice(data);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `ktx2` crate's reader (an independent parser) reads back the header, the keys and
    /// the level, and the level starts at the requested alignment.
    #[test]
    fn the_ktx2_reader_reads_it_back() {
        let data: Vec<u8> = (0..2 * 3 * 4 * 8).map(|i| i as u8).collect();
        let bytes = container_bytes(
            Format::R16G16B16A16_SFLOAT,
            [2, 3, 4],
            &data,
            &[("KTXwriter", "t"), ("x", "yz")],
            16,
        );
        let r = ktx2::Reader::new(&bytes[..]).unwrap();
        let h = r.header();
        assert_eq!((h.pixel_width, h.pixel_height, h.pixel_depth, h.level_count), (2, 3, 4, 1));
        assert_eq!(h.format, Some(Format::R16G16B16A16_SFLOAT));
        let kv: Vec<(String, Vec<u8>)> =
            r.key_value_data().map(|(k, v)| (k.to_owned(), v.to_vec())).collect();
        assert_eq!(kv, [("KTXwriter".to_owned(), b"t\0".to_vec()), ("x".to_owned(), b"yz\0".to_vec())]);
        let level = r.levels().next().unwrap();
        assert_eq!(level.data, &data[..]);
        let offset = bytes.len() - data.len();
        assert_eq!(offset % 16, 0);
        // No key/value data: a zero offset, as the specification asks.
        let bare = container_bytes(Format::R8G8B8A8_UNORM, [1, 1, 0], &[1, 2, 3, 4], &[], 4);
        assert_eq!(ktx2::Reader::new(&bare[..]).unwrap().header().index.kvd_byte_offset, 0);
    }
}
