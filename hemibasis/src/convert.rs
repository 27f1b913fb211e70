//! SH irradiance → hemispherical basis, the least-squares fit over the upper hemisphere.
//!
//! Given SH irradiance coefficients `e` (lightvol-sh order and normalisation), the function
//! `E = Σ e_j y_j` restricted to `z >= 0` is fitted by `c = G⁻¹ C e` with
//! `C_ij = ∫_H B_i y_j dω`. The matrix `M = G⁻¹ C` is derived by quadrature
//! ([`HemiRule::for_orders`], exact to rounding for every basis here; see [`crate::quad`]).
//! This replaces typed-in constant tables such as the thesis's Listing 2.1 (\[Ish11\] §2.3),
//! whose constants the tests recover from `M` for the modified H-basis.

use crate::basis::HemiBasis;
use crate::project::{Matrix, cross_gram, gram_inverse};
use crate::quad::HemiRule;
use crate::sh_basis::ShBasis;

/// `M = G⁻¹ C`, the `K × bands²` SH-irradiance-to-basis matrix of `basis`.
#[must_use]
pub fn sh_to_basis_matrix(basis: &dyn HemiBasis, bands: usize) -> Matrix {
    let sh = ShBasis::new(bands);
    let rule = HemiRule::for_orders(basis.order(), bands.saturating_sub(1));
    let c = cross_gram(basis, &sh, &rule);
    gram_inverse(basis).mul(&c)
}

/// The SH-irradiance conversion of every basis, here beside [`sh_to_basis_matrix`]. Call it on
/// a `dyn HemiBasis` (`Box<dyn HemiBasis>` or [`HemiBasis::as_dyn`]).
impl dyn HemiBasis + '_ {
    /// The `K × bands²` matrix that maps SH irradiance coefficients (lightvol-sh order and
    /// normalisation) to this basis: the least-squares fit over the upper hemisphere,
    /// `M = G⁻¹ C`, `C_ij = ∫_H B_i y_j dω`, derived by quadrature (never typed in); that is
    /// [`sh_to_basis_matrix`].
    #[must_use]
    pub fn sh_irradiance_matrix(&self, bands: usize) -> Matrix {
        sh_to_basis_matrix(self, bands)
    }

    /// Converts SH irradiance coefficients (length must be a square) to this basis.
    ///
    /// # Panics
    /// If `sh.len()` is not a square number.
    #[must_use]
    pub fn convert_sh_irradiance(&self, sh: &[f64]) -> Vec<f64> {
        self.sh_irradiance_matrix(square_bands(sh.len())).mul_vec(sh)
    }

    /// Converts RGB SH irradiance coefficients (coefficient-major) to this basis.
    ///
    /// # Panics
    /// If `sh.len()` is not a square number.
    #[must_use]
    pub fn convert_sh_irradiance_rgb(&self, sh: &[[f64; 3]]) -> Vec<[f64; 3]> {
        self.sh_irradiance_matrix(square_bands(sh.len())).mul_rgb(sh)
    }
}

/// The band count of `count` SH coefficients.
///
/// # Panics
/// If `count` is not a square number.
fn square_bands(count: usize) -> usize {
    let bands = count.isqrt();
    assert_eq!(bands * bands, count, "SH coefficient count must be a square");
    bands
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SH basis converted to itself must give the identity (SH on the hemisphere is not
    /// orthonormal, so this exercises G⁻¹). Rounding of the Cholesky solve is amplified by the
    /// condition number of the hemispherical SH Gram matrix, which grows with the band count
    /// (2e-12 observed at 4 bands); 1e-10 leaves margin.
    const IDENTITY_TOL: f64 = 1e-10;

    #[test]
    fn sh_to_sh_is_identity() {
        for bands in 1..=4 {
            let m = sh_to_basis_matrix(&ShBasis::new(bands), bands);
            let n = bands * bands;
            let d = m.max_abs_diff(&Matrix::identity(n));
            assert!(d < IDENTITY_TOL, "bands {bands}: {d:e}");
        }
    }
}
