//! Irradiance: the clamped-cosine factors `A_l` against quadrature, the [RH01] Eq. 12
//! constants, the three 9-coefficient evaluators, a directional light's truncation error and
//! the printed digits of [KL06] Table 1.

use std::f64::consts::PI;

use lightvol_sh::coeffs::{Sh, ShRgb};
use lightvol_sh::irradiance::{
    PackedIrradiance, RhMatrix, cosine_lobe_factor, irradiance, irradiance_rgb, rh_constants,
};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::project::project_directional;
use lightvol_sh::quadrature::SphereQuadrature;
use lightvol_sh::reference::k_norm;
use lightvol_sh::sampling::{Frame, sample_uniform_sphere};

/// Exact quadrature of polynomial integrands: f64 rounding over a few hundred terms.
const EXACT: f64 = 1e-12;
/// The bound between the three 9-coefficient evaluators; the packed form runs in f32.
const EVALUATORS_AGREE: f64 = 1e-6;

fn random_sh<const N: usize>(rng: &mut SplitMix64) -> Sh<f64, N> {
    Sh(core::array::from_fn(|_| rng.range(-1.0, 1.0)))
}

/// E(n) = ∫_{n·ω>0} L(ω) (n·ω) dω by a hemisphere product rule in the frame of n: there
/// the integrand is a polynomial, so the rule is exact (no kink inside the domain).
fn brute_force_irradiance<const N: usize>(l: &Sh<f64, N>, n: [f64; 3]) -> f64 {
    let frame = Frame::from_normal(n);
    let bands = N.isqrt();
    let quad = SphereQuadrature::hemisphere(bands + 2, 2 * bands + 3);
    quad.integrate(|local| l.eval(frame.to_world(local)) * local[2])
}

#[test]
fn closed_form_a_l_matches_quadrature() {
    let mut rng = SplitMix64::new(11);
    let l: Sh<f64, 36> = random_sh(&mut rng);
    for _ in 0..20 {
        let n = sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
        let e = irradiance(&l, n);
        let b = brute_force_irradiance(&l, n);
        assert!((e - b).abs() < EXACT, "{e} vs {b}");
    }
    // And the closed form for single even bands (l = 4: -π/24, l = 6: π/64).
    assert!((cosine_lobe_factor(4) + PI / 24.0).abs() < 1e-15);
    assert!((cosine_lobe_factor(6) - PI / 64.0).abs() < 1e-15);
    assert_eq!(cosine_lobe_factor(5), 0.0);
}

/// Each of the RH constants is A_l times a basis normalisation (K from the reference).
#[test]
fn rh_constants_derive_from_a_l() {
    let [c1, c2, c3, c4, c5] = rh_constants();
    let k22 = std::f64::consts::SQRT_2 * k_norm(2, 2) * 3.0; // y_22 = sqrt2 K_22 · 3 (x² - y²)
    let k11 = std::f64::consts::SQRT_2 * k_norm(1, 1); // y_11 = sqrt2 K_11 · x
    let k20 = k_norm(2, 0) * 0.5; // y_20 = K_20 · (3z² - 1)/2
    assert!((c1 - cosine_lobe_factor(2) * k22).abs() < 1e-15);
    assert!((2.0 * c2 - cosine_lobe_factor(1) * k11).abs() < 1e-15);
    assert!((c3 - cosine_lobe_factor(2) * 3.0 * k20).abs() < 1e-15);
    assert!((c4 - cosine_lobe_factor(0) * k_norm(0, 0)).abs() < 1e-15);
    assert!((c5 - cosine_lobe_factor(2) * k20).abs() < 1e-15);
    // The paper's six printed digits: c1, c4, c5 are the exact values correctly rounded. c2 and
    // c3 are not: sqrt(3π)/6 = 0.5116634 and 3 sqrt(5π)/16 = 0.7431239 round to 0.511663 and
    // 0.743124, but RH 2001 prints 0.511664 and 0.743125 (off by 6.5e-7 and 1.1e-6). The exact
    // expressions are what this crate uses.
    for (c, printed) in [(c1, 0.429043), (c4, 0.886227), (c5, 0.247708), (c2, 0.511663), (c3, 0.743124)] {
        assert!((c - printed).abs() <= 5e-7, "{c} vs correctly rounded {printed}");
    }
    assert!((c2 - 0.511664).abs() > 5e-7 && (c3 - 0.743125).abs() > 5e-7);
}

#[test]
fn three_evaluators_agree() {
    let mut rng = SplitMix64::new(7);
    for _ in 0..50 {
        let rgb = ShRgb::<f64, 9>([random_sh(&mut rng), random_sh(&mut rng), random_sh(&mut rng)]);
        let packed = PackedIrradiance::from_radiance(&rgb);
        let rh = [0, 1, 2].map(|c| RhMatrix::from_radiance(&rgb.0[c]));
        let n = sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
        let direct = irradiance_rgb(&rgb, n);
        let p = packed.irradiance(n.map(|v| v as f32));
        for c in 0..3 {
            let e_rh = rh[c].irradiance(n);
            assert!((direct[c] - e_rh).abs() < EXACT, "RH vs direct");
            assert!((direct[c] - f64::from(p[c])).abs() < EVALUATORS_AGREE, "packed vs direct");
            assert!((direct[c] - brute_force_irradiance(&rgb.0[c], n)).abs() < EXACT);
        }
    }
}

/// A single directional light: the 9-coefficient irradiance is
/// `3/32 + t/2 + 15t²/32` with `t = n·d`, whose largest deviation from `max(0, t)` is 3/32 of
/// the peak (at the terminator, t = 0).
#[test]
fn directional_light_truncation_error_is_three_32nds() {
    let d = [0.0, 0.6, 0.8];
    let l: Sh<f64, 9> = project_directional(d, 1.0);
    let mut worst: f64 = 0.0;
    let steps = 2000;
    for i in 0..=steps {
        let t = -1.0 + 2.0 * i as f64 / steps as f64;
        // A normal at angle acos(t) from d, in the plane of d and x.
        let s = (1.0 - t * t).max(0.0).sqrt();
        let n = [s, t * d[1], t * d[2]];
        let e = irradiance(&l, n);
        let closed = 3.0 / 32.0 + t / 2.0 + 15.0 * t * t / 32.0;
        assert!((e - closed).abs() < EXACT, "closed form at t={t}");
        worst = worst.max((e - t.max(0.0)).abs());
    }
    // The peak (E at n = d) is 1.
    assert!((worst - 3.0 / 32.0).abs() < EXACT, "max error {worst}");
}

/// [KL06] Table 1 prints wrong digits; the derivations give the right ones. This test pins
/// both, so nobody "fixes" a constant back to the printed value.
#[test]
#[allow(clippy::approx_constant, reason = "the printed digits of [KL06] are the subject of this test")]
fn kl06_table1_printed_digits_against_derivations() {
    let y0 = 0.5 / PI.sqrt();
    assert!((y0 - 0.282095).abs() < 5e-7, "Y_0 = 1/(2 sqrt pi) = {y0}");
    assert!((y0 - 0.282209).abs() > 1e-4, "the printed 0.282209 is wrong");
    let a1 = cosine_lobe_factor(1);
    assert!((a1 - 2.094395).abs() < 5e-7, "A_1 = 2pi/3 = {a1}");
    assert!((a1 - 2.09395).abs() > 4e-4, "the printed 2.09395 drops a digit");
    // The digits that are right: sqrt(3/4pi), sqrt(15/4pi), sqrt(5/16pi), sqrt(15/16pi), pi/4.
    for (v, printed) in [
        ((3.0 / (4.0 * PI)).sqrt(), 0.488603),
        ((15.0 / (4.0 * PI)).sqrt(), 1.092548),
        ((5.0 / (16.0 * PI)).sqrt(), 0.315392),
        ((15.0 / (16.0 * PI)).sqrt(), 0.546274),
        (cosine_lobe_factor(2), 0.785398),
        (cosine_lobe_factor(0), 3.141593),
    ] {
        assert!((v - printed).abs() < 5e-7, "{v} vs {printed}");
    }
}
