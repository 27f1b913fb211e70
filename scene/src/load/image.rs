//! Base-colour images as the loaders read them: PNG or JPEG told apart by their first
//! bytes, refused from the header when larger than [`MAX_TEXELS`], decoded into a
//! [`Texture`]. One decoder for glTF and OBJ, so both refuse the same images for the
//! same reasons.

use crate::base_color::Texture;

/// Most texels an image may have: 2^26 (8192 × 8192; 256 MiB as the 8-bit RGBA a texture
/// keeps, with the decoder's own copy beside it while it decodes). The decoder's own limit
/// is on its bytes (512 MiB), which a PNG of a few hundred KB reaches: a 261 KB
/// 16384 × 16384 grey PNG used to become 4.3 GB of texture.
pub(crate) const MAX_TEXELS: u64 = 1 << 26;

/// Image formats told apart by their first bytes.
pub(crate) fn sniff(bytes: &[u8]) -> &'static str {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        "png"
    } else if bytes.starts_with(&[0xff, 0xd8, 0xff]) {
        "jpeg"
    } else if bytes.starts_with(b"DDS ") {
        "DDS"
    } else if bytes.starts_with(b"\xabKTX 20\xbb") {
        "KTX2"
    } else if bytes.len() >= 12 && &bytes[..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        "WebP"
    } else {
        "unknown"
    }
}

/// Decodes the image `bytes` (named `label` in messages: "image 3", a file path): PNG or
/// JPEG of at most [`MAX_TEXELS`] texels, its size read from the header before anything
/// is decoded.
///
/// # Errors
/// A one-line reason naming `label`: another format, a damaged header or body, too many
/// texels, no texels.
pub(crate) fn decode_texture(bytes: &[u8], label: &str) -> Result<Texture, String> {
    let format = match sniff(bytes) {
        "png" => image::ImageFormat::Png,
        "jpeg" => image::ImageFormat::Jpeg,
        other => return Err(format!("{label} is {other}, which this build does not decode")),
    };
    let reader = || image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let (w, h) = reader().into_dimensions().map_err(|e| format!("{label}: {e}"))?;
    if u64::from(w) * u64::from(h) > MAX_TEXELS {
        return Err(format!("{label} is {w}×{h}, more than the {MAX_TEXELS} texels a texture may have"));
    }
    let decoded = reader().decode().map_err(|e| format!("{label}: {e}"))?;
    Texture::from_image(&decoded).ok_or_else(|| format!("{label} is empty"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_formats_are_sniffed() {
        assert_eq!(sniff(b"DDS \x7c\0\0\0"), "DDS");
        assert_eq!(sniff(b"\xabKTX 20\xbb\r\n"), "KTX2");
        assert_eq!(sniff(b"RIFF\0\0\0\0WEBPVP8 "), "WebP");
        assert_eq!(sniff(b"\x89PNG\r\n\x1a\n"), "png");
        assert_eq!(sniff(&[0xff, 0xd8, 0xff, 0xe0]), "jpeg");
        assert_eq!(sniff(b"xyz"), "unknown");
    }

    /// A PNG decodes to its texels; other formats and damaged files are one-line
    /// reasons naming the image.
    #[test]
    fn pngs_decode_and_others_are_refused_by_name() {
        let mut png = Vec::new();
        image::RgbImage::from_fn(3, 2, |x, _| image::Rgb([255 * (x % 2) as u8, 0, 0]))
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let t = decode_texture(&png, "image 0").unwrap();
        assert_eq!((t.width(), t.height()), (3, 2));
        assert_eq!((t.texel(0, 0), t.texel(1, 1)), ([0.0; 3], [1.0, 0.0, 0.0]));
        let e = decode_texture(b"DDS \x7c\0\0\0", "a.dds").unwrap_err();
        assert_eq!(e, "a.dds is DDS, which this build does not decode");
        let e = decode_texture(&png[..20], "image 7").unwrap_err();
        assert!(e.starts_with("image 7: ") && !e.contains('\n'), "{e}");
    }
}
