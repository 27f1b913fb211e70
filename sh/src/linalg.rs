//! Small dense linear algebra on row-major `Vec<f64>` matrices: Cholesky solves (least-squares
//! fits) and the cyclic Jacobi eigen-decomposition of symmetric matrices (SH exponentials
//! through the product matrix). Sizes here are at most a few hundred, where these textbook
//! methods are accurate and fast enough; no external crate needed.

/// Solves `A x = b` for a symmetric positive-definite `n × n` matrix `A` (row-major) by
/// Cholesky factorisation. Returns `None` when `A` is not numerically positive definite.
#[must_use]
pub fn cholesky_solve(a: &[f64], b: &[f64], n: usize) -> Option<Vec<f64>> {
    assert_eq!(b.len(), n, "rhs size");
    Some(cholesky_substitute(&cholesky_factor(a, n)?, b, n))
}

/// The Cholesky factor `L` (row-major, lower triangular, `A = L Lᵀ`) of a symmetric
/// positive-definite `n × n` matrix `A` (row-major); `None` when a pivot is not positive
/// (not SPD, or singular to working precision) or not finite.
#[must_use]
pub fn cholesky_factor(a: &[f64], n: usize) -> Option<Vec<f64>> {
    assert_eq!(a.len(), n * n, "matrix size");
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                if s <= 0.0 || !s.is_finite() {
                    return None;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    Some(l)
}

/// Solves `L Lᵀ x = b` with a factor from [`cholesky_factor`]: forward, then back
/// substitution.
#[must_use]
pub fn cholesky_substitute(l: &[f64], b: &[f64], n: usize) -> Vec<f64> {
    assert_eq!(l.len(), n * n, "factor size");
    assert_eq!(b.len(), n, "rhs size");
    let mut y = vec![0.0; n];
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * n + k] * y[k];
        }
        y[i] = s / l[i * n + i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let mut s = y[i];
        for k in (i + 1)..n {
            s -= l[k * n + i] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
    x
}

/// Eigen-decomposition of a symmetric `n × n` matrix by cyclic Jacobi rotations:
/// returns `(eigenvalues, eigenvectors)` with eigenvector `k` in column `k` of the row-major
/// matrix, so that `A = V diag(λ) Vᵀ`. Converges quadratically; sweeps stop when the
/// off-diagonal norm falls below `1e-15` of the matrix norm.
#[must_use]
pub fn symmetric_eigen(a: &[f64], n: usize) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(a.len(), n * n, "matrix size");
    let mut m = a.to_vec();
    let mut v = vec![0.0; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    let norm: f64 = m.iter().map(|x| x * x).sum::<f64>().sqrt();
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| m[i * n + j].powi(2))
            .sum::<f64>()
            .sqrt();
        if off <= 1e-15 * norm.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..n {
            for q in (p + 1)..n {
                let apq = m[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let app = m[p * n + p];
                let aqq = m[q * n + q];
                let theta = (aqq - app) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let mkp = m[k * n + p];
                    let mkq = m[k * n + q];
                    m[k * n + p] = c * mkp - s * mkq;
                    m[k * n + q] = s * mkp + c * mkq;
                }
                for k in 0..n {
                    let mpk = m[p * n + k];
                    let mqk = m[q * n + k];
                    m[p * n + k] = c * mpk - s * mqk;
                    m[q * n + k] = s * mpk + c * mqk;
                }
                for k in 0..n {
                    let vkp = v[k * n + p];
                    let vkq = v[k * n + q];
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ((0..n).map(|i| m[i * n + i]).collect(), v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves() {
        let a = [4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0];
        let x = [1.0, -2.0, 0.5];
        let b: Vec<f64> = (0..3).map(|i| (0..3).map(|j| a[i * 3 + j] * x[j]).sum()).collect();
        let got = cholesky_solve(&a, &b, 3).unwrap();
        for i in 0..3 {
            assert!((got[i] - x[i]).abs() < 1e-14);
        }
        assert!(cholesky_solve(&[1.0, 2.0, 2.0, 1.0], &[1.0, 1.0], 2).is_none());
        // The factor is lower triangular with L Lᵀ = A; by hand, L₀₀ = 2 and L₁₀ = 1.
        let l = cholesky_factor(&a, 3).unwrap();
        assert_eq!((l[0], l[3], l[1], l[2], l[5]), (2.0, 1.0, 0.0, 0.0, 0.0));
        for i in 0..3 {
            for j in 0..3 {
                let r: f64 = (0..3).map(|k| l[i * 3 + k] * l[j * 3 + k]).sum();
                assert!((r - a[i * 3 + j]).abs() < 1e-14);
            }
        }
        assert!(cholesky_factor(&[f64::NAN], 1).is_none());
    }

    #[test]
    fn eigen_reconstructs() {
        let a = [2.0, -1.0, 0.0, 0.5, -1.0, 2.0, -1.0, 0.0, 0.0, -1.0, 2.0, 0.3, 0.5, 0.0, 0.3, 1.0];
        let n = 4;
        let (l, v) = symmetric_eigen(&a, n);
        for i in 0..n {
            for j in 0..n {
                let r: f64 = (0..n).map(|k| v[i * n + k] * l[k] * v[j * n + k]).sum();
                assert!((r - a[i * n + j]).abs() < 1e-13);
                let o: f64 = (0..n).map(|k| v[k * n + i] * v[k * n + j]).sum();
                assert!((o - if i == j { 1.0 } else { 0.0 }).abs() < 1e-13);
            }
        }
    }
}
