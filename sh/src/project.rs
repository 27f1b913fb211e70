//! Projection of spherical functions onto the SH basis: `c_i = ∫ f(ω) y_i(ω) dω`.
//!
//! - [`project_fn`]: a closure, by deterministic Gauss-Legendre × uniform-φ quadrature,
//!   exact for band-limited functions (see [`crate::quadrature`]).
//! - [`ProjectionAccumulator`]: weighted Monte Carlo / QMC samples,
//!   `c_i ≈ (1/n) Σ f(ω_s) y_i(ω_s) / p(ω_s)`.
//! - [`project_latlong`]: a latitude-longitude image with exact per-texel solid angles.
//! - [`fit_least_squares`]: the least-squares SH fit of sparse, scattered samples.
//! - [`project_directional`]: a directional light (a delta function), and the zonal
//!   projections in [`crate::zonal`] (clamped cosine, spherical cap).

use std::f64::consts::PI;

use crate::coeffs::{Sh, ShDyn, ShRgb};
use crate::eval::{eval_basis, eval_into};
use crate::linalg::cholesky_solve;
use crate::quadrature::SphereQuadrature;

/// Projects `f` with the quadrature rule `quad`.
#[must_use]
pub fn project_fn<const N: usize>(f: impl Fn([f64; 3]) -> f64, quad: &SphereQuadrature) -> Sh<f64, N> {
    let mut out = Sh::<f64, N>::ZERO;
    for node in quad.nodes() {
        let y = eval_basis::<f64, N>(node.dir);
        let fw = f(node.dir) * node.weight;
        for i in 0..N {
            out.0[i] += fw * y[i];
        }
    }
    out
}

/// Projects `f` onto `bands` bands with a rule that is exact when `f` is band-limited to
/// degree `f_degree` (any number of bands; returns a dynamic vector).
#[must_use]
pub fn project_fn_dyn(f: impl Fn([f64; 3]) -> f64, bands: usize, f_degree: usize) -> ShDyn<f64> {
    let quad = SphereQuadrature::exact_for_degree((bands.saturating_sub(1) + f_degree).div_ceil(2) + 1);
    let mut out = ShDyn::zeros(bands);
    let mut y = vec![0.0; bands * bands];
    for node in quad.nodes() {
        eval_into(bands, node.dir, &mut y);
        let fw = f(node.dir) * node.weight;
        for (c, &yi) in out.as_mut_slice().iter_mut().zip(&y) {
            *c += fw * yi;
        }
    }
    out
}

/// SH of a directional light of intensity `intensity` arriving from the unit direction `dir`
/// (radiance `intensity · δ(ω - dir)`): `c_i = intensity · y_i(dir)`.
#[must_use]
pub fn project_directional<const N: usize>(dir: [f64; 3], intensity: f64) -> Sh<f64, N> {
    Sh(eval_basis::<f64, N>(dir)) * intensity
}

/// Accumulates weighted samples of an RGB spherical function into SH coefficients.
///
/// Each sample contributes `value · weight · y_i(dir)`, where `weight` is normally
/// `1 / pdf(dir)`; [`Self::finish`] divides by the sample count, giving the Monte Carlo
/// estimate of `∫ f y_i dω`. The sums are f64 and are added in call order, so a fixed sample
/// order gives bit-identical results.
#[derive(Clone, Debug)]
pub struct ProjectionAccumulator<const N: usize> {
    sum: ShRgb<f64, N>,
    count: u64,
}

impl<const N: usize> Default for ProjectionAccumulator<N> {
    fn default() -> Self {
        Self { sum: ShRgb::ZERO, count: 0 }
    }
}

impl<const N: usize> ProjectionAccumulator<N> {
    /// Empty accumulator.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one sample (`dir` must be a unit vector).
    #[inline]
    pub fn add(&mut self, dir: [f64; 3], value: [f64; 3], weight: f64) {
        let y = eval_basis::<f64, N>(dir);
        for c in 0..3 {
            let vw = value[c] * weight;
            for i in 0..N {
                self.sum.0[c].0[i] = vw.mul_add(y[i], self.sum.0[c].0[i]);
            }
        }
        self.count += 1;
    }

    /// Adds the samples of another accumulator (same estimator, disjoint samples).
    pub fn merge(&mut self, other: &Self) {
        self.sum += other.sum;
        self.count += other.count;
    }

    /// Number of samples added.
    #[must_use]
    pub fn count(&self) -> u64 {
        self.count
    }

    /// The estimate `(1/n) Σ f w y_i`; zero when empty.
    #[must_use]
    pub fn finish(&self) -> ShRgb<f64, N> {
        if self.count == 0 {
            return ShRgb::ZERO;
        }
        self.sum * (1.0 / self.count as f64)
    }
}

/// Direction of the centre of texel `(col, row)` of a `width × height` latitude-longitude
/// image. Convention: row 0 touches the `+z` pole (`θ` from 0 at the top to `π` at the
/// bottom), columns run in `φ` from 0 at the left edge to `2π`, and
/// `ω = (sin θ cos φ, sin θ sin φ, cos θ)`.
#[must_use]
pub fn latlong_texel_dir(col: usize, row: usize, width: usize, height: usize) -> [f64; 3] {
    let theta = PI * (row as f64 + 0.5) / height as f64;
    let phi = 2.0 * PI * (col as f64 + 0.5) / width as f64;
    [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()]
}

/// Exact solid angle of a texel of row `row`: `(cos θ0 - cos θ1) · 2π / width`.
#[must_use]
pub fn latlong_texel_solid_angle(row: usize, width: usize, height: usize) -> f64 {
    let t0 = PI * row as f64 / height as f64;
    let t1 = PI * (row + 1) as f64 / height as f64;
    (t0.cos() - t1.cos()) * 2.0 * PI / width as f64
}

/// Projects an RGB latitude-longitude image (row-major, `width × height` texels, layout of
/// [`latlong_texel_dir`]) with exact per-texel solid angles; the value of each texel is
/// taken as constant over the texel and its basis values at the texel centre.
///
/// # Panics
/// If `texels.len() != width * height`.
#[must_use]
pub fn project_latlong<const N: usize>(texels: &[[f32; 3]], width: usize, height: usize) -> ShRgb<f64, N> {
    assert_eq!(texels.len(), width * height, "texel count must be width * height");
    let mut out = ShRgb::<f64, N>::ZERO;
    for row in 0..height {
        let dw = latlong_texel_solid_angle(row, width, height);
        for col in 0..width {
            let y = eval_basis::<f64, N>(latlong_texel_dir(col, row, width, height));
            let t = texels[row * width + col];
            for c in 0..3 {
                let v = f64::from(t[c]) * dw;
                for i in 0..N {
                    out.0[c].0[i] = v.mul_add(y[i], out.0[c].0[i]);
                }
            }
        }
    }
    out
}

/// Least-squares fit of `bands` bands to scattered samples `(dir, value)`: minimises
/// `Σ (f(ω_s) - v_s)² + ridge · |c|²`. Returns `None` when the normal equations are singular
/// (too few or degenerate samples and `ridge == 0`).
#[must_use]
pub fn fit_least_squares(bands: usize, samples: &[([f64; 3], f64)], ridge: f64) -> Option<ShDyn<f64>> {
    let n = bands * bands;
    let mut ata = vec![0.0; n * n];
    let mut atb = vec![0.0; n];
    let mut y = vec![0.0; n];
    for &(dir, v) in samples {
        eval_into(bands, dir, &mut y);
        for i in 0..n {
            atb[i] += y[i] * v;
            for j in 0..n {
                ata[i * n + j] += y[i] * y[j];
            }
        }
    }
    for i in 0..n {
        ata[i * n + i] += ridge;
    }
    cholesky_solve(&ata, &atb, n).and_then(ShDyn::from_vec)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lowdisc::Halton;
    use crate::sampling::{sample_uniform_sphere, uniform_sphere_pdf};

    /// Exact rules: f64 rounding over a few hundred terms.
    const EXACT: f64 = 1e-13;

    fn band_limited(d: [f64; 3]) -> f64 {
        // Degree-3 polynomial: exactly representable with 4 bands.
        1.0 + 0.5 * d[0] - 0.25 * d[1] * d[2] + 0.3 * d[2] * d[2] * d[2]
    }

    #[test]
    fn quadrature_projection_reconstructs_band_limited_functions() {
        let quad = SphereQuadrature::exact_for_degree(6);
        let c: Sh<f64, 16> = project_fn(band_limited, &quad);
        let h = Halton::new(1, 2);
        for i in 0..50 {
            let d = sample_uniform_sphere(h.point::<2>(i));
            assert!((c.eval(d) - band_limited(d)).abs() < EXACT);
        }
        let dynv = project_fn_dyn(band_limited, 4, 3);
        for i in 0..16 {
            assert!((dynv[i] - c.0[i]).abs() < EXACT);
        }
    }

    /// QMC projection converges to the exact projection, faster than plain Monte Carlo:
    /// 16x more scrambled-Halton points must cut the worst coefficient error by more than the
    /// 4x that Monte Carlo's 1/sqrt(n) would give, and reach below 2e-3 (the Koksma-Hlawka
    /// scale (log n)²/n ≈ 6e-3 times this integrand's variation of ~0.3).
    #[test]
    fn qmc_projection_converges() {
        let quad = SphereQuadrature::exact_for_degree(6);
        let exact: Sh<f64, 16> = project_fn(band_limited, &quad);
        let err = |n: u64| {
            let h = Halton::new(2, 2);
            let mut acc = ProjectionAccumulator::<16>::new();
            for i in 0..n {
                let d = sample_uniform_sphere(h.point::<2>(i));
                let v = band_limited(d);
                acc.add(d, [v, 2.0 * v, 0.0], 1.0 / uniform_sphere_pdf());
            }
            let est = acc.finish();
            assert_eq!(est.0[2], Sh::ZERO);
            (0..16)
                .map(|i| {
                    (est.0[0].0[i] - exact.0[i]).abs().max((est.0[1].0[i] - 2.0 * exact.0[i]).abs() / 2.0)
                })
                .fold(0.0, f64::max)
        };
        let (e_small, e_big) = (err(1024), err(16384));
        assert!(e_big < 2e-3, "{e_big}");
        assert!(e_big < e_small / 4.0, "{e_small} -> {e_big}");
    }

    #[test]
    fn latlong_solid_angles_are_exact() {
        let (w, h) = (64, 32);
        let total: f64 = (0..h).map(|r| latlong_texel_solid_angle(r, w, h) * w as f64).sum();
        assert!((total - 4.0 * PI).abs() < EXACT);
        // A constant image projects to DC = c · sqrt(4π) exactly; odd-m and sine terms cancel.
        let img = vec![[1.0f32, 0.5, 2.0]; w * h];
        let c: ShRgb<f64, 9> = project_latlong(&img, w, h);
        assert!((c.0[0].0[0] - (4.0 * PI).sqrt()).abs() < EXACT);
        assert!((c.0[2].0[0] - 2.0 * (4.0 * PI).sqrt()).abs() < EXACT);
        for i in 1..9 {
            // Every coefficient but y_20 vanishes by symmetry (φ-periodicity for m != 0, the
            // equator for odd l). y_20 is not constant over a texel, so the centre value carries
            // the midpoint-rule error, O((π/H)²) ≈ 0.01 at H = 32.
            let tol = if i == 6 { (PI / h as f64).powi(2) } else { 1e-12 };
            assert!(c.0[0].0[i].abs() < tol, "coeff {i} = {}", c.0[0].0[i]);
        }
    }

    /// A band-limited image converges at second order in the texel size (midpoint rule): the
    /// error falls by about 4x when the resolution doubles.
    #[test]
    fn latlong_converges_second_order() {
        let quad = SphereQuadrature::exact_for_degree(6);
        let exact: Sh<f64, 16> = project_fn(band_limited, &quad);
        let err = |w: usize, h: usize| {
            let img: Vec<[f32; 3]> = (0..h)
                .flat_map(|r| (0..w).map(move |c| (c, r)))
                .map(|(c, r)| {
                    let v = band_limited(latlong_texel_dir(c, r, w, h)) as f32;
                    [v, v, v]
                })
                .collect();
            let p: ShRgb<f64, 16> = project_latlong(&img, w, h);
            (0..16).map(|i| (p.0[0].0[i] - exact.0[i]).abs()).fold(0.0, f64::max)
        };
        let (e1, e2) = (err(64, 32), err(128, 64));
        assert!(e1 < 5e-3, "e1 = {e1}");
        assert!(e2 < e1 / 3.0, "not second order: {e1} then {e2}");
    }

    #[test]
    fn least_squares_recovers_band_limited_function() {
        let h = Halton::new(5, 2);
        let samples: Vec<_> =
            (0..200).map(|i| sample_uniform_sphere(h.point::<2>(i))).map(|d| (d, band_limited(d))).collect();
        let fit = fit_least_squares(4, &samples, 0.0).unwrap();
        let quad = SphereQuadrature::exact_for_degree(6);
        let exact: Sh<f64, 16> = project_fn(band_limited, &quad);
        for i in 0..16 {
            // Noise-free data in the model space: the fit is exact up to conditioning (~1e-12).
            assert!((fit[i] - exact.0[i]).abs() < 1e-11, "coeff {i}");
        }
        assert!(fit_least_squares(4, &samples[..3], 0.0).is_none());
    }

    #[test]
    fn directional_light_reproduces_basis() {
        let d = [0.0, 0.6, 0.8];
        let c: Sh<f64, 9> = project_directional(d, 2.0);
        // ∫ 2 δ(ω - d) f(ω) dω = 2 f(d): the dot with any f's coefficients gives 2 f(d)
        // for band-limited f.
        let quad = SphereQuadrature::exact_for_degree(4);
        let f: Sh<f64, 9> = project_fn(|w| w[0] * w[1] + w[2], &quad);
        assert!((c.dot(&f) - 2.0 * (d[0] * d[1] + d[2])).abs() < EXACT);
    }
}
