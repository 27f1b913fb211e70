//! Struct-of-arrays lanes for the batched kernels of [`crate::batch`]: the lane width, one
//! f32 per lane, and the real SH basis evaluated across lanes (the recurrence of
//! lightvol-sh's generated straight-line code, Sloan 2013, operation for operation, so that
//! it equals `lightvol_sh::eval::eval_basis` bit for bit).

use crate::tables::MAX_BANDS;

/// Receivers per batch: two SSE registers of f32 per value, enough independent work to hide
/// latencies, small enough that a batch's accumulators (`(N + 29) × 8` f32) stay in L1.
pub const LANES: usize = 8;

/// One f32 per lane.
pub type Lanes = [f32; LANES];

/// Recurrence constants of the real SH basis up to [`MAX_BANDS`] bands, as f32: lightvol-sh's
/// closed forms (`lightvol_sh::recurrence`) rounded once, as its generated straight-line code
/// rounds them, so that [`eval_basis_lanes`] equals [`lightvol_sh::eval::eval_basis`] bit for
/// bit (tested).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BasisRecurrence {
    /// `Q_m^m`, indexed by `m`.
    diag: [f32; MAX_BANDS],
    /// `a_lm`, indexed `[l][m]`.
    a: [[f32; MAX_BANDS]; MAX_BANDS],
    /// `b_lm`, indexed `[l][m]`.
    b: [[f32; MAX_BANDS]; MAX_BANDS],
}

impl BasisRecurrence {
    /// Computes the constants (`lightvol_sh::recurrence`: `Q_m^m`, `a_lm`, `b_lm`).
    #[must_use]
    pub fn new() -> Self {
        let mut k = Self {
            diag: [0.0; MAX_BANDS],
            a: [[0.0; MAX_BANDS]; MAX_BANDS],
            b: [[0.0; MAX_BANDS]; MAX_BANDS],
        };
        use lightvol_sh::recurrence::{a_coef, b_coef, q_diag};
        for m in 0..MAX_BANDS as u64 {
            k.diag[m as usize] = q_diag(m) as f32;
            for l in m + 1..MAX_BANDS as u64 {
                k.a[l as usize][m as usize] = a_coef(l, m) as f32;
                if l >= m + 2 {
                    k.b[l as usize][m as usize] = b_coef(l, m) as f32;
                }
            }
        }
        k
    }
}

impl Default for BasisRecurrence {
    fn default() -> Self {
        Self::new()
    }
}

/// The real SH basis (`N` = 1, 4, 9 or 16 coefficients) at unit directions `(x, y, z)`, per
/// lane: the recurrence of lightvol-sh's generated code, operation for operation.
#[must_use]
#[inline(always)]
pub fn eval_basis_lanes<const N: usize>(k: &BasisRecurrence, x: &Lanes, y: &Lanes, z: &Lanes) -> [Lanes; N] {
    const { assert!(N == 1 || N == 4 || N == 9 || N == 16, "up to 4 bands") };
    let bands = N.isqrt();
    let mut out = [[0.0f32; LANES]; N];
    let (mut c, mut s) = ([1.0f32; LANES], [0.0f32; LANES]);
    for m in 0..bands {
        if m == 1 {
            (c, s) = (*x, *y);
        } else if m >= 2 {
            let (cp, sp) = (c, s);
            c = core::array::from_fn(|l| x[l] * cp[l] - y[l] * sp[l]);
            s = core::array::from_fn(|l| x[l] * sp[l] + y[l] * cp[l]);
        }
        let (mut q1, mut q2) = ([k.diag[m]; LANES], [0.0f32; LANES]);
        for l in m..bands {
            let (a, b) = (k.a[l][m], k.b[l][m]);
            let q: Lanes = if l == m {
                q1
            } else if l == m + 1 {
                core::array::from_fn(|i| a * z[i] * q1[i])
            } else {
                core::array::from_fn(|i| a * z[i] * q1[i] + b * q2[i])
            };
            if l > m {
                (q2, q1) = (q1, q);
            }
            let centre = l * (l + 1);
            if m == 0 {
                out[centre] = q;
            } else {
                out[centre + m] = core::array::from_fn(|i| q[i] * c[i]);
                out[centre - m] = core::array::from_fn(|i| q[i] * s[i]);
            }
        }
    }
    out
}
