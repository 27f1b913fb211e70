//! One interface for every kind of volume: [`VolumeField`], implemented by the uniform grid
//! ([`IrradianceVolume`]), the adaptive octree ([`AdaptiveVolume`]) and a uniform grid read
//! through one of Oat 2005's gradient lookups ([`GradientField`]); [`open`] reads whichever
//! kind a native file holds ([`AnyVolume`]).
//!
//! Every method evaluates Kontkanen & Laine 2006 (\[KL06\]) Eq. 2 (the interpolated
//! coefficients `L_j(x)`) and Eq. 3 (irradiance `E(x, n) = Σ_j A_j L_j(x) Y_j(n)`) by the
//! kind's own lookup: the uniform grid's and the octree's f32 fast paths, the gradient
//! lookups' f64 evaluation (`crate::gradient`).

use std::path::Path;

use crate::adaptive::AdaptiveVolume;
use crate::bricks::BrickVolume;
use crate::error::VolumeError;
use crate::gradient::{GradientLookup, VolumeGradients};
use crate::grid::GridSpec;
use crate::metadata::BakeMetadata;
use crate::volume::IrradianceVolume;

pub use crate::lookup::expand;

/// A baked volume that can be read anywhere in its grid (module docs).
pub trait VolumeField: Sync {
    /// The grid (for the octree, its base level).
    fn grid(&self) -> &GridSpec;

    /// SH coefficients per colour channel (4, 9 or 16).
    fn coeffs(&self) -> usize;

    /// The bake's metadata.
    fn metadata(&self) -> &BakeMetadata;

    /// The interpolated coefficients `L_j(p)` (\[KL06\] Eq. 2) at world point `p`, as
    /// `[coeff][rgb]`.
    ///
    /// # Errors
    /// A lookup the volume refuses (a gradient lookup outside its grid).
    fn coeffs_at(&self, p: [f64; 3]) -> Result<Vec<f64>, VolumeError>;

    /// Irradiance `E(p, n)` (\[KL06\] Eq. 3) for the world-space unit normal `n`.
    ///
    /// # Errors
    /// As [`Self::coeffs_at`].
    fn irradiance(&self, p: [f64; 3], n: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        let c = self.coeffs_at(p)?;
        Ok(expand(self.coeffs(), &c, n, true))
    }

    /// Irradiance `E(p, n)` as a renderer looking at `p` from the unit direction `to_eye`
    /// (from `p` towards the eye) reads it: the same as [`Self::irradiance`] except for
    /// lookups that move the sample towards the viewer (Unity APV's view bias,
    /// [`crate::engine_lookup::EngineField`]).
    ///
    /// # Errors
    /// As [`Self::coeffs_at`].
    fn irradiance_seen(&self, p: [f64; 3], n: [f64; 3], to_eye: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        let _ = to_eye;
        self.irradiance(p, n)
    }

    /// Radiance `L(p, ω) = Σ_j L_j(p) Y_j(ω)` arriving at `p` from the unit direction `dir`.
    ///
    /// # Errors
    /// As [`Self::coeffs_at`].
    fn radiance(&self, p: [f64; 3], dir: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        let c = self.coeffs_at(p)?;
        Ok(expand(self.coeffs(), &c, dir, false))
    }

    /// Run-time bytes of what a renderer keeps (each kind's own accounting; the uniform
    /// count is `crate::volume::sample_bytes`).
    fn memory_bytes(&self) -> usize;
}

fn f32x3(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

impl VolumeField for IrradianceVolume {
    fn grid(&self) -> &GridSpec {
        self.spec()
    }
    fn coeffs(&self) -> usize {
        IrradianceVolume::coeffs(self)
    }
    fn metadata(&self) -> &BakeMetadata {
        IrradianceVolume::metadata(self)
    }
    /// The f32 trilinear lookup ([`IrradianceVolume::coeffs_at`]).
    fn coeffs_at(&self, p: [f64; 3]) -> Result<Vec<f64>, VolumeError> {
        let mut out = vec![0.0f32; self.coeffs() * 3];
        IrradianceVolume::coeffs_at(self, f32x3(p), &mut out);
        Ok(out.into_iter().map(f64::from).collect())
    }
    /// The f32 trilinear lookup ([`IrradianceVolume::irradiance`]).
    fn irradiance(&self, p: [f64; 3], n: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        Ok(IrradianceVolume::irradiance(self, f32x3(p), f32x3(n)).map(f64::from))
    }
    /// The f32 trilinear lookup ([`IrradianceVolume::radiance`]).
    fn radiance(&self, p: [f64; 3], dir: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        Ok(IrradianceVolume::radiance(self, f32x3(p), f32x3(dir)).map(f64::from))
    }
    fn memory_bytes(&self) -> usize {
        IrradianceVolume::memory_bytes(self)
    }
}

impl VolumeField for AdaptiveVolume {
    fn grid(&self) -> &GridSpec {
        self.base().spec()
    }
    fn coeffs(&self) -> usize {
        AdaptiveVolume::coeffs(self)
    }
    fn metadata(&self) -> &BakeMetadata {
        AdaptiveVolume::metadata(self)
    }
    /// The octree's f32 lookup ([`AdaptiveVolume::coeffs_at`]).
    fn coeffs_at(&self, p: [f64; 3]) -> Result<Vec<f64>, VolumeError> {
        let mut out = vec![0.0f32; self.coeffs() * 3];
        AdaptiveVolume::coeffs_at(self, f32x3(p), &mut out);
        Ok(out.into_iter().map(f64::from).collect())
    }
    /// The octree's f32 lookup ([`AdaptiveVolume::irradiance`]).
    fn irradiance(&self, p: [f64; 3], n: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        Ok(AdaptiveVolume::irradiance(self, f32x3(p), f32x3(n)).map(f64::from))
    }
    /// The octree's f32 lookup ([`AdaptiveVolume::radiance`]).
    fn radiance(&self, p: [f64; 3], dir: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        Ok(AdaptiveVolume::radiance(self, f32x3(p), f32x3(dir)).map(f64::from))
    }
    fn memory_bytes(&self) -> usize {
        AdaptiveVolume::memory_bytes(self)
    }
}

impl VolumeField for BrickVolume {
    fn grid(&self) -> &GridSpec {
        self.spec()
    }
    fn coeffs(&self) -> usize {
        BrickVolume::coeffs(self)
    }
    fn metadata(&self) -> &BakeMetadata {
        BrickVolume::metadata(self)
    }
    /// The brick lookup's f32 fast path ([`BrickVolume::coeffs_at`]).
    fn coeffs_at(&self, p: [f64; 3]) -> Result<Vec<f64>, VolumeError> {
        let mut out = vec![0.0f32; self.coeffs() * 3];
        BrickVolume::coeffs_at(self, f32x3(p), &mut out);
        Ok(out.into_iter().map(f64::from).collect())
    }
    /// The brick lookup's f32 fast path ([`BrickVolume::irradiance`]).
    fn irradiance(&self, p: [f64; 3], n: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        Ok(BrickVolume::irradiance(self, f32x3(p), f32x3(n)).map(f64::from))
    }
    /// The brick lookup's f32 fast path ([`BrickVolume::radiance`]).
    fn radiance(&self, p: [f64; 3], dir: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        Ok(BrickVolume::radiance(self, f32x3(p), f32x3(dir)).map(f64::from))
    }
    /// The probes in the atlas plus the indirection texture.
    fn memory_bytes(&self) -> usize {
        self.probe_bytes() + self.indirection_bytes()
    }
}

/// A uniform grid with per-node gradients, read through one of \[Oat05\]'s lookups.
#[derive(Clone, Debug)]
pub struct GradientField {
    /// The grid's coefficients.
    pub volume: IrradianceVolume,
    /// Their gradients.
    pub gradients: VolumeGradients,
    /// How they are read.
    pub lookup: GradientLookup,
}

impl VolumeField for GradientField {
    fn grid(&self) -> &GridSpec {
        self.volume.spec()
    }
    fn coeffs(&self) -> usize {
        self.volume.coeffs()
    }
    fn metadata(&self) -> &BakeMetadata {
        self.volume.metadata()
    }
    /// The gradient lookup (`crate::gradient::coeffs_at`).
    fn coeffs_at(&self, p: [f64; 3]) -> Result<Vec<f64>, VolumeError> {
        crate::gradient::coeffs_at(&self.volume, &self.gradients, self.lookup, p)
    }
    /// The gradient lookup (`crate::gradient::irradiance`).
    fn irradiance(&self, p: [f64; 3], n: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        crate::gradient::irradiance(&self.volume, &self.gradients, self.lookup, p, n)
    }
    /// The coefficients and their gradients, f32, as \[Oat05\] counts them.
    fn memory_bytes(&self) -> usize {
        self.volume.memory_bytes() + self.gradients.memory_bytes()
    }
}

/// Whichever kind of volume a native file holds ([`open`]).
#[derive(Clone, Debug)]
pub enum AnyVolume {
    /// A uniform grid.
    Uniform(IrradianceVolume),
    /// A uniform grid with gradients (read by [`GRADIENT_FILE_LOOKUP`] unless changed).
    Gradient(GradientField),
    /// An adaptive octree.
    Adaptive(AdaptiveVolume),
    /// An octree resampled into bricks (the brick export, [`crate::io::bricks`]).
    Bricks(BrickVolume),
}

/// The lookup [`open`] gives a file with gradients: tricubic Hermite, the smoothest of
/// \[Oat05\]'s.
pub const GRADIENT_FILE_LOOKUP: GradientLookup = GradientLookup::Hermite;

impl AnyVolume {
    /// The kind as a word: `uniform`, `gradient`, `adaptive`, `bricks`.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Uniform(_) => "uniform",
            Self::Gradient(_) => "gradient",
            Self::Adaptive(_) => "adaptive",
            Self::Bricks(_) => "bricks",
        }
    }

    /// The volume as a [`VolumeField`].
    #[must_use]
    pub fn field(&self) -> &dyn VolumeField {
        match self {
            Self::Uniform(v) => v,
            Self::Gradient(v) => v,
            Self::Adaptive(v) => v,
            Self::Bricks(v) => v,
        }
    }

    /// The volume read without gradients: a gradient file's grid by trilinear interpolation
    /// (defined everywhere, where the gradient lookups refuse points outside the grid).
    #[must_use]
    pub fn trilinear_field(&self) -> &dyn VolumeField {
        match self {
            Self::Uniform(v) => v,
            Self::Gradient(g) => &g.volume,
            Self::Adaptive(v) => v,
            Self::Bricks(v) => v,
        }
    }

    /// The uniform grid of a uniform or gradient file (`None` for an octree or bricks).
    #[must_use]
    pub fn uniform(&self) -> Option<&IrradianceVolume> {
        match self {
            Self::Uniform(v) => Some(v),
            Self::Gradient(g) => Some(&g.volume),
            Self::Adaptive(_) | Self::Bricks(_) => None,
        }
    }
}

/// Reads a volume file of any kind. `.ktx2` and `.dds` files (lightvol's engine exports,
/// `crate::io::ktx2`, `crate::io::three`, `crate::io::dds`) are uniform grids, returned in
/// the internal frame like the native file, or a brick atlas (`crate::io::bricks`); anything else is read as a native
/// EXR file: an adaptive octree (`crate::io::adaptive::is_adaptive_exr`), a uniform grid with
/// gradients, or a plain uniform grid. A file whose header cannot be read as an octree's is
/// read as a uniform grid, so that the uniform reader names the problem.
///
/// # Errors
/// The file cannot be read or is not a lightvol volume ([`VolumeError`], naming the problem).
pub fn open(path: &Path) -> Result<AnyVolume, VolumeError> {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("ktx2") => {
            let bytes = crate::io::util::read_bounded(path)?;
            return if crate::io::bricks::is_bricks(&bytes) {
                crate::io::bricks::read_bricks(path).map(AnyVolume::Bricks)
            } else if crate::io::three::is_three(&bytes) {
                crate::io::three::three_from_bytes(&bytes).map(|(_, v)| AnyVolume::Uniform(v))
            } else {
                crate::io::ktx2::ktx2_from_bytes(&bytes).map(AnyVolume::Uniform)
            };
        }
        Some("dds") => return crate::io::dds::read_dds(path).map(AnyVolume::Uniform),
        _ => {}
    }
    if crate::io::adaptive::is_adaptive_exr(path).unwrap_or(false) {
        return crate::io::adaptive::read_adaptive_exr(path).map(AnyVolume::Adaptive);
    }
    Ok(match crate::io::exr::read_exr_with_gradients(path)? {
        (volume, Some(gradients)) => {
            AnyVolume::Gradient(GradientField { volume, gradients, lookup: GRADIENT_FILE_LOOKUP })
        }
        (volume, None) => AnyVolume::Uniform(volume),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rounding of f32 lookups of O(1) values.
    const F32_TOL: f64 = 1e-5;

    fn volume() -> IrradianceVolume {
        let spec = GridSpec::new([0.0; 3], [2.0, 1.0, 1.0], [3, 2, 2]).unwrap();
        IrradianceVolume::from_fn(spec, 9, |x| {
            (0..9)
                .map(|c| {
                    [
                        0.5 + 0.3 * x[0] + 0.01 * c as f64,
                        0.4 + 0.1 * x[1],
                        0.3 + 0.05 * x[2] - 0.02 * c as f64,
                    ]
                })
                .collect()
        })
        .unwrap()
    }

    /// The trait's default irradiance and radiance (from `coeffs_at`, f64) equal the uniform
    /// grid's own f32 paths, and every kind reads back through `open`.
    #[test]
    fn every_kind_agrees_with_its_own_lookup() {
        let v = volume();
        let p = [0.7, 0.4, 0.3];
        let n = [0.0, 0.6, 0.8];
        let field: &dyn VolumeField = &v;
        let c = field.coeffs_at(p).unwrap();
        let by_default = expand(9, &c, n, true);
        let fast = field.irradiance(p, n).unwrap();
        for ch in 0..3 {
            assert!(
                (by_default[ch] - fast[ch]).abs() < F32_TOL * fast[ch].abs().max(1.0),
                "{by_default:?} {fast:?}"
            );
        }
        let rad = expand(9, &c, n, false);
        let fast = field.radiance(p, n).unwrap();
        for ch in 0..3 {
            assert!((rad[ch] - fast[ch]).abs() < F32_TOL * fast[ch].abs().max(1.0));
        }
        assert_eq!(field.memory_bytes(), 12 * (27 + 1) * 4);

        // Zero gradients: every gradient lookup reduces to trilinear interpolation.
        let g = GradientField {
            gradients: VolumeGradients::zeros(&v),
            volume: v.clone(),
            lookup: GradientLookup::GradientTrilinear,
        };
        let e = g.irradiance(p, n).unwrap();
        let t = v.irradiance_reference(p, n);
        for ch in 0..3 {
            assert!((e[ch] - t[ch]).abs() < 1e-12, "{e:?} {t:?}");
        }
        assert_eq!(g.memory_bytes(), v.memory_bytes() + 12 * 27 * 3 * 4);

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("v.exr");
        crate::io::exr::write_exr(&path, &v, &crate::io::exr::ExrOptions::default()).unwrap();
        let opened = open(&path).unwrap();
        assert_eq!(opened.kind(), "uniform");
        assert_eq!(opened.uniform().unwrap().data(), v.data());
        crate::io::exr::write_exr_with_gradients(
            &path,
            &v,
            &g.gradients,
            &crate::io::exr::ExrOptions::default(),
        )
        .unwrap();
        assert_eq!(open(&path).unwrap().kind(), "gradient");
        assert!(open(&dir.path().join("missing.exr")).is_err());
    }
}
