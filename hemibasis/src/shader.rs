//! Generated WGSL and GLSL snippets that evaluate a basis in a shader.
//!
//! Every basis describes itself as a [`Program`]: a list of named temporaries and one
//! expression per basis function, over the tangent-space normal `(x, y, z)`. The same program
//! is printed as WGSL ([`wgsl`]) or GLSL ([`glsl`]) and interpreted in f64
//! ([`Program::eval`]); the tests check the interpreter against the Rust evaluation of the
//! basis and compile the printed code with `naga`, so what users paste is what was tested.
//!
//! Each snippet defines two functions, named after [`crate::HemiBasis::tag`]
//! (e.g. `lv_hsh9`):
//! - `lv_TAG_basis(n)`: the `K` basis values at the unit tangent-space normal `n`;
//! - `lv_TAG_irradiance(n, c)`: `Σ c[i] B_i(n)` for RGB coefficients `c`;
//! - `lv_TAG_irradiance_stored(n, t, count, range, inv_scale)`: \[Ish11\] Listing 2.2 on
//!   sampled 8-bit texels `t` (see [`crate::encode`]): the DC texel (coefficient
//!   [`HemiBasis::dc_index`]) is used as sampled, i.e. linearised by an `_SRGB` texture
//!   format ([`crate::encode::DcTransfer::Srgb`]), every other one is decoded by
//!   `2 range t - range`; only the first `count` terms are summed (the levels of detail of
//!   Listing 2.2: 1, 4 or 6 for the modified H-basis, see [`crate::lod`]), and the sum is
//!   multiplied by `inv_scale` (the inverse of the scale applied before encoding). It mirrors
//!   `lod::eval_listing_2_2`.
//!
//! Constants are printed with the shortest decimal that round-trips to the same `f32`.

use core::fmt::Write as _;
use core::ops::{Add, Div, Mul, Neg, Sub};

use crate::basis::HemiBasis;

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

    fn print(&self, out: &mut String) {
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

fn header(basis: &dyn HemiBasis, comment: &str) -> String {
    format!(
        "{comment} Generated by lightvol-hemibasis {}: {} ({} coefficients).\n{comment} Tangent space: z is the surface normal; n must be unit length with n.z >= 0.\n",
        env!("CARGO_PKG_VERSION"),
        basis.label(),
        basis.len()
    )
}

/// WGSL functions `lv_TAG_basis(n: vec3<f32>) -> array<f32, K>`,
/// `lv_TAG_irradiance(n: vec3<f32>, c: array<vec3<f32>, K>) -> vec3<f32>` and
/// `lv_TAG_irradiance_stored(n, t: array<vec3<f32>, K>, count: u32, range: f32, inv_scale: f32)`
/// (see the module docs).
#[must_use]
pub fn wgsl(basis: &dyn HemiBasis) -> String {
    let tag = basis.tag();
    let k = basis.len();
    let prog = basis.program();
    let mut s = header(basis, "//");
    let _ = writeln!(s, "fn lv_{tag}_basis(n: vec3<f32>) -> array<f32, {k}> {{");
    s.push_str("    let x = n.x;\n    let y = n.y;\n    let z = n.z;\n");
    for (i, t) in prog.temps.iter().enumerate() {
        let _ = write!(s, "    let t{i} = ");
        t.print(&mut s);
        s.push_str(";\n");
    }
    let _ = writeln!(s, "    var b: array<f32, {k}>;");
    for (i, e) in prog.outputs.iter().enumerate() {
        let _ = write!(s, "    b[{i}] = ");
        e.print(&mut s);
        s.push_str(";\n");
    }
    s.push_str("    return b;\n}\n\n");
    let _ = writeln!(s, "fn lv_{tag}_irradiance(n: vec3<f32>, c: array<vec3<f32>, {k}>) -> vec3<f32> {{");
    let _ = writeln!(s, "    let b = lv_{tag}_basis(n);");
    s.push_str("    return ");
    push_dot(&mut s, k);
    s.push_str(";\n}\n\n");
    let _ = writeln!(
        s,
        "fn lv_{tag}_irradiance_stored(n: vec3<f32>, t: array<vec3<f32>, {k}>, count: u32, range: f32, inv_scale: f32) -> vec3<f32> {{"
    );
    let _ = writeln!(s, "    var b = lv_{tag}_basis(n);\n    var tt = t;\n    var e = vec3<f32>(0.0);");
    let _ = writeln!(s, "    for (var i = 0u; i < min(count, {k}u); i++) {{");
    let _ = writeln!(s, "        var c = tt[i];");
    let _ =
        writeln!(s, "        if (i != {}u) {{ c = 2.0 * range * c - vec3<f32>(range); }}", dc_or_none(basis));
    s.push_str("        e += c * b[i];\n    }\n    return e * inv_scale;\n}\n");
    s
}

/// The DC index, or an index no coefficient has (HL2: every texel is range-compressed).
fn dc_or_none(basis: &dyn HemiBasis) -> usize {
    basis.dc_index().unwrap_or(basis.len())
}

/// GLSL functions `void lv_TAG_basis(vec3 n, out float b[K])`,
/// `vec3 lv_TAG_irradiance(vec3 n, vec3 c[K])` and
/// `vec3 lv_TAG_irradiance_stored(vec3 n, vec3 t[K], uint count, float range, float inv_scale)`
/// (GLSL 4.50 / ES 3.10 syntax).
#[must_use]
pub fn glsl(basis: &dyn HemiBasis) -> String {
    let tag = basis.tag();
    let k = basis.len();
    let prog = basis.program();
    let mut s = header(basis, "//");
    let _ = writeln!(s, "void lv_{tag}_basis(vec3 n, out float b[{k}]) {{");
    s.push_str("    float x = n.x;\n    float y = n.y;\n    float z = n.z;\n");
    for (i, t) in prog.temps.iter().enumerate() {
        let _ = write!(s, "    float t{i} = ");
        t.print(&mut s);
        s.push_str(";\n");
    }
    for (i, e) in prog.outputs.iter().enumerate() {
        let _ = write!(s, "    b[{i}] = ");
        e.print(&mut s);
        s.push_str(";\n");
    }
    s.push_str("}\n\n");
    let _ = writeln!(s, "vec3 lv_{tag}_irradiance(vec3 n, vec3 c[{k}]) {{");
    let _ = writeln!(s, "    float b[{k}];\n    lv_{tag}_basis(n, b);");
    s.push_str("    return ");
    push_dot(&mut s, k);
    s.push_str(";\n}\n\n");
    let _ = writeln!(
        s,
        "vec3 lv_{tag}_irradiance_stored(vec3 n, vec3 t[{k}], uint count, float range, float inv_scale) {{"
    );
    let _ = writeln!(s, "    float b[{k}];\n    lv_{tag}_basis(n, b);\n    vec3 e = vec3(0.0);");
    let _ = writeln!(s, "    for (uint i = 0u; i < min(count, {k}u); i++) {{");
    let _ = writeln!(s, "        vec3 c = t[i];");
    let _ = writeln!(s, "        if (i != {}u) {{ c = 2.0 * range * c - vec3(range); }}", dc_or_none(basis));
    s.push_str("        e += c * b[i];\n    }\n    return e * inv_scale;\n}\n");
    s
}

fn push_dot(s: &mut String, k: usize) {
    for i in 0..k {
        if i > 0 {
            s.push_str("\n        + ");
        }
        let _ = write!(s, "c[{i}] * b[{i}]");
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
