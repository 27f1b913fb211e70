//! How much of a sky an order-N spherical-harmonic projection loses, as the irradiance it
//! gives an unoccluded receiver: the figure a relit volume's error against a fresh bake of
//! the same sky is judged by, beside the bakes' own noise.
//!
//! The irradiance of an SH radiance `Σ l_lm Y_lm` at normal `n` is `Σ A_l l_lm Y_lm(n)`
//! (Ramamoorthi & Hanrahan 2001, Eq. 7, \[RH01\]; `A_l` is
//! [`cosine_lobe_factor`](lightvol_sh::irradiance::cosine_lobe_factor)). The sky's own
//! irradiance `E(n) = ∫ L(ω) max(0, n·ω) dω` is integrated by a Gauss-Legendre product rule
//! on each hemisphere, fine enough that its error (from the kink of the clamped cosine) is
//! far below the band-limit errors it is compared with. The figure is the relative RMS of
//! the difference over normals spread evenly over the sphere, in luminance, divided by the
//! mean irradiance (the plate metric's normalisation).
//!
//! It is the *open-sky* figure: a point that sees only part of the sky (a street canyon, a
//! room lit through a window) can see more of the projection's ringing than this.

use glam::DVec3;

use crate::envmap::luminance;
use crate::light_groups::sky_coefficients;
use crate::lights::Environment;

/// Normals the error is averaged over (a spherical Fibonacci set): enough that the mean
/// of the smooth squared irradiance error over the sphere is within 0.1% of its integral.
const NORMALS: usize = 1024;

/// Gauss-Legendre nodes in θ and uniform nodes in φ per hemisphere for the sky's own
/// irradiance: as [`sky_coefficients`] integrates maps, far finer than the bands measured.
const RULE: (usize, usize) = (128, 256);

/// The open-sky irradiance band-limit error of `env`'s projection onto its first `coeffs`
/// (1, 4, 9 or 16) SH coefficients: `sqrt(mean_n (E_N(n) - E(n))²) / mean_n E(n)` in
/// luminance (module docs). Zero for a sky of no light.
#[must_use]
pub fn irradiance_band_limit_error(env: &Environment, coeffs: usize) -> f64 {
    use lightvol_sh::irradiance::cosine_lobe_factor;
    use lightvol_sh::quadrature::SphereQuadrature;
    let bands = (coeffs as f64).sqrt().round() as usize;
    let proj: Vec<f64> = sky_coefficients(env, coeffs).iter().map(|&c| luminance(c)).collect();
    // The projection's irradiance coefficients A_l l_lm (index j = l² + l + m).
    let irr: Vec<f64> = proj
        .iter()
        .enumerate()
        .map(|(j, &c)| cosine_lobe_factor(lightvol_sh::index::sh_lm(j).0) * c)
        .collect();
    let rule = SphereQuadrature::hemisphere(RULE.0, RULE.1);
    let sky: Vec<(DVec3, f64)> = rule
        .nodes()
        .iter()
        .flat_map(|node| {
            let [x, y, z] = node.dir;
            [DVec3::new(x, y, z), DVec3::new(x, y, -z)].map(|d| (d, node.weight * luminance(env.radiance(d))))
        })
        .collect();
    let mut y = vec![0.0; coeffs];
    let (mut sq, mut sum) = (0.0, 0.0);
    for i in 0..NORMALS {
        let n = fibonacci_normal(i, NORMALS);
        let exact: f64 = sky.iter().map(|&(d, w)| w * n.dot(d).max(0.0)).sum();
        lightvol_sh::eval::eval_into(bands, n.to_array(), &mut y);
        let projected: f64 = irr.iter().zip(&y).map(|(c, yj)| c * yj).sum();
        sq += (projected - exact).powi(2);
        sum += exact;
    }
    if sum <= 0.0 { 0.0 } else { (sq / NORMALS as f64).sqrt() / (sum / NORMALS as f64) }
}

/// The `i`-th of `n` points of a spherical Fibonacci set: equal-area bands in z, golden-angle
/// steps in azimuth.
fn fibonacci_normal(i: usize, n: usize) -> DVec3 {
    let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
    let r = (1.0 - z * z).sqrt();
    let phi = golden_angle * i as f64;
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The quadrature's own error on the clamped cosine, relative: a step sky's exact
    /// figure is 0 and measures below this.
    const RULE_ERROR: f64 = 1e-4;

    #[test]
    fn a_sky_and_ground_step_has_linear_irradiance() {
        // E(n) = π (a + b)/2 + π (a - b)/2 n_z: bands 0 and 1 hold it exactly.
        let env = Environment::UniformSky { sky: [1.0, 0.9, 0.8], ground: Some([0.2, 0.2, 0.1]) };
        for coeffs in [4, 9, 16] {
            assert!(irradiance_band_limit_error(&env, coeffs) < RULE_ERROR, "{coeffs}");
        }
    }

    #[test]
    fn band_zero_of_a_white_hemisphere_misses_its_linear_term() {
        // Sky a, ground 0: E(n) = π a (1 + n_z)/2, its band-0 part π a/2; the difference
        // π a n_z/2 has RMS π a/(2√3) over the sphere, so the figure is 1/√3.
        let env = Environment::UniformSky { sky: [0.7; 3], ground: None };
        let e = irradiance_band_limit_error(&env, 1);
        assert!((e - 1.0 / 3f64.sqrt()).abs() < 1e-3, "{e}");
    }

    /// The repository's sunset gradient: 0.0094 from an independent computation (texels
    /// summed with their exact solid angles, the nine real SH written out by hand, 2,000
    /// normals); the tolerance covers this module's nearest-texel quadrature against that
    /// texel sum.
    #[test]
    fn the_sunset_gradient_matches_an_independent_texel_sum() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/env/gradient/gradient.exr");
        let env = Environment::Map(crate::envmap::EnvMap::from_exr(std::path::Path::new(path)).unwrap());
        let e = irradiance_band_limit_error(&env, 9);
        assert!((e - 0.0094).abs() < 5e-4, "{e}");
        // Order 4 adds only band 3, which the cosine lobe does not pass.
        assert!((irradiance_band_limit_error(&env, 16) - e).abs() < 1e-9);
    }

    #[test]
    fn no_light_has_no_error() {
        assert_eq!(irradiance_band_limit_error(&Environment::Black, 9), 0.0);
    }

    #[test]
    fn fibonacci_normals_are_unit_and_balanced() {
        let mean: DVec3 = (0..NORMALS).map(|i| fibonacci_normal(i, NORMALS)).sum::<DVec3>() / NORMALS as f64;
        assert!(mean.length() < 1e-3, "{mean}");
        assert!((0..NORMALS).all(|i| (fibonacci_normal(i, NORMALS).length() - 1.0).abs() < 1e-12));
    }
}
