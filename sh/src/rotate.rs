//! Rotation of SH expansions by the Ivanic-Ruedenberg recurrences.
//!
//! For a rotation `R`, the rotated function is `(R f)(ω) = f(R⁻¹ ω)`; its coefficients are
//! `c' = M(R) c` with a block-diagonal `M`, one orthogonal `(2l+1)²` block per band.
//!
//! Band 1 is the rotation matrix itself with rows and columns permuted to the basis order
//! `(y, z, x)` (this crate has no Condon-Shortley phase, so no signs appear). Higher bands
//! follow from band 1 and band `l-1` by the recurrences of Ivanic & Ruedenberg,
//! "Rotation Matrices for Real Spherical Harmonics. Direct Determination by Recursion",
//! J. Phys. Chem. 100 (1996), **with the corrections of their 1998 erratum** (J. Phys. Chem. A
//! 102, 9099): the `P` function's `b = ±l` cases and the `δ` factors in `V`. The recurrence
//! is covariant under the Condon-Shortley sign change, so the same code serves both
//! conventions given the matching band-1 matrix.
//!
//! [`ShRotation`] caches the per-band matrices, can be extended to more bands from the bands
//! it has (the recurrence only needs band `l-1`), and applies them to coefficient vectors in
//! place. The `u, v, w` factors of the recurrence depend only on `(l, m, n)` and are
//! tabulated once per process.

use std::sync::OnceLock;

use glam::{DMat3, DQuat};

use crate::coeffs::{Sh, ShRgb};
use crate::real::Real;

/// Bands for which the `u, v, w` factors are tabulated (beyond, they are computed on the fly).
const UVW_TABLE_BANDS: usize = 10;

/// Start of band `l`'s block in a flat array of blocks: `Σ_{k<l} (2k+1)² = l(2l-1)(2l+1)/3`.
const fn block_offset(l: usize) -> usize {
    if l == 0 { 0 } else { l * (2 * l - 1) * (2 * l + 1) / 3 }
}

fn kd(a: i32, b: i32) -> f64 {
    if a == b { 1.0 } else { 0.0 }
}

/// The `u, v, w` factors of the recurrence for `(l, m, n)` (erratum-corrected).
fn uvw(l: i32, m: i32, n: i32) -> [f64; 3] {
    let d = kd(m, 0);
    let lf = f64::from(l);
    let denom = if n.abs() == l { 2.0 * lf * (2.0 * lf - 1.0) } else { f64::from((l + n) * (l - n)) };
    let am = f64::from(m.abs());
    let u = (f64::from((l + m) * (l - m)) / denom).sqrt();
    let v = 0.5 * ((1.0 + d) * (lf + am - 1.0) * (lf + am) / denom).sqrt() * (1.0 - 2.0 * d);
    let w = -0.5 * ((lf - am - 1.0) * (lf - am) / denom).max(0.0).sqrt() * (1.0 - d);
    [u, v, w]
}

fn uvw_table() -> &'static Vec<[f64; 3]> {
    static TABLE: OnceLock<Vec<[f64; 3]>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = vec![[0.0; 3]; block_offset(UVW_TABLE_BANDS)];
        for l in 1..UVW_TABLE_BANDS as i32 {
            let size = 2 * l + 1;
            for m in -l..=l {
                for n in -l..=l {
                    t[block_offset(l as usize) + ((m + l) * size + (n + l)) as usize] = uvw(l, m, n);
                }
            }
        }
        t
    })
}

/// Cached SH rotation matrices for bands `0..bands`.
#[derive(Clone, Debug, PartialEq)]
pub struct ShRotation {
    bands: usize,
    /// Band blocks, row-major, band `l` at `block_offset(l)`.
    blocks: Vec<f64>,
}

impl ShRotation {
    /// Rotation matrices for `bands` bands from a 3×3 rotation matrix.
    #[must_use]
    pub fn from_mat3(bands: usize, r: DMat3) -> Self {
        let mut blocks = vec![0.0; block_offset(bands.max(2))];
        blocks[0] = 1.0;
        // Band 1: permute rows and columns to (y, z, x).
        let perm = [1usize, 2, 0];
        for i in 0..3 {
            for j in 0..3 {
                blocks[1 + i * 3 + j] = r.col(perm[j])[perm[i]];
            }
        }
        let mut out = Self { bands: bands.min(2), blocks };
        out.extend_to(bands);
        out
    }

    /// Rotation matrices for `bands` bands from a unit quaternion.
    #[must_use]
    pub fn from_quat(bands: usize, q: DQuat) -> Self {
        Self::from_mat3(bands, DMat3::from_quat(q))
    }

    /// Rotation matrices from an f32 quaternion (computed in f64).
    #[must_use]
    pub fn from_quat_f32(bands: usize, q: glam::Quat) -> Self {
        Self::from_quat(bands, q.as_dquat())
    }

    /// Number of bands held.
    #[must_use]
    pub fn bands(&self) -> usize {
        self.bands
    }

    /// The `(2l+1) × (2l+1)` row-major block of band `l`.
    ///
    /// # Panics
    /// If `l >= self.bands()`.
    #[must_use]
    pub fn band(&self, l: usize) -> &[f64] {
        assert!(l < self.bands, "band {l} not built");
        &self.blocks[block_offset(l)..block_offset(l + 1)]
    }

    /// Extends the cache to `bands` bands using the recurrence from the bands already held;
    /// a no-op when it already has that many.
    pub fn extend_to(&mut self, bands: usize) {
        if bands <= self.bands {
            return;
        }
        self.blocks.resize(block_offset(bands), 0.0);
        let table = uvw_table();
        for l in self.bands.max(2)..bands {
            self.build_band(l as i32, if l < UVW_TABLE_BANDS { Some(table) } else { None });
        }
        self.bands = bands;
    }

    fn build_band(&mut self, l: i32, table: Option<&Vec<[f64; 3]>>) {
        let (done, rest) = self.blocks.split_at_mut(block_offset(l as usize));
        let r1 = &done[1..10];
        let prev = &done[block_offset(l as usize - 1)..];
        let ps = 2 * l - 1; // previous band size
        let r1e = |i: i32, j: i32| r1[((i + 1) * 3 + (j + 1)) as usize];
        let pe = |a: i32, b: i32| prev[((a + l - 1) * ps + (b + l - 1)) as usize];
        // P of IR 1996 with the 1998 erratum.
        let p = |i: i32, a: i32, b: i32| -> f64 {
            if b == l {
                r1e(i, 1) * pe(a, l - 1) - r1e(i, -1) * pe(a, -l + 1)
            } else if b == -l {
                r1e(i, 1) * pe(a, -l + 1) + r1e(i, -1) * pe(a, l - 1)
            } else {
                r1e(i, 0) * pe(a, b)
            }
        };
        let size = 2 * l + 1;
        let out = &mut rest[..(size * size) as usize];
        for m in -l..=l {
            for n in -l..=l {
                let [u, v, w] = match table {
                    Some(t) => t[block_offset(l as usize) + ((m + l) * size + (n + l)) as usize],
                    None => uvw(l, m, n),
                };
                let mut val = 0.0;
                if u != 0.0 {
                    val += u * p(0, m, n);
                }
                if v != 0.0 {
                    let vv = if m == 0 {
                        p(1, 1, n) + p(-1, -1, n)
                    } else if m > 0 {
                        p(1, m - 1, n) * (1.0 + kd(m, 1)).sqrt() - p(-1, -m + 1, n) * (1.0 - kd(m, 1))
                    } else {
                        p(1, m + 1, n) * (1.0 - kd(m, -1)) + p(-1, -m - 1, n) * (1.0 + kd(m, -1)).sqrt()
                    };
                    val += v * vv;
                }
                if w != 0.0 {
                    let ww = if m > 0 {
                        p(1, m + 1, n) + p(-1, -m - 1, n)
                    } else {
                        p(1, m - 1, n) - p(-1, -m + 1, n)
                    };
                    val += w * ww;
                }
                out[((m + l) * size + (n + l)) as usize] = val;
            }
        }
    }

    /// Rotates coefficients in place (`coeffs.len()` must be `b²` with `b <= self.bands()`).
    ///
    /// # Panics
    /// If the coefficient count is not a square or needs more bands than are cached.
    #[inline]
    pub fn apply_in_place<T: Real>(&self, coeffs: &mut [T]) {
        let bands = crate::index::bands_of(coeffs.len()).expect("coefficient count must be a square");
        assert!(bands <= self.bands, "rotation has {} bands, coefficients need {bands}", self.bands);
        for l in 1..bands {
            let block = &self.blocks[block_offset(l)..block_offset(l + 1)];
            let src = &mut coeffs[l * l..(l + 1) * (l + 1)];
            // Fixed sizes let the compiler unroll the small blocks completely.
            match l {
                1 => apply_block::<T, 3>(block, src),
                2 => apply_block::<T, 5>(block, src),
                3 => apply_block::<T, 7>(block, src),
                4 => apply_block::<T, 9>(block, src),
                5 => apply_block::<T, 11>(block, src),
                6 => apply_block::<T, 13>(block, src),
                7 => apply_block::<T, 15>(block, src),
                _ => apply_block_dyn(block, src),
            }
        }
    }

    /// The rotated copy of a fixed-size vector.
    #[must_use]
    pub fn apply<T: Real, const N: usize>(&self, f: &Sh<T, N>) -> Sh<T, N> {
        let mut out = *f;
        self.apply_in_place(&mut out.0);
        out
    }

    /// The rotated copy of an RGB vector.
    #[must_use]
    pub fn apply_rgb<T: Real, const N: usize>(&self, f: &ShRgb<T, N>) -> ShRgb<T, N> {
        f.map(|c| self.apply(c))
    }
}

#[inline(always)]
fn apply_block<T: Real, const S: usize>(block: &[f64], src: &mut [T]) {
    let block = &block[..S * S];
    let src = &mut src[..S];
    let input: [T; S] = core::array::from_fn(|j| src[j]);
    for i in 0..S {
        let mut acc = T::ZERO;
        for j in 0..S {
            acc = T::from_f64(block[i * S + j]).mul_add(input[j], acc);
        }
        src[i] = acc;
    }
}

fn apply_block_dyn<T: Real>(block: &[f64], src: &mut [T]) {
    let size = src.len();
    let input = src.to_vec();
    for i in 0..size {
        let row = &block[i * size..(i + 1) * size];
        src[i] = row.iter().zip(&input).fold(T::ZERO, |acc, (&r, &x)| T::from_f64(r).mul_add(x, acc));
    }
}

/// Slow reference for tests and for rotations of very high order: the band-`l` matrix by
/// exact quadrature, `M_mn = ∫ y_lm(ω) y_ln(R⁻¹ ω) dω`.
#[must_use]
pub fn band_matrix_by_quadrature(l: usize, r: DMat3) -> Vec<f64> {
    let quad = crate::quadrature::SphereQuadrature::exact_for_degree(l + 1);
    let size = 2 * l + 1;
    let bands = l + 1;
    let mut out = vec![0.0; size * size];
    let mut y = vec![0.0; bands * bands];
    let mut yr = vec![0.0; bands * bands];
    let rinv = r.transpose();
    for node in quad.nodes() {
        let d = node.dir;
        let rd = rinv * glam::DVec3::from(d);
        crate::eval::eval_into(bands, d, &mut y);
        crate::eval::eval_into(bands, rd.to_array(), &mut yr);
        for i in 0..size {
            for j in 0..size {
                out[i * size + j] += node.weight * y[l * l + i] * yr[l * l + j];
            }
        }
    }
    out
}
