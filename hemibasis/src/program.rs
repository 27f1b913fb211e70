//! The straight-line programs that describe a basis: a tiny expression tree over the
//! tangent-space normal `(x, y, z)` ([`Expr`]) and a list of temporaries and outputs
//! ([`Program`]), with an f64 interpreter and the printing of expressions as shader source.
//! Every basis returns its functions as a [`Program`] ([`crate::basis::HemiBasis::program`]);
//! [`crate::shader`] prints them as the WGSL and GLSL snippets of \[Ish11\] Listing 2.2.
//!
//! Constants are printed with the shortest decimal that round-trips to the same `f32`.

use core::fmt::Write as _;
use core::ops::{Add, Div, Mul, Neg, Sub};

/// A scalar expression over the tangent-space normal (a tiny shader AST).
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    /// A constant.
    Num(f64),
    /// `n.x`.
    X,
    /// `n.y`.
    Y,
    /// `n.z`.
    Z,
    /// The temporary `t{index}` of the enclosing [`Program`].
    Temp(usize),
    /// Sum.
    Add(Box<Expr>, Box<Expr>),
    /// Difference.
    Sub(Box<Expr>, Box<Expr>),
    /// Product.
    Mul(Box<Expr>, Box<Expr>),
    /// Quotient.
    Div(Box<Expr>, Box<Expr>),
    /// Negation.
    Neg(Box<Expr>),
    /// Square root.
    Sqrt(Box<Expr>),
}

impl Expr {
    /// The constant `v`.
    #[must_use]
    pub fn num(v: f64) -> Self {
        Self::Num(v)
    }

    /// `sqrt(self)`.
    #[must_use]
    pub fn sqrt(self) -> Self {
        Self::Sqrt(Box::new(self))
    }

    /// Evaluates the expression at `dir` with the temporaries `temps` already computed.
    #[must_use]
    pub fn eval(&self, dir: [f64; 3], temps: &[f64]) -> f64 {
        match self {
            Self::Num(v) => *v,
            Self::X => dir[0],
            Self::Y => dir[1],
            Self::Z => dir[2],
            Self::Temp(i) => temps[*i],
            Self::Add(a, b) => a.eval(dir, temps) + b.eval(dir, temps),
            Self::Sub(a, b) => a.eval(dir, temps) - b.eval(dir, temps),
            Self::Mul(a, b) => a.eval(dir, temps) * b.eval(dir, temps),
            Self::Div(a, b) => a.eval(dir, temps) / b.eval(dir, temps),
            Self::Neg(a) => -a.eval(dir, temps),
            Self::Sqrt(a) => a.eval(dir, temps).sqrt(),
        }
    }

    /// Prints the expression as WGSL/GLSL source (the two share this syntax).
    pub(crate) fn print(&self, out: &mut String) {
        match self {
            Self::Num(v) => {
                let v = *v as f32;
                if v < 0.0 {
                    out.push_str("(-");
                    out.push_str(&float_literal(-v));
                    out.push(')');
                } else {
                    out.push_str(&float_literal(v));
                }
            }
            Self::X => out.push('x'),
            Self::Y => out.push('y'),
            Self::Z => out.push('z'),
            Self::Temp(i) => {
                let _ = write!(out, "t{i}");
            }
            Self::Add(a, b) => binary(out, a, " + ", b),
            Self::Sub(a, b) => binary(out, a, " - ", b),
            Self::Mul(a, b) => binary(out, a, " * ", b),
            Self::Div(a, b) => binary(out, a, " / ", b),
            Self::Neg(a) => {
                out.push_str("(-");
                a.print(out);
                out.push(')');
            }
            Self::Sqrt(a) => {
                out.push_str("sqrt(");
                a.print(out);
                out.push(')');
            }
        }
    }
}

fn binary(out: &mut String, a: &Expr, op: &str, b: &Expr) {
    out.push('(');
    a.print(out);
    out.push_str(op);
    b.print(out);
    out.push(')');
}

/// Shortest round-trip decimal of a non-negative `f32`, always with a `.` or exponent so both
/// WGSL and GLSL read it as a float.
fn float_literal(v: f32) -> String {
    let s = format!("{v:?}");
    if s.contains('.') || s.contains('e') { s } else { format!("{s}.0") }
}

macro_rules! expr_op {
    ($tr:ident, $f:ident, $var:ident) => {
        impl $tr for Expr {
            type Output = Expr;
            fn $f(self, rhs: Expr) -> Expr {
                Expr::$var(Box::new(self), Box::new(rhs))
            }
        }
    };
}
expr_op!(Add, add, Add);
expr_op!(Sub, sub, Sub);
expr_op!(Mul, mul, Mul);
expr_op!(Div, div, Div);

impl Neg for Expr {
    type Output = Expr;
    fn neg(self) -> Expr {
        Expr::Neg(Box::new(self))
    }
}

/// Straight-line code for a basis: temporaries `t0, t1, …` (each may use the earlier ones)
/// and one output expression per basis function.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Program {
    /// Temporaries, in order.
    pub temps: Vec<Expr>,
    /// One expression per basis function.
    pub outputs: Vec<Expr>,
}

impl Program {
    /// Appends a temporary and returns a reference to it.
    pub fn temp(&mut self, e: Expr) -> Expr {
        self.temps.push(e);
        Expr::Temp(self.temps.len() - 1)
    }

    /// Interprets the program in f64 at the unit direction `dir`.
    #[must_use]
    pub fn eval(&self, dir: [f64; 3]) -> Vec<f64> {
        let mut temps = Vec::with_capacity(self.temps.len());
        for t in &self.temps {
            let v = t.eval(dir, &temps);
            temps.push(v);
        }
        self.outputs.iter().map(|e| e.eval(dir, &temps)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn literals_are_floats_and_round_trip() {
        assert_eq!(float_literal(1.0), "1.0");
        assert_eq!(float_literal(0.5), "0.5");
        let c = (3.0f64 / (2.0 * std::f64::consts::PI)).sqrt() as f32;
        let lit = float_literal(c);
        assert_eq!(lit.parse::<f32>().unwrap(), c);
    }

    #[test]
    fn interpreter_follows_temporaries() {
        let mut p = Program::default();
        let t0 = p.temp(Expr::X * Expr::Y);
        let t1 = p.temp(t0.clone() + Expr::num(1.0));
        p.outputs.push(t1 * Expr::Z - t0);
        p.outputs.push((Expr::Z + Expr::num(3.0)).sqrt() / Expr::num(2.0));
        let v = p.eval([2.0, 3.0, 0.5]);
        assert_eq!(v, vec![(6.0 + 1.0) * 0.5 - 6.0, 3.5f64.sqrt() / 2.0]);
    }
}
