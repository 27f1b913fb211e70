//! What a compared entry baked, kept with its run so that it can be read anywhere, not only
//! on the plate: at the surfaces of a view ([`crate::eval::views`]). Each kind is read the
//! way its run reads the plate, so a view and the plate see the same volume through the
//! same lookup.

use std::fmt;
use std::sync::Arc;

use glam::DVec3;
use lightvol_volume::gradient::{GradientLookup, irradiance as gradient_irradiance};
use lightvol_volume::{AdaptiveVolume, IrradianceVolume, VolumeError};

use crate::eval::runs::GradientVolume;
use crate::view::IrradianceField;

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
    /// A uniform grid read by its f64 reference lookup
    /// ([`IrradianceVolume::irradiance_reference`], validity-weighted through the volume's
    /// mask): Unity APV, as its run reads the plate.
    Reference(Arc<IrradianceVolume>),
}

impl IrradianceField for RunVolume {
    fn irradiance(&self, p: DVec3, n: DVec3) -> Result<[f64; 3], VolumeError> {
        match self {
            Self::Uniform(v) => IrradianceField::irradiance(&**v, p, n),
            Self::Gradient { bake, lookup } => {
                gradient_irradiance(&bake.volume, &bake.gradients, *lookup, p.to_array(), n.to_array())
            }
            Self::Adaptive(v) => IrradianceField::irradiance(&**v, p, n),
            Self::Reference(v) => Ok(v.irradiance_reference(p.to_array(), n.to_array())),
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
            Self::Reference(v) => f.debug_tuple("Reference").field(&v.spec().res()).finish(),
        }
    }
}
