//! Struct-of-arrays lanes for the batched kernels of [`crate::batch`]: the lane width, one
//! f32 per lane, and the real SH basis evaluated across lanes (the recurrence of
//! lightvol-sh's generated straight-line code, Sloan 2013, operation for operation, so that
//! it equals `lightvol_sh::eval::eval_basis` bit for bit).

use crate::tables::MAX_BANDS;
use lightvol_sh::recurrence::RecurrenceF32;

/// Receivers per batch: two SSE registers of f32 per value, enough independent work to hide
/// latencies, small enough that a batch's accumulators (`(N + 29) × 8` f32) stay in L1.
pub const LANES: usize = 8;

/// One f32 per lane.
pub type Lanes = [f32; LANES];

/// Recurrence constants of the real SH basis up to [`MAX_BANDS`] bands, as f32: lightvol-sh's
/// closed forms rounded once ([`RecurrenceF32`]), as its generated straight-line code rounds
/// them, so that [`eval_basis_lanes`] equals [`lightvol_sh::eval::eval_basis`] bit for bit
/// (tested).
pub type BasisRecurrence = RecurrenceF32<MAX_BANDS>;

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
