//! Least-squares projection onto a basis over the upper hemisphere.
//!
//! For functions `B_i` with Gram matrix `G_ij = ∫_H B_i B_j dω`, the coefficients `c` that
//! minimise `∫_H (Σ c_i B_i - f)² dω` solve the normal equations `G c = b`,
//! `b_i = ∫_H f B_i dω`. For an orthonormal basis `G = I` and `c = b`; the modified H-basis
//! and SH on the hemisphere need `G⁻¹`, computed here by Cholesky factorisation.

use crate::basis::HemiBasis;
use crate::quad::HemiRule;

/// A small dense row-major matrix of `f64`.
#[derive(Clone, Debug, PartialEq)]
pub struct Matrix {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

impl Matrix {
    /// The `rows × cols` zero matrix.
    #[must_use]
    pub fn zeros(rows: usize, cols: usize) -> Self {
        Self { rows, cols, data: vec![0.0; rows * cols] }
    }

    /// The `n × n` identity.
    #[must_use]
    pub fn identity(n: usize) -> Self {
        let mut m = Self::zeros(n, n);
        for i in 0..n {
            m[(i, i)] = 1.0;
        }
        m
    }

    /// Row count.
    #[must_use]
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Column count.
    #[must_use]
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Row `i` as a slice.
    #[must_use]
    pub fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.cols..(i + 1) * self.cols]
    }

    /// `self · other`.
    ///
    /// # Panics
    /// If the inner dimensions differ.
    #[must_use]
    pub fn mul(&self, other: &Matrix) -> Matrix {
        assert_eq!(self.cols, other.rows, "matrix product dimension mismatch");
        let mut out = Matrix::zeros(self.rows, other.cols);
        for i in 0..self.rows {
            for k in 0..self.cols {
                let a = self[(i, k)];
                for j in 0..other.cols {
                    out[(i, j)] += a * other[(k, j)];
                }
            }
        }
        out
    }

    /// `self · v`.
    ///
    /// # Panics
    /// If `v.len() != cols`.
    #[must_use]
    pub fn mul_vec(&self, v: &[f64]) -> Vec<f64> {
        assert_eq!(v.len(), self.cols, "matrix-vector dimension mismatch");
        (0..self.rows).map(|i| self.row(i).iter().zip(v).map(|(a, b)| a * b).sum()).collect()
    }

    /// `self · v` for coefficient-major RGB vectors.
    ///
    /// # Panics
    /// If `v.len() != cols`.
    #[must_use]
    pub fn mul_rgb(&self, v: &[[f64; 3]]) -> Vec<[f64; 3]> {
        assert_eq!(v.len(), self.cols, "matrix-vector dimension mismatch");
        (0..self.rows)
            .map(|i| {
                let mut out = [0.0; 3];
                for (a, c) in self.row(i).iter().zip(v) {
                    for ch in 0..3 {
                        out[ch] += a * c[ch];
                    }
                }
                out
            })
            .collect()
    }

    /// Transpose.
    #[must_use]
    pub fn transpose(&self) -> Matrix {
        let mut out = Matrix::zeros(self.cols, self.rows);
        for i in 0..self.rows {
            for j in 0..self.cols {
                out[(j, i)] = self[(i, j)];
            }
        }
        out
    }

    /// Largest absolute entry of `self - other`.
    ///
    /// # Panics
    /// If the shapes differ.
    #[must_use]
    pub fn max_abs_diff(&self, other: &Matrix) -> f64 {
        assert_eq!((self.rows, self.cols), (other.rows, other.cols), "shape mismatch");
        self.data.iter().zip(&other.data).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
    }

    /// Inverse of a symmetric positive-definite matrix by Cholesky factorisation
    /// (`lightvol_sh::linalg`), column by column; `None` if a pivot is not positive (not SPD,
    /// or singular to working precision).
    #[must_use]
    pub fn spd_inverse(&self) -> Option<Matrix> {
        assert_eq!(self.rows, self.cols, "inverse of a non-square matrix");
        let n = self.rows;
        let l = lightvol_sh::linalg::cholesky_factor(&self.data, n)?;
        let mut inv = Matrix::zeros(n, n);
        let mut e = vec![0.0; n];
        for c in 0..n {
            e[c] = 1.0;
            for (i, x) in lightvol_sh::linalg::cholesky_substitute(&l, &e, n).into_iter().enumerate() {
                inv[(i, c)] = x;
            }
            e[c] = 0.0;
        }
        Some(inv)
    }
}

impl core::ops::Index<(usize, usize)> for Matrix {
    type Output = f64;
    fn index(&self, (i, j): (usize, usize)) -> &f64 {
        &self.data[i * self.cols + j]
    }
}

impl core::ops::IndexMut<(usize, usize)> for Matrix {
    fn index_mut(&mut self, (i, j): (usize, usize)) -> &mut f64 {
        &mut self.data[i * self.cols + j]
    }
}

/// Basis values at every node of `rule`: row `k` holds `B_i(ω_k)`.
#[must_use]
pub fn basis_table(basis: &dyn HemiBasis, rule: &HemiRule) -> Matrix {
    let k = basis.len();
    let mut t = Matrix::zeros(rule.nodes().len(), k);
    for (r, node) in rule.nodes().iter().enumerate() {
        basis.eval_f64(node.dir, &mut t.data[r * k..(r + 1) * k]);
    }
    t
}

/// `G_ij = ∫_H B_i B_j dω` under `rule`.
#[must_use]
pub fn gram(basis: &dyn HemiBasis, rule: &HemiRule) -> Matrix {
    cross_gram(basis, basis, rule)
}

/// `C_ij = ∫_H A_i B_j dω` under `rule`.
#[must_use]
pub fn cross_gram(a: &dyn HemiBasis, b: &dyn HemiBasis, rule: &HemiRule) -> Matrix {
    let ta = basis_table(a, rule);
    let tb = basis_table(b, rule);
    let mut c = Matrix::zeros(a.len(), b.len());
    for (r, node) in rule.nodes().iter().enumerate() {
        let (ra, rb) = (ta.row(r), tb.row(r));
        for i in 0..a.len() {
            let wa = node.weight * ra[i];
            for j in 0..b.len() {
                c[(i, j)] += wa * rb[j];
            }
        }
    }
    c
}

/// The inverse Gram matrix of `basis` (identity for an orthonormal basis).
///
/// # Panics
/// If the Gram matrix is not positive definite (the functions are linearly dependent), which
/// no basis in this crate is.
#[must_use]
pub fn gram_inverse(basis: &dyn HemiBasis) -> Matrix {
    if basis.orthonormal() {
        Matrix::identity(basis.len())
    } else {
        basis.gram().spd_inverse().expect("basis functions are linearly independent on the hemisphere")
    }
}

/// The fitting methods of every basis (\[Ish11\] §2.2.1): its Gram matrix and least-squares
/// projection, here beside [`Projector`] and [`gram`]. Call them on a `dyn HemiBasis`
/// (`Box<dyn HemiBasis>` or [`HemiBasis::as_dyn`]).
impl dyn HemiBasis + '_ {
    /// The Gram matrix `G_ij = ∫_H B_i B_j dω`, by a quadrature exact for the basis (see
    /// [`HemiRule::for_orders`]).
    #[must_use]
    pub fn gram(&self) -> Matrix {
        gram(self, &HemiRule::for_orders(self.order(), 0))
    }

    /// Least-squares projection of an arbitrary function `f` on the upper hemisphere:
    /// `c = G⁻¹ b`, `b_i = ∫_H f B_i dω`, by [`HemiRule::for_functions`] (a fine product rule;
    /// use [`Projector`] to choose the rule or to project many functions).
    #[must_use]
    pub fn project(&self, f: &dyn Fn([f64; 3]) -> f64) -> Vec<f64> {
        Projector::new(self, HemiRule::for_functions()).project(f)
    }

    /// The least-squares projection (`project`) per colour channel.
    #[must_use]
    pub fn project_rgb(&self, f: &dyn Fn([f64; 3]) -> [f64; 3]) -> Vec<[f64; 3]> {
        Projector::new(self, HemiRule::for_functions()).project_rgb(f)
    }
}

/// Least-squares projector for one basis and one quadrature rule: caches the basis table and
/// the inverse Gram matrix, so projecting many functions costs one pass over the nodes each.
#[derive(Clone, Debug)]
pub struct Projector {
    rule: HemiRule,
    table: Matrix,
    gram_inv: Matrix,
}

impl Projector {
    /// Projector for `basis` under `rule`.
    #[must_use]
    pub fn new(basis: &dyn HemiBasis, rule: HemiRule) -> Self {
        let table = basis_table(basis, &rule);
        Self { rule, table, gram_inv: gram_inverse(basis) }
    }

    /// The inner products `b_i = ∫_H f B_i dω` (before the Gram inverse).
    #[must_use]
    pub fn inner_products(&self, f: &dyn Fn([f64; 3]) -> f64) -> Vec<f64> {
        let k = self.table.cols();
        let mut b = vec![0.0; k];
        for (r, node) in self.rule.nodes().iter().enumerate() {
            let wf = node.weight * f(node.dir);
            for (bi, t) in b.iter_mut().zip(self.table.row(r)) {
                *bi += wf * t;
            }
        }
        b
    }

    /// Least-squares coefficients `G⁻¹ b`.
    #[must_use]
    pub fn project(&self, f: &dyn Fn([f64; 3]) -> f64) -> Vec<f64> {
        self.gram_inv.mul_vec(&self.inner_products(f))
    }

    /// Least-squares coefficients per colour channel.
    #[must_use]
    pub fn project_rgb(&self, f: &dyn Fn([f64; 3]) -> [f64; 3]) -> Vec<[f64; 3]> {
        let k = self.table.cols();
        let mut b = vec![[0.0; 3]; k];
        for (r, node) in self.rule.nodes().iter().enumerate() {
            let v = f(node.dir);
            for (bi, t) in b.iter_mut().zip(self.table.row(r)) {
                for ch in 0..3 {
                    bi[ch] += node.weight * v[ch] * t;
                }
            }
        }
        self.gram_inv.mul_rgb(&b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cholesky inverse of a well-conditioned 3×3 matrix: rounding only.
    const INV_TOL: f64 = 1e-14;

    #[test]
    fn spd_inverse_inverts() {
        let mut g = Matrix::zeros(3, 3);
        let vals = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.25], [0.5, 0.25, 2.0]];
        for i in 0..3 {
            for j in 0..3 {
                g[(i, j)] = vals[i][j];
            }
        }
        let inv = g.spd_inverse().unwrap();
        assert!(g.mul(&inv).max_abs_diff(&Matrix::identity(3)) < INV_TOL);
        let mut bad = g.clone();
        bad[(2, 2)] = -1.0;
        assert!(bad.spd_inverse().is_none());
    }
}
