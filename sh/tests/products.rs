//! Gaunt coefficients and SH products.

use lightvol_sh::coeffs::Sh;
use lightvol_sh::gaunt::{GauntTable, product, product_matrix, real_gaunt};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::project::project_fn;
use lightvol_sh::quadrature::SphereQuadrature;

/// Closed-form Gaunt values vs exact quadrature: both accurate to f64 rounding of O(1) sums.
const GAUNT_TOL: f64 = 1e-13;

#[test]
fn gaunt_equals_quadrature_of_triple_products() {
    let bands = 5;
    let n = bands * bands;
    // Triple products of degree <= 3·4 = 12: exact with 7 GL nodes and 13 azimuths.
    let quad = SphereQuadrature::exact_for_degree(6);
    let ys: Vec<(f64, Vec<f64>)> = quad
        .nodes()
        .iter()
        .map(|node| {
            let mut y = vec![0.0; n];
            lightvol_sh::eval_into(bands, node.dir, &mut y);
            (node.weight, y)
        })
        .collect();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let q: f64 = ys.iter().map(|(w, y)| w * y[i] * y[j] * y[k]).sum();
                let g = real_gaunt(i, j, k);
                assert!((g - q).abs() < GAUNT_TOL, "G[{i}][{j}][{k}] = {g} vs quadrature {q}");
            }
        }
    }
}

/// The number of non-zero real Gaunt coefficients over ordered triples (i, j, k) < bands².
#[test]
fn non_zero_counts_match_theory() {
    let counts: Vec<usize> = (2..=5).map(|b| GauntTable::new(b).entries().len()).collect();
    assert_eq!(counts, vec![10, 83, 353, 1158]);
}

#[test]
fn product_equals_projected_pointwise_product() {
    let mut rng = SplitMix64::new(3);
    let f = Sh::<f64, 36>(core::array::from_fn(|_| rng.range(-1.0, 1.0)));
    let g = Sh::<f64, 36>(core::array::from_fn(|_| rng.range(-1.0, 1.0)));
    // f·g has degree 10; projecting it onto degree 5 needs exactness for degree 15.
    let quad = SphereQuadrature::exact_for_degree(8);
    let want: Sh<f64, 36> = project_fn(|w| f.eval(w) * g.eval(w), &quad);
    let got = product(&f, &g);
    for k in 0..36 {
        assert!((got.0[k] - want.0[k]).abs() < 1e-12, "coeff {k}");
    }
    // Product matrix: M_f g = f * g, and M_f is symmetric.
    let m = product_matrix(&f);
    for k in 0..36 {
        let v: f64 = (0..36).map(|j| m[k * 36 + j] * g.0[j]).sum();
        assert!((v - got.0[k]).abs() < 1e-12);
        for j in 0..36 {
            assert!((m[k * 36 + j] - m[j * 36 + k]).abs() < 1e-15);
        }
    }
    // f32 path agrees with f64 to f32 precision (36 terms of O(1), relative 1e-5).
    let got32 = product(&f.cast::<f32>(), &g.cast::<f32>());
    for k in 0..36 {
        assert!((f64::from(got32.0[k]) - got.0[k]).abs() < 1e-5);
    }
}
