//! Sky occlusion as Unity's Adaptive Probe Volumes relight a changed sky: the baseline the
//! exact sky transfer ([`lightvol_volume::light_groups`], `bake --sky-transfer`) is
//! measured against.
//!
//! Unity APV bakes, beside its probes' lighting, a static *sky occlusion* per probe: the
//! light a probe receives from a white sky, bounces included, with every surface treated
//! as opaque and one grey albedo, stored as L1 SH (four coefficients), and a *sky shading
//! direction*, the mean direction in which the probe sees the sky. At run time the sky's
//! current colour, read from the ambient probe (the sky's own SH) in the shading
//! direction, is multiplied by the occlusion evaluated at the surface normal (\[Uni24\]).
//!
//! Here, with the same bake method as the volume it stands beside:
//!
//! 1. [`occlusion_scene`]: the scene with a uniform white sky of radiance 1 over the whole
//!    sphere, no sun, punctual or emissive lights, and every material the scene's mean
//!    albedo ([`mean_albedo`], grey). Its bake's coefficients `o_j` give
//!    `V(n) = Σ_j A_l Y_j(n) o_j / π`, the fraction of a white sky's irradiance that
//!    reaches a normal `n` (1 in open space), bounces included;
//! 2. [`relight_occlusion`]: for a new sky of SH radiance `l_j`, node `i`'s coefficients
//!    become `c_j = o_j · E_sky(d_i) / π` for the L1 terms (`j < 4`) and 0 above, where
//!    `E_sky(d) = Σ_j A_l Y_j(d) l_j` is the sky's unoccluded irradiance and `d_i` the
//!    direction of the node's L1 occlusion vector (the mean direction in which it sees the
//!    sky, [`shading_direction`]; +z where it sees none). Then `E(n) = V(n) E_sky(d_i)`,
//!    APV's product, and the lookups interpolate it like any volume.
//!
//! What it cannot follow, and the transfer does: the colour and direction of the light that
//! bounces (one grey albedo, one shading direction per node instead of the transfer from
//! every sky direction through every bounce), and anything above L1.

use lightvol_scene::{Environment, Scene};
use lightvol_sh::index::sh_lm;
use lightvol_sh::irradiance::cosine_lobe_factor;

/// Coefficients of the occlusion kept (L1, as Unity APV stores it).
pub const OCCLUSION_COEFFS: usize = 4;

/// The area-weighted mean albedo of the scene's triangles (each at its centroid,
/// texture included), as one grey value: the luminance (Rec. 709 weights) of the mean
/// colour. 0.5 for a scene without area.
#[must_use]
pub fn mean_albedo(scene: &Scene) -> f64 {
    let (mut sum, mut area) = ([0.0f64; 3], 0.0f64);
    for (i, t) in scene.triangles.iter().enumerate() {
        let a = t.area();
        if !(a.is_finite() && a > 0.0) {
            continue;
        }
        let c = scene.albedo(i as u32, 1.0 / 3.0, 1.0 / 3.0);
        for k in 0..3 {
            sum[k] += a * c[k];
        }
        area += a;
    }
    if area <= 0.0 {
        return 0.5;
    }
    (0.2126 * sum[0] + 0.7152 * sum[1] + 0.0722 * sum[2]) / area
}

/// The scene the occlusion is baked in (module docs, step 1): the same geometry and
/// material layout (so the scene's tracer serves it), a white sky of radiance 1 in every
/// direction, no other light, every material grey at `albedo` without texture or emission.
#[must_use]
pub fn occlusion_scene(scene: &Scene, albedo: f64) -> Scene {
    let mut s = scene.clone();
    s.environment = Environment::UniformSky { sky: [1.0; 3], ground: Some([1.0; 3]) };
    s.sun = None;
    s.punctual.clear();
    s.punctual_names.clear();
    for m in &mut s.materials {
        m.albedo = [albedo; 3];
        m.albedo_texture = None;
        m.emission = [0.0; 3];
    }
    s
}

/// The node's sky shading direction from its occlusion coefficients `o` (one channel,
/// at least [`OCCLUSION_COEFFS`]): the direction of the L1 vector `(o_3, o_1, o_2)` (the
/// real SH `Y_1,-1, Y_10, Y_11` are `y, z, x` times one constant), which is the mean of the
/// directions in which the node sees the sky; +z when it is zero.
#[must_use]
pub fn shading_direction(o: &[f64]) -> [f64; 3] {
    let v = [o[3], o[1], o[2]];
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len > 0.0 && len.is_finite() { v.map(|x| x / len) } else { [0.0, 0.0, 1.0] }
}

/// The sky's unoccluded irradiance at normal `d`: `Σ_j A_l Y_j(d) l_j` per channel for a
/// sky of SH radiance `sky` (Ramamoorthi & Hanrahan 2001, Eq. 7-8).
#[must_use]
pub fn sky_irradiance(sky: &[[f64; 3]], d: [f64; 3]) -> [f64; 3] {
    let bands = (sky.len() as f64).sqrt().round() as usize;
    let mut y = vec![0.0; sky.len()];
    lightvol_sh::eval::eval_into(bands, d, &mut y);
    let mut e = [0.0; 3];
    for (j, (l, yj)) in sky.iter().zip(&y).enumerate() {
        let a = cosine_lobe_factor(sh_lm(j).0);
        for c in 0..3 {
            e[c] += a * yj * l[c];
        }
    }
    e
}

/// The node coefficients APV's sky occlusion gives under the sky of SH radiance `sky`
/// (module docs, step 2), in the layout of `occlusion` (`[node][coeff][rgb]`, `coeffs`
/// per node): the occlusion's L1 terms scaled by the sky's irradiance in each node's
/// shading direction over π, the higher terms 0.
///
/// # Panics
/// If `coeffs < 4` or `occlusion` is not a whole number of nodes.
#[must_use]
pub fn relight_occlusion(occlusion: &[f32], coeffs: usize, sky: &[[f64; 3]]) -> Vec<f32> {
    assert!(coeffs >= OCCLUSION_COEFFS && occlusion.len().is_multiple_of(3 * coeffs), "occlusion layout");
    let mut out = vec![0.0f32; occlusion.len()];
    for (o, c) in occlusion.chunks_exact(3 * coeffs).zip(out.chunks_exact_mut(3 * coeffs)) {
        // The white sky is grey: the channels' occlusions differ only by rounding; the
        // direction comes from their mean.
        let mean: Vec<f64> = (0..OCCLUSION_COEFFS)
            .map(|j| (0..3).map(|k| f64::from(o[3 * j + k])).sum::<f64>() / 3.0)
            .collect();
        let e = sky_irradiance(sky, shading_direction(&mean));
        for j in 0..OCCLUSION_COEFFS {
            for k in 0..3 {
                c[3 * j + k] = (f64::from(o[3 * j + k]) * e[k] / std::f64::consts::PI) as f32;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// In open space (the white sky's coefficients: `o_0 = √(4π)`, the rest 0) a sky
    /// relights to its own irradiance's mean: `c_0 = √(4π) E_sky(+z)/π`, which for a
    /// uniform sky of radiance `L` is `√(4π) L`, the SH of that sky itself.
    #[test]
    fn open_space_relights_to_the_sky_itself() {
        let root_4pi = (4.0 * std::f64::consts::PI).sqrt();
        let mut occ = vec![0.0f32; 27];
        for k in 0..3 {
            occ[k] = root_4pi as f32;
        }
        let sky = lightvol_scene::light_groups::sky_coefficients(
            &Environment::UniformSky { sky: [2.0, 1.0, 0.5], ground: Some([2.0, 1.0, 0.5]) },
            9,
        );
        let c = relight_occlusion(&occ, 9, &sky);
        for (k, l) in [2.0f64, 1.0, 0.5].iter().enumerate() {
            let want = root_4pi * l;
            assert!((f64::from(c[k]) - want).abs() < 1e-5 * want, "{} {want}", c[k]);
        }
        assert!(c[3..].iter().all(|&v| v == 0.0));
    }

    /// The shading direction is the L1 vector's: `Y_1,-1 ∝ y`, `Y_10 ∝ z`, `Y_11 ∝ x`
    /// (checked against the SH evaluation itself).
    #[test]
    fn shading_direction_follows_the_l1_vector() {
        for d in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [0.6, 0.0, 0.8]] {
            let mut y = vec![0.0; 4];
            lightvol_sh::eval::eval_into(2, d, &mut y);
            let got = shading_direction(&y);
            for a in 0..3 {
                assert!((got[a] - d[a]).abs() < 1e-12, "{d:?} {got:?}");
            }
        }
        assert_eq!(shading_direction(&[1.0, 0.0, 0.0, 0.0]), [0.0, 0.0, 1.0]);
    }

    /// The sky's irradiance: a sky of radiance 1 everywhere gives π at every normal; one
    /// above the horizon only gives, at order 3, exactly π at +z and 0 at -z (its L2 term
    /// vanishes, below).
    #[test]
    fn sky_irradiance_of_uniform_skies() {
        let pi = std::f64::consts::PI;
        let uniform = lightvol_scene::light_groups::sky_coefficients(
            &Environment::UniformSky { sky: [1.0; 3], ground: Some([1.0; 3]) },
            9,
        );
        for d in [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, -0.6, -0.8]] {
            let e = sky_irradiance(&uniform, d);
            assert!((e[0] - pi).abs() < 1e-9, "{e:?}");
        }
        // Sky above only, order 3: L_00 = √π, L_10 = √(3π)/2, L_20 = 0 (odd-even), so
        // E(+z) = π·Y_00·√π + (2π/3)·Y_10(+z)·√(3π)/2 = π/2 + π/2 = π.
        let upper = lightvol_scene::light_groups::sky_coefficients(
            &Environment::UniformSky { sky: [1.0; 3], ground: None },
            9,
        );
        let e_up = sky_irradiance(&upper, [0.0, 0.0, 1.0]);
        let e_down = sky_irradiance(&upper, [0.0, 0.0, -1.0]);
        assert!((e_up[0] - pi).abs() < 1e-9 && e_down[0].abs() < 1e-9, "{e_up:?} {e_down:?}");
    }
}
