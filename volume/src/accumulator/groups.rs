//! The light groups' numerators of an [`Accumulator`] (see the parent module's docs, "Light
//! groups"): one numerator per group beside the whole bake's, over the same denominator.

use super::{Accumulator, add_terms};
use crate::error::VolumeError;
use crate::fixed::FixedSums;
use crate::volume::IrradianceVolume;

/// What a bake split by light group records about its groups: their names, and with a sky
/// transfer the SH coefficients of the sky it was baked with
/// ([`crate::light_groups::GroupedVolume`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GroupLabels {
    /// The group names, in group order.
    pub names: Vec<String>,
    /// A sky transfer's baked sky coefficients, per channel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sky: Option<Vec<[f64; 3]>>,
}

impl Accumulator {
    /// Starts one empty numerator per light group of `labels` (module docs), replacing any
    /// earlier ones.
    pub fn enable_groups(&mut self, labels: GroupLabels) {
        self.groups = vec![FixedSums::zeros(self.numerator.len()); labels.names.len()];
        self.group_labels = Some(labels);
    }

    /// The light groups' labels, if the bake is split by group.
    #[must_use]
    pub fn group_labels(&self) -> Option<&GroupLabels> {
        self.group_labels.as_ref()
    }

    /// Each light group's raw numerator sums, in group order (empty without groups).
    #[must_use]
    pub fn groups_raw(&self) -> Vec<&[i128]> {
        self.groups.iter().map(FixedSums::raw).collect()
    }

    /// `total` (this accumulator's finalized volume, with its metadata) and the light
    /// groups ([`Self::finalize_groups`]) as a [`GroupedVolume`](crate::GroupedVolume);
    /// `None` without groups.
    ///
    /// # Errors
    /// When the groups and `total` do not fit together.
    pub fn finalize_grouped(
        &self,
        total: &IrradianceVolume,
    ) -> Option<Result<crate::light_groups::GroupedVolume, VolumeError>> {
        let labels = self.group_labels.as_ref()?;
        let g = crate::light_groups::GroupedVolume::new(
            total.clone(),
            labels.names.clone(),
            self.finalize_groups(),
        );
        Some(match (g, &labels.sky) {
            (Ok(g), Some(sky)) => g.with_baked_sky(sky.clone()),
            (g, _) => g,
        })
    }

    /// The number of light-group numerators (0 for a bake not split by group).
    #[must_use]
    pub fn group_count(&self) -> usize {
        self.groups.len()
    }

    /// Adds one sample's terms for light group `g` to node `node`: the numerator arithmetic
    /// of [`Self::add`] on group `g`'s numerator only (the denominator is the whole bake's,
    /// added by [`Self::add`] for the same sample).
    ///
    /// # Panics
    /// If `g` or `node` is out of range or `basis.len() != coeffs`.
    #[inline]
    pub fn add_group(&mut self, g: usize, node: usize, b: f64, radiance_over_pdf: [f64; 3], basis: &[f64]) {
        assert_eq!(basis.len(), self.coeffs, "basis length must equal coeffs");
        let k = self.coeffs * 3;
        add_terms(&mut self.groups[g], node * k, b, radiance_over_pdf, basis);
    }

    /// Each light group's coefficients (module docs), `[node][coeff][rgb]` as f32: Eq. 6's
    /// division by the whole bake's denominators, then the fill and checks of
    /// [`Self::volume_from`] with the whole bake's weights, so that the groups sum to
    /// [`Self::finalize`]'s coefficients up to rounding.
    #[must_use]
    pub fn finalize_groups(&self) -> Vec<Vec<f32>> {
        let (_, weights, _) = self.estimates();
        let n = self.spec.node_count();
        let k = self.coeffs * 3;
        self.groups
            .iter()
            .map(|g| {
                let mut values = vec![0.0f64; n * k];
                for node in 0..n {
                    let d = self.denominator.get(node);
                    if d.is_finite() && d > 0.0 {
                        for (i, out) in values[node * k..(node + 1) * k].iter_mut().enumerate() {
                            *out = g.get(node * k + i) / d;
                        }
                    }
                }
                self.volume_from(values, &weights, 0).0.data().to_vec()
            })
            .collect()
    }
}

impl Accumulator {
    /// Makes light group `g`'s numerator `other`'s whole numerator: a lighting scenario
    /// baked separately over the same samples ([`GroupLabels`] named `scenario.NAME`).
    /// Its coefficients then finalize ([`Self::finalize_groups`]) to exactly what `other`
    /// finalizes to, which is why the two must agree on everything the light does not
    /// change: grid, coefficients, denominators and outside sums.
    ///
    /// # Errors
    /// [`VolumeError::Mismatch`] when `g` is not a group, or the grids, coefficient counts,
    /// denominators or outside sums differ (a different geometry, grid or sample set).
    pub fn set_group_from(&mut self, g: usize, other: &Accumulator) -> Result<(), VolumeError> {
        if g >= self.groups.len() {
            return Err(VolumeError::Mismatch(format!("group {g} of {}", self.groups.len())));
        }
        if other.spec != self.spec
            || other.coeffs != self.coeffs
            || other.denominator != self.denominator
            || other.outside != self.outside
        {
            return Err(VolumeError::Mismatch(
                "a scenario's samples differ from the first scenario's (grid, coefficients or domain weights)"
                    .into(),
            ));
        }
        self.groups[g] = other.numerator.clone();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSpec;

    fn acc(radiance: f64, at: [f64; 3]) -> Accumulator {
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let mut a = Accumulator::new(spec, 4).unwrap();
        a.add_sample(at, [radiance, 2.0 * radiance, 0.5], &[1.0, 0.25, -0.5, 0.125]);
        a
    }

    /// A scenario's numerator becomes a group that finalizes exactly as its own bake does;
    /// a scenario over other samples is refused.
    #[test]
    fn a_scenario_group_finalizes_as_its_own_bake() {
        let at = [0.3, 0.6, 0.2];
        let mut first = acc(1.0, at);
        let second = acc(3.0, at);
        first.enable_groups(GroupLabels { names: vec!["scenario.a".into(), "scenario.b".into()], sky: None });
        let own = [first.clone(), second.clone()];
        for (g, a) in own.iter().enumerate() {
            first.set_group_from(g, a).unwrap();
        }
        let groups = first.finalize_groups();
        for (g, a) in own.iter().enumerate() {
            assert_eq!(groups[g], a.finalize().0.data(), "scenario {g}");
        }
        assert!(first.set_group_from(0, &acc(1.0, [0.9, 0.1, 0.5])).is_err(), "other samples");
        assert!(first.set_group_from(2, &second).is_err(), "no group 2");
    }
}
