#![doc = include_str!("../README.md")]

pub mod coeffs;
pub mod convention;
pub mod eval;
pub mod gaunt;
#[rustfmt::skip]
mod generated;
pub mod index;
pub mod irradiance;
pub mod linalg;
pub mod lowdisc;
pub mod project;
pub mod quadrature;
pub mod real;
pub mod recurrence;
pub mod reference;
pub mod rotate;
pub mod sampling;
pub mod shexp;
pub mod window;
pub mod zonal;

pub use coeffs::{
    Sh, Sh1, Sh4, Sh9, Sh16, Sh25, Sh36, Sh49, Sh64, ShDyn, ShRgb, ShRgb4, ShRgb9, ShRgb16, ShRgb25, ShRgb36,
    eval_sh,
};
pub use eval::{eval_basis, eval_into};
pub use real::Real;

/// The most used items, for `use lightvol_sh::prelude::*`.
pub mod prelude {
    pub use crate::coeffs::{Sh, Sh4, Sh9, Sh16, Sh25, Sh36, ShDyn, ShRgb, ShRgb4, ShRgb9, ShRgb16, eval_sh};
    pub use crate::eval::{eval_basis, eval_into};
    pub use crate::irradiance::{irradiance, irradiance_rgb, radiance_to_irradiance};
    pub use crate::project::{ProjectionAccumulator, project_fn};
    pub use crate::quadrature::SphereQuadrature;
    pub use crate::real::Real;
    pub use crate::rotate::ShRotation;
    pub use crate::zonal::Zh;
}
