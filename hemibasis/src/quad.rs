//! Product quadrature over the upper hemisphere in the variable `u = sqrt(z)`.
//!
//! The shifted bases are not polynomials: HSH and Makhotkin functions carry `sqrt(z)` and
//! `sqrt(1 + z)` factors, Zernike functions `1/sqrt(1 + z)`. Their *Gram matrices* are
//! polynomial in `z` per azimuthal order, so the plain Gauss-Legendre × uniform-φ rule of
//! [`lightvol_sh::quadrature::SphereQuadrature::hemisphere`] integrates them exactly (the
//! orthonormality tests use that rule). Their inner products with SH functions, however,
//! contain `sqrt(z)` (a branch point at the rim, where plain Gauss-Legendre converges only
//! algebraically).
//!
//! Substituting `z = u²`, `dz = 2u du`, removes every `sqrt(z)`: the integrand becomes
//! analytic in `u` on `[0, 1]` with its nearest singularities at `u = ±i` (from `sqrt(1+u²)`),
//! so Gauss-Legendre in `u` converges geometrically, by a factor `≈ 4.6²` per node (Bernstein
//! ellipse through `±i` for `[0, 1]`); polynomials of degree `d` in `z` are integrated exactly
//! with `d + 1` nodes. With the sizes chosen here the rounding of the sum dominates
//! (the tests in this module compare two sizes).

use std::f64::consts::PI;

use lightvol_sh::quadrature::{QuadNode, gauss_legendre};

/// A product rule over the upper hemisphere: Gauss-Legendre in `u = sqrt(z)` times uniform
/// azimuths (trapezoid, exact for trigonometric polynomials of degree `< n_phi`).
#[derive(Clone, Debug)]
pub struct HemiRule {
    nodes: Vec<QuadNode>,
    n_u: usize,
    n_phi: usize,
}

impl HemiRule {
    /// `n_u` Gauss-Legendre nodes in `u = sqrt(z) ∈ [0, 1]` times `n_phi` azimuths.
    ///
    /// # Panics
    /// If either count is zero.
    #[must_use]
    pub fn new(n_u: usize, n_phi: usize) -> Self {
        assert!(n_u > 0 && n_phi > 0, "HemiRule needs at least one node per dimension");
        let (x, w) = gauss_legendre(n_u);
        let dphi = 2.0 * PI / n_phi as f64;
        let mut nodes = Vec::with_capacity(n_u * n_phi);
        for (&xi, &wi) in x.iter().zip(&w) {
            let u = 0.5 * (xi + 1.0);
            let z = u * u;
            // dω = dz dφ = 2u du dφ; du = dx / 2.
            let wz = wi * 0.5 * 2.0 * u;
            let s = ((1.0 - z) * (1.0 + z)).max(0.0).sqrt();
            for j in 0..n_phi {
                let phi = (j as f64 + 0.5) * dphi;
                nodes.push(QuadNode { dir: [s * phi.cos(), s * phi.sin(), z], weight: wz * dphi });
            }
        }
        Self { nodes, n_u, n_phi }
    }

    /// A rule for products of two functions of orders `a` and `b` (band or radial order):
    /// polynomial parts up to degree `2(a + b)` in `z` are integrated exactly and the
    /// non-polynomial factors of the shifted bases converge to rounding (module docs).
    #[must_use]
    pub fn for_orders(a: usize, b: usize) -> Self {
        Self::new(2 * (a + b) + 24, 2 * (a + b) + 8)
    }

    /// The default rule for projecting arbitrary (smooth) functions: 64 × 128 nodes.
    #[must_use]
    pub fn for_functions() -> Self {
        Self::new(64, 128)
    }

    /// Gauss-Legendre node count in `u`.
    #[must_use]
    pub fn n_u(&self) -> usize {
        self.n_u
    }

    /// Azimuth count.
    #[must_use]
    pub fn n_phi(&self) -> usize {
        self.n_phi
    }

    /// The nodes (directions with `z >= 0`, weights in steradians summing to `2π`).
    #[must_use]
    pub fn nodes(&self) -> &[QuadNode] {
        &self.nodes
    }

    /// `∫_H f dω` under this rule (lightvol-sh's `quadrature::integrate`).
    #[must_use]
    pub fn integrate(&self, f: impl FnMut([f64; 3]) -> f64) -> f64 {
        lightvol_sh::quadrature::integrate(&self.nodes, f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sum of a few hundred O(1) terms rounds at a few ulps of 2π.
    const SUM_TOL: f64 = 1e-13;

    #[test]
    fn integrates_polynomials_and_square_roots_exactly() {
        let r = HemiRule::new(12, 9);
        assert!((r.integrate(|_| 1.0) - 2.0 * PI).abs() < SUM_TOL);
        // ∫_H z^k dω = 2π/(k+1).
        for k in 0..10 {
            let got = r.integrate(|d| d[2].powi(k));
            assert!((got - 2.0 * PI / f64::from(k + 1)).abs() < SUM_TOL, "k={k}: {got}");
        }
        // ∫_H sqrt(z) dω = 2π · 2/3: exact only because of the u = sqrt(z) substitution.
        let got = r.integrate(|d| d[2].sqrt());
        assert!((got - 4.0 * PI / 3.0).abs() < SUM_TOL);
        // ∫_H x² dω = 2π/3.
        assert!((r.integrate(|d| d[0] * d[0]) - 2.0 * PI / 3.0).abs() < SUM_TOL);
    }

    #[test]
    fn analytic_non_polynomial_integrand_converges() {
        // ∫_H sqrt(z (1 + z)) dω has no polynomial form; two rule sizes must agree to rounding.
        let f = |d: [f64; 3]| (d[2] * (1.0 + d[2])).sqrt() * (1.0 - d[2]);
        let a = HemiRule::new(24, 4).integrate(f);
        let b = HemiRule::new(48, 4).integrate(f);
        assert!((a - b).abs() < SUM_TOL, "{a} vs {b}");
    }
}
