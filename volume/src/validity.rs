//! Per-node validity: which nodes a run-time lookup may read.
//!
//! Engines that point-sample their probes mark the probes that see the inside of geometry
//! as *invalid* and, at run time, leave them out of the trilinear interpolation: Unity's
//! Adaptive Probe Volumes renormalise the trilinear weights over the valid corners of the
//! cell (Unity 6 manual, "Adaptive Probe Volumes": "Light Probe validity", and the
//! "Probe Dilation" settings of the Adaptive Probe Volumes panel). A [`ValidityMask`]
//! attached to an [`crate::IrradianceVolume`] ([`crate::IrradianceVolume::with_validity`])
//! makes every CPU trilinear lookup of the volume do the same ([`crate::lookup`]), and it
//! travels with the volume through the native EXR file ([`crate::io::exr`]) and the
//! KTX2/DDS sidecar ([`crate::io::sidecar`]).
//!
//! ## The weighting
//!
//! For a query with trilinear corner weights `w_c` (`c = dx + 2dy + 4dz`) and validity
//! `v_c ∈ {0, 1}`, let `s = Σ_c v_c w_c` (summed in corner order). Then
//!
//! - if every corner is valid, or `s = 0` (no corner is valid, or only corners with zero
//!   weight are), the weights stay the plain trilinear `w_c` — like Unity, which falls
//!   back to plain trilinear interpolation when no corner of the cell is valid;
//! - otherwise `w'_c = v_c w_c / s`: invalid corners get weight 0 and the valid corners'
//!   weights sum to 1.
//!
//! The weights only change when the query's cell has an invalid corner with non-zero weight,
//! so a volume whose mask marks every node valid is looked up bit for bit like the same
//! volume without a mask. Near an invalid node the valid weight `s` is small and the lookup
//! takes the valid corners' values however little weight they have: the weighting is
//! discontinuous at invalid nodes by design (a dilated invalid node holds a blend of its
//! valid neighbours, so the jump is small where dilation found them).
//!
//! The trilinear lookups ([`crate::lookup`]) and the gradient lookups ([`crate::gradient`])
//! read the mask, and so do lightvol-gpu's Vulkan evaluator and engine shader code
//! (`lightvol_irradiance_valid`); the adaptive octree does not.
//!
//! ## In files
//!
//! The mask is stored as one bit per node in node order (x fastest), packed into bytes
//! least significant bit first (node `i` is bit `i % 8` of byte `i / 8`, 1 = valid) and
//! written as lowercase hex, two digits per byte ([`ValidityMask::to_hex`]); the EXR stores
//! it as a `validity` part of 1.0/0.0 samples instead.

use crate::error::VolumeError;

/// Which nodes of a volume are valid (module docs).
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct ValidityMask {
    valid: Vec<bool>,
}

/// A summary: the node and invalid counts.
impl std::fmt::Debug for ValidityMask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ValidityMask({} nodes, {} invalid)", self.valid.len(), self.invalid_count())
    }
}

impl ValidityMask {
    /// The mask with `valid[i]` for node `i`.
    #[must_use]
    pub fn new(valid: Vec<bool>) -> Self {
        Self { valid }
    }

    /// Node count.
    #[must_use]
    pub fn len(&self) -> usize {
        self.valid.len()
    }

    /// Whether the mask covers no node.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.valid.is_empty()
    }

    /// Whether `node` is valid.
    ///
    /// # Panics
    /// If `node` is not below [`Self::len`].
    #[must_use]
    #[inline]
    pub fn is_valid(&self, node: usize) -> bool {
        self.valid[node]
    }

    /// One flag per node.
    #[must_use]
    pub fn as_slice(&self) -> &[bool] {
        &self.valid
    }

    /// Nodes marked invalid.
    #[must_use]
    pub fn invalid_count(&self) -> usize {
        self.valid.iter().filter(|v| !**v).count()
    }

    /// Run-time bytes: one byte per node, the size of the 8-bit 3D texture (or byte buffer)
    /// a renderer uploads it as.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.valid.len()
    }

    /// The packed bits as hex (module docs): `2 · ⌈len / 8⌉` lowercase digits.
    #[must_use]
    pub fn to_hex(&self) -> String {
        const DIGITS: &[u8; 16] = b"0123456789abcdef";
        let mut out = String::with_capacity(self.valid.len().div_ceil(8) * 2);
        for chunk in self.valid.chunks(8) {
            let byte = chunk.iter().enumerate().fold(0u8, |b, (i, &v)| b | (u8::from(v) << i));
            out.push(char::from(DIGITS[usize::from(byte >> 4)]));
            out.push(char::from(DIGITS[usize::from(byte & 15)]));
        }
        out
    }

    /// Parses [`Self::to_hex`]'s text for `nodes` nodes; errors (naming what is wrong) on a
    /// wrong length, a character that is not a hex digit, or a set bit beyond the last node.
    pub fn from_hex(text: &str, nodes: usize) -> Result<Self, VolumeError> {
        let bad = |r: String| VolumeError::InvalidData(format!("validity bits: {r}"));
        let want = nodes.div_ceil(8) * 2;
        if text.len() != want {
            return Err(bad(format!("{} hex digits, {nodes} nodes need {want}", text.len())));
        }
        let digit = |c: u8| -> Result<u8, VolumeError> {
            hex_digit(c).ok_or_else(|| bad(format!("{:?} is not a lowercase hex digit", char::from(c))))
        };
        let mut valid = Vec::with_capacity(nodes);
        for (i, pair) in text.as_bytes().chunks_exact(2).enumerate() {
            let byte = (digit(pair[0])? << 4) | digit(pair[1])?;
            let here = (nodes - 8 * i).min(8);
            if u16::from(byte) >> here != 0 {
                return Err(bad(format!("bits set beyond the last of {nodes} nodes")));
            }
            valid.extend((0..here).map(|b| byte & (1 << b) != 0));
        }
        Ok(Self { valid })
    }

    /// Renormalises the trilinear weights `w` of the corners `nodes` (module docs), f32.
    #[inline]
    pub fn reweight_f32(&self, nodes: impl Fn(usize) -> usize, w: &mut [f32; 8]) {
        self.reweight(nodes, w);
    }

    /// [`Self::reweight_f32`] in f64 (the reference lookups): the same steps in the same
    /// order (one generic body), tested against each other through the lookups
    /// (`tests/validity.rs`, `masked_fast_paths_match_each_other_and_the_reference`).
    #[inline]
    pub fn reweight_f64(&self, nodes: impl Fn(usize) -> usize, w: &mut [f64; 8]) {
        self.reweight(nodes, w);
    }

    /// The renormalisation in either precision: nothing when every corner is valid;
    /// otherwise valid weights divided by their sum and invalid ones zeroed, unless no
    /// valid corner has weight (then `w` is left as it is).
    #[inline]
    fn reweight<T>(&self, nodes: impl Fn(usize) -> usize, w: &mut [T; 8])
    where
        T: Copy + Default + PartialOrd + std::ops::AddAssign + std::ops::Div<Output = T>,
    {
        let v: [bool; 8] = std::array::from_fn(|c| self.valid[nodes(c)]);
        renormalise(v, w);
    }
}

/// The weighting of the module docs for corner flags `v` (1 = the corner may be read):
/// nothing when every corner may be read; otherwise the readable weights divided by their
/// sum and the others zeroed, unless no readable corner has weight (then `w` is left as it
/// is). Shared by the validity mask and the node reach ([`crate::reach`]).
#[inline]
pub(crate) fn renormalise<T>(v: [bool; 8], w: &mut [T; 8])
where
    T: Copy + Default + PartialOrd + std::ops::AddAssign + std::ops::Div<Output = T>,
{
    if v.iter().all(|&x| x) {
        return;
    }
    let zero = T::default();
    let mut s = zero;
    for c in 0..8 {
        if v[c] {
            s += w[c];
        }
    }
    if s > zero {
        for c in 0..8 {
            w[c] = if v[c] { w[c] / s } else { zero };
        }
    }
}

/// The value of one lowercase hex digit (the hex texts of the validity bits and the node
/// reach, [`crate::reach`]), or `None` for any other character.
pub(crate) fn hex_digit(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'a'..=b'f' => Some(c - b'a' + 10),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The packing of the module docs, by hand: nodes 0, 2 and 9 valid of 10.
    #[test]
    fn hex_packs_least_significant_bit_first() {
        let m = ValidityMask::new((0..10).map(|i| [0, 2, 9].contains(&i)).collect());
        assert_eq!(m.to_hex(), "0502");
        assert_eq!(ValidityMask::from_hex("0502", 10).unwrap(), m);
        assert_eq!(m.invalid_count(), 7);
        for n in [0, 1, 7, 8, 9, 63, 64, 65] {
            let m = ValidityMask::new((0..n).map(|i| i % 3 != 1).collect());
            assert_eq!(ValidityMask::from_hex(&m.to_hex(), n).unwrap(), m, "{n} nodes");
        }
    }

    #[test]
    fn hex_rejects_bad_text() {
        let e = |t: &str, n: usize| ValidityMask::from_hex(t, n).unwrap_err().to_string();
        assert_eq!(e("05", 10), "invalid data: validity bits: 2 hex digits, 10 nodes need 4");
        assert_eq!(e("05g2", 10), "invalid data: validity bits: 'g' is not a lowercase hex digit");
        assert_eq!(e("05F2", 10), "invalid data: validity bits: 'F' is not a lowercase hex digit");
        assert_eq!(e("0506", 10), "invalid data: validity bits: bits set beyond the last of 10 nodes");
    }

    /// The weighting of the module docs on fixed weights: invalid corners drop out and the
    /// valid ones are scaled by 1/s; all valid, or s = 0, keep the weights.
    #[test]
    fn reweighting_follows_the_definition() {
        let w = [0.05, 0.1, 0.15, 0.2, 0.05, 0.15, 0.2, 0.1];
        let mask = ValidityMask::new(vec![true, false, true, true, false, true, true, true]);
        let mut got = w;
        mask.reweight_f64(|c| c, &mut got);
        let s = 0.05 + 0.15 + 0.2 + 0.15 + 0.2 + 0.1;
        for c in 0..8 {
            let want = if mask.is_valid(c) { w[c] / s } else { 0.0 };
            assert_eq!(got[c], want, "corner {c}");
        }
        let all = ValidityMask::new(vec![true; 8]);
        let none = ValidityMask::new(vec![false; 8]);
        for m in [&all, &none] {
            let mut same = w;
            m.reweight_f64(|c| c, &mut same);
            assert_eq!(same, w);
        }
        // Only corners 1 and 4 have weight and both are invalid: s = 0, plain weights.
        let edge = [0.0, 0.5, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0];
        let mut same = edge;
        mask.reweight_f64(|c| c, &mut same);
        assert_eq!(same, edge);
        let mut wf = w.map(|x| x as f32);
        mask.reweight_f32(|c| c, &mut wf);
        assert_eq!(wf[1], 0.0);
        assert_eq!(wf[4], 0.0);
    }
}
