//! Compiles the WGSL shaders to SPIR-V (placeholder).
fn main() {}
