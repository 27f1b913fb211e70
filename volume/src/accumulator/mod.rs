//! The bake's working form: exact numerators and denominators per node (Kontkanen & Laine
//! 2006, Eq. 5-6).
//!
//! Eq. 6 estimates each coefficient as a ratio of two Monte Carlo sums over the samples
//! `(x_s, ω_s)`:
//!
//! `c_ij ≈ 4π Σ_s L(x_s, ω_s) Y_j(ω_s) b_i(x_s) / Σ_s b_i(x_s)`.
//!
//! The accumulator keeps both sums separately, per node: `numerator[node][j][c]` and
//! `denominator[node]`, in the fixed point of [`crate::fixed`] (each term rounded once to a
//! multiple of 2^-64, then added as integers). Integer addition is associative, so bakes
//! over disjoint sample sets (shards, resumed runs, threads) combine by
//! [`Accumulator::merge`] into bit-identical sums whatever the grouping and order.
//! [`Accumulator::finalize`] divides and yields an [`IrradianceVolume`].
//!
//! The caller passes `radiance / pdf(ω)` (which is `4π L` for uniform sphere directions)
//! and the node's trilinear weight `b = b_i(x_s)`; point sampling (Eq. 4) uses `b = 1`.
//!
//! ## Node weights and the domain of interest
//! A candidate sample position that the baker rejects as outside the domain of interest
//! can be recorded with [`Accumulator::add_outside`]. The finalized node weight is then
//! `Σ_inside b / (Σ_inside b + Σ_outside b)`, an estimate of the fraction of the node's
//! support `∫ b_i` that lies in the domain (the denominator of Eq. 5 relative to the full
//! support). A baker that never calls `add_outside` gets weight 1 for every sampled node.
//!
//! ## Node reach
//! A bake may record each node's reach ([`crate::reach`]) with [`Accumulator::set_reach`].
//! It travels with the sums as six more integers per node, each the f32 bits of one reach
//! plus one (0 = not recorded), so that shards covering disjoint nodes merge by the same
//! integer addition into the whole bake's values. `finalize` attaches the reach to the
//! volume; a node no shard recorded (an incomplete shard set), or a value no single
//! record gives, reaches a full cell (no lookup leaves it out).
//!
//! ## Light groups
//! A bake split by light group ([`crate::light_groups`]) keeps, beside the numerator, one
//! numerator per group ([`Accumulator::enable_groups`], [`Accumulator::add_group`]): the
//! same terms with the radiance of that group's lights only, over the same denominator.
//! [`Accumulator::finalize_groups`] divides and fills each one as `finalize` does the whole.
//!
//! ## Zero-weight fill
//! Nodes whose denominator is zero (no sample landed in their support inside the domain)
//! have no estimate. `finalize` fills them as documented in [`crate::fill`] and counts
//! them in the [`FillReport`]; their weight stays 0.

mod groups;

pub use groups::GroupLabels;

use crate::error::VolumeError;
use crate::fill::{FillReport, fill_empty_nodes};
use crate::fixed::FixedSums;
use crate::grid::GridSpec;
use crate::metadata::BakeMetadata;
use crate::reach::NodeReach;
use crate::volume::{IrradianceVolume, check_coeffs};

/// Per-node exact sums of Kontkanen & Laine 2006 Eq. 6 (see the module docs).
#[derive(Clone, PartialEq)]
pub struct Accumulator {
    spec: GridSpec,
    coeffs: usize,
    numerator: FixedSums,
    denominator: FixedSums,
    outside: FixedSums,
    contributions: u64,
    /// Auxiliary exact sums that travel with the accumulator (for example a least-squares
    /// fit's mass matrix), by name.
    aux: Option<(String, FixedSums)>,
    /// The node reach as recorded (module docs): `6 · node + direction`, f32 bits + 1.
    reach: Option<FixedSums>,
    /// Per light group, its share of the numerator (module docs).
    groups: Vec<FixedSums>,
    /// The groups' names and a sky transfer's baked sky (module docs).
    group_labels: Option<GroupLabels>,
}

/// A summary, not the sums themselves.
impl std::fmt::Debug for Accumulator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let empty = (0..self.denominator.len()).filter(|&i| self.denominator.get(i) <= 0.0).count();
        f.debug_struct("Accumulator")
            .field("spec", &self.spec)
            .field("coeffs", &self.coeffs)
            .field("contributions", &self.contributions)
            .field("nodes_without_weight", &empty)
            .finish_non_exhaustive()
    }
}

impl Accumulator {
    /// An empty accumulator for `coeffs` (4, 9 or 16) RGB coefficients per node.
    pub fn new(spec: GridSpec, coeffs: usize) -> Result<Self, VolumeError> {
        check_coeffs(coeffs)?;
        let n = spec.node_count();
        Ok(Self {
            spec,
            coeffs,
            numerator: FixedSums::zeros(n * coeffs * 3),
            denominator: FixedSums::zeros(n),
            outside: FixedSums::zeros(n),
            contributions: 0,
            aux: None,
            reach: None,
            groups: Vec::new(),
            group_labels: None,
        })
    }

    /// Records node `node`'s reach ([`crate::reach`], six values in `[0, 1]`, module docs).
    ///
    /// # Panics
    /// If `node` is out of range.
    pub fn set_reach(&mut self, node: usize, reach: [f32; 6]) {
        let n = self.spec.node_count();
        let sums = self.reach.get_or_insert_with(|| FixedSums::zeros(6 * n));
        for (d, v) in reach.iter().enumerate() {
            sums.add_raw(6 * node + d, i128::from(v.to_bits()) + 1);
        }
    }

    /// Whether the accumulator carries a node reach (module docs).
    #[must_use]
    pub fn has_reach(&self) -> bool {
        self.reach.is_some()
    }

    /// Starts an empty node reach (every node unrecorded), for a shard file that carries
    /// one.
    pub fn enable_reach(&mut self) {
        let n = self.spec.node_count();
        self.reach.get_or_insert_with(|| FixedSums::zeros(6 * n));
    }

    /// The recorded node reach's raw integers (module docs), if any.
    #[must_use]
    pub fn reach_raw(&self) -> Option<&[i128]> {
        self.reach.as_ref().map(FixedSums::raw)
    }

    /// The node reach the records give (module docs), if the accumulator carries one.
    #[must_use]
    pub fn reach(&self) -> Option<NodeReach> {
        let raw = self.reach.as_ref()?.raw();
        let decode = |v: i128| {
            u32::try_from(v - 1).ok().map(f32::from_bits).filter(|r| (0.0..=1.0).contains(r)).unwrap_or(1.0)
        };
        let nodes = raw.chunks_exact(6).map(|c| std::array::from_fn(|d| decode(c[d]))).collect();
        Some(NodeReach::new(nodes).expect("decoded reaches are in [0, 1]"))
    }

    /// Attaches auxiliary exact sums (named, e.g. `"mass"`); they are merged, saved and
    /// read back with the accumulator. Replaces any earlier ones.
    pub fn set_aux(&mut self, name: &str, sums: FixedSums) {
        self.aux = Some((name.to_owned(), sums));
    }

    /// The auxiliary sums and their name, if any.
    #[must_use]
    pub fn aux(&self) -> Option<(&str, &FixedSums)> {
        self.aux.as_ref().map(|(n, s)| (n.as_str(), s))
    }

    /// Rebuilds an accumulator from its raw fixed-point sums ([`crate::fixed`]), as a shard
    /// file stores them; errors if the lengths do not fit the grid.
    pub fn from_fixed_parts(
        spec: GridSpec,
        coeffs: usize,
        numerator: Vec<i128>,
        denominator: Vec<i128>,
        outside: Vec<i128>,
        contributions: u64,
    ) -> Result<Self, VolumeError> {
        check_coeffs(coeffs)?;
        let n = spec.node_count();
        if numerator.len() != n * coeffs * 3 || denominator.len() != n || outside.len() != n {
            return Err(VolumeError::Mismatch(format!(
                "accumulator arrays of {}, {}, {} values for {n} nodes x {coeffs} coeffs",
                numerator.len(),
                denominator.len(),
                outside.len()
            )));
        }
        Ok(Self {
            spec,
            coeffs,
            numerator: FixedSums::from_raw(numerator),
            denominator: FixedSums::from_raw(denominator),
            outside: FixedSums::from_raw(outside),
            contributions,
            aux: None,
            reach: None,
            groups: Vec::new(),
            group_labels: None,
        })
    }

    /// Adds raw fixed-point value `v` to the sum at flat index `i` of the concatenation
    /// numerator ‖ denominator ‖ outside ‖ auxiliary sums ‖ node reach ‖ light-group
    /// numerators (the shard-file order). Used to merge shard files as they stream in.
    ///
    /// # Panics
    /// If `i` is out of range.
    pub fn add_raw_at(&mut self, i: usize, v: i128) {
        let (a, b, c) = (self.numerator.len(), self.denominator.len(), self.outside.len());
        if i < a {
            self.numerator.add_raw(i, v);
        } else if i < a + b {
            self.denominator.add_raw(i - a, v);
        } else if i < a + b + c {
            self.outside.add_raw(i - a - b, v);
        } else if let Some(aux) = self.aux.as_mut().map(|x| &mut x.1).filter(|x| i < a + b + c + x.len()) {
            aux.add_raw(i - a - b - c, v);
        } else {
            let d = self.aux.as_ref().map_or(0, |x| x.1.len());
            let r = self.reach.as_ref().map_or(0, FixedSums::len);
            let at = i - a - b - c - d;
            if at < r {
                self.reach.as_mut().expect("r > 0 only with a reach").add_raw(at, v);
            } else {
                let g = (at - r) / a;
                let group =
                    self.groups.get_mut(g).expect("an index past the sums needs a reach or light groups");
                group.add_raw((at - r) % a, v);
            }
        }
    }

    /// Adds `n` to the contribution count (for a merged shard file).
    pub fn add_contributions(&mut self, n: u64) {
        self.contributions = self.contributions.saturating_add(n);
    }

    /// The raw fixed-point sums `(numerator, denominator, outside)`, or the name and index of
    /// the first poisoned sum (a non-finite or unrepresentable term reached the bake).
    pub fn fixed_parts(&self) -> Result<[&[i128]; 3], (&'static str, usize)> {
        for (what, v) in
            [("numerator", &self.numerator), ("denominator", &self.denominator), ("outside", &self.outside)]
        {
            if let Some(i) = v.first_poisoned() {
                return Err((what, i));
            }
        }
        Ok([self.numerator.raw(), self.denominator.raw(), self.outside.raw()])
    }

    /// Rebuilds an accumulator from f64 sums (each rounded to the fixed point once, as a
    /// term would be; version-1 shard files stored f64); errors if the lengths do not fit
    /// the grid or a sum is not representable.
    pub fn from_parts(
        spec: GridSpec,
        coeffs: usize,
        numerator: Vec<f64>,
        denominator: Vec<f64>,
        outside: Vec<f64>,
        contributions: u64,
    ) -> Result<Self, VolumeError> {
        // The lengths are checked by `from_fixed_parts`.
        let conv = |what: &'static str, v: &[f64]| -> Result<Vec<i128>, VolumeError> {
            v.iter()
                .enumerate()
                .map(|(index, &x)| crate::fixed::to_fixed(x).ok_or(VolumeError::NonFinite { what, index }))
                .collect()
        };
        Self::from_fixed_parts(
            spec,
            coeffs,
            conv("numerator", &numerator)?,
            conv("denominator", &denominator)?,
            conv("outside", &outside)?,
            contributions,
        )
    }

    /// The grid.
    #[must_use]
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// SH coefficients per channel.
    #[must_use]
    pub fn coeffs(&self) -> usize {
        self.coeffs
    }

    /// Number of [`Self::add`] calls recorded (including those of merged accumulators).
    #[must_use]
    pub fn contributions(&self) -> u64 {
        self.contributions
    }

    /// The numerator sums as f64, `[node][coeff][rgb]` (NaN where a term was not finite).
    #[must_use]
    pub fn numerator(&self) -> Vec<f64> {
        self.numerator.to_f64()
    }

    /// The denominator sums `Σ b` as f64, one per node.
    #[must_use]
    pub fn denominator(&self) -> Vec<f64> {
        self.denominator.to_f64()
    }

    /// The sums `Σ b` of rejected (outside-domain) candidates as f64, one per node.
    #[must_use]
    pub fn outside(&self) -> Vec<f64> {
        self.outside.to_f64()
    }

    /// Adds one sample to one node: `numerator[node][j][c] += b · radiance_over_pdf[c] ·
    /// basis[j]` and `denominator[node] += b` (Eq. 6).
    ///
    /// # Panics
    /// If `node` is out of range or `basis.len() != coeffs` (programming errors in the
    /// hot loop of a bake; checked always, they cost one comparison each).
    #[inline]
    pub fn add(&mut self, node: usize, b: f64, radiance_over_pdf: [f64; 3], basis: &[f64]) {
        assert_eq!(basis.len(), self.coeffs, "basis length must equal coeffs");
        let k = self.coeffs * 3;
        assert!(node < self.denominator.len(), "node {node} out of range");
        add_terms(&mut self.numerator, node * k, b, radiance_over_pdf, basis);
        self.denominator.add(node, b);
        self.contributions += 1;
    }

    /// Adds one sample at grid-space position `p` to the 8 nodes of its cell with their
    /// trilinear weights `b_i(p)` (zero weights are skipped).
    pub fn add_sample(&mut self, p: [f64; 3], radiance_over_pdf: [f64; 3], basis: &[f64]) {
        let (nodes, w) = self.spec.trilinear(p);
        for c in 0..8 {
            if w[c] > 0.0 {
                self.add(nodes[c], w[c], radiance_over_pdf, basis);
            }
        }
    }

    /// Records that a candidate sample with trilinear weight `b` for `node` was rejected as
    /// outside the domain of interest (lowers the node's finalized weight, see the module
    /// docs).
    ///
    /// # Panics
    /// If `node` is out of range.
    #[inline]
    pub fn add_outside(&mut self, node: usize, b: f64) {
        self.outside.add(node, b);
    }

    /// Adds a disjoint sample set (another shard, thread or resumed run). The sums are
    /// exact integers, so any grouping and order of merges gives bit-identical sums, equal
    /// to those of one pass over all the samples. Errors if the grids or coefficient counts
    /// differ.
    pub fn merge(&mut self, other: &Accumulator) -> Result<(), VolumeError> {
        if !self.spec.same_nodes(&other.spec) {
            return Err(VolumeError::Mismatch("cannot merge accumulators over different grids".into()));
        }
        if self.coeffs != other.coeffs {
            return Err(VolumeError::Mismatch(format!(
                "cannot merge accumulators with {} and {} coefficients",
                self.coeffs, other.coeffs
            )));
        }
        match (&mut self.aux, &other.aux) {
            (None, None) => {}
            (Some((a, x)), Some((b, y))) if a == b && x.len() == y.len() => x.merge(y),
            _ => {
                return Err(VolumeError::Mismatch(
                    "cannot merge accumulators with different auxiliary sums (e.g. one with a least-squares mass matrix)".into(),
                ));
            }
        }
        match (&mut self.reach, &other.reach) {
            (None, None) => {}
            (Some(x), Some(y)) => x.merge(y),
            _ => {
                return Err(VolumeError::Mismatch(
                    "cannot merge accumulators with and without a node reach (doi and another method)".into(),
                ));
            }
        }
        if self.group_labels != other.group_labels || self.groups.len() != other.groups.len() {
            return Err(VolumeError::Mismatch(
                "cannot merge accumulators with different light groups (names, count or baked sky)".into(),
            ));
        }
        for (a, b) in self.groups.iter_mut().zip(&other.groups) {
            a.merge(b);
        }
        self.numerator.merge(&other.numerator);
        self.denominator.merge(&other.denominator);
        self.outside.merge(&other.outside);
        self.contributions = self.contributions.saturating_add(other.contributions);
        Ok(())
    }

    /// The f64 coefficient estimate of one node, `numerator / denominator` (`[coeff][rgb]`),
    /// or `None` if the node received no weight.
    #[must_use]
    pub fn node_estimate(&self, node: usize) -> Option<Vec<f64>> {
        let d = self.denominator.get(node);
        (d > 0.0).then(|| {
            let k = self.coeffs * 3;
            (node * k..(node + 1) * k).map(|i| self.numerator.get(i) / d).collect()
        })
    }

    /// Divides numerators by denominators (Eq. 6), fills zero-weight nodes (see
    /// [`crate::fill`]) and converts to an f32 [`IrradianceVolume`] whose weights are the
    /// inside fractions described in the module docs.
    #[must_use]
    pub fn finalize(&self) -> (IrradianceVolume, FillReport) {
        let (values, weights, non_finite) = self.estimates();
        self.volume_from(values, &weights, non_finite)
    }

    /// The two halves of [`Self::finalize`], first: Eq. 6's node values (`[node][coeff][rgb]`,
    /// zero where the denominator is zero or not finite), the nodes' domain weights (module
    /// docs; zero for nodes without an estimate) and the number of non-finite denominators
    /// and weights met (a non-finite weight becomes 1).
    #[must_use]
    pub fn estimates(&self) -> (Vec<f64>, Vec<f64>, usize) {
        let n = self.spec.node_count();
        let k = self.coeffs * 3;
        let mut values = vec![0.0f64; n * k];
        let mut weights = vec![0.0f64; n];
        let mut non_finite = 0usize;
        for node in 0..n {
            let d = self.denominator.get(node);
            if !d.is_finite() {
                non_finite += 1;
                continue;
            }
            if d > 0.0 {
                for (i, out) in values[node * k..(node + 1) * k].iter_mut().enumerate() {
                    *out = self.numerator.get(node * k + i) / d;
                }
                let w = d / (d + self.outside.get(node));
                weights[node] = if w.is_finite() {
                    w.clamp(0.0, 1.0)
                } else {
                    non_finite += 1;
                    1.0
                };
            }
        }
        (values, weights, non_finite)
    }

    /// The second half of [`Self::finalize`], for Eq. 6's values or any other node values
    /// over this grid (e.g. a least-squares fit): values that are not finite or exceed the
    /// f32 range are zeroed and counted *before* the fill, so they cannot spread (a NaN
    /// radiance or weight from a broken scene must not poison the volume); then nodes with
    /// weight 0 are filled ([`crate::fill`]) and everything is converted to f32.
    /// `non_finite` (from [`Self::estimates`]) is added to the report's count.
    ///
    /// # Panics
    /// If `values` or `weights` do not have one entry per node (and coefficient channel).
    #[must_use]
    pub fn volume_from(
        &self,
        mut values: Vec<f64>,
        weights: &[f64],
        non_finite: usize,
    ) -> (IrradianceVolume, FillReport) {
        let n = self.spec.node_count();
        let k = self.coeffs * 3;
        assert!(
            values.len() == n * k && weights.len() == n,
            "one value per node and channel, one weight per node"
        );
        let mut non_finite = non_finite;
        for v in &mut values {
            if !(v.is_finite() && v.abs() <= f64::from(f32::MAX)) {
                *v = 0.0;
                non_finite += 1;
            }
        }
        let report = fill_empty_nodes(&self.spec, k, &mut values, weights);
        let report = FillReport { non_finite_zeroed: non_finite, ..report };
        let data: Vec<f32> = values.iter().map(|&v| v as f32).collect();
        let weights: Vec<f32> = weights.iter().map(|&w| w as f32).collect();
        let volume = IrradianceVolume::new(self.spec.clone(), self.coeffs, data, weights)
            .expect("finalize builds consistent, finite parts")
            .with_metadata(BakeMetadata::default());
        let volume = match self.reach() {
            Some(r) => volume.with_reach(r).expect("the reach covers the accumulator's nodes"),
            None => volume,
        };
        (volume, report)
    }
}

/// Adds one sample's numerator terms `b · r[c] · y_j` to `sums[at + 3j + c]`: the exact
/// arithmetic of [`Accumulator::add`], shared with sparse accumulators of node subsets so
/// that both round every term identically.
#[inline]
pub fn add_terms(sums: &mut FixedSums, at: usize, b: f64, radiance_over_pdf: [f64; 3], basis: &[f64]) {
    let s = [b * radiance_over_pdf[0], b * radiance_over_pdf[1], b * radiance_over_pdf[2]];
    for (j, &y) in basis.iter().enumerate() {
        sums.add(at + 3 * j, s[0] * y);
        sums.add(at + 3 * j + 1, s[1] * y);
        sums.add(at + 3 * j + 2, s[2] * y);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_sh::eval::eval_basis;
    use lightvol_sh::lowdisc::{Halton, SplitMix64};
    use lightvol_sh::sampling::sample_uniform_sphere;

    /// Agreement of two f64 sums of the same ~10^3 terms in different orders, relative to
    /// the largest sum (individual sums may cancel toward zero; their rounding error scales
    /// with the terms, not with the result).
    const MERGE_REL_TOL: f64 = 1e-12;

    fn spec() -> GridSpec {
        GridSpec::new([0.0; 3], [2.0, 1.0, 1.0], [3, 2, 2]).unwrap()
    }

    /// Sample `s` of a deterministic synthetic bake: position, radiance/pdf, basis.
    fn sample(seed: u64, s: u64) -> ([f64; 3], [f64; 3], [f64; 9]) {
        let h = Halton::new(seed, 5);
        let u: [f64; 5] = h.point(s);
        let p = [2.0 * u[0], u[1], u[2]];
        let dir = sample_uniform_sphere([u[3], u[4]]);
        let l = [1.0 + dir[2], 0.5 + 0.25 * dir[0], 2.0 * p[0]];
        let four_pi = 4.0 * std::f64::consts::PI;
        (p, l.map(|v| v * four_pi), eval_basis(dir))
    }

    #[test]
    fn merge_equals_single_pass_and_commutes() {
        let mut all = Accumulator::new(spec(), 9).unwrap();
        let mut a = Accumulator::new(spec(), 9).unwrap();
        let mut b = Accumulator::new(spec(), 9).unwrap();
        for s in 0..3000 {
            let (p, l, y) = sample(11, s);
            all.add_sample(p, l, &y);
            if s % 3 == 0 { a.add_sample(p, l, &y) } else { b.add_sample(p, l, &y) }
        }
        let mut ab = a.clone();
        ab.merge(&b).unwrap();
        let mut ba = b.clone();
        ba.merge(&a).unwrap();
        // Exact: any grouping equals the single pass, bit for bit.
        assert_eq!(ab, ba);
        assert_eq!(ab, all);
        assert_eq!(ab.contributions(), all.contributions());
        let (va, _) = ab.finalize();
        let (vb, _) = all.finalize();
        assert_eq!(va.data(), vb.data());
        // And the exact sums agree with a plain f64 single pass to f64 rounding of the
        // ~10^3 terms (relative to the largest sum).
        let mut plain = vec![0.0f64; all.numerator().len()];
        for s in 0..3000 {
            let (p, l, y) = sample(11, s);
            let (nodes, w) = spec().trilinear(p);
            for c in 0..8 {
                if w[c] > 0.0 {
                    for j in 0..9 {
                        for ch in 0..3 {
                            plain[nodes[c] * 27 + 3 * j + ch] += w[c] * l[ch] * y[j];
                        }
                    }
                }
            }
        }
        let num = all.numerator();
        let scale = num.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (x, y) in num.iter().zip(&plain) {
            assert!((x - y).abs() <= MERGE_REL_TOL * scale, "{x} vs {y}");
        }
    }

    #[test]
    fn merge_rejects_mismatch() {
        let mut a = Accumulator::new(spec(), 9).unwrap();
        let b = Accumulator::new(spec(), 4).unwrap();
        assert!(a.merge(&b).is_err());
        let c = Accumulator::new(GridSpec::new([0.0; 3], [1.0; 3], [3, 2, 2]).unwrap(), 9).unwrap();
        assert!(a.merge(&c).is_err());
    }

    #[test]
    fn finalize_divides_and_reports_weights() {
        let mut acc = Accumulator::new(spec(), 4).unwrap();
        // Node 0: two samples with b = 0.5 and 0.25 of constant radiance 2 (times basis).
        let y = [1.0, 0.5, -0.5, 0.25];
        acc.add(0, 0.5, [2.0, 4.0, 6.0], &y);
        acc.add(0, 0.25, [2.0, 4.0, 6.0], &y);
        acc.add_outside(0, 0.25);
        let (vol, report) = acc.finalize();
        // c = Σ b L y / Σ b = L y exactly for a constant L.
        assert_eq!(vol.coeff_rgb(0, 0), [2.0, 4.0, 6.0]);
        assert_eq!(vol.coeff_rgb(0, 3), [0.5, 1.0, 1.5]);
        assert_eq!(vol.weights()[0], 0.75);
        assert_eq!(report.filled, vol.spec().node_count() - 1);
        // Every other node was filled from node 0, the only source.
        assert_eq!(vol.coeff_rgb(5, 1), [1.0, 2.0, 3.0]);
        assert_eq!(vol.weights()[5], 0.0);
    }

    #[test]
    fn non_finite_samples_are_zeroed_and_counted_not_spread() {
        let mut acc = Accumulator::new(spec(), 4).unwrap();
        let y = [1.0, 0.0, 0.0, 0.0];
        acc.add(0, 1.0, [f64::NAN, 1.0, 2.0], &y); // a NaN red radiance at node 0
        acc.add(1, f64::INFINITY, [1.0, 1.0, 1.0], &y); // non-finite weight at node 1
        acc.add(2, 1.0, [3.0, 3.0, 3.0], &y);
        acc.add_outside(2, f64::NAN);
        let (vol, report) = acc.finalize();
        // Node 0: the red channel of all 4 coefficients (NaN · 0 is NaN); node 1: its
        // denominator; node 2: its weight.
        assert_eq!(report.non_finite_zeroed, 4 + 1 + 1);
        assert!(vol.data().iter().all(|v| v.is_finite()));
        assert_eq!(vol.coeff_rgb(0, 0), [0.0, 1.0, 2.0]);
        assert_eq!(vol.weights()[1], 0.0); // treated as empty, then filled
        assert_eq!(vol.weights()[2], 1.0);
    }

    #[test]
    fn point_sampling_estimates_projection() {
        // Eq. 4 by Monte Carlo with b = 1: radiance L(ω) = 1 + z has SH c_0 = sqrt(4π),
        // c_2 (y_10) = sqrt(4π/3).
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let mut acc = Accumulator::new(spec, 4).unwrap();
        let mut rng = SplitMix64::new(5);
        let n = 20_000;
        let h = Halton::new(9, 2);
        for s in 0..n {
            let dir = sample_uniform_sphere(h.point(s));
            let l = 4.0 * std::f64::consts::PI * (1.0 + dir[2]);
            let y: [f64; 4] = eval_basis(dir);
            acc.add(0, 1.0, [l, l, l], &y);
            let _ = rng.next_f64();
        }
        let est = acc.node_estimate(0).unwrap();
        let pi4 = 4.0 * std::f64::consts::PI;
        // Halton QMC error for 2·10^4 points on this smooth integrand is far below 1e-3.
        const QMC_TOL: f64 = 1e-3;
        assert!((est[0] - pi4.sqrt()).abs() < QMC_TOL, "{}", est[0]);
        assert!((est[6] - (pi4 / 3.0).sqrt()).abs() < QMC_TOL, "{}", est[6]);
        assert!(est[3].abs() < QMC_TOL && est[9].abs() < QMC_TOL);
    }
}
