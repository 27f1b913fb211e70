//! Sphere proxies (Sloan et al. 2007, \[SGNS07\] §3) and the geometry of one proxy as seen from
//! one receiver: direction, `α = sin θ` (Eq. 1), solid angle (Eq. 2), and the
//! self-shadowing replacement rule for spheres that contain the receiver or cross its
//! tangent plane.

use std::f64::consts::PI;

/// A sphere standing in for part of a moving object: it blocks light (its visibility cap,
/// Eq. 3) and re-radiates it as a diffuse sphere of the given albedo (§5).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SphereProxy {
    /// Centre `c_i`, world space.
    pub center: [f64; 3],
    /// Radius `r_i > 0`.
    pub radius: f64,
    /// Diffuse albedo (linear RGB, each in `[0, 1]`) used for the indirect light.
    pub albedo: [f64; 3],
}

impl SphereProxy {
    /// A proxy with the given centre, radius and albedo.
    #[must_use]
    pub const fn new(center: [f64; 3], radius: f64, albedo: [f64; 3]) -> Self {
        Self { center, radius, albedo }
    }
}

/// One proxy as seen from a receiver, after the replacement rule: the unit direction `d̂`
/// towards its (possibly replaced) centre and `α = sin θ = r / d` (Eq. 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProxyView {
    /// Unit direction from the receiver to the effective centre.
    pub dir: [f64; 3],
    /// `α = sin θ` in `(0, 1]`.
    pub alpha: f64,
}

impl ProxyView {
    /// Solid angle `ω = 2π (1 - sqrt(1 - α²))` (Eq. 2).
    #[must_use]
    pub fn solid_angle(&self) -> f64 {
        solid_angle(self.alpha)
    }
}

/// Solid angle of a sphere with `sin θ = alpha` (\[SGNS07\] Eq. 2).
#[must_use]
#[inline]
pub fn solid_angle(alpha: f64) -> f64 {
    // 1 - sqrt(1 - a²) = a² / (1 + sqrt(1 - a²)), without cancellation for small a.
    let a2 = alpha * alpha;
    2.0 * PI * a2 / (1.0 + (1.0 - a2).max(0.0).sqrt())
}

/// The sphere a receiver at `p` with unit normal `n` actually accumulates for `proxy`
/// (the self-shadowing replacement rule, \[SGNS07\] §3 citing \[Ren06\]; this is our own
/// continuous variant, documented here because \[SGNS07\] does not state the cited rule).
///
/// Let `h = (c - p)·n` be the height of the centre above the tangent plane.
/// - `h >= r`: the sphere lies above the plane and is used as is.
/// - `h <= -r`: it lies below the plane, where the diffuse receiver sees nothing: `None`.
/// - `-r < h < r` (this includes every sphere that contains `p`): the sphere is replaced by
///   the largest sphere inside it that lies above the plane, radius `r' = (h + r)/2`,
///   centre `c + (r' - h) n`. It equals the original at `h = r` and vanishes at `h = -r`,
///   so shading is continuous as a proxy moves through the plane; and since it lies above
///   the plane, `p` is never strictly inside it (`α <= 1`, with `α = 1` only where it
///   touches `p`).
///
/// The replacement underestimates the blocked solid angle of the part above the plane (the
/// inscribed sphere is smaller than the spherical segment); that is the price of continuity
/// without a cap-clipping table.
#[must_use]
pub fn view_from(proxy: &SphereProxy, p: [f64; 3], n: [f64; 3]) -> Option<ProxyView> {
    let r = proxy.radius;
    let c = proxy.center;
    let h = (0..3).map(|k| (c[k] - p[k]) * n[k]).sum::<f64>();
    if !(r > 0.0) || h <= -r {
        return None;
    }
    let (c, r) = if h >= r {
        (c, r)
    } else {
        let r2 = 0.5 * (h + r);
        let s = r2 - h;
        ([c[0] + s * n[0], c[1] + s * n[1], c[2] + s * n[2]], r2)
    };
    let v = [c[0] - p[0], c[1] - p[1], c[2] - p[2]];
    let d = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if !(d > 0.0) {
        // The receiver is the tangent point of a vanishing sphere: nothing to block.
        return None;
    }
    let alpha = (r / d).min(1.0);
    Some(ProxyView { dir: [v[0] / d, v[1] / d, v[2] / d], alpha })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rounding of a handful of f64 operations.
    const EPS: f64 = 1e-12;

    #[test]
    fn solid_angle_matches_cap_formula() {
        for a in [1e-4, 0.1, 0.5, 0.9, 1.0] {
            let theta = f64::asin(a);
            assert!((solid_angle(a) - 2.0 * PI * (1.0 - theta.cos())).abs() < EPS);
        }
    }

    #[test]
    fn replacement_rule_is_continuous_and_vanishes_below() {
        let n = [0.0, 0.0, 1.0];
        let p = [0.3, 0.0, 0.0];
        let at = |h: f64| view_from(&SphereProxy::new([0.0, 0.0, h], 0.5, [1.0; 3]), p, n);
        // Continuous at h = r.
        let (a, b) = (at(0.5 - 1e-9).unwrap(), at(0.5 + 1e-9).unwrap());
        assert!((a.alpha - b.alpha).abs() < 1e-8);
        // Vanishes continuously at h = -r.
        assert!(at(-0.5).is_none());
        assert!(at(-0.5 + 1e-6).unwrap().alpha < 1e-5);
        // A sphere containing p gives a proper cap (alpha <= 1) pointing upwards.
        let inside = at(0.1).unwrap();
        assert!(inside.alpha <= 1.0 && inside.dir[2] > 0.0);
        // The touching configuration: centre straight above p, h in (-r, r).
        let touch = view_from(&SphereProxy::new(p, 0.5, [1.0; 3]), p, n).unwrap();
        assert!((touch.alpha - 1.0).abs() < EPS && (touch.dir[2] - 1.0).abs() < EPS);
    }
}
