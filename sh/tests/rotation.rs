//! Rotations.

use glam::{DMat3, DQuat, DVec3};
use lightvol_sh::coeffs::Sh;
use lightvol_sh::eval::eval_into;
use lightvol_sh::project::project_fn;
use lightvol_sh::quadrature::SphereQuadrature;
use lightvol_sh::rotate::{ShRotation, band_matrix_by_quadrature};
use lightvol_sh::zonal::Zh;
use proptest::prelude::*;

/// Rotation matrices are built by ~l recurrence steps of O(1) products from an orthogonal
/// 3×3 matrix; errors stay at a few hundred ulps even at l = 15.
const ROT_TOL: f64 = 1e-12;

fn quat(ax: f64, ay: f64, az: f64, angle: f64) -> DQuat {
    let axis = DVec3::new(ax, ay, az);
    let axis = if axis.length() < 1e-6 { DVec3::Z } else { axis.normalize() };
    DQuat::from_axis_angle(axis, angle)
}

fn test_function(d: [f64; 3]) -> f64 {
    // A degree-5 polynomial: exactly 36 coefficients.
    0.7 + d[0] - 0.5 * d[1] * d[2] + 0.2 * d[0] * d[0] * d[1] + 0.9 * d[2].powi(4) * d[0] - 0.3 * d[1].powi(5)
}

fn arb_quat() -> impl Strategy<Value = DQuat> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0, -3.2f64..3.2).prop_map(|(x, y, z, a)| quat(x, y, z, a))
}

fn arb_dir() -> impl Strategy<Value = [f64; 3]> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0).prop_filter_map("nonzero", |(x, y, z)| {
        let v = DVec3::new(x, y, z);
        (v.length() > 1e-3).then(|| v.normalize().to_array())
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, rng_seed: proptest::test_runner::RngSeed::Fixed(0x0707), ..ProptestConfig::default() })]

    /// (R f)(ω) = f(R⁻¹ ω) at random ω, for a 36-coefficient function.
    #[test]
    fn rotated_function_values(q in arb_quat(), w in arb_dir()) {
        let quad = SphereQuadrature::exact_for_degree(6);
        let f: Sh<f64, 36> = project_fn(test_function, &quad);
        let rot = ShRotation::from_quat(6, q);
        let g = rot.apply(&f);
        let rinv_w = (q.inverse() * DVec3::from(w)).to_array();
        prop_assert!((g.eval(w) - f.eval(rinv_w)).abs() < ROT_TOL);
        prop_assert!((g.eval(w) - test_function(rinv_w)).abs() < 1e-11);
    }

    /// M(R1 R2) = M(R1) M(R2): rotating by R2 then R1 equals rotating by R1 R2.
    #[test]
    fn composition(q1 in arb_quat(), q2 in arb_quat()) {
        let quad = SphereQuadrature::exact_for_degree(6);
        let f: Sh<f64, 36> = project_fn(test_function, &quad);
        let two_steps = ShRotation::from_quat(6, q1).apply(&ShRotation::from_quat(6, q2).apply(&f));
        let one_step = ShRotation::from_quat(6, q1 * q2).apply(&f);
        for i in 0..36 {
            prop_assert!((two_steps.0[i] - one_step.0[i]).abs() < ROT_TOL);
        }
    }

    /// Every band matrix is orthogonal, up to l = 15.
    #[test]
    fn band_matrices_are_orthogonal(q in arb_quat()) {
        let rot = ShRotation::from_quat(16, q);
        for l in 0..16 {
            let m = rot.band(l);
            let s = 2 * l + 1;
            for i in 0..s {
                for j in 0..s {
                    let d: f64 = (0..s).map(|k| m[i * s + k] * m[j * s + k]).sum();
                    let want = if i == j { 1.0 } else { 0.0 };
                    prop_assert!((d - want).abs() < ROT_TOL, "l={} ({},{}) = {}", l, i, j, d);
                }
            }
        }
    }

    /// The ZH rotation of [SGNS07] Eq. 8 equals the full rotation of the ZH.
    #[test]
    fn zh_rotation_equals_full_rotation(q in arb_quat()) {
        let zh = Zh::<f64, 6>::cap(0.8);
        let axis = (q * DVec3::Z).to_array();
        let by_zh: Sh<f64, 36> = zh.rotate_to(axis);
        let by_matrix = ShRotation::from_quat(6, q).apply(&zh.to_sh::<36>());
        for i in 0..36 {
            prop_assert!((by_zh.0[i] - by_matrix.0[i]).abs() < ROT_TOL);
        }
    }

    /// Rotate-then-project equals project-the-rotated-function.
    #[test]
    fn rotate_then_project(q in arb_quat()) {
        let quad = SphereQuadrature::exact_for_degree(6);
        let f: Sh<f64, 36> = project_fn(test_function, &quad);
        let rotated = ShRotation::from_quat(6, q).apply(&f);
        let qi = q.inverse();
        let projected: Sh<f64, 36> = project_fn(|w| test_function((qi * DVec3::from(w)).to_array()), &quad);
        for i in 0..36 {
            prop_assert!((rotated.0[i] - projected.0[i]).abs() < ROT_TOL);
        }
    }
}

/// The recurrence against the slow reference (quadrature of y_lm(ω) y_ln(R⁻¹ω)), per band.
#[test]
fn recurrence_matches_quadrature_reference() {
    for q in [quat(1.0, 2.0, 3.0, 0.7), quat(-0.3, 0.0, 1.0, 2.9), quat(0.0, 1.0, 0.0, -1.2)] {
        let r = DMat3::from_quat(q);
        let rot = ShRotation::from_mat3(9, r);
        for l in 0..9 {
            let want = band_matrix_by_quadrature(l, r);
            for (a, b) in rot.band(l).iter().zip(&want) {
                assert!((a - b).abs() < ROT_TOL, "l={l}: {a} vs {b}");
            }
        }
    }
}

/// Extending a cached rotation to more bands equals building at the higher order directly,
/// bit for bit (the same recurrence steps run in the same order).
#[test]
fn extension_equals_direct_build() {
    let q = quat(0.2, -0.9, 0.4, 1.1);
    let mut small = ShRotation::from_quat(3, q);
    small.extend_to(12);
    let big = ShRotation::from_quat(12, q);
    assert_eq!(small, big);
}

/// Rotating the basis itself: y(R⁻¹ω) expressed through the rotation gives the same values
/// as direct evaluation, also in f32 (in-place application).
#[test]
fn in_place_f32_application() {
    let q = quat(0.5, 0.5, -0.2, 0.9);
    let rot = ShRotation::from_quat(4, q);
    let f36: Sh<f64, 36> = project_fn(test_function, &SphereQuadrature::exact_for_degree(6));
    let f64c: Sh<f64, 16> = f36.resize();
    let mut f32c: [f32; 16] = f64c.0.map(|v| v as f32);
    rot.apply_in_place(&mut f32c);
    let want = rot.apply(&f64c);
    for i in 0..16 {
        // f32 storage: 16 products of O(1) values, relative 1e-6.
        assert!((f64::from(f32c[i]) - want.0[i]).abs() < 1e-6);
    }
    // Identity rotation is the identity.
    let id = ShRotation::from_quat(4, DQuat::IDENTITY);
    assert_eq!(id.apply(&f64c), f64c);
    let mut y = vec![0.0f64; 16];
    eval_into(4, [0.0, 0.0, 1.0], &mut y);
    assert!(y.iter().all(|v| v.is_finite()));
}
