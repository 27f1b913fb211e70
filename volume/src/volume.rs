//! The baked irradiance volume: RGB SH radiance coefficients and a weight per node.
//!
//! Kontkanen & Laine 2006, \[KL06\] §3: each node `i` stores the coefficients `c_ij` of
//! the incident *radiance* `L(x_i, ω) ≈ Σ_j c_ij Y_j(ω)` (Eq. 2), from which irradiance is
//! reconstructed at run time (Eq. 1 and 3; see [`crate::lookup`]). The per-node weight is
//! the fraction of the node's trilinear support that lies in the domain of interest (the
//! normalised denominator of Eq. 5-6, see [`crate::accumulator`]): 0 marks a node that
//! received no samples and was filled from its neighbours.
//!
//! A volume may also carry a per-node validity mask ([`crate::validity`]): then its
//! trilinear lookups leave invalid corners out (Unity APV's run-time weighting).
//!
//! This module holds the data and its plain accessors, below everything that reads it: the
//! lookups (`irradiance`, `radiance`, `coeffs_at`, the batched and reference paths) are
//! methods of [`IrradianceVolume`] implemented in [`crate::lookup`], the frame conversion
//! in [`crate::frame`], checksums, encodings and files above those. The bake metadata it
//! carries is [`crate::metadata`]'s.

use lightvol_sh::coeffs::{Sh, ShRgb};

use crate::error::{VolumeError, check_finite};
use crate::grid::GridSpec;
use crate::lookup_params::LookupParams;
use crate::reach::NodeReach;
use crate::validity::ValidityMask;

pub use crate::metadata::{BakeMetadata, BakeRecord, FitRecord};

/// The default SH coefficient count per colour channel: 3 bands, the nine coefficients that
/// capture irradiance to a few percent (Ramamoorthi & Hanrahan 2001; \[KL06\] §3).
pub const DEFAULT_COEFFS: usize = 9;

/// The SH coefficient counts per colour channel this crate supports (2, 3 and 4 bands).
pub const SUPPORTED_COEFFS: [usize; 3] = [4, 9, 16];

/// Checks that `coeffs` is one of [`SUPPORTED_COEFFS`].
pub fn check_coeffs(coeffs: usize) -> Result<(), VolumeError> {
    if SUPPORTED_COEFFS.contains(&coeffs) { Ok(()) } else { Err(VolumeError::UnsupportedCoeffs(coeffs)) }
}

/// SH floats per sample in \[Oat05\]'s "Memory Requirements" accounting: `3 n²` for RGB SH of
/// order (bands) `n`, times 4 with gradients (each coefficient adds a 3-vector).
#[must_use]
pub const fn floats_per_sample(bands: usize, gradients: bool) -> usize {
    let sh = 3 * bands * bands;
    if gradients { sh * 4 } else { sh }
}

/// Bytes for `samples` samples of f32 data ([`floats_per_sample`] · 4 each).
#[must_use]
pub const fn sample_bytes(samples: usize, bands: usize, gradients: bool) -> usize {
    samples * floats_per_sample(bands, gradients) * 4
}

/// An irradiance volume: a [`GridSpec`], `coeffs` (4, 9 or 16) RGB SH radiance coefficients
/// per node and a weight per node (Kontkanen & Laine 2006, §3).
///
/// Coefficients are stored as f32 in the layout `[node][coeff][rgb]` (the 3·coeffs floats of
/// one node are contiguous, which makes the 8 fetches of a trilinear lookup 8 short
/// contiguous reads). Coefficient `j` follows lightvol-sh: real orthonormal SH, flat index
/// `l(l+1)+m`, no Condon-Shortley phase, +z polar axis, world-space directions.
///
/// An optional [`ValidityMask`] ([`Self::with_validity`]) makes the trilinear lookups
/// renormalise their weights over valid corners ([`crate::validity`]); an optional
/// [`NodeReach`] ([`Self::with_reach`]) over the corners that see the query
/// ([`crate::reach`]).
#[derive(Clone, PartialEq)]
pub struct IrradianceVolume {
    spec: GridSpec,
    coeffs: usize,
    data: Vec<f32>,
    weights: Vec<f32>,
    validity: Option<ValidityMask>,
    reach: Option<NodeReach>,
    meta: BakeMetadata,
    lut: LookupParams,
}

/// A summary, not the millions of coefficients a real volume holds.
impl std::fmt::Debug for IrradianceVolume {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let filled = self.weights.iter().filter(|&&w| w == 0.0).count();
        f.debug_struct("IrradianceVolume")
            .field("spec", &self.spec)
            .field("coeffs", &self.coeffs)
            .field("data", &format_args!("[{} f32]", self.data.len()))
            .field("weights", &format_args!("[{} f32, {filled} zero]", self.weights.len()))
            .field("validity", &self.validity)
            .field("reach", &self.reach)
            .field("meta", &self.meta)
            .finish()
    }
}

impl IrradianceVolume {
    /// Builds a volume from its parts; errors if the lengths do not match the grid, the
    /// coefficient count is unsupported, a value is not finite, or a weight is outside
    /// `[0, 1]`.
    pub fn new(
        spec: GridSpec,
        coeffs: usize,
        data: Vec<f32>,
        weights: Vec<f32>,
    ) -> Result<Self, VolumeError> {
        check_coeffs(coeffs)?;
        let n = spec.node_count();
        if data.len() != n * coeffs * 3 {
            return Err(VolumeError::Mismatch(format!(
                "coefficient array has {} floats, grid needs {} ({n} nodes x {coeffs} coeffs x 3)",
                data.len(),
                n * coeffs * 3
            )));
        }
        if weights.len() != n {
            return Err(VolumeError::Mismatch(format!("{} weights for {n} nodes", weights.len())));
        }
        check_finite("coefficients", &data)?;
        check_finite("weights", &weights)?;
        if let Some(i) = weights.iter().position(|w| !(0.0..=1.0).contains(w)) {
            return Err(VolumeError::InvalidData(format!(
                "weight {} at node {i} outside [0, 1]",
                weights[i]
            )));
        }
        let lut = LookupParams::new(&spec, coeffs);
        Ok(Self {
            spec,
            coeffs,
            data,
            weights,
            validity: None,
            reach: None,
            meta: BakeMetadata::default(),
            lut,
        })
    }

    /// The same volume (grid, weights, validity, reach, metadata) with other coefficients,
    /// `[node][coeff][rgb]`; errors if their count differs or one is not finite.
    pub fn with_data(&self, data: Vec<f32>) -> Result<Self, VolumeError> {
        if data.len() != self.data.len() {
            return Err(VolumeError::Mismatch(format!(
                "{} coefficients for a volume of {}",
                data.len(),
                self.data.len()
            )));
        }
        check_finite("coefficients", &data)?;
        Ok(Self { data, ..self.clone() })
    }

    /// An all-zero volume with all weights 1.
    pub fn zeros(spec: GridSpec, coeffs: usize) -> Result<Self, VolumeError> {
        check_coeffs(coeffs)?;
        let n = spec.node_count();
        Self::new(spec, coeffs, vec![0.0; n * coeffs * 3], vec![1.0; n])
    }

    /// A volume whose node `i` holds `f(world position of node i)`, which must return
    /// `coeffs` RGB triples `[coeff][rgb]`; weights are 1.
    pub fn from_fn(
        spec: GridSpec,
        coeffs: usize,
        mut f: impl FnMut([f64; 3]) -> Vec<[f64; 3]>,
    ) -> Result<Self, VolumeError> {
        check_coeffs(coeffs)?;
        let n = spec.node_count();
        let mut data = Vec::with_capacity(n * coeffs * 3);
        for node in 0..n {
            let [i, j, k] = spec.node_coords(node);
            let c = f(spec.node_position_world(i, j, k));
            if c.len() != coeffs {
                return Err(VolumeError::Mismatch(format!(
                    "closure returned {} coefficients, want {coeffs}",
                    c.len()
                )));
            }
            data.extend(c.iter().flatten().map(|&v| v as f32));
        }
        Self::new(spec, coeffs, data, vec![1.0; n])
    }

    /// The grid.
    #[must_use]
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// The f32 constants of the fast lookup paths.
    #[inline]
    pub(crate) fn lookup_params(&self) -> &LookupParams {
        &self.lut
    }

    /// SH coefficients per colour channel (4, 9 or 16).
    #[must_use]
    pub fn coeffs(&self) -> usize {
        self.coeffs
    }

    /// SH bands (`sqrt(coeffs)`: 2, 3 or 4).
    #[must_use]
    pub fn bands(&self) -> usize {
        self.coeffs.isqrt()
    }

    /// All coefficients, `[node][coeff][rgb]`.
    #[must_use]
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// The `3 · coeffs` floats of one node, `[coeff][rgb]`.
    #[must_use]
    #[inline]
    pub fn node(&self, node: usize) -> &[f32] {
        let k = self.coeffs * 3;
        &self.data[node * k..(node + 1) * k]
    }

    /// Coefficient `j` of `node` as RGB.
    #[must_use]
    pub fn coeff_rgb(&self, node: usize, j: usize) -> [f32; 3] {
        let s = self.node(node);
        [s[3 * j], s[3 * j + 1], s[3 * j + 2]]
    }

    /// The coefficients of `node` as a lightvol-sh [`ShRgb`]; errors if `N` is not the
    /// volume's coefficient count.
    pub fn node_sh<const N: usize>(&self, node: usize) -> Result<ShRgb<f32, N>, VolumeError> {
        if N != self.coeffs || node >= self.spec.node_count() {
            return Err(VolumeError::Mismatch(format!(
                "node {node} as {N} coefficients (volume has {} nodes x {})",
                self.spec.node_count(),
                self.coeffs
            )));
        }
        let s = self.node(node);
        Ok(ShRgb(std::array::from_fn(|ch| Sh(std::array::from_fn(|j| s[3 * j + ch])))))
    }

    /// Overwrites one node's coefficients (`[coeff][rgb]`, 3·coeffs finite floats).
    pub fn set_node(&mut self, node: usize, values: &[f32]) -> Result<(), VolumeError> {
        let k = self.coeffs * 3;
        if node >= self.spec.node_count() || values.len() != k {
            return Err(VolumeError::Mismatch(format!("node {node} / {} values (want {k})", values.len())));
        }
        check_finite("node coefficients", values)?;
        self.data[node * k..(node + 1) * k].copy_from_slice(values);
        Ok(())
    }

    /// Per-node weights in `[0, 1]`: the fraction of the node's support inside the domain
    /// of interest; 0 for filled nodes.
    #[must_use]
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// The validity mask, if the volume has one ([`crate::validity`]).
    #[must_use]
    pub fn validity(&self) -> Option<&ValidityMask> {
        self.validity.as_ref()
    }

    /// Attaches (`Some`) or removes (`None`) the validity mask; errors if the mask does not
    /// have one flag per node.
    pub fn set_validity(&mut self, mask: Option<ValidityMask>) -> Result<(), VolumeError> {
        if let Some(m) = &mask
            && m.len() != self.spec.node_count()
        {
            return Err(VolumeError::Mismatch(format!(
                "validity mask of {} nodes for {} nodes",
                m.len(),
                self.spec.node_count()
            )));
        }
        self.validity = mask;
        Ok(())
    }

    /// The same volume with `mask` attached ([`Self::set_validity`]).
    pub fn with_validity(mut self, mask: ValidityMask) -> Result<Self, VolumeError> {
        self.set_validity(Some(mask))?;
        Ok(self)
    }

    /// The node reach, if the volume has one ([`crate::reach`]).
    #[must_use]
    pub fn reach(&self) -> Option<&NodeReach> {
        self.reach.as_ref()
    }

    /// Attaches (`Some`) or removes (`None`) the node reach; errors if it does not cover
    /// every node.
    pub fn set_reach(&mut self, reach: Option<NodeReach>) -> Result<(), VolumeError> {
        if let Some(r) = &reach
            && r.len() != self.spec.node_count()
        {
            return Err(VolumeError::Mismatch(format!(
                "node reach of {} nodes for {} nodes",
                r.len(),
                self.spec.node_count()
            )));
        }
        self.reach = reach;
        Ok(())
    }

    /// The same volume with `reach` attached ([`Self::set_reach`]).
    pub fn with_reach(mut self, reach: NodeReach) -> Result<Self, VolumeError> {
        self.set_reach(Some(reach))?;
        Ok(self)
    }

    /// The bake metadata.
    #[must_use]
    pub fn metadata(&self) -> &BakeMetadata {
        &self.meta
    }

    /// Replaces the bake metadata.
    pub fn set_metadata(&mut self, meta: BakeMetadata) {
        self.meta = meta;
    }

    /// The same volume with `meta` attached.
    #[must_use]
    pub fn with_metadata(mut self, meta: BakeMetadata) -> Self {
        self.meta = meta;
        self
    }

    /// Bytes of coefficient and weight storage at f32: \[Oat05\]'s run-time figure
    /// ([`sample_bytes`]: 9 RGB coefficients are 108 bytes per node) plus 4
    /// bytes of bake weight per node (112 per node at 9 coefficients), plus the validity
    /// mask's ([`ValidityMask::memory_bytes`]) and the node reach's
    /// ([`NodeReach::memory_bytes`]) when there are.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        sample_bytes(self.spec.node_count(), self.bands(), false)
            + self.weights.len() * size_of::<f32>()
            + self.validity.as_ref().map_or(0, ValidityMask::memory_bytes)
            + self.reach.as_ref().map_or(0, NodeReach::memory_bytes)
    }

    /// Consumes the volume, returning `(spec, coeffs, data, weights, metadata)`; the
    /// validity mask and node reach, if any, are dropped (clone it first from [`Self::validity`]).
    #[must_use]
    pub fn into_parts(self) -> (GridSpec, usize, Vec<f32>, Vec<f32>, BakeMetadata) {
        (self.spec, self.coeffs, self.data, self.weights, self.meta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validates_parts() {
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        assert!(IrradianceVolume::new(spec.clone(), 9, vec![0.0; 8 * 27], vec![1.0; 8]).is_ok());
        assert!(matches!(
            IrradianceVolume::new(spec.clone(), 5, vec![0.0; 8 * 15], vec![1.0; 8]),
            Err(VolumeError::UnsupportedCoeffs(5))
        ));
        assert!(IrradianceVolume::new(spec.clone(), 9, vec![0.0; 8 * 26], vec![1.0; 8]).is_err());
        let mut d = vec![0.0; 8 * 27];
        d[100] = f32::NAN;
        assert!(matches!(
            IrradianceVolume::new(spec.clone(), 9, d, vec![1.0; 8]),
            Err(VolumeError::NonFinite { index: 100, .. })
        ));
        assert!(IrradianceVolume::new(spec, 4, vec![0.0; 8 * 12], vec![1.5; 8]).is_err());
    }

    #[test]
    fn memory_is_27_floats_per_node_at_order_3() {
        // [Oat05], "GPU Memory Requirements (Constant Store)": "3rd order SH approximation
        // for R, G, and B: 27 floats" per sample.
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [17, 17, 17]).unwrap();
        let v = IrradianceVolume::zeros(spec, 9).unwrap();
        assert_eq!(v.data().len(), 17 * 17 * 17 * 27);
        assert_eq!(v.memory_bytes(), 17 * 17 * 17 * (27 + 1) * 4);
    }
}
