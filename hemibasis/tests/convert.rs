//! Converting SH irradiance to each basis equals the least-squares
//! projection of the SH irradiance function, checked by quadrature; plus f32/f64 agreement
//! and the RGB variants.

use lightvol_hemibasis::imse::{signal, table_bases};
use lightvol_hemibasis::project::Matrix;
use lightvol_hemibasis::{HemiBasis, HemiRule, Projector, ShBasis};
use lightvol_sh::quadrature::SphereQuadrature;

/// Conversion matrix vs. projection with the default fine rule: both exact to rounding.
const SAME_RULE_TOL: f64 = 1e-12;

/// Conversion matrix vs. an independent projection with the *plain* Gauss-Legendre
/// hemisphere rule of lightvol-sh (300 nodes in z): the `sqrt(z)` factors of HSH and
/// Makhotkin make plain Gauss-Legendre converge only algebraically (≈ n^-3), so this
/// cross-check is good to ~1e-7, not to rounding.
const PLAIN_GL_TOL: f64 = 1e-6;

/// f32 vs. f64 evaluation of O(1) values with a few dozen operations.
const F32_TOL: f64 = 2e-6;

fn irradiance(e: &[f64]) -> impl Fn([f64; 3]) -> f64 + '_ {
    let sh = ShBasis::new(3);
    move |d| sh.reconstruct_f64(e, d)
}

#[test]
fn conversion_equals_least_squares_projection() {
    for b in table_bases() {
        let m = b.sh_irradiance_matrix(3);
        let proj = Projector::new(b.as_ref(), HemiRule::for_functions());
        for s in 0..3 {
            let e = signal(11, s);
            let f = irradiance(&e);
            let via_matrix = b.convert_sh_irradiance(&e);
            assert_eq!(via_matrix, m.mul_vec(&e));
            let via_projection = proj.project(&f);
            for (a, c) in via_matrix.iter().zip(&via_projection) {
                assert!((a - c).abs() < SAME_RULE_TOL, "{}: {a} vs {c}", b.tag());
            }
            // Independent: plain GL rule, own Gram matrix and normal equations.
            let q = SphereQuadrature::hemisphere(300, 16);
            let k = b.len();
            let mut g = Matrix::zeros(k, k);
            let mut rhs = vec![0.0; k];
            let mut v = vec![0.0; k];
            for node in q.nodes() {
                b.eval_f64(node.dir, &mut v);
                let fv = f(node.dir);
                for i in 0..k {
                    rhs[i] += node.weight * fv * v[i];
                    for j in 0..k {
                        g[(i, j)] += node.weight * v[i] * v[j];
                    }
                }
            }
            let c = g.spd_inverse().unwrap().mul_vec(&rhs);
            for (a, c) in via_matrix.iter().zip(&c) {
                assert!((a - c).abs() < PLAIN_GL_TOL, "{}: {a} vs {c}", b.tag());
            }
        }
    }
}

#[test]
fn rgb_variants_are_per_channel() {
    for b in table_bases() {
        let e: Vec<[f64; 3]> = {
            let (r, g, bl) = (signal(1, 0), signal(1, 1), signal(1, 2));
            (0..9).map(|j| [r[j], g[j], bl[j]]).collect()
        };
        let c = b.convert_sh_irradiance_rgb(&e);
        let proj = b.project_rgb(&|d| {
            let sh = ShBasis::new(3);
            let mut y = [0.0; 9];
            sh.eval_f64(d, &mut y);
            let mut out = [0.0; 3];
            for j in 0..9 {
                for ch in 0..3 {
                    out[ch] += e[j][ch] * y[j];
                }
            }
            out
        });
        for ch in 0..3 {
            let single: Vec<f64> = e.iter().map(|v| v[ch]).collect();
            let cs = b.convert_sh_irradiance(&single);
            for i in 0..b.len() {
                assert!((c[i][ch] - cs[i]).abs() < SAME_RULE_TOL);
                assert!((proj[i][ch] - cs[i]).abs() < SAME_RULE_TOL);
            }
        }
        let d = [0.3, -0.4, (1.0f64 - 0.25).sqrt()];
        let rgb = b.reconstruct_rgb_f64(&c, d);
        let c32: Vec<[f32; 3]> = c.iter().map(|v| v.map(|x| x as f32)).collect();
        let rgb32 = b.reconstruct_rgb_f32(&c32, d.map(|x| x as f32));
        for ch in 0..3 {
            let single: Vec<f64> = c.iter().map(|v| v[ch]).collect();
            assert!((rgb[ch] - b.reconstruct_f64(&single, d)).abs() < SAME_RULE_TOL);
            assert!((f64::from(rgb32[ch]) - rgb[ch]).abs() < 10.0 * F32_TOL);
        }
    }
}

#[test]
fn f32_matches_f64() {
    let mut bases = table_bases();
    for name in ["hsh", "makhotkin"] {
        bases.extend(lightvol_hemibasis::by_name(name, 16));
    }
    bases.extend(lightvol_hemibasis::by_name("zernike", 10));
    for b in bases {
        let (mut v64, mut v32) = (vec![0.0f64; b.len()], vec![0.0f32; b.len()]);
        for i in 0..=10 {
            for j in 0..7 {
                let z = f64::from(i) / 10.0;
                let phi = f64::from(j) * 0.9;
                let s = (1.0 - z * z).sqrt();
                let d = [s * phi.cos(), s * phi.sin(), z];
                b.eval_f64(d, &mut v64);
                b.eval_f32(d.map(|x| x as f32), &mut v32);
                for k in 0..b.len() {
                    let scale = 1.0 + v64[k].abs();
                    assert!(
                        (f64::from(v32[k]) - v64[k]).abs() < F32_TOL * scale,
                        "{} B{k} at {d:?}",
                        b.tag()
                    );
                }
            }
        }
    }
}

#[test]
fn by_name_rejects_unknown_sizes() {
    assert!(lightvol_hemibasis::by_name("sh", 5).is_none());
    assert!(lightvol_hemibasis::by_name("nope", 4).is_none());
    assert_eq!(lightvol_hemibasis::by_name("sh", 9).map(|b| b.len()), Some(9));
}
