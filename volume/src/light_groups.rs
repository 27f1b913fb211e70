//! A volume split by light group: the whole bake and, per group of lights, the coefficients
//! the lights of that group alone contribute, from the same paths.
//!
//! Light transport is linear in the emitters, and a bake's node values are linear in the
//! radiance its samples carry (Kontkanen & Laine 2006, Eq. 4-6: sums of radiance times
//! basis functions over a denominator that does not depend on the light; the fill of
//! \[`crate::fill`\] averages neighbours with weights that do not either). So a bake that
//! tags each sample's radiance with its light group has, per group, node values `c_g`
//! with `Σ_g c_g = c` up to rounding, and the volume of a scene whose group `g` lights are
//! scaled by `s_g` (a colour per channel) is `Σ_g s_g c_g` ([`GroupedVolume::relit`]), with
//! no new rays. Every lookup is linear in the node values too, so a lookup of the relit
//! volume equals the weighted sum of the groups' lookups.
//!
//! ## Sky transfer
//! A bake with a sky transfer has, after the groups of its other lights, one group per SH
//! coefficient of the sky's radiance, named `sky.sh00`, `sky.sh01`, …
//! ([`SKY_TRANSFER_PREFIX`]): group `sky.shJJ` holds the volume a sky of radiance `Y_j`
//! would give, every bounce included, so that a sky `L = Σ_j l_j Y_j` (per channel) gives
//! `Σ_j l_j ⊙ c_{sky.j}` (Sloan, Kautz & Snyder 2002: the transfer vector of each node's
//! coefficient, Eq. 3-4). [`GroupedVolume::sky_scales`] turns a sky's coefficients into
//! the scales of [`GroupedVolume::relit`]; [`GroupedVolume::baked_sky`] keeps the
//! coefficients of the sky the volume was baked with, so that relighting with them gives
//! the whole bake up to the sky's band-limit error ([`GroupedVolume::sum_error`]).
//!
//! ## Lighting scenarios
//! A file of lighting scenarios holds one whole bake per lighting of the same geometry
//! (groups named `scenario.NAME`, [`SCENARIO_PREFIX`]); the whole bake is the first
//! scenario's. Blending scenarios `Σ_s w_s c_s` (weights summing to 1 for a blend) is
//! [`GroupedVolume::relit`] with [`GroupedVolume::parse_blend`]'s scales.
//!
//! Each group is stored as coefficients only: the weights, validity, reach, grid and
//! metadata are the whole bake's ([`GroupedVolume::total`]), which a group's volume
//! ([`GroupedVolume::group`]) shares.

use crate::error::VolumeError;
use crate::volume::IrradianceVolume;

/// A volume and its light groups' coefficients (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct GroupedVolume {
    total: IrradianceVolume,
    names: Vec<String>,
    /// Per group, coefficients in the total's layout `[node][coeff][rgb]`.
    layers: Vec<Vec<f32>>,
    /// With a sky transfer: the SH coefficients of the sky the volume was baked with.
    baked_sky: Option<Vec<[f64; 3]>>,
}

/// The name prefix of a sky transfer's groups (module docs).
pub const SKY_TRANSFER_PREFIX: &str = "sky.sh";

/// The name prefix of lighting scenarios (module docs).
pub const SCENARIO_PREFIX: &str = "scenario.";

/// Checks a group name: not empty, at most 64 bytes, printable ASCII without `"` or `\`
/// (it travels in file headers and generated shader code comments).
pub fn check_group_name(name: &str) -> Result<(), VolumeError> {
    if name.is_empty()
        || name.len() > 64
        || !name.bytes().all(|b| (0x20..0x7f).contains(&b) && b != b'"' && b != b'\\')
    {
        return Err(VolumeError::InvalidData(format!(
            "light group name {name:?} is not 1-64 printable ASCII characters without quotes or backslashes"
        )));
    }
    Ok(())
}

impl GroupedVolume {
    /// The volume `total` with one coefficient layer per group, in `total`'s layout; errors
    /// if there are no groups, the names are not unique or valid ([`check_group_name`]), a
    /// layer's length differs from the total's data or a value is not finite.
    pub fn new(
        total: IrradianceVolume,
        names: Vec<String>,
        layers: Vec<Vec<f32>>,
    ) -> Result<Self, VolumeError> {
        if names.is_empty() || names.len() != layers.len() {
            return Err(VolumeError::Mismatch(format!(
                "{} light group names for {} layers (at least one group)",
                names.len(),
                layers.len()
            )));
        }
        for (i, n) in names.iter().enumerate() {
            check_group_name(n)?;
            if names[..i].contains(n) {
                return Err(VolumeError::InvalidData(format!("light group {n:?} named twice")));
            }
        }
        for (n, l) in names.iter().zip(&layers) {
            if l.len() != total.data().len() {
                return Err(VolumeError::Mismatch(format!(
                    "light group {n:?} has {} values, the volume {}",
                    l.len(),
                    total.data().len()
                )));
            }
            crate::error::check_finite("light group coefficients", l)?;
        }
        let v = Self { total, names, layers, baked_sky: None };
        if let Some((base, n)) = v.sky_transfer() {
            let want: Vec<String> = (0..n).map(|j| format!("{SKY_TRANSFER_PREFIX}{j:02}")).collect();
            if v.names[base..] != want[..] || ![4, 9, 16].contains(&n) {
                return Err(VolumeError::InvalidData(format!(
                    "sky transfer groups must be the last groups, {SKY_TRANSFER_PREFIX}00 to {SKY_TRANSFER_PREFIX}03, 08 or 15 in order"
                )));
            }
        }
        Ok(v)
    }

    /// Whether the groups are lighting scenarios (module docs).
    #[must_use]
    pub fn is_scenarios(&self) -> bool {
        self.names.iter().all(|n| n.starts_with(SCENARIO_PREFIX))
    }

    /// Scales that blend lighting scenarios: `NAME=W;NAME=W` (the names without the
    /// `scenario.` prefix), the scenarios not named weighted 0.
    ///
    /// # Errors
    /// A volume without scenarios, an unknown or repeated name, a weight that is not a
    /// finite number.
    pub fn parse_blend(&self, spec: &str) -> Result<Vec<[f64; 3]>, VolumeError> {
        let bad = |m: String| VolumeError::InvalidData(m);
        if !self.is_scenarios() {
            return Err(bad("the volume has no lighting scenarios (bake it with --scenario)".into()));
        }
        let listing = || {
            self.names.iter().map(|n| n.trim_start_matches(SCENARIO_PREFIX)).collect::<Vec<_>>().join(", ")
        };
        let mut scales = vec![[0.0; 3]; self.names.len()];
        let mut given = vec![false; self.names.len()];
        for item in spec.split(';').map(str::trim).filter(|s| !s.is_empty()) {
            let (name, w) =
                item.split_once('=').ok_or_else(|| bad(format!("scenario weight {item:?} is not NAME=W")))?;
            let g = self.find(&format!("{SCENARIO_PREFIX}{}", name.trim())).ok_or_else(|| {
                bad(format!("no scenario {:?} (the volume has {})", name.trim(), listing()))
            })?;
            if std::mem::replace(&mut given[g], true) {
                return Err(bad(format!("scenario {:?} weighted twice", name.trim())));
            }
            let w: f64 = w
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| bad(format!("scenario weight {w:?} is not a finite number")))?;
            scales[g] = [w; 3];
        }
        Ok(scales)
    }

    /// The volume with the coefficients of the sky it was baked with (module docs); errors
    /// without a sky transfer or with another count.
    pub fn with_baked_sky(mut self, sky: Vec<[f64; 3]>) -> Result<Self, VolumeError> {
        let n = self.sky_transfer().map(|t| t.1);
        if n != Some(sky.len()) || sky.iter().flatten().any(|v| !v.is_finite()) {
            return Err(VolumeError::Mismatch(format!(
                "{} finite sky coefficients for a sky transfer of {n:?}",
                sky.len()
            )));
        }
        self.baked_sky = Some(sky);
        Ok(self)
    }

    /// The coefficients of the sky the volume was baked with, when it has a sky transfer
    /// that records them.
    #[must_use]
    pub fn baked_sky(&self) -> Option<&[[f64; 3]]> {
        self.baked_sky.as_deref()
    }

    /// The sky transfer, if any: its first group and its SH coefficient count (the groups
    /// named with [`SKY_TRANSFER_PREFIX`], which come last).
    #[must_use]
    pub fn sky_transfer(&self) -> Option<(usize, usize)> {
        let base = self.names.iter().position(|n| n.starts_with(SKY_TRANSFER_PREFIX))?;
        Some((base, self.names.len() - base))
    }

    /// The scales that relight the volume with the sky of SH coefficients `sky` (per
    /// channel), the other groups scaled by `others` (one per group before the transfer;
    /// `None`: 1).
    ///
    /// # Errors
    /// Without a sky transfer, or with a coefficient count other than the transfer's.
    pub fn sky_scales(
        &self,
        sky: &[[f64; 3]],
        others: Option<&[[f64; 3]]>,
    ) -> Result<Vec<[f64; 3]>, VolumeError> {
        let (base, n) = self.sky_transfer().ok_or_else(|| {
            VolumeError::InvalidData("the volume has no sky transfer (bake it with --sky-transfer)".into())
        })?;
        if sky.len() != n {
            return Err(VolumeError::Mismatch(format!(
                "{} sky coefficients for a transfer of {n}",
                sky.len()
            )));
        }
        let mut scales = match others {
            Some(o) if o.len() >= base => o[..base].to_vec(),
            _ => vec![[1.0; 3]; base],
        };
        scales.extend_from_slice(sky);
        Ok(scales)
    }

    /// The whole bake.
    #[must_use]
    pub fn total(&self) -> &IrradianceVolume {
        &self.total
    }

    /// The group names, in group order.
    #[must_use]
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Group `g`'s coefficients, in the total's layout.
    ///
    /// # Panics
    /// If `g` is out of range.
    #[must_use]
    pub fn layer(&self, g: usize) -> &[f32] {
        &self.layers[g]
    }

    /// The index of the group named `name`.
    #[must_use]
    pub fn find(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Group `g` alone as a volume: the total's grid, weights, validity, reach and metadata
    /// with the group's coefficients.
    ///
    /// # Panics
    /// If `g` is out of range.
    #[must_use]
    pub fn group(&self, g: usize) -> IrradianceVolume {
        self.total.with_data(self.layers[g].clone()).expect("layers are checked against the total")
    }

    /// The volume with group `g` scaled by `scales[g]` (per channel), `Σ_g s_g c_g`,
    /// summed in f64 in group order and rounded to f32 once (module docs). With every
    /// scale 1 it is the sum of the groups, the whole bake up to rounding.
    ///
    /// # Errors
    /// [`VolumeError::Mismatch`] unless there is one scale per group;
    /// [`VolumeError::InvalidData`] for a scale or result that is not finite.
    pub fn relit(&self, scales: &[[f64; 3]]) -> Result<IrradianceVolume, VolumeError> {
        if scales.len() != self.layers.len() {
            return Err(VolumeError::Mismatch(format!(
                "{} scales for {} light groups ({})",
                scales.len(),
                self.layers.len(),
                self.names.join(", ")
            )));
        }
        if let Some(s) = scales.iter().flatten().find(|s| !s.is_finite()) {
            return Err(VolumeError::InvalidData(format!("light group scale {s} is not finite")));
        }
        let data: Vec<f32> = (0..self.total.data().len())
            .map(|i| {
                let c = i % 3;
                let v: f64 = self.layers.iter().zip(scales).map(|(l, s)| s[c] * f64::from(l[i])).sum();
                v as f32
            })
            .collect();
        crate::error::check_finite("relit coefficients", &data)?;
        self.total.with_data(data)
    }

    /// Parses scales given as `NAME=S` or `NAME=R,G,B`, separated by `;`: the named groups
    /// get those scales, the others 1.
    ///
    /// # Errors
    /// A malformed item, an unknown group name (the message lists the names), a group
    /// named twice, or a scale that is not a finite number.
    pub fn parse_scales(&self, spec: &str) -> Result<Vec<[f64; 3]>, VolumeError> {
        let bad = |m: String| VolumeError::InvalidData(m);
        let mut scales = vec![[1.0; 3]; self.layers.len()];
        let mut given = vec![false; self.layers.len()];
        for item in spec.split(';').map(str::trim).filter(|s| !s.is_empty()) {
            let (name, value) = item
                .split_once('=')
                .ok_or_else(|| bad(format!("light group scale {item:?} is not NAME=S")))?;
            let g = self.find(name.trim()).ok_or_else(|| {
                bad(format!("no light group {:?} (the volume has {})", name.trim(), self.names.join(", ")))
            })?;
            if std::mem::replace(&mut given[g], true) {
                return Err(bad(format!("light group {:?} scaled twice", name.trim())));
            }
            let v: Vec<f64> = value
                .split(',')
                .map(|x| x.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
                .collect::<Option<_>>()
                .ok_or_else(|| bad(format!("light group scale {value:?} is not a finite number")))?;
            scales[g] = match v[..] {
                [s] => [s; 3],
                [r, g, b] => [r, g, b],
                _ => return Err(bad(format!("light group scale {value:?} is not S or R,G,B"))),
            };
        }
        Ok(scales)
    }

    /// The largest difference between the groups relit as baked and the whole bake,
    /// relative to the largest absolute coefficient of the whole bake (0 for an empty
    /// volume): the plain groups at scale 1, lighting scenarios as the first alone, and a
    /// sky transfer's groups at the baked sky's coefficients (without those, the transfer is left out and the error is `NaN`). For
    /// plain groups this is f32 rounding; with a sky transfer it adds the baked sky's
    /// band-limit error.
    #[must_use]
    pub fn sum_error(&self) -> f64 {
        let scale = self.total.data().iter().fold(0.0f64, |m, &v| m.max(f64::from(v.abs())));
        if scale == 0.0 {
            return 0.0;
        }
        let scales = match (self.sky_transfer(), &self.baked_sky) {
            (None, _) if self.is_scenarios() => {
                let mut s = vec![[0.0; 3]; self.layers.len()];
                s[0] = [1.0; 3];
                s
            }
            (None, _) => vec![[1.0; 3]; self.layers.len()],
            (Some(_), Some(sky)) => match self.sky_scales(sky, None) {
                Ok(s) => s,
                Err(_) => return f64::NAN,
            },
            (Some(_), None) => return f64::NAN,
        };
        let worst = (0..self.total.data().len())
            .map(|i| {
                let s: f64 = self.layers.iter().zip(&scales).map(|(l, w)| w[i % 3] * f64::from(l[i])).sum();
                (s - f64::from(self.total.data()[i])).abs()
            })
            .fold(0.0f64, f64::max);
        worst / scale
    }

    /// The same volume with its sky transfer expressed for skies given in the file frame
    /// `up` (the frame engine exports are in, [`crate::frame::to_file_frame`]): with `R`
    /// the SH rotation from lightvol's frame to the file's (`l_file = R l`), the relit
    /// volume `Σ_k l_k c_k = Σ_j l_file,j (Σ_k R_jk c_k)`, so the file-frame group `j` is
    /// `Σ_k R_jk c_k` and the baked sky's coefficients become `R l` (Sloan, Kautz & Snyder
    /// 2002, §5: a transfer vector rotates with its lighting). The layers stay in
    /// lightvol's frame (the export rotates every layer's coefficients as it writes it);
    /// only which sky coefficient each sky group answers changes. Without a sky transfer,
    /// or for a z-up file, the volume is unchanged.
    ///
    /// # Errors
    /// If a mixed coefficient is not finite.
    pub fn sky_in_frame(&self, up: crate::up_axis::UpAxis) -> Result<Self, VolumeError> {
        let Some((base, n)) = self.sky_transfer() else { return Ok(self.clone()) };
        if up == crate::up_axis::UpAxis::Z {
            return Ok(self.clone());
        }
        let bands = (n as f64).sqrt().round() as usize;
        let r = glam::DMat3::from_cols_array_2d(&std::array::from_fn(|c| {
            let e: [f64; 3] = std::array::from_fn(|i| f64::from(u8::from(i == c)));
            up.to_file(e)
        }));
        let rot = lightvol_sh::rotate::ShRotation::from_mat3(bands, r);
        // Column k of R: the rotation of the unit coefficient vector e_k.
        let columns: Vec<Vec<f64>> = (0..n)
            .map(|k| {
                let mut e = vec![0.0f64; n];
                e[k] = 1.0;
                rot.apply_in_place(&mut e);
                e
            })
            .collect();
        let mut out = self.clone();
        for j in 0..n {
            let mixed: Vec<f32> = (0..self.total.data().len())
                .map(|i| {
                    (0..n).map(|k| columns[k][j] * f64::from(self.layers[base + k][i])).sum::<f64>() as f32
                })
                .collect();
            crate::error::check_finite("rotated sky transfer", &mixed)?;
            out.layers[base + j] = mixed;
        }
        out.baked_sky = self.baked_sky.as_ref().map(|sky| {
            (0..n).map(|j| std::array::from_fn(|c| (0..n).map(|k| columns[k][j] * sky[k][c]).sum())).collect()
        });
        Ok(out)
    }

    /// Bytes the groups add to the whole bake's coefficients (f32 values).
    #[must_use]
    pub fn layer_bytes(&self) -> usize {
        self.layers.iter().map(|l| l.len() * 4).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSpec;

    fn grouped() -> GroupedVolume {
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let a: Vec<f32> = (0..8 * 27).map(|i| (i % 7) as f32 * 0.25).collect();
        let b: Vec<f32> = (0..8 * 27).map(|i| (i % 5) as f32 * 0.5 - 0.5).collect();
        let total: Vec<f32> = a.iter().zip(&b).map(|(x, y)| x + y).collect();
        let vol = IrradianceVolume::new(spec, 9, total, vec![1.0; 8]).unwrap();
        GroupedVolume::new(vol, vec!["day".into(), "lamps".into()], vec![a, b]).unwrap()
    }

    #[test]
    fn relit_scales_each_group_and_unit_scales_give_the_total() {
        let g = grouped();
        // Quarters and halves: every sum here is exact in f32.
        assert_eq!(g.relit(&[[1.0; 3], [1.0; 3]]).unwrap().data(), g.total().data());
        assert_eq!(g.sum_error(), 0.0);
        let r = g.relit(&[[2.0, 1.0, 0.0], [0.0; 3]]).unwrap();
        for (i, (&x, &a)) in r.data().iter().zip(g.layer(0)).enumerate() {
            assert_eq!(x, a * [2.0, 1.0, 0.0][i % 3]);
        }
        assert_eq!(g.group(1).data(), g.layer(1));
        assert_eq!(g.group(1).weights(), g.total().weights());
    }

    #[test]
    fn scales_parse_by_name_and_refuse_bad_input() {
        let g = grouped();
        assert_eq!(g.parse_scales("lamps=0.5").unwrap(), [[1.0; 3], [0.5; 3]]);
        assert_eq!(g.parse_scales("day=1,0.5,0.25; lamps=0").unwrap(), [[1.0, 0.5, 0.25], [0.0; 3]]);
        for (spec, says) in [
            ("moon=1", "the volume has day, lamps"),
            ("day", "not NAME=S"),
            ("day=x", "not a finite"),
            ("day=1,2", "not S or R,G,B"),
            ("day=1;day=2", "twice"),
            ("day=inf", "not a finite"),
        ] {
            let e = g.parse_scales(spec).unwrap_err().to_string();
            assert!(e.contains(says), "{spec}: {e}");
        }
        assert!(g.relit(&[[1.0; 3]]).is_err());
    }

    #[test]
    fn construction_checks_names_and_lengths() {
        let g = grouped();
        let t = g.total().clone();
        let l = g.layer(0).to_vec();
        assert!(GroupedVolume::new(t.clone(), vec![], vec![]).is_err());
        assert!(
            GroupedVolume::new(t.clone(), vec!["a".into(), "a".into()], vec![l.clone(), l.clone()]).is_err()
        );
        assert!(GroupedVolume::new(t.clone(), vec!["a\"b".into()], vec![l.clone()]).is_err());
        assert!(GroupedVolume::new(t.clone(), vec!["a".into()], vec![l[1..].to_vec()]).is_err());
        let mut nan = l;
        nan[3] = f32::NAN;
        assert!(GroupedVolume::new(t, vec!["a".into()], vec![nan]).is_err());
    }

    /// A sky given in a y-up file's frame relights the frame-mixed transfer as the same sky
    /// in lightvol's frame relights the original: the rotation from `to_file` applied to the
    /// sky (`l_file = R l`, lightvol-sh's rotation, tested there against quadrature) and the
    /// mixing of [`GroupedVolume::sky_in_frame`] cancel.
    #[test]
    fn sky_transfer_in_a_file_frame_relights_the_same() {
        use crate::up_axis::UpAxis;
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let layer = |g: usize| -> Vec<f32> {
            (0..8 * 27).map(|i| (((i * 7 + g * 13) % 11) as f32 - 5.0) * 0.125).collect()
        };
        let names: Vec<String> =
            std::iter::once("lamp".to_string()).chain((0..9).map(|j| format!("sky.sh{j:02}"))).collect();
        let layers: Vec<Vec<f32>> = (0..10).map(layer).collect();
        let vol = IrradianceVolume::new(spec, 9, layer(99), vec![1.0; 8]).unwrap();
        let sky: Vec<[f64; 3]> = (0..9).map(|j| [1.0 - 0.1 * j as f64, 0.3, 0.05 * j as f64]).collect();
        let g = GroupedVolume::new(vol, names, layers).unwrap().with_baked_sky(sky.clone()).unwrap();
        assert_eq!(g.sky_in_frame(UpAxis::Z).unwrap(), g);
        let y = g.sky_in_frame(UpAxis::Y).unwrap();
        assert_eq!(y.layer(0), g.layer(0), "other groups are untouched");
        // The sky in the file frame, rotated as the file-frame conversion rotates SH.
        let r = glam::DMat3::from_cols_array_2d(&std::array::from_fn(|c| {
            let e: [f64; 3] = std::array::from_fn(|i| f64::from(u8::from(i == c)));
            UpAxis::Y.to_file(e)
        }));
        let rot = lightvol_sh::rotate::ShRotation::from_mat3(3, r);
        let file_sky: Vec<[f64; 3]> = {
            let mut out = vec![[0.0; 3]; 9];
            for c in 0..3 {
                let mut v: Vec<f64> = sky.iter().map(|s| s[c]).collect();
                rot.apply_in_place(&mut v);
                for j in 0..9 {
                    out[j][c] = v[j];
                }
            }
            out
        };
        for (a, b) in y.baked_sky().unwrap().iter().zip(&file_sky) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() < 1e-12, "baked sky rotated: {a:?} {b:?}");
            }
        }
        let want = g.relit(&g.sky_scales(&sky, None).unwrap()).unwrap();
        let got = y.relit(&y.sky_scales(&file_sky, None).unwrap()).unwrap();
        // f32 layers mixed in f64 and rounded once more: a few ulps of the largest term.
        const MIXING_ULPS: f32 = 1e-5;
        for (a, b) in want.data().iter().zip(got.data()) {
            assert!((a - b).abs() <= MIXING_ULPS, "{a} {b}");
        }
        // Negative control: the unrotated sky on the mixed groups is another lighting.
        let wrong = y.relit(&y.sky_scales(&sky, None).unwrap()).unwrap();
        assert!(want.data().iter().zip(wrong.data()).any(|(a, b)| (a - b).abs() > 0.01));
    }
}
