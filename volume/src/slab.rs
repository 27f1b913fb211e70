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

/// The stacked layout of a volume's light groups (the groups' KTX2 texture).
pub const STACKED_LAYOUT: &str = "width nx, height groups*ny, depth coeffs*nz; texel (x, g*ny + y, j*nz + z) = RGB of \
     SH coefficient j at node (x, y, z) of light group g, A = node weight; little-endian f16";

/// The f16 texels of light-group layers stacked along y ([`STACKED_LAYOUT`]): `layers[g]`
/// holds group `g`'s coefficients in `vol`'s layout `[node][coeff][rgb]`, `vol` gives the
/// grid, the coefficient count and the weights. Errors if a value exceeds the f16 range or
/// a layer has the wrong length.
pub fn stacked_slab_texels(vol: &IrradianceVolume, layers: &[&[f32]]) -> Result<Vec<u8>, VolumeError> {
    let [nx, ny, nz] = vol.spec().res().map(|v| v as usize);
    let coeffs = vol.coeffs();
    let k = 3 * coeffs;
    if let Some(l) = layers.iter().find(|l| l.len() != vol.data().len()) {
        return Err(VolumeError::Mismatch(format!(
            "a light group layer of {} values for a volume of {}",
            l.len(),
            vol.data().len()
        )));
    }
    let mut out = Vec::with_capacity(nx * ny * nz * coeffs * layers.len() * TEXEL_BYTES);
    for j in 0..coeffs {
        for z in 0..nz {
            for layer in layers {
                for y in 0..ny {
                    for x in 0..nx {
                        let node = (z * ny + y) * nx + x;
                        let c = &layer[node * k + 3 * j..node * k + 3 * j + 3];
                        for v in [c[0], c[1], c[2], vol.weights()[node]] {
                            out.extend_from_slice(&f16_bytes(v, "texel")?);
                        }
                    }
                }
            }
        }
    }
    Ok(out)
}

/// The light-group layers (`[node][coeff][rgb]` f32, group order) of stacked texels
/// ([`STACKED_LAYOUT`]) for a grid of `res` nodes and `coeffs` coefficients; `data` must
/// hold exactly `groups · n · coeffs` texels. The inverse of [`stacked_slab_texels`] up to
/// the f16 rounding.
pub fn layers_from_stacked_texels(
    res: [u32; 3],
    coeffs: usize,
    groups: usize,
    data: &[u8],
    format: FileFormat,
) -> Result<Vec<Vec<f32>>, VolumeError> {
    let [nx, ny, nz] = res.map(|v| v as usize);
    let n = nx * ny * nz;
    if Some(data.len()) != n.checked_mul(coeffs * groups * TEXEL_BYTES) {
        return Err(VolumeError::malformed(
            format,
            format!(
                "{} texel bytes, {groups} groups of {n} nodes x {coeffs} coefficients do not fit",
                data.len()
            ),
        ));
    }
    let k = 3 * coeffs;
    let mut layers = vec![vec![0.0f32; n * k]; groups];
    for (t, px) in data.chunks_exact(TEXEL_BYTES).enumerate() {
        let x = t % nx;
        let row = t / nx;
        let (y, g) = (row % ny, (row / ny) % groups);
        let slab = row / (ny * groups);
        let (z, j) = (slab % nz, slab / nz);
        let node = (z * ny + y) * nx + x;
        for ch in 0..3 {
            layers[g][node * k + 3 * j + ch] =
                half::f16::from_le_bytes([px[2 * ch], px[2 * ch + 1]]).to_f32();
        }
    }
    Ok(layers)
}

#[cfg(test)]
mod stacked_tests {
    use super::*;
    use crate::grid::GridSpec;

    /// Stacked texels read back to the layers (values exact in f16), and each group's texels
    /// sit where the layout says: group g's node (x, y, z) coefficient j at texel
    /// (x, g·ny + y, j·nz + z) of a width nx, height groups·ny texture.
    #[test]
    fn stacked_texels_round_trip_and_follow_the_layout() {
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [3, 2, 4]).unwrap();
        let n = 24;
        let layer = |g: usize| -> Vec<f32> { (0..n * 12).map(|i| (i + 100 * g) as f32 * 0.25).collect() };
        let vol = IrradianceVolume::new(spec, 4, layer(9), vec![0.5; n]).unwrap();
        let layers = [layer(0), layer(1), layer(2)];
        let refs: Vec<&[f32]> = layers.iter().map(Vec::as_slice).collect();
        let texels = stacked_slab_texels(&vol, &refs).unwrap();
        let back = layers_from_stacked_texels([3, 2, 4], 4, 3, &texels, FileFormat::Ktx2).unwrap();
        assert_eq!(back, layers);
        let (x, y, z, g, j) = (2usize, 1usize, 3usize, 2usize, 3usize);
        let texel = ((j * 4 + z) * (3 * 2) + g * 2 + y) * 3 + x;
        let node = (z * 2 + y) * 3 + x;
        let red = half::f16::from_le_bytes([texels[8 * texel], texels[8 * texel + 1]]).to_f32();
        assert_eq!(red, layers[g][node * 12 + 3 * j]);
        assert!(layers_from_stacked_texels([3, 2, 4], 4, 2, &texels, FileFormat::Ktx2).is_err());
        assert!(stacked_slab_texels(&vol, &[&layers[0][1..]]).is_err());
    }
}
