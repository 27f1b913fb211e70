//! Generic EXR images, not only volumes: the single-threaded encode and pedantic decode
//! pipelines of every lightvol EXR file (volumes, surface maps, plates, views) and the
//! canonical attribute order that makes equal images equal bytes (OpenEXR file layout:
//! magic number, version, headers of `name\0 type\0 size value` attributes).

use std::io::Cursor;

use exr::image::{AnyChannels, FlatSamples, Image, Layer};
use exr::meta::attribute::Text;
use exr::meta::header::ImageAttributes;
use exr::prelude::{ReadChannels, ReadLayers, WritableImage};

use crate::error::VolumeError;

/// `s` as an EXR text attribute; errors if it has characters EXR text cannot hold.
pub(crate) fn text(s: &str) -> Result<Text, VolumeError> {
    Text::new_or_none(s).ok_or_else(|| {
        VolumeError::InvalidData(format!("{s:?} has characters EXR text attributes cannot hold"))
    })
}

/// One part of an EXR file with flat (not deep) channels.
pub type ExrLayer = Layer<AnyChannels<FlatSamples>>;

/// A whole EXR file of flat parts, as [`decode_image`] reads it.
pub type ExrImage = Image<exr::image::Layers<AnyChannels<FlatSamples>>>;

/// Encodes parts into EXR bytes, single-threaded, attributes in the canonical order
/// ([`canonical_attribute_order`]): the write pipeline of every lightvol EXR file (volumes,
/// surface maps, plates, views), so that equal images give equal bytes.
///
/// # Errors
/// [`VolumeError::InvalidData`] if the encoder refuses the parts.
pub fn encode_image(ia: ImageAttributes, layers: Vec<ExrLayer>) -> Result<Vec<u8>, VolumeError> {
    let image = Image::from_layers(ia, layers);
    let mut out = Cursor::new(Vec::new());
    image
        .write()
        .non_parallel()
        .to_buffered(&mut out)
        .map_err(|e| VolumeError::InvalidData(format!("EXR encoder: {e}")))?;
    let mut bytes = out.into_inner();
    canonical_attribute_order(&mut bytes)?;
    Ok(bytes)
}

/// Decodes every flat part of an EXR file, all channels and attributes, single-threaded and
/// pedantic (a damaged file is an error, not a guess): the read pipeline of every lightvol
/// EXR reader, run after the reader has checked the headers it expects.
///
/// # Errors
/// The `exr` crate's error for data it cannot decode.
pub fn decode_image(bytes: &[u8]) -> Result<ExrImage, exr::error::Error> {
    exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .non_parallel()
        .pedantic()
        .from_buffered(Cursor::new(bytes))
}

/// Puts the attributes of every header of an EXR file in a fixed order, in place, so that
/// equal images give equal bytes.
///
/// The `exr` crate keeps custom attributes in a `std` `HashMap`
/// (`ImageAttributes::other`, `LayerAttributes::other`) and writes them in that map's
/// iteration order, which the randomly seeded hasher makes differ from map to map and from
/// run to run: two writes of the same volume came out with the same attributes in different
/// orders. Here every header keeps the standard attributes (the names of
/// `exr::meta::header::standard_names`) first, in the order the crate wrote them (fixed by
/// its code), and the custom ones follow, sorted by name (bytewise). Attributes only move
/// within their header and every header keeps its length, so the offset tables, which hold
/// absolute file positions, stay valid and the pixel data is untouched.
///
/// Every writer of EXR files in lightvol (volumes, adaptive volumes, surface maps, plates)
/// calls this on the encoder's output. Errors (leaving `bytes` unchanged) if `bytes` is not
/// an EXR file whose headers parse.
pub fn canonical_attribute_order(bytes: &mut [u8]) -> Result<(), VolumeError> {
    for header in header_layout(bytes)? {
        let name = |a: &RawAttribute| &bytes[a.name.clone()];
        let whole = |a: &RawAttribute| &bytes[a.bytes.clone()];
        let (standard, mut custom): (Vec<&RawAttribute>, Vec<&RawAttribute>) =
            header.attributes.iter().partition(|a| is_standard_attribute(name(a)));
        // By name; by the whole attribute if a (malformed) header repeats a name.
        custom.sort_by(|a, b| name(a).cmp(name(b)).then_with(|| whole(a).cmp(whole(b))));
        let mut ordered = Vec::with_capacity(header.bytes.len());
        for a in standard.into_iter().chain(custom) {
            ordered.extend_from_slice(whole(a));
        }
        debug_assert_eq!(ordered.len(), header.bytes.len(), "a header's attributes fill it exactly");
        bytes[header.bytes].copy_from_slice(&ordered);
    }
    Ok(())
}

/// The attribute names of every header of an EXR file, in file order (what
/// [`canonical_attribute_order`] arranges); errors if the headers do not parse.
pub fn header_attribute_names(bytes: &[u8]) -> Result<Vec<Vec<String>>, VolumeError> {
    Ok(header_layout(bytes)?
        .into_iter()
        .map(|h| {
            h.attributes
                .iter()
                .map(|a| String::from_utf8_lossy(&bytes[a.name.clone()]).into_owned())
                .collect()
        })
        .collect())
}

/// Whether `name` is one of the attribute names the OpenEXR standard defines.
fn is_standard_attribute(name: &[u8]) -> bool {
    exr::meta::header::standard_names::ALL.contains(&name)
}

/// One attribute of a header: its bytes (name, type, size, value) and its name's bytes.
struct RawAttribute {
    bytes: std::ops::Range<usize>,
    name: std::ops::Range<usize>,
}

/// One header: the bytes of its attributes (without the terminating zero byte) and each
/// attribute.
struct RawHeader {
    bytes: std::ops::Range<usize>,
    attributes: Vec<RawAttribute>,
}

/// Where the headers and their attributes lie in an EXR file (the OpenEXR file layout:
/// magic number, version and flags, then one header, or for multi-part files headers up to
/// an empty one; a header is a list of `name\0 type\0 size value` ended by a zero byte).
fn header_layout(bytes: &[u8]) -> Result<Vec<RawHeader>, VolumeError> {
    let bad = |what: &str| VolumeError::InvalidData(format!("EXR headers: {what}"));
    const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
    const MULTIPART: u32 = 0x1000;
    if bytes.len() < 8 || bytes[..4] != MAGIC {
        return Err(bad("not an EXR file"));
    }
    let multipart = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) & MULTIPART != 0;
    // The zero-terminated string at `*pos`, without its terminator.
    let cstr = |pos: &mut usize| -> Result<std::ops::Range<usize>, VolumeError> {
        let len = bytes
            .get(*pos..)
            .and_then(|rest| rest.iter().position(|&b| b == 0))
            .ok_or_else(|| bad("unterminated name"))?;
        let r = *pos..*pos + len;
        *pos += len + 1;
        Ok(r)
    };
    let mut headers = Vec::new();
    let mut pos = 8usize;
    loop {
        if multipart && bytes.get(pos) == Some(&0) {
            break; // the empty header that ends a multi-part file's header list
        }
        let start = pos;
        let mut attributes = Vec::new();
        loop {
            let at = pos;
            let name = cstr(&mut pos)?;
            if name.is_empty() {
                break;
            }
            cstr(&mut pos)?; // the type name
            let size = bytes.get(pos..pos + 4).ok_or_else(|| bad("truncated attribute size"))?;
            let size = usize::try_from(i32::from_le_bytes([size[0], size[1], size[2], size[3]]))
                .map_err(|_| bad("negative attribute size"))?;
            pos = pos
                .checked_add(4 + size)
                .filter(|&end| end <= bytes.len())
                .ok_or_else(|| bad("truncated attribute value"))?;
            attributes.push(RawAttribute { bytes: at..pos, name });
        }
        headers.push(RawHeader { bytes: start..pos - 1, attributes });
        if !multipart {
            break;
        }
    }
    Ok(headers)
}
