//! The "coefficient slabs along z" RGBA16F texel layout shared by the KTX2 and DDS exports.
//!
//! A volume with `nx × ny × nz` nodes and `coeffs` coefficients becomes a 3D texture of
//! width `nx`, height `ny` and depth `coeffs · nz`; texel `(x, y, j·nz + z)` holds the RGB of
//! coefficient `j` at node `(x, y, z)` and the node weight in alpha, as little-endian f16.
//! In memory (x fastest, then y, then z) texel `t` is coefficient `t / n` of node `t % n`,
//! `n = nx·ny·nz`, because `((j nz + z) ny + y) nx + x = j n + node`.

use crate::error::{FileFormat, VolumeError};
use crate::volume::IrradianceVolume;

/// Bytes per RGBA16F texel.
pub const TEXEL_BYTES: usize = 8;

/// The layout in words (the format modules prefix their container name).
pub const SLAB_LAYOUT: &str = "width nx, height ny, depth coeffs*nz; texel (x, y, j*nz + z) = RGB of SH \
                               coefficient j at node (x, y, z), A = node weight; little-endian f16";

/// Little-endian f16 bytes of an f32, erroring if it exceeds the f16 range.
pub(crate) fn f16_bytes(v: f32, what: &str) -> Result<[u8; 2], VolumeError> {
    let h = half::f16::from_f32(v);
    if h.is_finite() {
        Ok(h.to_le_bytes())
    } else {
        Err(VolumeError::InvalidData(format!("{what} value {v} exceeds the f16 range (65504)")))
    }
}

/// The f16 texel bytes of `vol`; errors if a value exceeds the f16 range.
pub fn slab_texels(vol: &IrradianceVolume) -> Result<Vec<u8>, VolumeError> {
    let n = vol.spec().node_count();
    let coeffs = vol.coeffs();
    let mut out = Vec::with_capacity(n * coeffs * TEXEL_BYTES);
    for j in 0..coeffs {
        for node in 0..n {
            let c = vol.coeff_rgb(node, j);
            for v in [c[0], c[1], c[2], vol.weights()[node]] {
                out.extend_from_slice(&f16_bytes(v, "texel")?);
            }
        }
    }
    Ok(out)
}

/// Coefficients `[node][coeff][rgb]` and weights from slab texels; `data` must hold exactly
/// `n · coeffs` texels, and every slab must carry the same alpha for a node.
pub fn volume_from_slab_texels(
    n: usize,
    coeffs: usize,
    data: &[u8],
    format: FileFormat,
) -> Result<(Vec<f32>, Vec<f32>), VolumeError> {
    if data.len() != n * coeffs * TEXEL_BYTES {
        return Err(VolumeError::malformed(
            format,
            format!(
                "{} texel bytes, {n} nodes x {coeffs} coefficients need {}",
                data.len(),
                n * coeffs * TEXEL_BYTES
            ),
        ));
    }
    let k = coeffs * 3;
    let mut values = vec![0.0f32; n * k];
    let mut weights = vec![0.0f32; n];
    for (t, px) in data.chunks_exact(TEXEL_BYTES).enumerate() {
        let (j, node) = (t / n, t % n);
        let h = |i: usize| half::f16::from_le_bytes([px[2 * i], px[2 * i + 1]]).to_f32();
        for ch in 0..3 {
            values[node * k + 3 * j + ch] = h(ch);
        }
        if j == 0 {
            weights[node] = h(3);
        } else if h(3).to_bits() != weights[node].to_bits() {
            return Err(VolumeError::malformed(format, format!("node {node}: alpha differs between slabs")));
        }
    }
    Ok((values, weights))
}
