//! Block compression of encoded coefficient planes: BC1 (DXT1, \[Ish11\] §2.2.4) and BC7.
//!
//! Both go through the pure-Rust `block_compression` crate (a CPU port of Intel's ISPC
//! texture compressor kernels), which also decodes them; round trips here use that crate
//! both ways. Planes whose size is not a multiple of 4 are padded by repeating the last
//! row and column (so padding never pulls a block's endpoints away from real texels) and
//! cropped after decoding.
//!
//! Storage per texel and coefficient: BC1 0.5 bytes (6:1 against RGB8, 8:1 against RGBA8),
//! BC7 1 byte. \[Ish11\] §2.2.4 warns that the errors of several compressed planes add up
//! in the sum `Σ c_j H_j(n)`; [`crate::map::map_error`] measures exactly that sum's error.

use block_compression::decode::decompress_blocks_as_rgba8;
use block_compression::encode::compress_rgba8;
use block_compression::{BC7Settings, CompressionVariant};

use crate::HemiBasis;
use crate::encode::{ClampStats, Encoding};
use crate::map::{CoeffMap, MapError, Plane, map_error};

/// A GPU block-compression format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BlockFormat {
    /// BC1 / DXT1: two RGB565 endpoints and 2-bit indices per 4×4 block (8 bytes).
    Bc1,
    /// BC7: 16 bytes per 4×4 block, opaque modes, `block_compression`'s "basic" opaque
    /// settings.
    Bc7,
}

impl BlockFormat {
    /// Lower-case name (`"bc1"`, `"bc7"`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Bc1 => "bc1",
            Self::Bc7 => "bc7",
        }
    }

    /// Bytes per 4×4 block.
    #[must_use]
    pub const fn block_bytes(self) -> usize {
        match self {
            Self::Bc1 => 8,
            Self::Bc7 => 16,
        }
    }

    /// Bytes per texel of one plane (`block_bytes / 16`).
    #[must_use]
    pub fn bytes_per_texel(self) -> f64 {
        self.block_bytes() as f64 / 16.0
    }

    fn variant(self) -> CompressionVariant {
        match self {
            Self::Bc1 => CompressionVariant::BC1,
            Self::Bc7 => CompressionVariant::BC7(BC7Settings::opaque_basic()),
        }
    }
}

/// A block-compressed plane.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CompressedPlane {
    /// The format of [`Self::blocks`].
    pub format: BlockFormat,
    /// Width of the (uncropped) plane in texels.
    pub width: usize,
    /// Height of the plane in texels.
    pub height: usize,
    /// The blocks, row-major over `ceil(width/4) × ceil(height/4)` blocks.
    pub blocks: Vec<u8>,
}

fn padded(n: usize) -> usize {
    n.div_ceil(4) * 4
}

/// Block-compresses `plane` to `format`.
///
/// # Panics
/// If the plane is empty or larger than `u32::MAX` texels on a side.
#[must_use]
pub fn compress(plane: &Plane, format: BlockFormat) -> CompressedPlane {
    assert!(plane.width > 0 && plane.height > 0, "empty plane");
    let (pw, ph) = (padded(plane.width), padded(plane.height));
    let mut rgba = Vec::with_capacity(pw * ph * 4);
    for y in 0..ph {
        let sy = y.min(plane.height - 1);
        for x in 0..pw {
            let sx = x.min(plane.width - 1);
            rgba.extend_from_slice(&plane.texels[sy * plane.width + sx]);
        }
    }
    let (w32, h32) =
        (u32::try_from(pw).expect("width fits u32"), u32::try_from(ph).expect("height fits u32"));
    let variant = format.variant();
    let mut blocks = vec![0u8; variant.blocks_byte_size(w32, h32)];
    compress_rgba8(variant, &rgba, &mut blocks, w32, h32, w32 * 4);
    CompressedPlane { format, width: plane.width, height: plane.height, blocks }
}

/// Decodes a compressed plane back to RGBA8 (cropped to its size), with the same crate.
///
/// # Panics
/// If `blocks` does not hold exactly the blocks of the plane's padded size.
#[must_use]
pub fn decompress(c: &CompressedPlane) -> Plane {
    let (pw, ph) = (padded(c.width), padded(c.height));
    let (w32, h32) = (pw as u32, ph as u32);
    let mut rgba = vec![0u8; pw * ph * 4];
    decompress_blocks_as_rgba8(c.format.variant(), w32, h32, &c.blocks, &mut rgba);
    let mut texels = Vec::with_capacity(c.width * c.height);
    for y in 0..c.height {
        for x in 0..c.width {
            let i = (y * pw + x) * 4;
            texels.push([rgba[i], rgba[i + 1], rgba[i + 2], rgba[i + 3]]);
        }
    }
    Plane { width: c.width, height: c.height, texels }
}

/// `decompress(compress(plane, format))`.
#[must_use]
pub fn round_trip(plane: &Plane, format: BlockFormat) -> Plane {
    decompress(&compress(plane, format))
}

/// Encodes `map` with `enc` into 8-bit planes, optionally block-compresses and decodes
/// every plane with `format`, decodes the coefficients, and returns the irradiance error
/// of the whole round trip against `map` ([`map_error`]) with the clamp counts.
#[must_use]
pub fn stored_map_error(
    basis: &dyn HemiBasis,
    map: &CoeffMap,
    enc: &Encoding,
    format: Option<BlockFormat>,
) -> (MapError, ClampStats) {
    let (mut planes, clamped) = enc.encode_map(basis, map);
    if let Some(f) = format {
        for p in &mut planes {
            *p = round_trip(p, f);
        }
    }
    (map_error(basis, map, &enc.decode_map(basis, &planes)), clamped)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// BC1 reproduces a constant block to within RGB565 rounding of the endpoints plus the
    /// 1/3-2/3 palette interpolation: at most one 5-bit step, 255/31 ≈ 8.2 → 9 codes.
    const BC1_CONSTANT_TOL: i32 = 9;
    /// BC7's opaque modes keep at least 5-bit endpoints with a shared p-bit and 3-4 bit
    /// indices; a constant colour comes back within a couple of codes.
    const BC7_CONSTANT_TOL: i32 = 2;

    fn gradient(w: usize, h: usize) -> Plane {
        let texels = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                [(x * 255 / w.max(1)) as u8, (y * 255 / h.max(1)) as u8, 128, 255]
            })
            .collect();
        Plane { width: w, height: h, texels }
    }

    #[test]
    fn constant_planes_survive_both_formats() {
        for (format, tol) in [(BlockFormat::Bc1, BC1_CONSTANT_TOL), (BlockFormat::Bc7, BC7_CONSTANT_TOL)] {
            let p = Plane { width: 8, height: 4, texels: vec![[200, 37, 91, 255]; 32] };
            let c = compress(&p, format);
            assert_eq!(c.blocks.len(), 2 * format.block_bytes());
            let back = decompress(&c);
            for t in &back.texels {
                for ch in 0..3 {
                    let d = i32::from(t[ch]) - i32::from(p.texels[0][ch]);
                    assert!(d.abs() <= tol, "{format:?} {t:?}");
                }
            }
        }
    }

    #[test]
    fn odd_sizes_are_padded_and_cropped() {
        let p = gradient(7, 5);
        for format in [BlockFormat::Bc1, BlockFormat::Bc7] {
            let c = compress(&p, format);
            assert_eq!(c.blocks.len(), 2 * 2 * format.block_bytes());
            let back = decompress(&c);
            assert_eq!((back.width, back.height, back.texels.len()), (7, 5, 35));
        }
        // BC7 is much closer than BC1 on a smooth gradient (more endpoint bits and indices).
        let err = |f| {
            let b = round_trip(&p, f);
            b.texels
                .iter()
                .zip(&p.texels)
                .map(|(a, b)| (0..3).map(|c| (i32::from(a[c]) - i32::from(b[c])).abs()).max().unwrap())
                .max()
                .unwrap()
        };
        assert!(err(BlockFormat::Bc7) < err(BlockFormat::Bc1));
        assert_eq!(BlockFormat::Bc1.bytes_per_texel(), 0.5);
        assert_eq!(BlockFormat::Bc7.bytes_per_texel(), 1.0);
    }
}
