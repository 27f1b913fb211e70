//! Shared test helpers: test directions and the orthonormality check.

use lightvol_sh::quadrature::SphereQuadrature;

use crate::basis::HemiBasis;

/// Unit directions on the closed upper hemisphere, including the pole and the rim.
pub(crate) const TEST_DIRS: &[[f64; 3]] = &[
    [0.0, 0.0, 1.0],
    [0.6, -0.48, 0.64],
    [-0.8, 0.0, 0.6],
    [0.28, 0.96, 0.0],
    [-0.36, -0.48, 0.8],
    [0.0, -0.6, 0.8],
    [0.96, 0.0, 0.28],
    [-0.6, 0.8, 0.0],
];

/// Orthonormality: `|G - I| < 1e-10` by the exact Gauss-Legendre × uniform-φ rule.
/// The Gram integrands of every basis here are polynomials in `z` per azimuthal order (see
/// `crate::quad`), so the rule is exact and only rounding remains (~1e-15); 1e-10 leaves
/// room for that rounding.
pub(crate) const GRAM_TOL: f64 = 1e-10;

/// The Gram matrix by lightvol-sh's plain hemisphere rule (independent of `crate::quad`).
pub(crate) fn gram_gl(b: &dyn HemiBasis) -> Vec<Vec<f64>> {
    let l = b.order();
    let q = SphereQuadrature::hemisphere(2 * l + 4, 4 * l + 4);
    let k = b.len();
    let mut g = vec![vec![0.0; k]; k];
    let mut v = vec![0.0; k];
    for node in q.nodes() {
        b.eval_f64(node.dir, &mut v);
        for i in 0..k {
            for j in 0..k {
                g[i][j] += node.weight * v[i] * v[j];
            }
        }
    }
    g
}

/// Asserts `|G - I| < GRAM_TOL` entrywise.
#[cfg_attr(
    not(any(
        feature = "hl2",
        feature = "hsh",
        feature = "makhotkin",
        feature = "zernike",
        feature = "hbasis"
    )),
    allow(dead_code)
)]
pub(crate) fn assert_orthonormal(b: &dyn HemiBasis) {
    let g = gram_gl(b);
    for (i, row) in g.iter().enumerate() {
        for (j, &gij) in row.iter().enumerate() {
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((gij - want).abs() < GRAM_TOL, "{} K={}: G[{i}][{j}] = {gij}", b.name(), b.len());
        }
    }
}
