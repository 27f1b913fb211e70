//! Direction sampling in pbrt's threes: `sample_*` maps `[0,1)²` to a direction, `*_pdf`
//! gives its density with respect to solid angle, and `invert_*` maps the direction back.
//!
//! All mappings take the upper hemisphere around `+z`; use [`Frame`] to place them around a
//! surface normal. Conventions: `z = cos θ`, `φ = atan2(y, x) ∈ [0, 2π)`.

use std::f64::consts::{FRAC_1_PI, PI};

fn phi_of(x: f64, y: f64) -> f64 {
    let p = y.atan2(x);
    if p < 0.0 { p + 2.0 * PI } else { p }
}

fn from_z_phi(z: f64, phi: f64) -> [f64; 3] {
    let r = (1.0 - z * z).max(0.0).sqrt();
    [r * phi.cos(), r * phi.sin(), z]
}

/// Uniform direction on the unit sphere: `z = 1 - 2 u0`, `φ = 2π u1`.
#[must_use]
#[inline]
pub fn sample_uniform_sphere(u: [f64; 2]) -> [f64; 3] {
    from_z_phi(1.0 - 2.0 * u[0], 2.0 * PI * u[1])
}

/// Density of [`sample_uniform_sphere`]: `1 / 4π`.
#[must_use]
#[inline]
pub fn uniform_sphere_pdf() -> f64 {
    0.25 * FRAC_1_PI
}

/// Inverse of [`sample_uniform_sphere`].
#[must_use]
#[inline]
pub fn invert_uniform_sphere(w: [f64; 3]) -> [f64; 2] {
    [(1.0 - w[2]) * 0.5, phi_of(w[0], w[1]) / (2.0 * PI)]
}

/// Uniform direction on the upper hemisphere: `z = u0`, `φ = 2π u1`.
#[must_use]
#[inline]
pub fn sample_uniform_hemisphere(u: [f64; 2]) -> [f64; 3] {
    from_z_phi(u[0], 2.0 * PI * u[1])
}

/// Density of [`sample_uniform_hemisphere`]: `1 / 2π`.
#[must_use]
#[inline]
pub fn uniform_hemisphere_pdf() -> f64 {
    0.5 * FRAC_1_PI
}

/// Inverse of [`sample_uniform_hemisphere`].
#[must_use]
#[inline]
pub fn invert_uniform_hemisphere(w: [f64; 3]) -> [f64; 2] {
    [w[2], phi_of(w[0], w[1]) / (2.0 * PI)]
}

/// Cosine-weighted direction on the upper hemisphere (Malley's method with the polar disk
/// map): `sin θ = sqrt(u0)`, `φ = 2π u1`.
#[must_use]
#[inline]
pub fn sample_cosine_hemisphere(u: [f64; 2]) -> [f64; 3] {
    from_z_phi((1.0 - u[0]).max(0.0).sqrt(), 2.0 * PI * u[1])
}

/// Density of [`sample_cosine_hemisphere`]: `cos θ / π` (zero below the horizon).
#[must_use]
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f64) -> f64 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Inverse of [`sample_cosine_hemisphere`].
#[must_use]
#[inline]
pub fn invert_cosine_hemisphere(w: [f64; 3]) -> [f64; 2] {
    [(w[0] * w[0] + w[1] * w[1]).min(1.0), phi_of(w[0], w[1]) / (2.0 * PI)]
}

/// Uniform direction in the cone `cos θ >= cos_max` around `+z`.
#[must_use]
#[inline]
pub fn sample_uniform_cone(u: [f64; 2], cos_max: f64) -> [f64; 3] {
    from_z_phi(1.0 - u[0] * (1.0 - cos_max), 2.0 * PI * u[1])
}

/// Density of [`sample_uniform_cone`]: `1 / (2π (1 - cos_max))`.
#[must_use]
#[inline]
pub fn uniform_cone_pdf(cos_max: f64) -> f64 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Inverse of [`sample_uniform_cone`].
#[must_use]
#[inline]
pub fn invert_uniform_cone(w: [f64; 3], cos_max: f64) -> [f64; 2] {
    [(1.0 - w[2]) / (1.0 - cos_max), phi_of(w[0], w[1]) / (2.0 * PI)]
}

/// The `n` points of a spherical Fibonacci lattice (\[Gon10\]): point `i` at
/// `z = 1 - (2i + 1)/n`, azimuth `i · π (3 - √5)` (the golden angle). Nearly uniform, each
/// point the centre of a cell of area `4π/n`; a deterministic set of directions for
/// searches and quadratures.
pub fn fibonacci_sphere(n: usize) -> impl Iterator<Item = [f64; 3]> {
    let golden = PI * (3.0 - 5f64.sqrt());
    (0..n).map(move |i| {
        let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * i as f64;
        [r * phi.cos(), r * phi.sin(), z]
    })
}

/// An orthonormal frame around a unit vector `n` (Duff et al. 2017, "Building an
/// Orthonormal Basis, Revisited"): `to_world` maps local `+z` to `n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Local x axis in world space.
    pub t: [f64; 3],
    /// Local y axis in world space.
    pub b: [f64; 3],
    /// Local z axis (the normal).
    pub n: [f64; 3],
}

impl Frame {
    /// The frame around the unit normal `n`.
    #[must_use]
    pub fn from_normal(n: [f64; 3]) -> Self {
        let sign = 1.0_f64.copysign(n[2]);
        let a = -1.0 / (sign + n[2]);
        let b = n[0] * n[1] * a;
        let t = [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]];
        let bt = [b, sign + n[1] * n[1] * a, -n[1]];
        Self { t, b: bt, n }
    }

    /// Local to world.
    #[must_use]
    #[inline]
    pub fn to_world(&self, v: [f64; 3]) -> [f64; 3] {
        core::array::from_fn(|i| self.t[i] * v[0] + self.b[i] * v[1] + self.n[i] * v[2])
    }

    /// World to local.
    #[must_use]
    #[inline]
    pub fn to_local(&self, v: [f64; 3]) -> [f64; 3] {
        let d = |a: [f64; 3]| a[0] * v[0] + a[1] * v[1] + a[2] * v[2];
        [d(self.t), d(self.b), d(self.n)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lowdisc::Halton;

    /// Round trips go through sqrt/atan2: a few ulps of O(1) values.
    const ROUND_TRIP: f64 = 1e-12;

    fn close2(a: [f64; 2], b: [f64; 2]) -> bool {
        (a[0] - b[0]).abs() < ROUND_TRIP && (a[1] - b[1]).abs() < ROUND_TRIP
    }

    /// The Fibonacci lattice is unit length and equal-area: each point's `z` is the centre
    /// of one of `n` equal `z` bands (Archimedes: equal `z` bands have equal area), so any
    /// `z` slab holds its area's share of points to within one, and the points' centroid is
    /// near zero (the golden angle spreads the azimuths).
    #[test]
    fn fibonacci_lattice_is_unit_and_equal_area() {
        let n = 1000;
        let pts: Vec<[f64; 3]> = fibonacci_sphere(n).collect();
        assert_eq!(pts.len(), n);
        for p in &pts {
            assert!((p[0] * p[0] + p[1] * p[1] + p[2] * p[2] - 1.0).abs() < ROUND_TRIP);
        }
        for (lo, hi) in [(-1.0, 0.0), (0.2, 0.7), (-0.9, -0.35)] {
            let inside = pts.iter().filter(|p| p[2] > lo && p[2] <= hi).count() as f64;
            assert!((inside - n as f64 * (hi - lo) / 2.0).abs() <= 1.0, "{lo}..{hi}: {inside}");
        }
        let c = pts.iter().fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]]);
        // About 1/n for the golden-angle spiral; 10/n leaves room for the poles.
        assert!(c.iter().all(|v| v.abs() / (n as f64) < 10.0 / n as f64), "{c:?}");
    }

    #[test]
    fn round_trips() {
        let h = Halton::new(3, 2);
        for i in 1..500 {
            let u = h.point::<2>(i);
            assert!(close2(invert_uniform_sphere(sample_uniform_sphere(u)), u));
            assert!(close2(invert_uniform_hemisphere(sample_uniform_hemisphere(u)), u));
            assert!(close2(invert_cosine_hemisphere(sample_cosine_hemisphere(u)), u));
            assert!(close2(invert_uniform_cone(sample_uniform_cone(u, 0.7), 0.7), u));
        }
    }

    /// The estimator `mean(f / pdf)` with each mapping must integrate known functions; with
    /// 4096 stratified points the QMC error on these smooth integrands is far below 1e-3.
    #[test]
    fn pdfs_integrate_correctly() {
        let h = Halton::new(9, 2);
        let n = 4096;
        let mut cos_sum = 0.0;
        let mut one_sum = 0.0;
        let mut x2_sum = 0.0;
        for i in 0..n {
            let u = h.point::<2>(i);
            let w = sample_cosine_hemisphere(u);
            cos_sum += w[2] / cosine_hemisphere_pdf(w[2]);
            let w = sample_uniform_hemisphere(u);
            one_sum += w[2] / uniform_hemisphere_pdf();
            let w = sample_uniform_sphere(u);
            x2_sum += w[0] * w[0] / uniform_sphere_pdf();
        }
        let nf = n as f64;
        assert!((cos_sum / nf - PI).abs() < 1e-9, "∫cos = π exactly with the cosine pdf");
        assert!((one_sum / nf - PI).abs() < 1e-3);
        assert!((x2_sum / nf - 4.0 * PI / 3.0).abs() < 1e-3);
    }

    #[test]
    fn frame_is_orthonormal() {
        for n in [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.6, 0.0, 0.8], [0.0, -0.6, -0.8]] {
            let f = Frame::from_normal(n);
            let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            assert!((dot(f.t, f.t) - 1.0).abs() < 1e-15);
            assert!((dot(f.b, f.b) - 1.0).abs() < 1e-15);
            assert!(dot(f.t, f.b).abs() < 1e-15 && dot(f.t, n).abs() < 1e-15 && dot(f.b, n).abs() < 1e-15);
            let w = f.to_world([0.0, 0.0, 1.0]);
            assert!((0..3).all(|i| (w[i] - n[i]).abs() < 1e-15));
            let v = [0.3, -0.4, 0.5];
            let back = f.to_local(f.to_world(v));
            assert!((0..3).all(|i| (back[i] - v[i]).abs() < 1e-15));
        }
    }
}
