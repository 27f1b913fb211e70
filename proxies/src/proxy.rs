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
/// (the f64 reference of [`view_f32`]; the self-shadowing replacement rule, \[SGNS07\] §3 citing \[Ren06\]; this is our own
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

/// [`view_from`] in f32, its twin for the f32 kernels (`crate::kernel`, and per lane in
/// `crate::batch`): the same replacement rule and the same guards (`None` for a radius that
/// is not positive or is NaN, for a sphere below the tangent plane, and for a receiver at the
/// tangent point of a vanishing sphere), in the same order of operations. Returns the unit
/// direction to the effective centre and `α = sin θ` (\[SGNS07\] Eq. 1). The tests compare the
/// two with a named tolerance.
#[must_use]
#[inline]
pub fn view_f32(c: [f32; 3], r: f32, p: [f32; 3], n: [f32; 3]) -> Option<([f32; 3], f32)> {
    let h = (c[0] - p[0]) * n[0] + (c[1] - p[1]) * n[1] + (c[2] - p[2]) * n[2];
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
        return None;
    }
    Some(([v[0] / d, v[1] / d, v[2] / d], (r / d).min(1.0)))
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

    /// [`view_f32`] against its f64 twin [`view_from`] on the same (f32) inputs, as positions:
    /// `|Δα| · d` and `|Δd̂| · d` in scene units, `d` the distance to the effective centre
    /// (the error of `α = r' / d` and of `d̂ = v / d` is the f32 error of the replaced centre
    /// and radius, divided by `d`). Coordinates are up to 4 units, where an f32 ulp is 4.8e-7,
    /// and the view rounds them about ten times (the height, the replacement, the distance):
    /// ten ulps, 5e-6. Measured worst: 5.2e-7.
    const VIEW_F32_VS_F64: f64 = 5e-6;

    fn view_pair(
        c: [f32; 3],
        r: f32,
        p: [f32; 3],
        n: [f32; 3],
    ) -> (Option<ProxyView>, Option<([f32; 3], f32)>) {
        let wide = SphereProxy::new(c.map(f64::from), f64::from(r), [1.0; 3]);
        (view_from(&wide, p.map(f64::from), n.map(f64::from)), view_f32(c, r, p, n))
    }

    #[test]
    fn f32_view_matches_f64_view() {
        let mut rng = lightvol_sh::lowdisc::SplitMix64::new(9);
        let (mut worst, mut both, mut boundary) = (0.0f64, 0, 0);
        for i in 0..200_000 {
            let mut coord = || rng.range(-2.0, 2.0) as f32;
            let p = [coord(), coord(), coord()];
            let r = (coord() + 2.0) / 4.0;
            let m = [coord(), coord(), coord()];
            let len = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            let n = m.map(|v| v / len);
            // Every tenth sphere sits on the tangent plane's far side, `h = -r` up to f32
            // rounding, where it vanishes; the others anywhere.
            let c = if i % 10 == 0 {
                let t = [coord(), coord(), coord()];
                core::array::from_fn(|k| {
                    p[k] - r * n[k] + 0.1 * (t[k] - n[k] * (t[0] * n[0] + t[1] * n[1] + t[2] * n[2]))
                })
            } else {
                [coord(), coord(), coord()]
            };
            // The replaced radius r' in f64 (r' = α d).
            let h: f64 = (0..3).map(|k| (f64::from(c[k]) - f64::from(p[k])) * f64::from(n[k])).sum();
            let r64 = f64::from(r);
            let r_eff = if h >= r64 { r64 } else { 0.5 * (h + r64) };
            match view_pair(c, r, p, n) {
                (None, None) => {}
                (Some(a), Some((dir, alpha))) => {
                    both += 1;
                    // d = r' / α (at most that where α is clamped to 1).
                    let d = r_eff / a.alpha;
                    let e_alpha = (f64::from(alpha) - a.alpha).abs();
                    let e_dir = (0..3).map(|k| (f64::from(dir[k]) - a.dir[k]).abs()).fold(0.0, f64::max);
                    worst = worst.max(e_alpha.max(e_dir) * d);
                }
                // Where the f32 and f64 heights round to opposite sides of `h = -r`: the sphere
                // that one of them sees has vanished to within the tolerance.
                (Some(_), None) | (None, Some(_)) => {
                    boundary += 1;
                    assert!(r_eff.abs() < VIEW_F32_VS_F64, "views differ at r' = {r_eff:e}");
                }
            }
        }
        println!("view_f32 vs view_from: worst {worst:.2e} over {both} views, {boundary} at the plane");
        assert!(worst < VIEW_F32_VS_F64);
        assert!(both > 10_000 && boundary > 0);
        // Degenerate radii and NaN positions: both give nothing.
        let (c, p, n) = ([0.0, 0.0, 1.0], [0.0; 3], [0.0, 0.0, 1.0]);
        for r in [0.0, -0.0, -0.5, f32::NAN, f32::NEG_INFINITY] {
            assert_eq!(view_pair(c, r, p, n), (None, None), "radius {r}");
        }
        assert_eq!(view_pair([f32::NAN, 0.0, 1.0], 0.5, p, n), (None, None));
        assert_eq!(view_pair(c, 0.5, [0.0, f32::NAN, 0.0], n), (None, None));
        assert_eq!(view_pair(c, 0.5, p, [0.0, 0.0, f32::NAN]), (None, None));
    }
}
