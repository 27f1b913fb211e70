//! What a compared entry baked, kept with its run so that it can be read anywhere, not only
//! on the plate: at the surfaces of a view ([`crate::views`]). Each kind is read the
//! way its run reads the plate, so a view and the plate see the same volume through the
//! same lookup.

use std::fmt;
use std::sync::Arc;

use lightvol_volume::engine_lookup::EngineField;
use lightvol_volume::gradient::{
    GradientLookup, coeffs_at as gradient_coeffs_at, irradiance as gradient_irradiance,
};
use lightvol_volume::{
    AdaptiveVolume, BakeMetadata, EngineLookup, GridSpec, IrradianceVolume, VolumeError, VolumeField,
    VolumeGradients, bricks::BrickVolume,
};

use lightvol_sampler::gradient_estimator::GradientEstimator;
use lightvol_sampler::stats::BakeStats;

/// A bake with gradients, shared by every lookup on the same base method.
pub struct GradientVolume {
    /// The Eq. 6 volume.
    pub volume: IrradianceVolume,
    /// Its gradients.
    pub gradients: VolumeGradients,
    /// The bake's statistics.
    pub stats: BakeStats,
    /// Estimator used.
    pub estimator: GradientEstimator,
    /// Singular nodes (basis estimator).
    pub singular_nodes: usize,
    /// Directions traced beyond the bake (central estimator).
    pub extra_directions: u64,
    /// Seconds beyond the bake.
    pub gradient_seconds: f64,
}

/// A run's baked volume and its lookup (shared, cheap to clone).
#[derive(Clone)]
pub enum RunVolume {
    /// A uniform grid read by its trilinear f32 lookup (\[KL06\] Eq. 2-3): the plain and
    /// fitted bakes and the engine baselines without validity-weighted lookups.
    Uniform(Arc<IrradianceVolume>),
    /// A uniform grid with gradients read by one of \[Oat05\]'s lookups.
    Gradient {
        /// The bake (shared by every lookup on the same base method).
        bake: Arc<GradientVolume>,
        /// The lookup.
        lookup: GradientLookup,
    },
    /// \[Oat05\]'s octree, read by its f32 lookup.
    Adaptive(Arc<AdaptiveVolume>),
    /// The octree's brick export, read by its f32 lookup.
    Bricks(Arc<BrickVolume>),
    /// A uniform grid read by its f64 reference lookup
    /// ([`IrradianceVolume::irradiance_reference`], validity-weighted through the volume's
    /// mask): Unity APV, as its run reads the plate.
    Reference(Arc<IrradianceVolume>),
    /// A uniform grid read as an engine reads it
    /// ([`IrradianceVolume::engine_irradiance`]): `compare --lookup`.
    Engine(Arc<IrradianceVolume>, EngineLookup),
}

impl RunVolume {
    /// The uniform grid of a uniform-grid run (`None` for gradient and octree runs).
    #[must_use]
    pub fn uniform(&self) -> Option<&Arc<IrradianceVolume>> {
        match self {
            Self::Uniform(v) | Self::Reference(v) | Self::Engine(v, _) => Some(v),
            Self::Gradient { .. } | Self::Adaptive(_) | Self::Bricks(_) => None,
        }
    }
}

/// Each kind read as its run reads the plate (the enum's docs).
impl VolumeField for RunVolume {
    fn grid(&self) -> &GridSpec {
        match self {
            Self::Uniform(v) | Self::Reference(v) | Self::Engine(v, _) => v.spec(),
            Self::Gradient { bake, .. } => bake.volume.spec(),
            Self::Adaptive(v) => v.base().spec(),
            Self::Bricks(v) => v.spec(),
        }
    }
    fn coeffs(&self) -> usize {
        match self {
            Self::Uniform(v) | Self::Reference(v) | Self::Engine(v, _) => v.coeffs(),
            Self::Gradient { bake, .. } => bake.volume.coeffs(),
            Self::Adaptive(v) => v.coeffs(),
            Self::Bricks(v) => v.coeffs(),
        }
    }
    fn metadata(&self) -> &BakeMetadata {
        match self {
            Self::Uniform(v) | Self::Reference(v) | Self::Engine(v, _) => v.metadata(),
            Self::Gradient { bake, .. } => bake.volume.metadata(),
            Self::Adaptive(v) => v.metadata(),
            Self::Bricks(v) => v.metadata(),
        }
    }
    fn coeffs_at(&self, p: [f64; 3]) -> Result<Vec<f64>, VolumeError> {
        match self {
            Self::Uniform(v) => VolumeField::coeffs_at(&**v, p),
            Self::Gradient { bake, lookup } => gradient_coeffs_at(&bake.volume, &bake.gradients, *lookup, p),
            Self::Adaptive(v) => VolumeField::coeffs_at(&**v, p),
            Self::Bricks(v) => VolumeField::coeffs_at(&**v, p),
            Self::Reference(v) => Ok(v.coeffs_reference(p)),
            Self::Engine(v, lookup) => EngineField { volume: v, lookup: *lookup }.coeffs_at(p),
        }
    }
    fn irradiance(&self, p: [f64; 3], n: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        match self {
            Self::Uniform(v) => VolumeField::irradiance(&**v, p, n),
            Self::Gradient { bake, lookup } => {
                gradient_irradiance(&bake.volume, &bake.gradients, *lookup, p, n)
            }
            Self::Adaptive(v) => VolumeField::irradiance(&**v, p, n),
            Self::Bricks(v) => VolumeField::irradiance(&**v, p, n),
            Self::Reference(v) => Ok(v.irradiance_reference(p, n)),
            Self::Engine(v, lookup) => Ok(v.engine_irradiance(*lookup, p, n, n)),
        }
    }
    fn irradiance_seen(&self, p: [f64; 3], n: [f64; 3], to_eye: [f64; 3]) -> Result<[f64; 3], VolumeError> {
        match self {
            Self::Engine(v, lookup) => Ok(v.engine_irradiance(*lookup, p, n, to_eye)),
            _ => self.irradiance(p, n),
        }
    }
    fn memory_bytes(&self) -> usize {
        match self {
            Self::Uniform(v) | Self::Reference(v) | Self::Engine(v, _) => v.memory_bytes(),
            Self::Gradient { bake, .. } => bake.volume.memory_bytes() + bake.gradients.memory_bytes(),
            Self::Adaptive(v) => v.memory_bytes(),
            Self::Bricks(v) => VolumeField::memory_bytes(&**v),
        }
    }
}

impl fmt::Debug for RunVolume {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Uniform(v) => f.debug_tuple("Uniform").field(&v.spec().res()).finish(),
            Self::Gradient { bake, lookup } => f
                .debug_struct("Gradient")
                .field("res", &bake.volume.spec().res())
                .field("lookup", lookup)
                .finish(),
            Self::Adaptive(v) => f.debug_tuple("Adaptive").field(&v.stored_nodes()).finish(),
            Self::Bricks(v) => f.debug_tuple("Bricks").field(&v.bricks().len()).finish(),
            Self::Reference(v) => f.debug_tuple("Reference").field(&v.spec().res()).finish(),
            Self::Engine(v, lookup) => f.debug_tuple("Engine").field(&v.spec().res()).field(lookup).finish(),
        }
    }
}
