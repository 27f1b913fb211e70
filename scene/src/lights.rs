//! Light sources: the environment (uniform sky or lat-long map), the sun, and punctual lights.
//! Emissive triangles are materials ([`Material::emission`](crate::Material)).
//!
//! Units are radiometric and follow the scene: radiance L, irradiance E = ∫ L cos θ dω.
//! glTF photometric intensities (candela, lux) are taken as radiometric values one to one.

use glam::DVec3;

use crate::envmap::EnvMap;

/// What a ray that leaves the scene sees.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Environment {
    /// Nothing: black.
    #[default]
    Black,
    /// Constant radiance `sky` over the upper hemisphere (z > 0) and `ground` below
    /// (black when `None`).
    UniformSky {
        /// Radiance of the sky, linear RGB.
        sky: [f64; 3],
        /// Radiance below the horizon.
        ground: Option<[f64; 3]>,
    },
    /// A latitude-longitude radiance map (see [`EnvMap`]).
    Map(EnvMap),
}

impl Environment {
    /// Radiance arriving from direction `dir` (unit, pointing away from the receiver).
    #[must_use]
    pub fn radiance(&self, dir: DVec3) -> [f64; 3] {
        match self {
            Self::Black => [0.0; 3],
            Self::UniformSky { sky, ground } => {
                if dir.z > 0.0 {
                    *sky
                } else {
                    ground.unwrap_or([0.0; 3])
                }
            }
            Self::Map(m) => m.radiance(dir),
        }
    }
}

/// A sun: a uniform disk of angular radius `angular_radius` around `direction`.
///
/// The radiance inside the cone is `irradiance / (π sin² r)`, so that a surface facing the
/// sun receives exactly `irradiance` (∫_cone cos θ dω = π sin² r). With `angular_radius = 0`
/// the sun is a directional (delta) light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// Unit vector towards the sun.
    pub direction: DVec3,
    /// Irradiance on a surface facing the sun, linear RGB.
    pub irradiance: [f64; 3],
    /// Angular radius in radians (the real sun: 0.00465).
    pub angular_radius: f64,
}

impl Sun {
    /// A sun from elevation and azimuth in degrees (azimuth from +X towards +Y).
    #[must_use]
    pub fn from_angles(
        elevation_deg: f64,
        azimuth_deg: f64,
        irradiance: [f64; 3],
        angular_radius: f64,
    ) -> Self {
        let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
        Self {
            direction: DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin()),
            irradiance,
            angular_radius,
        }
    }

    /// True for a zero angular radius (sampled only by next-event estimation).
    #[must_use]
    pub fn is_delta(&self) -> bool {
        !(self.angular_radius > 0.0)
    }

    /// Cosine of the angular radius.
    #[must_use]
    pub fn cos_max(&self) -> f64 {
        self.angular_radius.cos()
    }

    /// Solid angle of the disk, 2π(1 − cos r).
    #[must_use]
    pub fn solid_angle(&self) -> f64 {
        // 2π(1 - cos r) = 4π sin²(r/2), the second form keeps precision for tiny r.
        4.0 * std::f64::consts::PI * (0.5 * self.angular_radius).sin().powi(2)
    }

    /// Radiance inside the disk: `irradiance / (π sin² r)`.
    #[must_use]
    pub fn radiance(&self) -> [f64; 3] {
        let s = std::f64::consts::PI * self.angular_radius.sin().powi(2);
        self.irradiance.map(|e| e / s)
    }

    /// Radiance seen along `dir` (zero outside the disk, zero for a delta sun).
    #[must_use]
    pub fn radiance_along(&self, dir: DVec3) -> [f64; 3] {
        if !self.is_delta() && dir.dot(self.direction) >= self.cos_max() { self.radiance() } else { [0.0; 3] }
    }
}

/// glTF KHR_lights_punctual lights (delta lights, reached only by next-event estimation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PunctualLight {
    /// Isotropic point light: radiant intensity `intensity` (W/sr, candela in glTF).
    Point {
        /// World position.
        position: DVec3,
        /// Intensity per channel.
        intensity: [f64; 3],
    },
    /// Spot light; glTF's smooth falloff between the inner and outer cone.
    Spot {
        /// World position.
        position: DVec3,
        /// Unit axis the light shines along.
        axis: DVec3,
        /// Intensity inside the inner cone.
        intensity: [f64; 3],
        /// Inner cone half-angle (radians).
        inner: f64,
        /// Outer cone half-angle (radians).
        outer: f64,
    },
    /// Directional light: irradiance on a surface facing it.
    Directional {
        /// Unit vector towards the light (opposite to the direction light travels).
        to_light: DVec3,
        /// Irradiance per channel (lux in glTF).
        irradiance: [f64; 3],
    },
}

impl PunctualLight {
    /// The direction from `x` to the light, the distance (infinite for directional lights),
    /// and the irradiance at `x` on a surface facing the light (before visibility and cosine).
    #[must_use]
    pub fn incident(&self, x: DVec3) -> Option<(DVec3, f64, [f64; 3])> {
        match *self {
            Self::Point { position, intensity } => {
                let d = position - x;
                let r2 = d.length_squared();
                (r2 > 0.0).then(|| (d / r2.sqrt(), r2.sqrt(), intensity.map(|i| i / r2)))
            }
            Self::Spot { position, axis, intensity, inner, outer } => {
                let d = position - x;
                let r2 = d.length_squared();
                if !(r2 > 0.0) {
                    return None;
                }
                let dir = d / r2.sqrt();
                let cos = (-dir).dot(axis);
                let (ci, co) = (inner.cos(), outer.cos());
                // KHR_lights_punctual reference falloff: smooth step of the cosine, squared.
                let t = if ci > co {
                    ((cos - co) / (ci - co)).clamp(0.0, 1.0)
                } else {
                    f64::from(u8::from(cos >= co))
                };
                let att = t * t;
                (att > 0.0).then(|| (dir, r2.sqrt(), intensity.map(|i| i * att / r2)))
            }
            Self::Directional { to_light, irradiance } => Some((to_light, f64::INFINITY, irradiance)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_sh::quadrature::SphereQuadrature;

    /// ∫_cone L cos θ dω over the sun disk equals the stated irradiance: checked by
    /// Gauss-Legendre quadrature over the cap (θ in [0, r]), independent of the closed form.
    #[test]
    fn sun_radiance_integrates_to_irradiance() {
        let sun = Sun { direction: DVec3::Z, irradiance: [3.0, 2.0, 1.0], angular_radius: 0.2 };
        let (nodes, weights) = lightvol_sh::quadrature::gauss_legendre(16);
        // θ = r (x + 1) / 2; dω = 2π sin θ dθ (azimuthally symmetric).
        let r = sun.angular_radius;
        let integral: f64 = nodes
            .iter()
            .zip(&weights)
            .map(|(&x, &w)| {
                let th = r * (x + 1.0) / 2.0;
                w * r / 2.0 * 2.0 * std::f64::consts::PI * th.sin() * th.cos()
            })
            .sum();
        let l = sun.radiance();
        // GL with 16 nodes on a smooth integrand: exact to rounding.
        assert!((l[0] * integral - 3.0).abs() < 1e-12);
        let cap: f64 = nodes
            .iter()
            .zip(&weights)
            .map(|(&x, &w)| w * r / 2.0 * 2.0 * std::f64::consts::PI * (r * (x + 1.0) / 2.0).sin())
            .sum();
        assert!((cap - sun.solid_angle()).abs() < 1e-14);
    }

    /// A uniform sky of radiance L gives E = πL on an upward plane (sphere quadrature).
    #[test]
    fn uniform_sky_quadrature() {
        let env = Environment::UniformSky { sky: [1.0, 2.0, 0.5], ground: None };
        let q = SphereQuadrature::hemisphere(32, 64);
        let e: f64 = q.integrate(|d| env.radiance(DVec3::from_array(d))[1] * d[2]);
        assert!((e - 2.0 * std::f64::consts::PI).abs() < 1e-9, "{e}");
    }

    #[test]
    fn spot_falloff_limits() {
        let s = PunctualLight::Spot {
            position: DVec3::Z,
            axis: -DVec3::Z,
            intensity: [4.0; 3],
            inner: 0.2,
            outer: 0.4,
        };
        let (_, r, e) = s.incident(DVec3::ZERO).unwrap();
        assert_eq!((r, e[0]), (1.0, 4.0));
        assert!(s.incident(DVec3::new(10.0, 0.0, 0.0)).is_none());
    }
}
