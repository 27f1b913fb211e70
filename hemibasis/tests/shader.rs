//! The generated WGSL and GLSL snippets compile (naga front end +
//! validator), and the shader programs compute what the Rust evaluation computes.

use lightvol_hemibasis::imse::table_bases;
use lightvol_hemibasis::shader::{glsl, wgsl};
use lightvol_hemibasis::{HemiBasis, ShBasis};

/// Interpreting the program in f64 vs. the Rust evaluation: both are straight-line f64
/// arithmetic of O(1) terms, but the shader form evaluates polynomials in monomial (Horner)
/// form, so allow rounding of a few dozen operations.
const PROGRAM_TOL: f64 = 1e-12;

fn all_bases() -> Vec<Box<dyn HemiBasis>> {
    let mut v = table_bases();
    // Larger orders exercise the generators beyond Table 3.1's sizes.
    v.push(Box::new(ShBasis::new(4)));
    for name in ["hsh", "makhotkin"] {
        if let Some(b) = lightvol_hemibasis::by_name(name, 16) {
            v.push(b);
        }
    }
    if let Some(b) = lightvol_hemibasis::by_name("zernike", 10) {
        v.push(b);
    }
    v
}

fn dirs() -> Vec<[f64; 3]> {
    let mut out = vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]];
    for i in 0..6 {
        for j in 0..8 {
            let z = (f64::from(i) + 0.5) / 6.0;
            let phi = f64::from(j) * 0.8 + 0.1;
            let s = (1.0 - z * z).sqrt();
            out.push([s * phi.cos(), s * phi.sin(), z]);
        }
    }
    out
}

#[test]
fn programs_match_rust_evaluation() {
    for b in all_bases() {
        let p = b.program();
        assert_eq!(p.outputs.len(), b.len());
        let mut v = vec![0.0; b.len()];
        for d in dirs() {
            b.eval_f64(d, &mut v);
            let got = p.eval(d);
            for i in 0..b.len() {
                assert!(
                    (got[i] - v[i]).abs() < PROGRAM_TOL,
                    "{} B{i} at {d:?}: {} vs {}",
                    b.tag(),
                    got[i],
                    v[i]
                );
            }
        }
    }
}

fn validate(module: &naga::Module, what: &str) {
    let mut validator =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty());
    if let Err(e) = validator.validate(module) {
        panic!("{what}: validation failed: {e:?}");
    }
}

#[test]
fn wgsl_snippets_compile() {
    for b in all_bases() {
        let k = b.len();
        let tag = b.tag();
        let src = format!(
            "{}\n@fragment\nfn fs_main(@location(0) n: vec3<f32>) -> @location(0) vec4<f32> {{\n    var c: array<vec3<f32>, {k}>;\n    for (var i = 0; i < {k}; i++) {{ c[i] = vec3<f32>(f32(i)); }}\n    return vec4<f32>(lv_{tag}_irradiance(normalize(n), c) + lv_{tag}_irradiance_stored(normalize(n), c, 4u, 0.75, 2.0), 1.0);\n}}\n",
            wgsl(b.as_ref())
        );
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{tag} WGSL parse: {}\n{src}", e.emit_to_string(&src)));
        assert!(module.functions.iter().any(|(_, f)| f.name.as_deref() == Some(&format!("lv_{tag}_basis"))));
        validate(&module, &format!("{tag} WGSL"));
    }
}

#[test]
fn glsl_snippets_compile() {
    for b in all_bases() {
        let k = b.len();
        let tag = b.tag();
        let src = format!(
            "#version 450\n{}\nlayout(location = 0) in vec3 v_normal;\nlayout(location = 0) out vec4 o_color;\nvoid main() {{\n    vec3 c[{k}];\n    for (int i = 0; i < {k}; i++) {{ c[i] = vec3(float(i)); }}\n    o_color = vec4(lv_{tag}_irradiance(normalize(v_normal), c) + lv_{tag}_irradiance_stored(normalize(v_normal), c, 4u, 0.75, 2.0), 1.0);\n}}\n",
            glsl(b.as_ref())
        );
        let mut frontend = naga::front::glsl::Frontend::default();
        let module = frontend
            .parse(&naga::front::glsl::Options::from(naga::ShaderStage::Fragment), &src)
            .unwrap_or_else(|e| panic!("{tag} GLSL parse: {e:?}\n{src}"));
        validate(&module, &format!("{tag} GLSL"));
    }
}

/// Negative control: the harness above really rejects bad code (type error, undefined name).
#[test]
fn naga_rejects_broken_snippets() {
    let bad_wgsl = "fn f(n: vec3<f32>) -> f32 { return n.x * undefined_name; }";
    assert!(naga::front::wgsl::parse_str(bad_wgsl).is_err());
    let bad_glsl = "#version 450\nvoid main() { float b[3]; b[0] = undefined_name * 2.0; }\n";
    let mut frontend = naga::front::glsl::Frontend::default();
    assert!(
        frontend.parse(&naga::front::glsl::Options::from(naga::ShaderStage::Fragment), bad_glsl).is_err()
    );
    // Parses, but the validator must reject the type mismatch (vec3 returned as f32).
    let bad_types = "fn f(n: vec3<f32>) -> f32 { return n; }";
    match naga::front::wgsl::parse_str(bad_types) {
        Err(_) => {}
        Ok(m) => {
            let mut v = naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::empty(),
            );
            assert!(v.validate(&m).is_err());
        }
    }
}
