//! Compiles the WGSL compute shaders in `shaders/` to SPIR-V in `OUT_DIR` with naga (pure
//! Rust: no C++ toolchain, no checked-in binaries).
//!
//! A shader may be built in several *variants*: the build prepends a few `const`
//! declarations (e.g. `const COEFFS: u32 = 9u;`) and shared helper files (`sh.wgsl`) to the
//! kernel's source, so loops over coefficients have compile-time bounds and private arrays
//! have fixed sizes. Each variant is validated
//! by naga and written to `OUT_DIR/<name>.spv`; `src/shaders.rs` includes them.

use std::path::{Path, PathBuf};

const C4: &str = "const COEFFS: u32 = 4u;\nconst BANDS: u32 = 2u;\n";
const C9: &str = "const COEFFS: u32 = 9u;\nconst BANDS: u32 = 3u;\n";
const C16: &str = "const COEFFS: u32 = 16u;\nconst BANDS: u32 = 4u;\n";

/// `(output name, shader files concatenated in order, prepended WGSL constants)`.
const VARIANTS: &[(&str, &[&str], &str)] = &[
    ("lookup_4", &["sh.wgsl", "weights.wgsl", "lookup.wgsl"], C4),
    ("lookup_9", &["sh.wgsl", "weights.wgsl", "lookup.wgsl"], C9),
    ("lookup_16", &["sh.wgsl", "weights.wgsl", "lookup.wgsl"], C16),
    ("accumulate_9", &["sh.wgsl", "accumulate.wgsl"], C9),
    ("accumulate_16", &["sh.wgsl", "accumulate.wgsl"], C16),
    ("exponentiate_9", &["exponentiate.wgsl"], C9),
    ("exponentiate_16", &["exponentiate.wgsl"], C16),
    ("upsample", &["upsample.wgsl"], ""),
];

fn main() {
    let manifest =
        PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo::rerun-if-changed=build.rs");
    for (name, files, prelude) in VARIANTS {
        let mut source = format!("// variant {name}\n{prelude}");
        for file in *files {
            let path = manifest.join("shaders").join(file);
            println!("cargo::rerun-if-changed={}", path.display());
            let body = std::fs::read_to_string(&path)
                .unwrap_or_else(|e| panic!("cannot read shader {}: {e}", path.display()));
            source.push_str(&format!("// ---- {file}\n{body}"));
        }
        let path = manifest.join("shaders").join(files[files.len() - 1]);
        let words = compile(&source, &path);
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let out = out_dir.join(format!("{name}.spv"));
        std::fs::write(&out, bytes).unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
    }
}

/// WGSL -> validated naga module -> SPIR-V 1.0 words; panics with naga's diagnostic (the
/// prelude shifts line numbers by the number of prepended lines).
fn compile(source: &str, path: &Path) -> Vec<u32> {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("WGSL parse error in {}:\n{}", path.display(), e.emit_to_string(source)));
    let info =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty())
            .validate(&module)
            .unwrap_or_else(|e| {
                panic!("WGSL validation error in {}:\n{}", path.display(), e.emit_to_string(source))
            });
    let options = naga::back::spv::Options {
        lang_version: (1, 0),
        // Every index into a buffer or array is clamped into range (naga's `Restrict`
        // policy), so even a dispatch with inconsistent sizes cannot read or write outside
        // the buffers bound to it. The host checks sizes too; this is the second fence.
        bounds_check_policies: naga::proc::BoundsCheckPolicies {
            index: naga::proc::BoundsCheckPolicy::Restrict,
            buffer: naga::proc::BoundsCheckPolicy::Restrict,
            image_load: naga::proc::BoundsCheckPolicy::Restrict,
            binding_array: naga::proc::BoundsCheckPolicy::Restrict,
        },
        ..naga::back::spv::Options::default()
    };
    naga::back::spv::write_vec(&module, &info, &options, None)
        .unwrap_or_else(|e| panic!("SPIR-V generation failed for {}: {e}", path.display()))
}
