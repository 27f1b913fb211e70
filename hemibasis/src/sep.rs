//! Separable function families: the common shape of SH, HSH, Makhotkin and Zernike.
//!
//! Each of these bases has functions of the form
//!
//! ```text
//! B(x, y, z) = k · W(z) · p(v(z)) · R(z)^|m| · T_m(x, y)
//! ```
//!
//! - `T_m` = `Re (x + i y)^m` for `m > 0`, `Im (x + i y)^|m|` for `m < 0`, `1` for `m = 0`;
//!   that is `sin^|m| θ · cos(mφ)` or `sin^|m| θ · sin(|m|φ)` (SH sign convention of
//!   lightvol-sh: no Condon-Shortley phase, `m < 0` ↔ sine);
//! - `R(z)` converts `sin θ` into the family's own radial factor:
//!   `1` (SH), `sqrt(z / (1 + z))` (HSH and Makhotkin: `sqrt(z (1 - z)) / sin θ`),
//!   `1 / sqrt(1 + z)` (Zernike: `ρ / sin θ` with `ρ = sqrt(1 - z)`);
//! - `W(z)` = `1`, or `sqrt(z)` for Makhotkin;
//! - `p` is a polynomial in the family's variable `v`: `z` (SH), `t = 2z - 1` (HSH,
//!   Makhotkin) or `ρ² = 1 - z` (Zernike).
//!
//! Written this way there is no division by `sin θ` and no trigonometric function, so the
//! evaluation is exact at the pole and the rim, and the same description prints as shader
//! code ([`Separable::program`]).

use lightvol_sh::Real;

use crate::program::{Expr, Program};

/// A polynomial with ascending coefficients `c_0 + c_1 v + …`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Poly(pub Vec<f64>);

impl Poly {
    pub(crate) fn constant(c: f64) -> Self {
        Self(vec![c])
    }

    /// `a + b v`.
    pub(crate) fn linear(a: f64, b: f64) -> Self {
        Self(vec![a, b])
    }

    pub(crate) fn mul(&self, o: &Poly) -> Poly {
        let mut out = vec![0.0; self.0.len() + o.0.len() - 1];
        for (i, a) in self.0.iter().enumerate() {
            for (j, b) in o.0.iter().enumerate() {
                out[i + j] += a * b;
            }
        }
        Poly(out)
    }

    pub(crate) fn scale(&self, s: f64) -> Poly {
        Poly(self.0.iter().map(|c| c * s).collect())
    }

    pub(crate) fn add(&self, o: &Poly) -> Poly {
        let n = self.0.len().max(o.0.len());
        Poly((0..n).map(|i| self.0.get(i).unwrap_or(&0.0) + o.0.get(i).unwrap_or(&0.0)).collect())
    }

    /// Horner evaluation.
    #[cfg(test)]
    pub(crate) fn eval(&self, v: f64) -> f64 {
        self.0.iter().rev().fold(0.0, |acc, c| acc * v + c)
    }
}

/// The polynomial variable `v(z)` of a family.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Var {
    /// `v = z` (SH).
    Z,
    /// `v = 2z - 1` (HSH, Makhotkin).
    #[cfg_attr(not(any(feature = "hsh", feature = "makhotkin")), allow(dead_code))]
    TwoZMinusOne,
    /// `v = 1 - z` (Zernike's `ρ²`).
    #[cfg_attr(not(feature = "zernike"), allow(dead_code))]
    OneMinusZ,
}

/// The radial factor `R(z)` raised to `|m|`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Radial {
    /// `R = 1`.
    One,
    /// `R = sqrt(z / (1 + z))`.
    #[cfg_attr(not(any(feature = "hsh", feature = "makhotkin")), allow(dead_code))]
    SqrtZOverOnePlusZ,
    /// `R = 1 / sqrt(1 + z)`.
    #[cfg_attr(not(feature = "zernike"), allow(dead_code))]
    InvSqrtOnePlusZ,
}

/// One function `k · p(v) · R^|m| · T_m` of a family.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct SepFn {
    pub scale: f64,
    pub poly: Poly,
    pub m: i32,
}

/// A family of separable functions sharing `v`, `R` and `W`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Separable {
    pub var: Var,
    pub radial: Radial,
    /// Multiply every function by `W = sqrt(z)` (Makhotkin).
    pub sqrt_z_weight: bool,
    pub fns: Vec<SepFn>,
    /// Coefficients cast to f32 once, for the f32 path.
    pub polys_f32: Vec<Vec<f32>>,
    max_m: usize,
}

impl Separable {
    pub(crate) fn new(var: Var, radial: Radial, sqrt_z_weight: bool, fns: Vec<SepFn>) -> Self {
        let max_m = fns.iter().map(|f| f.m.unsigned_abs() as usize).max().unwrap_or(0);
        let polys_f32 =
            fns.iter().map(|f| f.poly.0.iter().map(|&c| (c * f.scale) as f32).collect()).collect();
        Self { var, radial, sqrt_z_weight, fns, polys_f32, max_m }
    }

    #[cfg_attr(not(any(feature = "hsh", feature = "makhotkin", feature = "zernike")), allow(dead_code))]
    pub(crate) fn len(&self) -> usize {
        self.fns.len()
    }

    /// Evaluates every function at the unit direction `dir` (`z >= 0`) into `out`.
    #[cfg_attr(not(any(feature = "hsh", feature = "makhotkin", feature = "zernike")), allow(dead_code))]
    pub(crate) fn eval<T: PolyEval>(&self, dir: [T; 3], out: &mut [T]) {
        let [x, y, z] = dir;
        let one = T::ONE;
        let v = match self.var {
            Var::Z => z,
            Var::TwoZMinusOne => z + z - one,
            Var::OneMinusZ => one - z,
        };
        let r = match self.radial {
            Radial::One => one,
            Radial::SqrtZOverOnePlusZ => (z / (one + z)).sqrt(),
            Radial::InvSqrtOnePlusZ => one / (one + z).sqrt(),
        };
        let w = if self.sqrt_z_weight { z.max_zero().sqrt() } else { one };
        // cos/sin parts of (x + iy)^m times R^m, m = 0..=max_m (at most a few dozen).
        let mut c = [T::ZERO; 32];
        let mut s = [T::ZERO; 32];
        assert!(self.max_m < 32, "azimuthal order above 31 is not supported");
        c[0] = w;
        for m in 1..=self.max_m {
            let (pc, ps) = (c[m - 1], s[m - 1]);
            c[m] = (pc * x - ps * y) * r;
            s[m] = (pc * y + ps * x) * r;
        }
        for (i, f) in self.fns.iter().enumerate() {
            let p = T::eval_poly(self, i, v);
            let m = f.m.unsigned_abs() as usize;
            out[i] = p * if f.m < 0 { s[m] } else { c[m] };
        }
    }

    /// The family as straight-line shader code.
    pub(crate) fn program(&self) -> Program {
        let mut p = Program::default();
        let v = match self.var {
            Var::Z => Expr::Z,
            Var::TwoZMinusOne => p.temp(Expr::num(2.0) * Expr::Z - Expr::num(1.0)),
            Var::OneMinusZ => p.temp(Expr::num(1.0) - Expr::Z),
        };
        let r = match self.radial {
            Radial::One => None,
            Radial::SqrtZOverOnePlusZ if self.max_m > 0 => {
                Some(p.temp((Expr::Z / (Expr::num(1.0) + Expr::Z)).sqrt()))
            }
            Radial::InvSqrtOnePlusZ if self.max_m > 0 => {
                Some(p.temp(Expr::num(1.0) / (Expr::num(1.0) + Expr::Z).sqrt()))
            }
            _ => None,
        };
        let w = self.sqrt_z_weight.then(|| p.temp(Expr::Z.sqrt()));
        // Azimuthal factors R^m T_m (without W), m >= 1, by the same recurrence as `eval`.
        let mut cs: Vec<(Expr, Expr)> = Vec::new();
        for m in 1..=self.max_m {
            let (c, s) = if m == 1 {
                (Expr::X, Expr::Y)
            } else {
                let (pc, ps) = cs[m - 2].clone();
                (pc.clone() * Expr::X - ps.clone() * Expr::Y, pc * Expr::Y + ps * Expr::X)
            };
            let (c, s) = match &r {
                Some(r) => (c * r.clone(), s * r.clone()),
                None => (c, s),
            };
            cs.push((p.temp(c), p.temp(s)));
        }
        for f in &self.fns {
            // Horner with the scale folded into the coefficients.
            let coeffs: Vec<f64> = f.poly.0.iter().map(|c| c * f.scale).collect();
            let mut e = Expr::num(*coeffs.last().expect("non-empty polynomial"));
            for &c in coeffs.iter().rev().skip(1) {
                e = e * v.clone();
                if c != 0.0 {
                    e = e + Expr::num(c);
                }
            }
            let m = f.m.unsigned_abs() as usize;
            if m > 0 {
                let (c, s) = &cs[m - 1];
                e = e * if f.m < 0 { s.clone() } else { c.clone() };
            }
            if let Some(w) = &w {
                e = e * w.clone();
            }
            p.outputs.push(e);
        }
        p
    }
}

/// Per-precision polynomial evaluation (f32 uses the pre-cast, pre-scaled coefficients).
// Without the shifted bases only the f32/f64 bound is used (SH evaluates through lightvol-sh).
#[cfg_attr(not(any(feature = "hsh", feature = "makhotkin", feature = "zernike")), allow(dead_code))]
pub(crate) trait PolyEval: Real {
    fn eval_poly(fam: &Separable, i: usize, v: Self) -> Self;
    fn max_zero(self) -> Self;
}

impl PolyEval for f64 {
    #[inline]
    fn eval_poly(fam: &Separable, i: usize, v: f64) -> f64 {
        let f = &fam.fns[i];
        f.scale * f.poly.0.iter().rev().fold(0.0, |acc, &c| acc.mul_add(v, c))
    }
    #[inline]
    fn max_zero(self) -> Self {
        self.max(0.0)
    }
}

impl PolyEval for f32 {
    #[inline]
    fn eval_poly(fam: &Separable, i: usize, v: f32) -> f32 {
        fam.polys_f32[i].iter().rev().fold(0.0, |acc, &c| acc.mul_add(v, c))
    }
    #[inline]
    fn max_zero(self) -> Self {
        self.max(0.0)
    }
}

/// `n!` as f64 (exact to 22!, correctly rounded products beyond).
pub(crate) fn factorial(n: u32) -> f64 {
    (1..=n).map(f64::from).product()
}

/// The polynomial part `P̄_l^m(v)` of the associated Legendre function
/// `P_l^m(v) = P̄_l^m(v) (1 - v²)^{m/2}` (no Condon-Shortley phase), as coefficients in `v`,
/// by the recurrences of \[Ish11\] §1.8.1 (rules 1-3) run on polynomials.
pub(crate) fn legendre_poly(l: u32, m: u32) -> Poly {
    let mut pmm = Poly::constant((1..=m).map(|k| f64::from(2 * k - 1)).product());
    if l == m {
        return pmm;
    }
    let mut pmm1 = Poly::linear(0.0, f64::from(2 * m + 1)).mul(&pmm);
    for ll in (m + 2)..=l {
        let a = Poly::linear(0.0, f64::from(2 * ll - 1)).mul(&pmm1);
        let b = pmm.scale(-f64::from(ll + m - 1));
        let next = a.add(&b).scale(1.0 / f64::from(ll - m));
        pmm = pmm1;
        pmm1 = next;
    }
    pmm1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Polynomial vs. recurrence evaluation for low orders: rounding of O(10)-sized sums.
    const POLY_TOL: f64 = 1e-12;

    #[test]
    fn legendre_poly_matches_reference_recurrence() {
        for l in 0..6u32 {
            for m in 0..=l {
                for &v in &[-0.9, -0.3, 0.0, 0.4, 0.77] {
                    let s = (1.0f64 - v * v).powf(f64::from(m) / 2.0);
                    let want = lightvol_sh::reference::legendre_p(l, m, v);
                    let got = legendre_poly(l, m).eval(v) * s;
                    assert!((got - want).abs() < POLY_TOL, "l={l} m={m} v={v}: {got} vs {want}");
                }
            }
        }
    }
}
