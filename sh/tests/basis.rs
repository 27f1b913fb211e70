//! The SH basis: orthonormality by quadrature, the fast path
//! against the slow reference, and values against an independent mpmath oracle.

use lightvol_sh::eval::{MAX_FAST_BANDS, eval_basis, eval_into};
use lightvol_sh::index::sh_index;
use lightvol_sh::quadrature::SphereQuadrature;
use lightvol_sh::reference::sh_reference;
use proptest::prelude::*;

/// Gram matrix entries are sums of ~300 products of O(1) values computed by an exact rule:
/// f64 rounding alone, far below the 1e-12 allowed here.
const GRAM_TOL: f64 = 1e-12;
/// Fast vs reference in f64: both are exact formulas; differences are rounding (~1e-15).
const F64_TOL: f64 = 1e-12;
/// Fast f32 vs f64 reference, relative to the band's peak magnitude sqrt((2l+1)/4π):
/// f32 has a 6e-8 unit roundoff and the recurrence runs up to 8 steps.
const F32_REL_TOL: f64 = 1e-6;
/// Against the 25-digit mpmath oracle. The direction itself is rounded to f64 first.
const ORACLE_TOL: f64 = 1e-12;

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / n, v[1] / n, v[2] / n]
}

/// Every entry of G - I below 1e-12, all bands up to l = 8, exact quadrature.
#[test]
fn orthonormal_up_to_l8() {
    let bands = 9;
    let n = bands * bands;
    // Products have degree <= 16: 9 GL nodes and 17 azimuths are exact; use a margin.
    let quad = SphereQuadrature::exact_for_degree(2 * (bands - 1) + 2);
    let mut gram = vec![0.0; n * n];
    let mut y = vec![0.0; n];
    for node in quad.nodes() {
        eval_into(bands, node.dir, &mut y);
        for i in 0..n {
            for j in 0..n {
                gram[i * n + j] += node.weight * y[i] * y[j];
            }
        }
    }
    for i in 0..n {
        for j in 0..n {
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((gram[i * n + j] - want).abs() < GRAM_TOL, "G[{i}][{j}] = {}", gram[i * n + j]);
        }
    }
}

/// The reference itself is orthonormal too (a check on the oracle of
/// `fast_matches_reference`).
#[test]
fn reference_is_orthonormal_up_to_l4() {
    let quad = SphereQuadrature::exact_for_degree(10);
    for l1 in 0..5u32 {
        for m1 in -(l1 as i32)..=(l1 as i32) {
            for l2 in 0..5u32 {
                for m2 in -(l2 as i32)..=(l2 as i32) {
                    let g = quad.integrate(|d| sh_reference(l1, m1, d) * sh_reference(l2, m2, d));
                    let want = if (l1, m1) == (l2, m2) { 1.0 } else { 0.0 };
                    assert!((g - want).abs() < GRAM_TOL);
                }
            }
        }
    }
}

fn check_fast_against_reference(dir: [f64; 3]) {
    let mut fast64 = [0.0f64; 64];
    eval_into(MAX_FAST_BANDS, dir, &mut fast64);
    let dir32 = dir.map(|v| v as f32);
    let mut fast32 = [0.0f32; 64];
    eval_into(MAX_FAST_BANDS, dir32, &mut fast32);
    // The f32 path is checked against the f64 path at the *same* (f32-rounded) input, which
    // isolates its evaluation error. The f64 path is checked against the reference on the unit
    // sphere below, so together they bound the f32 path against the reference. (Comparing the
    // f32 path directly with the angle-based reference would mostly measure the input
    // rounding: the rounded vector is off unit length by ~1e-7, and near the poles y_l0 has a
    // slope of l(l+1)/2 · peak in z, i.e. a ~3e-6 relative change at l = 7 from input alone.)
    let dir32_64 = dir32.map(f64::from);
    let mut same_input64 = [0.0f64; 64];
    eval_into(MAX_FAST_BANDS, dir32_64, &mut same_input64);
    for l in 0..MAX_FAST_BANDS as u32 {
        let peak = ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt();
        for m in -(l as i32)..=(l as i32) {
            let i = sh_index(l, m);
            let r = sh_reference(l, m, dir);
            assert!((fast64[i] - r).abs() < F64_TOL, "f64 l={l} m={m}: {} vs {r}", fast64[i]);
            let rel = (f64::from(fast32[i]) - same_input64[i]).abs() / peak;
            assert!(rel < F32_REL_TOL, "f32 l={l} m={m}: rel err {rel:e} at {dir32:?}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, rng_seed: proptest::test_runner::RngSeed::Fixed(0x5EED), ..ProptestConfig::default() })]

    /// Fast path vs slow reference at random directions, every band it covers.
    #[test]
    fn fast_matches_reference(x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0) {
        let r2 = x * x + y * y + z * z;
        prop_assume!(r2 > 1e-6);
        check_fast_against_reference(unit([x, y, z]));
    }
}

#[test]
fn fast_matches_reference_at_poles_and_axes() {
    // Not closer to the pole than 1e-3: the reference goes through acos(z), whose absolute
    // error there is ~1e-16/θ, so at θ = 1e-9 the *reference* would be off by 5e-10.
    for d in [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [1e-3, 0.0, 1.0]] {
        check_fast_against_reference(unit(d));
    }
}

/// The fixed-size API returns the same values as the slice API.
#[test]
fn fixed_size_api_agrees() {
    let d = unit([0.2, 0.9, -0.3]);
    let mut all = [0.0f64; 64];
    eval_into(8, d, &mut all);
    let y9: [f64; 9] = eval_basis(d);
    let y36: [f64; 36] = eval_basis(d);
    assert_eq!(&all[..9], &y9[..]);
    assert_eq!(&all[..36], &y36[..]);
}

/// Values against the mpmath oracle (`tests/data/gen_sh_oracle.py`), l <= 8.
#[test]
fn matches_mpmath_oracle() {
    let text = include_str!("data/sh_oracle.txt");
    let mut checked = 0;
    let mut y = vec![0.0; 81];
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let f: Vec<&str> = line.split_whitespace().collect();
        let theta: f64 = f[0].parse().unwrap();
        let phi: f64 = f[1].parse().unwrap();
        let l: u32 = f[2].parse().unwrap();
        let m: i32 = f[3].parse().unwrap();
        let want: f64 = f[4].parse().unwrap();
        let dir = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
        eval_into(9, dir, &mut y);
        let got = y[sh_index(l, m)];
        assert!((got - want).abs() < ORACLE_TOL, "theta={theta} phi={phi} l={l} m={m}: {got} vs {want}");
        checked += 1;
    }
    assert_eq!(checked, 12 * 81, "oracle file incomplete");
}

/// The sign convention the crate promises: no Condon-Shortley phase, so
/// y_1,-1 ∝ +y, y_10 ∝ +z, y_11 ∝ +x with positive constants.
#[test]
fn convention_signs() {
    let c = (3.0 / (4.0 * std::f64::consts::PI)).sqrt();
    let y: [f64; 4] = eval_basis([0.0, 1.0, 0.0]);
    assert!((y[1] - c).abs() < 1e-15);
    let y: [f64; 4] = eval_basis([0.0, 0.0, 1.0]);
    assert!((y[2] - c).abs() < 1e-15);
    let y: [f64; 4] = eval_basis([1.0, 0.0, 0.0]);
    assert!((y[3] - c).abs() < 1e-15);
}
