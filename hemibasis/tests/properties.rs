//! Property tests over random hemisphere directions and random signals: fast evaluation vs.
//! the slow angle-form references, f32 vs. f64, and linearity of projection.

use lightvol_hemibasis::imse::table_bases;
use lightvol_hemibasis::{HemiBasis, HemiRule, Projector, ShBasis};
use proptest::prelude::*;

/// Cartesian separable form vs. angle form (acos/atan2/cos/powf): rounding.
const FORM_TOL: f64 = 1e-11;

/// f32 vs. f64 on O(1) values through a few dozen operations.
const F32_TOL: f64 = 3e-6;

/// Projection is a fixed linear map; rounding of a ~8,000-term sum.
const LINEAR_TOL: f64 = 1e-11;

/// A unit direction with `z >= 0` from two uniforms (uniform on the hemisphere).
fn dir(u: f64, v: f64) -> [f64; 3] {
    let z = u;
    let s = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * v;
    [s * phi.cos(), s * phi.sin(), z]
}

fn close(a: &[f64], b: &[f64], tol: f64) -> Result<(), TestCaseError> {
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        prop_assert!((x - y).abs() < tol * (1.0 + y.abs()), "B{}: {} vs {}", i, x, y);
    }
    Ok(())
}

proptest! {
    #[test]
    fn fast_matches_reference(u in 0.0f64..=1.0, v in 0.0f64..1.0) {
        let d = dir(u, v);
        #[cfg(feature = "hsh")]
        {
            let b = lightvol_hemibasis::Hsh::new(5);
            let mut out = vec![0.0; b.len()];
            b.eval_f64(d, &mut out);
            close(&out, &b.reference(d), FORM_TOL)?;
        }
        #[cfg(feature = "makhotkin")]
        {
            let b = lightvol_hemibasis::Makhotkin::new(5);
            let mut out = vec![0.0; b.len()];
            b.eval_f64(d, &mut out);
            close(&out, &b.reference(d), FORM_TOL)?;
        }
        #[cfg(feature = "zernike")]
        {
            let b = lightvol_hemibasis::Zernike::new(5);
            let mut out = vec![0.0; b.len()];
            b.eval_f64(d, &mut out);
            close(&out, &b.reference(d), FORM_TOL)?;
        }
        #[cfg(feature = "hbasis")]
        for b in [lightvol_hemibasis::HBasis::new(6).unwrap(), lightvol_hemibasis::HBasis::modified(6).unwrap()] {
            let mut out = vec![0.0; 6];
            b.eval_f64(d, &mut out);
            close(&out, &b.reference(d), FORM_TOL)?;
        }
        let sh = ShBasis::new(4);
        let mut out = vec![0.0; 16];
        sh.eval_f64(d, &mut out);
        let r = lightvol_sh::reference::sh_reference_all(4, d);
        close(&out, &r, FORM_TOL)?;
    }

    #[test]
    fn f32_matches_f64(u in 0.0f64..=1.0, v in 0.0f64..1.0) {
        let d = dir(u, v);
        let d32 = d.map(|x| x as f32);
        for b in table_bases() {
            let (mut a, mut c) = (vec![0.0f64; b.len()], vec![0.0f32; b.len()]);
            // Compare at the f32-rounded direction so only the evaluation differs.
            b.eval_f64(d32.map(f64::from), &mut a);
            b.eval_f32(d32, &mut c);
            let c: Vec<f64> = c.iter().map(|&x| f64::from(x)).collect();
            close(&c, &a, F32_TOL)?;
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]
    #[test]
    fn projection_is_linear(a in -2.0f64..2.0, b in -2.0f64..2.0, k in 0usize..13) {
        let bases = table_bases();
        let basis = &bases[k % bases.len()];
        let p = Projector::new(basis.as_ref(), HemiRule::new(32, 24));
        let f = |d: [f64; 3]| (3.0 * d[0] - d[2]).exp() * 0.1;
        let g = |d: [f64; 3]| d[1] * d[2] + 0.3;
        let pf = p.project(&f);
        let pg = p.project(&g);
        let pfg = p.project(&|d| a * f(d) + b * g(d));
        let want: Vec<f64> = pf.iter().zip(&pg).map(|(x, y)| a * x + b * y).collect();
        close(&pfg, &want, LINEAR_TOL)?;
    }
}
