//! Each engine's lookup of a uniform probe grid, emulated on the CPU in f64: what a volume
//! looks like when an engine, not lightvol, reads it.
//!
//! A baked grid is only half of what a user sees; the other half is the engine's rule for
//! reading it between the nodes. The engines differ in where they sample (a normal or view
//! offset), which nodes they leave out (validity, reach) and what they store (SH or an
//! ambient cube), and these differences are as large as the differences between baking
//! methods. [`EngineLookup`] names each rule, cites the engine's source, and
//! [`IrradianceVolume::engine_irradiance`] evaluates it for a surface point `p`, its unit
//! normal `n` and the unit direction `v` from the point towards the eye.
//!
//! All of them interpolate the same node values with trilinear weights (Kontkanen & Laine
//! 2006 Eq. 2) clamped to the grid's box, and turn SH into irradiance with the clamped-cosine
//! factors (Eq. 3; Ramamoorthi & Hanrahan 2001); the rules:
//!
//! | lookup | sample point | corners left out | evaluation |
//! |---|---|---|---|
//! | [`Lightvol`](EngineLookup::Lightvol) | `p` | invalid ones, and those the node reach cuts off | SH irradiance |
//! | [`Trilinear`](EngineLookup::Trilinear) | `p` | none | SH irradiance |
//! | [`Three`](EngineLookup::Three) | `p + n ⊙ h / 2` | none | SH irradiance |
//! | [`Bevy`](EngineLookup::Bevy) | `p` | none | ambient cube `Σ_a n_a² C_a±` |
//! | [`Apv`](EngineLookup::Apv) | `p + b_n n + b_v v` | invalid ones | SH irradiance |
//!
//! `h` is the grid's cell size per axis. The Bevy rule reads the ambient cube that
//! `--format bevy` stores (each face the SH irradiance at the node for the axis normal,
//! [`crate::io::bevy::ambient_cubes`]); the f16 rounding of the textures is left out, so
//! a real engine's frame differs from these by the encoding's rounding only.

use lightvol_sh::eval::eval_into;
use lightvol_sh::index::sh_lm;
use lightvol_sh::irradiance::cosine_lobe_factor;

use crate::error::VolumeError;
use crate::field::VolumeField;
use crate::grid::GridSpec;
use crate::metadata::BakeMetadata;
use crate::volume::IrradianceVolume;

/// An engine's rule for reading a probe grid (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum EngineLookup {
    /// lightvol's own lookup: trilinear over the valid corners that the node reach does not
    /// cut off ([`crate::lookup`], [`crate::reach`]).
    #[default]
    Lightvol,
    /// Plain clamped trilinear interpolation of the SH, nothing left out: Godot's probe
    /// grids and any engine without leak handling.
    Trilinear,
    /// three.js `LightProbeGrid` (r187, `examples/jsm/lighting/LightProbeGridWebGL.js`):
    /// probes at the centres of the grid's cells, hardware trilinear filtering clamped to
    /// the outermost probes, sampled half a cell out along the normal.
    Three,
    /// Bevy's irradiance volume (bevy_pbr 0.19.1, `src/light_probe/irradiance_volume.wgsl` lines 59-91):
    /// an ambient cube per voxel, each face filtered trilinearly, weighted by the squared
    /// normal components.
    Bevy,
    /// Unity 6's Adaptive Probe Volumes (core render pipeline package,
    /// `Runtime/Lighting/ProbeVolume/ProbeVolume.hlsl`): the point pushed along the normal
    /// and towards the viewer (`TryToGetPoolUVWAndSubdiv`: `posWS + normalWS · normalBias +
    /// viewDirWS · viewBias`, [`APV_NORMAL_BIAS`], [`APV_VIEW_BIAS`]), then trilinear over
    /// the valid probes with the weights renormalised (`QualityLeakReduction`, the default
    /// leak-reduction mode, which realises those weights with up to three filtered samples).
    /// APV's per-pixel sampling noise (a jitter meant to hide seams) is left out.
    Apv,
}

/// How far beyond its box, in cells, three.js still lights a fragment from a probe grid
/// (`lightprobes_pars_fragment.glsl.js` line 22: 1% of a cell, for precision).
pub const THREE_BOX_MARGIN: f64 = 0.01;

/// Unity APV's default normal bias, metres: `ProbeVolumesOptions.normalBias` of Unity 6's
/// core render pipeline package (`Runtime/Lighting/ProbeVolume/ProbeVolumesOptions.cs`,
/// `ClampedFloatParameter(0.05f, 0.0f, 2.0f)`; the earlier HDRP-only experimental version
/// defaulted to 0.33 with no view bias).
pub const APV_NORMAL_BIAS: f64 = 0.05;
/// Unity APV's default view bias, metres: `ProbeVolumesOptions.viewBias` of the same file
/// (`ClampedFloatParameter(0.1f, 0.0f, 2.0f)`).
pub const APV_VIEW_BIAS: f64 = 0.1;

impl EngineLookup {
    /// Every lookup, in the order reports list them.
    pub const ALL: [Self; 5] = [Self::Lightvol, Self::Trilinear, Self::Three, Self::Bevy, Self::Apv];

    /// The name `--lookup` takes and sidecars record.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Lightvol => "lightvol",
            Self::Trilinear => "trilinear",
            Self::Three => "three",
            Self::Bevy => "bevy",
            Self::Apv => "apv",
        }
    }

    /// The lookup named `name` ([`Self::name`]).
    #[must_use]
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|l| l.name() == name)
    }

    /// Where the engine implements the rule: file and line in the engine's source.
    #[must_use]
    pub fn source(self) -> &'static str {
        match self {
            Self::Lightvol => "lightvol-volume: lookup.rs, reach.rs, validity.rs",
            Self::Trilinear => {
                "any engine that filters a probe texture trilinearly (Godot's LightmapGI probes)"
            }
            Self::Three => "three.js r187 examples/jsm/lighting/LightProbeGridWebGL.js",
            Self::Bevy => "bevy_pbr 0.19.1 src/light_probe/irradiance_volume.wgsl",
            Self::Apv => {
                "Unity Graphics com.unity.render-pipelines.core Runtime/Lighting/ProbeVolume/ProbeVolume.hlsl"
            }
        }
    }
}

impl std::fmt::Display for EngineLookup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for EngineLookup {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::parse(s).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|l| l.name()).collect();
            format!("unknown lookup {s:?} (expected one of {})", names.join(", "))
        })
    }
}

impl IrradianceVolume {
    /// Irradiance at world point `p` with unit normal `n`, as `lookup`'s engine reads this
    /// volume (module docs); `v` is the unit direction from `p` towards the eye (only
    /// [`EngineLookup::Apv`] reads it).
    #[must_use]
    pub fn engine_irradiance(&self, lookup: EngineLookup, p: [f64; 3], n: [f64; 3], v: [f64; 3]) -> [f64; 3] {
        match lookup {
            EngineLookup::Lightvol => self.irradiance_reference(p, n),
            EngineLookup::Trilinear => self.sh_irradiance_at(p, n, false),
            EngineLookup::Three => {
                let h = self.spec().cell_size();
                let q = std::array::from_fn(|a| p[a] + n[a] * h[a] * 0.5);
                // lightprobes_pars_fragment.glsl.js lines 15-26: a sample point outside the
                // box grown by 1% of a cell leaves the fragment unlit by the grid.
                if self.outside_engine_box(q, THREE_BOX_MARGIN) {
                    return [0.0; 3];
                }
                self.sh_irradiance_at(q, n, false)
            }
            EngineLookup::Bevy => {
                // light_probe.wgsl: a fragment outside the probe's unit cube (half a voxel
                // beyond the outermost voxel centres) finds no irradiance volume.
                if self.outside_engine_box(p, 0.0) {
                    return [0.0; 3];
                }
                self.ambient_cube_at(p, n)
            }
            EngineLookup::Apv => {
                let q = std::array::from_fn(|a| p[a] + n[a] * APV_NORMAL_BIAS + v[a] * APV_VIEW_BIAS);
                self.sh_irradiance_at(q, n, true)
            }
        }
    }

    /// Whether world point `q` lies outside the engines' box of this grid, half a cell
    /// beyond the outermost nodes on every axis (Bevy's cube of the probe texture), grown
    /// by `margin` cells.
    #[must_use]
    pub fn outside_engine_box(&self, q: [f64; 3], margin: f64) -> bool {
        let spec = self.spec();
        let g = spec.to_grid(q);
        let (lo, hi) = spec.bounds();
        let h = spec.cell_size();
        (0..3).any(|a| g[a] < lo[a] - h[a] * (0.5 + margin) || g[a] > hi[a] + h[a] * (0.5 + margin))
    }

    /// SH irradiance at `q` for normal `n` from trilinear weights, renormalised over the
    /// valid corners when `valid` and the volume has a mask.
    fn sh_irradiance_at(&self, q: [f64; 3], n: [f64; 3], valid: bool) -> [f64; 3] {
        let (nodes, mut w) = self.spec().trilinear_world(q);
        if valid && let Some(mask) = self.validity() {
            mask.reweight_f64(|c| nodes[c], &mut w);
        }
        let coeffs = self.coeffs();
        let mut y = vec![0.0; coeffs];
        eval_into(self.bands(), n, &mut y);
        let mut e = [0.0; 3];
        for c in 0..8 {
            if w[c] == 0.0 {
                continue;
            }
            let node = self.node(nodes[c]);
            for j in 0..coeffs {
                let a = cosine_lobe_factor(sh_lm(j).0) * y[j] * w[c];
                for ch in 0..3 {
                    e[ch] += a * f64::from(node[3 * j + ch]);
                }
            }
        }
        e
    }

    /// Bevy's ambient-cube reading at `p`: each face colour interpolated trilinearly over
    /// the cell's corners (each corner's faces the SH irradiance for the axis normals),
    /// then `Σ_a n_a² C(sign n_a, a)`.
    fn ambient_cube_at(&self, p: [f64; 3], n: [f64; 3]) -> [f64; 3] {
        let (nodes, w) = self.spec().trilinear_world(p);
        let coeffs = self.coeffs();
        let mut e = [0.0; 3];
        for a in 0..3 {
            let mut axis = [0.0; 3];
            axis[a] = if n[a] < 0.0 { -1.0 } else { 1.0 };
            let mut face = [0.0; 3];
            for c in 0..8 {
                let node: Vec<f64> = self.node(nodes[c]).iter().map(|&x| f64::from(x)).collect();
                let f = crate::lookup::expand(coeffs, &node, axis, true);
                for ch in 0..3 {
                    face[ch] += w[c] * f[ch];
                }
            }
            for ch in 0..3 {
                e[ch] += n[a] * n[a] * face[ch];
            }
        }
        e
    }
}

/// An engine's lookup at one query as a linear form of the node values: every rule of the
/// module docs interpolates the nodes with per-corner weights (trilinear, renormalised by
/// validity or reach, zero outside the engine's box) and expands each corner's coefficients
/// with one per-coefficient vector (`A_j Y_j(n)` for SH irradiance, Kontkanen & Laine 2006
/// Eq. 3; `Σ_a n_a² A_j Y_j(±e_a)` for Bevy's ambient cube), so
/// `E_ch = Σ_c corner_c Σ_j basis_j · node(nodes_c)[3j + ch]`. A bake that chooses node
/// values for an engine fits through this form; [`IrradianceVolume::engine_irradiance`]
/// is its slow reference (a test keeps them equal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EngineWeights {
    /// The cell's 8 corner nodes (flat indices).
    pub nodes: [usize; 8],
    /// Each corner's weight (all zero where the engine leaves the point unlit).
    pub corner: [f64; 8],
    /// The per-coefficient factors; entries past the volume's coefficient count are zero.
    pub basis: [f64; 16],
}

impl EngineWeights {
    /// The irradiance this form gives over `vol`'s node values.
    #[must_use]
    pub fn apply(&self, vol: &IrradianceVolume) -> [f64; 3] {
        let mut e = [0.0; 3];
        for c in 0..8 {
            if self.corner[c] == 0.0 {
                continue;
            }
            let node = vol.node(self.nodes[c]);
            for j in 0..vol.coeffs() {
                let a = self.corner[c] * self.basis[j];
                for ch in 0..3 {
                    e[ch] += a * f64::from(node[3 * j + ch]);
                }
            }
        }
        e
    }

    /// Whether the engine lights the point at all (some corner has weight).
    #[must_use]
    pub fn lit(&self) -> bool {
        self.corner.iter().any(|&w| w != 0.0)
    }
}

/// `A_j Y_j(n)` for the first `coeffs` coefficients: the SH irradiance expansion (Eq. 3).
fn irradiance_basis(coeffs: usize, n: [f64; 3]) -> [f64; 16] {
    let mut y = [0.0; 16];
    eval_into(coeffs.isqrt(), n, &mut y[..coeffs]);
    std::array::from_fn(|j| if j < coeffs { cosine_lobe_factor(sh_lm(j).0) * y[j] } else { 0.0 })
}

impl IrradianceVolume {
    /// [`Self::engine_irradiance`] as a linear form of the node values ([`EngineWeights`]).
    #[must_use]
    pub fn engine_weights(
        &self,
        lookup: EngineLookup,
        p: [f64; 3],
        n: [f64; 3],
        v: [f64; 3],
    ) -> EngineWeights {
        let coeffs = self.coeffs();
        let unlit = |nodes| EngineWeights { nodes, corner: [0.0; 8], basis: irradiance_basis(coeffs, n) };
        let sh = |(nodes, corner): ([usize; 8], [f64; 8])| EngineWeights {
            nodes,
            corner,
            basis: irradiance_basis(coeffs, n),
        };
        match lookup {
            EngineLookup::Lightvol => sh(self.reference_weights(p, Some(n))),
            EngineLookup::Trilinear => sh(self.spec().trilinear_world(p)),
            EngineLookup::Three => {
                let h = self.spec().cell_size();
                let q = std::array::from_fn(|a| p[a] + n[a] * h[a] * 0.5);
                let tri = self.spec().trilinear_world(q);
                if self.outside_engine_box(q, THREE_BOX_MARGIN) { unlit(tri.0) } else { sh(tri) }
            }
            EngineLookup::Bevy => {
                let (nodes, corner) = self.spec().trilinear_world(p);
                if self.outside_engine_box(p, 0.0) {
                    return unlit(nodes);
                }
                let mut basis = [0.0; 16];
                for a in 0..3 {
                    let mut axis = [0.0; 3];
                    axis[a] = if n[a] < 0.0 { -1.0 } else { 1.0 };
                    let face = irradiance_basis(coeffs, axis);
                    for j in 0..coeffs {
                        basis[j] += n[a] * n[a] * face[j];
                    }
                }
                EngineWeights { nodes, corner, basis }
            }
            EngineLookup::Apv => {
                let q = std::array::from_fn(|a| p[a] + n[a] * APV_NORMAL_BIAS + v[a] * APV_VIEW_BIAS);
                let (nodes, mut w) = self.spec().trilinear_world(q);
                if let Some(mask) = self.validity() {
                    mask.reweight_f64(|c| nodes[c], &mut w);
                }
                sh((nodes, w))
            }
        }
    }
}

/// A uniform volume read through an engine's lookup, as a [`VolumeField`]: irradiance by
/// [`IrradianceVolume::engine_irradiance`] (viewed along the normal when no eye is given,
/// [`VolumeField::irradiance`]; from the eye by [`VolumeField::irradiance_seen`]),
/// coefficients and radiance by plain trilinear interpolation.
#[derive(Clone, Copy, Debug)]
pub struct EngineField<'a> {
    /// The volume.
    pub volume: &'a IrradianceVolume,
    /// The engine's lookup.
    pub lookup: EngineLookup,
}

impl VolumeField for EngineField<'_> {
    fn grid(&self) -> &GridSpec {
        self.volume.spec()
    }
    fn coeffs(&self) -> usize {
        self.volume.coeffs()
    }
    fn metadata(&self) -> &BakeMetadata {
        self.volume.metadata()
    }
    fn coeffs_at(&self, p: [f64; 3]) -> Result<Vec<f64>, VolumeError> {
        if self.lookup == EngineLookup::Lightvol {
            return Ok(self.volume.coeffs_reference(p));
        }
        let (nodes, w) = self.volume.spec().trilinear_world(p);
        let mut out = vec![0.0; 3 * self.volume.coeffs()];
        for c in 0..8 {
            for (o, v) in out.iter_mut().zip(self.volume.node(nodes[c])) {
                *o += w[c] * f64::from(*v);
            }
        }
        Ok(out)
    }
    fn irradiance(&self, p: [f64; 3], n: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        Ok(self.volume.engine_irradiance(self.lookup, p, n, n))
    }
    fn irradiance_seen(&self, p: [f64; 3], n: [f64; 3], to_eye: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        Ok(self.volume.engine_irradiance(self.lookup, p, n, to_eye))
    }
    fn memory_bytes(&self) -> usize {
        self.volume.memory_bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A volume whose nodes hold `L(ω) = a(x) + b·ω` per channel, `a` linear in position.
    fn linear_volume() -> IrradianceVolume {
        let spec = GridSpec::new([0.0, 0.0, 0.0], [4.0, 2.0, 3.0], [5, 3, 4]).unwrap();
        IrradianceVolume::from_fn(spec, 9, |x| {
            let a = 1.0 + 0.25 * x[0] + 0.5 * x[2];
            // Y00 = 0.2820948, Y1(-1) ∝ y, Y10 ∝ z, Y11 ∝ x (lightvol's order).
            let mut c = vec![[0.0; 3]; 9];
            c[0] = [a / 0.282_094_791_773_878_1, 2.0 * a, 0.5 * a];
            c[2] = [0.3, 0.0, 0.1];
            c
        })
        .unwrap()
    }

    /// Names round-trip, and an unknown name lists the known ones.
    #[test]
    fn names_parse_back() {
        for l in EngineLookup::ALL {
            assert_eq!(l.name().parse::<EngineLookup>(), Ok(l));
            assert_eq!(l.to_string(), l.name());
        }
        let e = "unity".parse::<EngineLookup>().unwrap_err();
        assert!(e.contains("lightvol, trilinear, three, bevy, apv"), "{e}");
    }

    /// Without a mask or reach, lightvol's lookup is plain trilinear; three's is trilinear
    /// half a cell along the normal (a field linear in position gives the exact shift);
    /// APV's moves by its biases; for an axis normal Bevy's ambient cube is the SH
    /// irradiance itself.
    #[test]
    fn engine_rules_on_a_linear_field() {
        // The node values are f32 (2^-24 relative) of irradiances up to ~10.
        const TOL: f64 = 1e-6;
        let vol = linear_volume();
        let p = [1.3, 0.7, 1.1];
        let n = [0.0, 0.0, 1.0];
        let v = [1.0, 0.0, 0.0];
        let tri = vol.engine_irradiance(EngineLookup::Trilinear, p, n, v);
        assert_eq!(vol.engine_irradiance(EngineLookup::Lightvol, p, n, v), vol.irradiance_reference(p, n));
        for ch in 0..3 {
            assert!((tri[ch] - vol.irradiance_reference(p, n)[ch]).abs() < 1e-12);
        }
        // E = π · Y00 · c0 + (2π/3) · Y10 · c2 with c0 = a / Y00 (red): d E / d z = π · 0.5.
        let three = vol.engine_irradiance(EngineLookup::Three, p, n, v);
        let h = vol.spec().cell_size()[2];
        assert!((three[0] - tri[0] - std::f64::consts::PI * 0.5 * h / 2.0).abs() < TOL, "{three:?} {tri:?}");
        let apv = vol.engine_irradiance(EngineLookup::Apv, p, n, v);
        let want = std::f64::consts::PI * (0.25 * APV_VIEW_BIAS + 0.5 * APV_NORMAL_BIAS);
        assert!((apv[0] - tri[0] - want).abs() < TOL, "{apv:?} {tri:?}");
        let bevy = vol.engine_irradiance(EngineLookup::Bevy, p, n, v);
        for ch in 0..3 {
            assert!((bevy[ch] - tri[ch]).abs() < TOL, "{bevy:?} {tri:?}");
        }
    }

    /// Every lookup's linear form gives its reference irradiance, with a validity mask
    /// and a node reach on the volume (which lightvol's and APV's rules read), inside and
    /// outside the engines' boxes.
    #[test]
    fn engine_weights_equal_the_reference_lookups() {
        // Both sum the same f64 products in a different order: 1e-12 of values up to ~10.
        const TOL: f64 = 1e-11;
        let mut vol = linear_volume();
        let nodes = vol.spec().node_count();
        vol.set_validity(Some(crate::validity::ValidityMask::new((0..nodes).map(|i| i % 7 != 3).collect())))
            .unwrap();
        let reach: Vec<[f32; 6]> =
            (0..nodes).map(|i| if i % 5 == 1 { [0.3, 1.0, 1.0, 0.6, 1.0, 1.0] } else { [1.0; 6] }).collect();
        vol.set_reach(Some(crate::reach::NodeReach::new(reach).unwrap())).unwrap();
        let mut checked = 0;
        for i in 0..200 {
            let f = |k: u32| f64::from((i * 37 + k * 11) % 101) / 100.0;
            let p = [-0.6 + 5.2 * f(1), -0.6 + 3.2 * f(2), -0.6 + 4.2 * f(3)];
            let n = {
                let d = [f(4) - 0.5, f(5) - 0.5, f(6) - 0.45];
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                d.map(|x| x / l)
            };
            let v = [n[1], -n[0], n[2]];
            for l in EngineLookup::ALL {
                let want = vol.engine_irradiance(l, p, n, v);
                let got = vol.engine_weights(l, p, n, v).apply(&vol);
                for ch in 0..3 {
                    assert!((want[ch] - got[ch]).abs() < TOL, "{l} at {p:?}: {got:?} against {want:?}");
                }
                checked += usize::from(want[0] != 0.0);
            }
        }
        assert!(checked > 800, "only {checked} lit queries");
    }

    /// three.js lights a fragment only while its sample point (half a cell along the normal)
    /// stays within the box grown by 1% of a cell; Bevy only inside the probe's cube. The
    /// box is half a cell beyond the outermost nodes.
    #[test]
    fn engines_light_only_inside_their_box() {
        let vol = linear_volume();
        let up = [0.0, 0.0, 1.0];
        let down = [0.0, 0.0, -1.0];
        let v = [1.0, 0.0, 0.0];
        // Top nodes at z = 3, cell 1: three's box ends at 3.5, its margin at 3.51.
        let lit = |p: [f64; 3], n| vol.engine_irradiance(EngineLookup::Three, p, n, v)[0] > 0.0;
        assert!(lit([1.0, 1.0, 2.9], up), "sample at 3.4: inside");
        assert!(lit([1.0, 1.0, 3.005], up), "sample at 3.505: inside the margin");
        assert!(!lit([1.0, 1.0, 3.02], up), "sample at 3.52: outside");
        assert!(lit([1.0, 1.0, 3.9], down), "sample at 3.4 from above: inside");
        let bevy = |p: [f64; 3]| vol.engine_irradiance(EngineLookup::Bevy, p, up, v)[0] > 0.0;
        assert!(bevy([1.0, 1.0, 3.49]) && !bevy([1.0, 1.0, 3.51]));
        assert!(bevy([-0.49, 1.0, 1.0]) && !bevy([-0.51, 1.0, 1.0]));
    }
}
