//! The [`HemiBasis`] trait shared by every basis.
//!
//! A basis is a finite set of real functions `B_i` on the upper hemisphere `z >= 0` of
//! tangent space (`z` = surface normal). Everything else in the crate (projection, SH
//! conversion, encoding, shader generation, the IMSE comparison) is written once against
//! this trait. The fitting methods of `dyn HemiBasis` live beside their algorithms, so this
//! module depends on none of them: `gram`, `project` and `project_rgb` in [`crate::project`],
//! `sh_irradiance_matrix` and `convert_sh_irradiance(_rgb)` in [`crate::convert`]; the bases
//! by name in [`crate::family`].

use crate::program::Program;

/// A set of basis functions on the upper hemisphere.
///
/// The trait is object safe: the comparison code keeps `Box<dyn HemiBasis>`.
///
/// Coefficient vectors are plain slices of length [`len`](Self::len); RGB coefficients are
/// coefficient-major `[[r, g, b]; len]` (one `vec3` per basis function, as shaders want).
pub trait HemiBasis: Send + Sync {
    /// Stable machine name used in JSON output: `"sh"`, `"hl2"`, `"hsh"`, `"makhotkin"`,
    /// `"zernike"`, `"hbasis"` or `"hbasis_mod"`.
    fn name(&self) -> &'static str;

    /// Human-readable name, e.g. `"Hemispherical Harmonics"`.
    fn label(&self) -> &'static str;

    /// Number of coefficients `K`.
    fn len(&self) -> usize;

    /// Always false: a basis has at least one function. (Present for `clippy::len_without_is_empty`.)
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Shader identifier, name plus count: `hsh9`, `hbasis_mod6`.
    fn tag(&self) -> String {
        format!("{}{}", self.name(), self.len())
    }

    /// True when the functions are orthonormal on the upper hemisphere (projection is then a
    /// plain inner product; otherwise it goes through the inverse Gram matrix).
    fn orthonormal(&self) -> bool;

    /// Highest polynomial order (band `l`, or radial order `n`) of the functions; sizes the
    /// quadrature rules.
    fn order(&self) -> usize;

    /// Index of the coefficient that is a lightmap (non-negative for non-negative signals) and
    /// is stored through a transfer curve (gamma 2.2 or sRGB) by [`crate::encode`]; `None` when
    /// there is none (Half-Life 2).
    fn dc_index(&self) -> Option<usize> {
        Some(0)
    }

    /// Evaluates all `K` functions at the unit tangent-space direction `dir` (`dir[2] >= 0`).
    ///
    /// # Panics
    /// If `out.len() < K`.
    fn eval_f64(&self, dir: [f64; 3], out: &mut [f64]);

    /// [`eval_f64`](Self::eval_f64) in single precision.
    fn eval_f32(&self, dir: [f32; 3], out: &mut [f32]);

    /// The functions as straight-line shader code (see [`crate::shader`]).
    fn program(&self) -> Program;

    /// `Σ c_i B_i(dir)`.
    fn reconstruct_f64(&self, coeffs: &[f64], dir: [f64; 3]) -> f64 {
        let mut b = vec![0.0; self.len()];
        self.eval_f64(dir, &mut b);
        b.iter().zip(coeffs).map(|(b, c)| b * c).sum()
    }

    /// `Σ c_i B_i(dir)` in single precision.
    fn reconstruct_f32(&self, coeffs: &[f32], dir: [f32; 3]) -> f32 {
        let mut b = vec![0.0; self.len()];
        self.eval_f32(dir, &mut b);
        b.iter().zip(coeffs).map(|(b, c)| b * c).sum()
    }

    /// `Σ c_i B_i(dir)` per colour channel.
    fn reconstruct_rgb_f64(&self, coeffs: &[[f64; 3]], dir: [f64; 3]) -> [f64; 3] {
        let mut b = vec![0.0; self.len()];
        self.eval_f64(dir, &mut b);
        let mut out = [0.0; 3];
        for (b, c) in b.iter().zip(coeffs) {
            for ch in 0..3 {
                out[ch] += b * c[ch];
            }
        }
        out
    }

    /// `Σ c_i B_i(dir)` per colour channel, in single precision.
    fn reconstruct_rgb_f32(&self, coeffs: &[[f32; 3]], dir: [f32; 3]) -> [f32; 3] {
        let mut b = vec![0.0; self.len()];
        self.eval_f32(dir, &mut b);
        let mut out = [0.0; 3];
        for (b, c) in b.iter().zip(coeffs) {
            for ch in 0..3 {
                out[ch] += b * c[ch];
            }
        }
        out
    }

    /// This basis as a trait object, whose fitting methods live with the algorithms: the
    /// Gram matrix and least-squares projection in [`crate::project`], the SH-irradiance
    /// conversion in [`crate::convert`] (`basis.as_dyn().gram()` for a concrete basis).
    fn as_dyn(&self) -> &dyn HemiBasis;
}

/// Implements the precision-specific trait methods from an inherent generic
/// `fn eval<T: Real>(&self, dir: [T; 3], out: &mut [T])`.
macro_rules! forward_eval {
    () => {
        fn eval_f64(&self, dir: [f64; 3], out: &mut [f64]) {
            self.eval(dir, out);
        }
        fn eval_f32(&self, dir: [f32; 3], out: &mut [f32]) {
            self.eval(dir, out);
        }
        fn as_dyn(&self) -> &dyn $crate::basis::HemiBasis {
            self
        }
    };
}
pub(crate) use forward_eval;
