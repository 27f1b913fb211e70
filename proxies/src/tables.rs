//! Per-proxy tables as functions of `α = sin θ` (\[SGNS07\] §3, §4.1, §5), computed at
//! start-up from exact integrals, never typed in:
//!
//! - `V(α)`: ZH of the proxy's visibility cap (Eq. 3), closed form
//!   ([`lightvol_sh::zonal::Zh::cap`]);
//! - `O^log(α)`: ZH of the log of the environment visibility `1 - V` (Eq. 4), by
//!   [`lightvol_sh::shexp::log_reference`] of the projected cap visibility. The truncated
//!   visibility is zonal, products of zonal vectors are zonal, so its log is zonal and only
//!   the `m = 0` entries are kept (the others are rounding; tested). Where the truncated
//!   visibility has no exact log (large caps: beyond about 60° at order 3 and 50° at order 4,
//!   see lightvol-sh's `tests/shexp.rs`) the entry is the floored-eigenvalue log refined by
//!   Newton, and [`ProxyTables::log_residual`] records `‖exp(log g) - g‖ / ‖g‖`;
//! - `D(α)`: the averaged indirect operator of Eq. 14 ([`crate::operators::d_exact`]);
//! - `M(α)`: the exact indirect operator of Eq. 16 ([`crate::operators::m_exact`]).
//!
//! Entries sit at `α_i = i / (TABLE_ENTRIES - 1)`; lookups interpolate linearly in `α²`
//! ([`locate`]).
//! [`SmoothClamp`] implements the paper's smooth clamping near `α = 1/η` (§4.1).

use std::sync::OnceLock;

use lightvol_sh::coeffs::Sh;
use lightvol_sh::eval::eval_basis;
use lightvol_sh::real::Real;
use lightvol_sh::shexp::{exp_reference, log_reference, unit};
use lightvol_sh::zonal::{Zh, zh_scale};

use crate::operators::{d_exact, m_exact};

/// Number of table entries over `α ∈ [0, 1]` (spacing 1/256); the interpolation error of
/// `O^log` is measured in `tests/tables.rs`.
pub const TABLE_ENTRIES: usize = 257;

/// The largest number of bands the tables hold.
pub const MAX_BANDS: usize = 4;

/// A ZH with up to [`MAX_BANDS`] bands (unused bands are 0).
pub type Zh4 = [f64; MAX_BANDS];

/// Tables for one SH order (3 or 4 bands).
#[derive(Clone, Debug)]
pub struct ProxyTables {
    bands: usize,
    olog: Vec<Zh4>,
    vis: Vec<Zh4>,
    d: Vec<Zh4>,
    m: Vec<Vec<f64>>,
    log_residual: Vec<f64>,
}

/// `α` of table entry `i`.
#[must_use]
#[inline]
pub fn table_alpha(i: usize) -> f64 {
    i as f64 / (TABLE_ENTRIES - 1) as f64
}

fn zh_of<const N: usize>(v: &Sh<f64, N>) -> Zh4 {
    core::array::from_fn(|l| if l * l < N { v.0[l * (l + 1)] } else { 0.0 })
}

fn build<const N: usize>() -> ProxyTables {
    let bands = N.isqrt();
    let mut t = ProxyTables {
        bands,
        olog: Vec::with_capacity(TABLE_ENTRIES),
        vis: Vec::with_capacity(TABLE_ENTRIES),
        d: Vec::with_capacity(TABLE_ENTRIES),
        m: Vec::with_capacity(TABLE_ENTRIES),
        log_residual: Vec::with_capacity(TABLE_ENTRIES),
    };
    for i in 0..TABLE_ENTRIES {
        let alpha = table_alpha(i);
        let cap = Zh::<f64, MAX_BANDS>::cap(alpha.asin()).0;
        let mut v: Zh4 = [0.0; MAX_BANDS];
        v[..bands].copy_from_slice(&cap[..bands]);
        let g = unit::<N>() - zh_to_sh::<N>(&v);
        let (f, residual) = if alpha == 0.0 { (Sh::ZERO, 0.0) } else { log_reference(&g) };
        let d = d_exact(alpha, bands);
        let mut dz: Zh4 = [0.0; MAX_BANDS];
        dz[..bands].copy_from_slice(&d);
        t.olog.push(zh_of(&f));
        t.vis.push(v);
        t.d.push(dz);
        t.m.push(m_exact::<N>(alpha));
        t.log_residual.push(residual / g.norm());
    }
    t
}

fn zh_to_sh<const N: usize>(z: &Zh4) -> Sh<f64, N> {
    let mut s = Sh::ZERO;
    for l in 0..N.isqrt() {
        s.0[l * (l + 1)] = z[l];
    }
    s
}

/// Which table a lookup reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Table {
    /// Canonical log visibility `O^log(α)` (Eq. 4).
    LogVisibility,
    /// Canonical proxy visibility `V(α)` (Eq. 3).
    Visibility,
    /// Averaged indirect operator `D(α)` (Eq. 14).
    Averaged,
}

impl ProxyTables {
    /// Builds the tables for `N = 9` or `N = 16` coefficients (about 0.1-0.5 s in release).
    #[must_use]
    pub fn build<const N: usize>() -> Self {
        const { assert!(N == 9 || N == 16, "proxy tables exist for 9 or 16 coefficients") };
        build::<N>()
    }

    /// The process-wide tables for `N = 9` or `N = 16`, built on first use.
    #[must_use]
    pub fn shared<const N: usize>() -> &'static Self {
        const { assert!(N == 9 || N == 16, "proxy tables exist for 9 or 16 coefficients") };
        static T9: OnceLock<ProxyTables> = OnceLock::new();
        static T16: OnceLock<ProxyTables> = OnceLock::new();
        if N == 9 { T9.get_or_init(build::<9>) } else { T16.get_or_init(build::<16>) }
    }

    /// Number of bands.
    #[must_use]
    pub fn bands(&self) -> usize {
        self.bands
    }

    /// Raw entry `i` of a table.
    #[must_use]
    pub fn entry(&self, table: Table, i: usize) -> Zh4 {
        match table {
            Table::LogVisibility => self.olog[i],
            Table::Visibility => self.vis[i],
            Table::Averaged => self.d[i],
        }
    }

    /// `‖exp(O^log) - (1 - V)‖ / ‖1 - V‖` at entry `i` (reference exponential): 0 to rounding
    /// where the exact log exists.
    #[must_use]
    pub fn log_residual(&self, i: usize) -> f64 {
        self.log_residual[i]
    }

    /// Exact operator `M` (Eq. 16, row-major `N × N`) at entry `i`.
    #[must_use]
    pub fn m_entry(&self, i: usize) -> &[f64] {
        &self.m[i]
    }

    /// A table at `alpha`, linearly interpolated, with the smooth clamp applied to the entries
    /// when given (§4.1).
    #[must_use]
    pub fn lookup(&self, table: Table, alpha: f64, clamp: Option<&SmoothClamp>) -> Zh4 {
        let (i, t) = locate(alpha);
        let (w0, w1) = match clamp {
            Some(c) => (c.weight(table_alpha(i)), c.weight(table_alpha(i + 1))),
            None => (1.0, 1.0),
        };
        let (a, b) = (self.entry(table, i), self.entry(table, i + 1));
        core::array::from_fn(|l| (1.0 - t) * w0 * a[l] + t * w1 * b[l])
    }

    /// `M(α)` by linear interpolation between entries.
    #[must_use]
    pub fn m_lookup(&self, alpha: f64) -> Vec<f64> {
        let (i, t) = locate(alpha);
        self.m[i].iter().zip(&self.m[i + 1]).map(|(a, b)| (1.0 - t) * a + t * b).collect()
    }

    /// The reference round trip `exp(O^log(α_i))` against `1 - V(α_i)`, both as SH vectors
    /// along `+z` (for tests and reports).
    #[must_use]
    pub fn round_trip<const N: usize>(&self, i: usize) -> (Sh<f64, N>, Sh<f64, N>) {
        let g = unit::<N>() - zh_to_sh::<N>(&self.vis[i]);
        (exp_reference(&zh_to_sh::<N>(&self.olog[i])), g)
    }
}

/// Entry index `i` and weight `t` of entry `i + 1` for `alpha` (clamped to `[0, 1]`). The
/// weight is linear in `α²`, not `α`: every table starts like `α²` (solid angle), which
/// linear interpolation in `α` gets wrong by up to 11% of the value in the first intervals,
/// and interpolation in `α²` reproduces exactly.
#[inline]
pub fn locate(alpha: f64) -> (usize, f64) {
    let a = alpha.clamp(0.0, 1.0);
    let n = (TABLE_ENTRIES - 1) as f64;
    let i = ((a * n) as usize).min(TABLE_ENTRIES - 2);
    let (a0, a1) = (i as f64 / n, (i + 1) as f64 / n);
    (i, (a * a - a0 * a0) / (a1 * a1 - a0 * a0))
}

/// Smooth clamping of a proxy's sphere of influence (\[SGNS07\] §4.1): table entries are
/// re-weighted by `w(α_i)` ([`SmoothClamp::weight`]), 0 at and below `1/η` and rising
/// smoothly to 1 over the next four entries, so a proxy's contribution fades to 0
/// continuously and is exactly 0 outside its sphere of influence `|p - c| >= η r`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmoothClamp {
    /// Radius expansion factor `η`.
    pub eta: f64,
}

/// Table entries over which the clamp rises from 0 to 1 (the paper's "4 table entries
/// around 1/η").
pub const CLAMP_ENTRIES: f64 = 4.0;

impl SmoothClamp {
    /// The clamp for expansion factor `eta > 1`.
    #[must_use]
    pub const fn new(eta: f64) -> Self {
        Self { eta }
    }

    /// Weight of a table entry at `alpha` (meant for entry positions `α_i`): 0 up to and
    /// including the first entry at or above `1/η` (so interpolated lookups are exactly 0 for
    /// every `α <= 1/η`), then `3x² - 2x³` over the next [`CLAMP_ENTRIES`] entries.
    #[must_use]
    pub fn weight(&self, alpha: f64) -> f64 {
        let n = (TABLE_ENTRIES - 1) as f64;
        let first = (n / self.eta).ceil();
        let x = ((alpha * n - first) / CLAMP_ENTRIES).clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    }

    /// `α` below which the weight is 0: `1/η`.
    #[must_use]
    pub fn alpha_min(&self) -> f64 {
        1.0 / self.eta
    }
}

/// Rotates a ZH to `axis` (\[SGNS07\] Eq. 8): `rot(g, z')_lm = sqrt(4π/(2l+1)) g_l y_lm(z')`.
/// `N` is 9 or 16. (lightvol-sh's `Zh::rotate_to` needs the band count as a type parameter;
/// this is the same formula for a runtime-sized ZH. TODO(sh): a `Zh::rotate_to` for
/// `[T; B]` with `B >= sqrt(N)` would make this helper unnecessary.)
#[must_use]
#[inline]
pub fn rotate_zh<T: Real, const N: usize>(zh: &[T; MAX_BANDS], axis: [T; 3]) -> Sh<T, N> {
    let mut y = eval_basis::<T, N>(axis);
    let bands = N.isqrt();
    for l in 0..bands {
        let s = zh[l] * T::from_f64(zh_scale(l as u32));
        for v in &mut y[l * l..(l + 1) * (l + 1)] {
            *v *= s;
        }
    }
    Sh(y)
}

/// `sqrt(4π)`, the DC coefficient of the constant 1.
pub const SQRT_4PI: f64 = 3.544_907_701_811_031_8;

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn sqrt_4pi_constant() {
        assert_eq!(SQRT_4PI, (4.0 * PI).sqrt());
    }

    #[test]
    fn rotate_zh_matches_lightvol_sh() {
        let z = Zh::<f64, 4>([0.3, -0.2, 0.1, 0.05]);
        let axis = [0.36, -0.48, 0.8];
        let a: Sh<f64, 16> = rotate_zh(&z.0, axis);
        let b = z.rotate_to::<16>(axis);
        assert!((a - b).norm() < 1e-15);
    }

    #[test]
    fn clamp_weight_shape() {
        let c = SmoothClamp::new(10.0);
        let first = ((TABLE_ENTRIES - 1) as f64 / 10.0).ceil() as usize;
        assert!(table_alpha(first) >= 0.1 && table_alpha(first - 1) < 0.1);
        assert_eq!(c.weight(0.05), 0.0);
        assert_eq!(c.weight(table_alpha(first)), 0.0);
        assert!((c.weight(table_alpha(first + 2)) - 0.5).abs() < 1e-12);
        assert_eq!(c.weight(table_alpha(first + 4)), 1.0);
    }
}
