//! Deterministic quadrature: Gauss-Legendre nodes and product rules over the sphere and the
//! upper hemisphere.
//!
//! A product rule with `n` Gauss-Legendre nodes in `z = cos θ` and `m` equally spaced
//! azimuths integrates exactly (to rounding) every polynomial in `(x, y, z)` of degree
//! `<= min(2n - 1, m - 1)` over the sphere: Gauss-Legendre is exact for polynomials of
//! degree `2n - 1` in `z`, and the trapezoid rule in `φ` is exact for trigonometric
//! polynomials of degree `< m`. A product of SH functions of degrees `l1` and `l2` is such a
//! polynomial of degree `l1 + l2`, which is why projections and Gram matrices computed here
//! are exact, not estimates.

use std::f64::consts::PI;

/// Gauss-Legendre nodes and weights on `[-1, 1]`, by Newton's method on `P_n` from the
/// Tricomi initial guesses, iterated to f64 convergence. Weights sum to 2.
///
/// # Panics
/// If `n == 0`.
#[must_use]
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    assert!(n > 0, "gauss_legendre needs at least one node");
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        // Initial guess (Tricomi), then Newton on P_n(x) = 0.
        let mut x = (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (p, d) = legendre_and_derivative(n, x);
            dp = d;
            let dx = p / d;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let (_, d) = legendre_and_derivative(n, x);
        dp = if d != 0.0 { d } else { dp };
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        nodes[i] = -x;
        nodes[n - 1 - i] = x;
        weights[i] = w;
        weights[n - 1 - i] = w;
    }
    if n % 2 == 1 {
        nodes[n / 2] = 0.0;
    }
    (nodes, weights)
}

/// `(P_n(x), P_n'(x))` by the Bonnet recurrence.
fn legendre_and_derivative(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    for k in 2..=n {
        let kf = k as f64;
        let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
        p0 = p1;
        p1 = p2;
    }
    let p = if n == 0 { 1.0 } else { p1 };
    let pm1 = if n == 0 { 0.0 } else { p0 };
    let d = n as f64 * (x * p - pm1) / (x * x - 1.0);
    (p, d)
}

/// One quadrature node: a unit direction and its weight (solid angle, steradians).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadNode {
    /// Unit direction.
    pub dir: [f64; 3],
    /// Weight; the weights of a sphere rule sum to `4π`, of a hemisphere rule to `2π`.
    pub weight: f64,
}

/// `Σ wᵢ f(dᵢ)` over `nodes`: the integral of `f` under any rule made of them (the sphere
/// rules here, lightvol-hemibasis's hemisphere rules).
#[must_use]
pub fn integrate(nodes: &[QuadNode], mut f: impl FnMut([f64; 3]) -> f64) -> f64 {
    nodes.iter().map(|n| n.weight * f(n.dir)).sum()
}

/// A product quadrature rule over the sphere (or the upper hemisphere).
#[derive(Clone, Debug)]
pub struct SphereQuadrature {
    nodes: Vec<QuadNode>,
}

impl SphereQuadrature {
    /// Full sphere: `n_theta` Gauss-Legendre nodes in `cos θ` times `n_phi` azimuths.
    #[must_use]
    pub fn sphere(n_theta: usize, n_phi: usize) -> Self {
        let (z, w) = gauss_legendre(n_theta);
        Self::from_z_rule(&z, &w, n_phi, 1.0, 0.0)
    }

    /// Upper hemisphere `z >= 0`: Gauss-Legendre mapped to `cos θ ∈ [0, 1]`.
    #[must_use]
    pub fn hemisphere(n_theta: usize, n_phi: usize) -> Self {
        let (z, w) = gauss_legendre(n_theta);
        Self::from_z_rule(&z, &w, n_phi, 0.5, 0.5)
    }

    /// The smallest sphere rule that integrates every product of two functions of degree
    /// `<= max_degree` exactly (total degree `2·max_degree`).
    #[must_use]
    pub fn exact_for_degree(max_degree: usize) -> Self {
        Self::sphere(max_degree + 1, 2 * max_degree + 1)
    }

    /// The nodes.
    #[must_use]
    pub fn nodes(&self) -> &[QuadNode] {
        &self.nodes
    }

    /// `∫ f dω` under this rule ([`integrate`]).
    #[must_use]
    pub fn integrate(&self, f: impl FnMut([f64; 3]) -> f64) -> f64 {
        integrate(&self.nodes, f)
    }

    fn from_z_rule(z: &[f64], w: &[f64], n_phi: usize, scale: f64, shift: f64) -> Self {
        let mut nodes = Vec::with_capacity(z.len() * n_phi);
        let dphi = 2.0 * PI / n_phi as f64;
        for (&zi, &wi) in z.iter().zip(w) {
            let cz = zi * scale + shift;
            let s = (1.0 - cz * cz).max(0.0).sqrt();
            for j in 0..n_phi {
                // Half-step offset keeps nodes off the seams of lat-long images.
                let phi = (j as f64 + 0.5) * dphi;
                nodes.push(QuadNode { dir: [s * phi.cos(), s * phi.sin(), cz], weight: wi * scale * dphi });
            }
        }
        Self { nodes }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rounding of a sum of a few dozen O(1) terms.
    const QUAD_TOL: f64 = 1e-14;

    #[test]
    fn gauss_legendre_integrates_monomials() {
        for n in 1..=20 {
            let (x, w) = gauss_legendre(n);
            for k in 0..(2 * n) {
                let exact = if k % 2 == 1 { 0.0 } else { 2.0 / (k as f64 + 1.0) };
                let got: f64 = x.iter().zip(&w).map(|(&x, &w)| w * x.powi(k as i32)).sum();
                assert!((got - exact).abs() < QUAD_TOL, "n={n} k={k}: {got} vs {exact}");
            }
        }
    }

    #[test]
    fn sphere_and_hemisphere_areas() {
        let s = SphereQuadrature::sphere(5, 9);
        assert!((s.integrate(|_| 1.0) - 4.0 * PI).abs() < QUAD_TOL);
        let h = SphereQuadrature::hemisphere(5, 9);
        assert!((h.integrate(|_| 1.0) - 2.0 * PI).abs() < QUAD_TOL);
        // ∫_{H} cos θ dω = π.
        assert!((h.integrate(|d| d[2]) - PI).abs() < QUAD_TOL);
        // ∫_{S²} x² dω = 4π/3.
        assert!((s.integrate(|d| d[0] * d[0]) - 4.0 * PI / 3.0).abs() < QUAD_TOL);
    }
}
