//! Shader functions for engines that sample lightvol volumes: one WGSL source, translated by
//! naga into HLSL and GLSL, and run on the device by the tests against the CPU lookup.
//!
//! The source ([`wgsl_source`]) holds, for either texel [`Layout`]:
//!
//! - `LightvolGrid`: the world-to-grid affine rows, grid minimum, `(n − 1)/(max − min)`, node
//!   counts and coefficient count ([`grid_words`] fills it from a [`GridSpec`]);
//! - `lightvol_grid_position`: world position → continuous node coordinates, clamped to the
//!   box (lightvol's clamping);
//! - `lightvol_sh_basis`: lightvol-sh's real orthonormal SH (no Condon-Shortley phase, +z
//!   polar axis) by its normalised recurrence, with the constants computed on the host in
//!   f64 ([`ShRecurrence`]) and written into the source as f32 literals;
//! - `lightvol_fetch`: one node's coefficient (RGB) — from the KTX2 export's RGBA16F 3D
//!   texture (`textureLoad` at `(x, y, j·nz + z)`; the hardware decodes f16), or from the
//!   native `[node][coeff][rgb]` f32 array in a storage buffer;
//! - `lightvol_irradiance(p, n)`: trilinear interpolation of every coefficient (Kontkanen &
//!   Laine 2006, Eq. 2) and `E = Σ_j A_l(j) Y_j(n) c_j` (Eq. 3, `A_l` the cosine-lobe
//!   factors of lightvol-sh, also written as literals);
//! - `lightvol_irradiance_valid(p, n)`: the same with the trilinear weights renormalised
//!   over the valid corners (a `point+apv` volume's validity mask, one bit per node in a
//!   storage buffer; lightvol-volume's `validity`);
//! - `lightvol_irradiance_reach(p, n)`: the same with the weights renormalised over the
//!   corners whose node reach sees the test point `p + n · bias` (a `doi` volume's reach, six
//!   f32 per node in a storage buffer; lightvol-volume's `reach`, its edge test and
//!   tolerance; `bias` in the grid block, [`grid_words`]);
//! - `lightvol_irradiance_groups`, `_groups_valid`, `_groups_reach`: the same three lookups
//!   of a volume split by light group, relit by one RGB scale per group (a storage buffer
//!   of `vec4`, its length the group count): `Σ_g s_g c_g` interpolated and shaded. The
//!   groups' coefficients come from the export's stacked `STEM.groups.ktx2` (groups along
//!   y: texel `(x, g·ny + y, j·nz + z)`) or from `[group][node][coeff][rgb]` f32 in a storage
//!   buffer. A sky transfer's scales are the new sky's SH radiance coefficients, scenarios'
//!   their blend weights (lightvol-volume's `light_groups`);
//! - a compute entry point `main` that evaluates queries from buffers with the lookup a
//!   selector names (the tests run it; an engine keeps the functions and drops it).
//!
//! Positions and normals are in the frame of the file the texels came from (exports are in
//! the scene file's frame; see the sidecar's `frame`).

use lightvol_sh::index::sh_lm;
use lightvol_sh::irradiance::cosine_lobe_factor;
use lightvol_volume::GridSpec;
use lightvol_volume::reach::REACH_EDGE_TOLERANCE;

use crate::error::GpuError;
use crate::lookup::ShRecurrence;

/// Where the coefficients come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Layout {
    /// The KTX2 export: RGBA16F 3D texture, coefficient `j` of node `(x, y, z)` at texel
    /// `(x, y, j·nz + z)` (lightvol-volume's `slab` layout).
    Ktx2,
    /// The native layout: `[node][coeff][rgb]` f32, nodes x fastest (the EXR's data).
    Native,
}

/// Target shading language.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Language {
    /// WGSL (the source).
    Wgsl,
    /// HLSL, shader model 5.1 (naga's HLSL backend).
    Hlsl,
    /// GLSL 4.50 core (naga's GLSL backend).
    Glsl,
}

/// Words of the `LightvolGrid` block ([`grid_words`]).
pub const GRID_WORDS: usize = 24;

/// Bindings of the sources' group 0: the grid block, the coefficients, the test entry
/// point's points, normals and results, the validity mask, the node reach, the test entry
/// point's lookup selector, the light groups' coefficients and their scales (module docs).
pub const BINDINGS: u32 = 10;

/// The `LightvolGrid` block for `spec` with `coeffs` coefficients, as 4-byte words: rows of
/// the world-to-grid map (identity when unplaced), grid minimum and the node reach's
/// test-point offset (`lightvol_volume::lookup::reach_bias`), `(n − 1)/(max − min)`, then
/// `nx, ny, nz, coeffs` as u32. f32 values are computed in f64 and rounded once.
#[must_use]
pub fn grid_words(spec: &GridSpec, coeffs: usize) -> [u32; GRID_WORDS] {
    let mut w = [0u32; GRID_WORDS];
    let to_grid = spec.placement().map_or(
        [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
        lightvol_volume::Placement::to_grid_matrix,
    );
    for r in 0..3 {
        for c in 0..4 {
            w[4 * r + c] = (to_grid[r][c] as f32).to_bits();
        }
    }
    let (min, max) = spec.bounds();
    let res = spec.res();
    for a in 0..3 {
        w[12 + a] = (min[a] as f32).to_bits();
        w[16 + a] = ((f64::from(res[a] - 1) / (max[a] - min[a])) as f32).to_bits();
        w[20 + a] = res[a];
    }
    w[15] = (lightvol_volume::lookup::reach_bias(spec) as f32).to_bits();
    w[23] = coeffs as u32;
    w
}

/// An f32 literal that WGSL reads back to the same f32 (shortest round-trip form).
fn lit(v: f32) -> String {
    let s = format!("{v:?}");
    if s.contains('.') || s.contains('e') { s } else { format!("{s}.0") }
}

fn array_lit(v: &[f32]) -> String {
    format!("array<f32, {}>({})", v.len(), v.iter().map(|&x| lit(x)).collect::<Vec<_>>().join(", "))
}

/// The generated constants: the SH recurrence, the cosine-lobe factors `A_l(j)` and the
/// node reach's edge limit.
pub(crate) fn constants() -> String {
    let r = ShRecurrence::new();
    let lobe: Vec<f32> = (0..16).map(|j| cosine_lobe_factor(sh_lm(j).0) as f32).collect();
    format!(
        "// Generated by lightvol-gpu from lightvol-sh (f64, rounded once to f32).\n\
         const LIGHTVOL_SH_DIAG = {};\nconst LIGHTVOL_SH_A = {};\nconst LIGHTVOL_SH_B = {};\n\
         // A_l(j): pi, 2 pi / 3, pi / 4, 0 for bands 0..3 (Ramamoorthi & Hanrahan 2001).\n\
         const LIGHTVOL_COSINE_LOBE = {};\n\
         // A cell edge is blocked from both ends when its two reaches sum to at most this\n\
         // (one cell plus lightvol-volume's REACH_EDGE_TOLERANCE).\n\
         const LIGHTVOL_REACH_EDGE = {};\n",
        array_lit(&r.diag),
        array_lit(&r.a),
        array_lit(&r.b),
        array_lit(&lobe),
        lit((1.0 + REACH_EDGE_TOLERANCE) as f32)
    )
}

// `lightvol_sh_basis` in CORE is the twin of the evaluator's `sh_basis` (`shaders/sh.wgsl`):
// the same recurrence and operation order, with the constants as generated literals instead
// of the evaluator's uniform block (an engine binds no lightvol uniforms). The device tests
// hold both against the CPU lookups (`tests/lookup.rs`, `tests/engine_shader.rs`).
const CORE: &str = include_str!("../shaders/engine.wgsl");

/// The SH basis and the trilinear corner weights, shared with the brick sampling code
/// ([`crate::brick_shader`]).
pub(crate) const COMMON: &str = include_str!("../shaders/engine_common.wgsl");

/// `lightvol_renormalise`, shared with the Vulkan evaluator's lookup kernel.
const WEIGHTS: &str = include_str!("../shaders/weights.wgsl");

const FETCH_TEXTURE: &str = r"
// KTX2 export: RGBA16F 3D texture, coefficient j of node (x, y, z) at texel (x, y, j nz + z).
@group(0) @binding(1) var lightvol_volume_texture: texture_3d<f32>;

fn lightvol_fetch(grid: LightvolGrid, node: vec3<u32>, j: u32) -> vec3<f32> {
    let t = vec3<i32>(i32(node.x), i32(node.y), i32(j * grid.dims.z + node.z));
    return textureLoad(lightvol_volume_texture, t, 0).rgb;
}

// The groups' KTX2 texture (export's STEM.groups.ktx2): RGBA16F, the groups stacked along y,
// coefficient j of node (x, y, z) in group g at texel (x, g ny + y, j nz + z).
@group(0) @binding(8) var lightvol_group_texture: texture_3d<f32>;

fn lightvol_fetch_group(grid: LightvolGrid, node: vec3<u32>, j: u32, g: u32, groups: u32) -> vec3<f32> {
    let t = vec3<i32>(i32(node.x), i32(g * grid.dims.y + node.y), i32(j * grid.dims.z + node.z));
    return textureLoad(lightvol_group_texture, t, 0).rgb;
}
";

const FETCH_F16_BUFFER: &str = r"
// KTX2 texels as stored (RGBA16F, two u32 words per texel), decoded as the hardware does.
@group(0) @binding(1) var<storage, read> lightvol_volume_texels: array<u32>;

fn lightvol_fetch(grid: LightvolGrid, node: vec3<u32>, j: u32) -> vec3<f32> {
    let z = j * grid.dims.z + node.z;
    let texel = (z * grid.dims.y + node.y) * grid.dims.x + node.x;
    let rg = unpack2x16float(lightvol_volume_texels[2u * texel]);
    let ba = unpack2x16float(lightvol_volume_texels[2u * texel + 1u]);
    return vec3<f32>(rg.x, rg.y, ba.x);
}

// The groups' KTX2 texels as stored (groups stacked along y), decoded as the hardware does.
@group(0) @binding(8) var<storage, read> lightvol_group_texels: array<u32>;

fn lightvol_fetch_group(grid: LightvolGrid, node: vec3<u32>, j: u32, g: u32, groups: u32) -> vec3<f32> {
    let z = j * grid.dims.z + node.z;
    let texel = (z * groups * grid.dims.y + g * grid.dims.y + node.y) * grid.dims.x + node.x;
    let rg = unpack2x16float(lightvol_group_texels[2u * texel]);
    let ba = unpack2x16float(lightvol_group_texels[2u * texel + 1u]);
    return vec3<f32>(rg.x, rg.y, ba.x);
}
";

const FETCH_NATIVE: &str = r"
// Native layout: [node][coeff][rgb] f32, nodes x fastest.
@group(0) @binding(1) var<storage, read> lightvol_volume_coeffs: array<f32>;

fn lightvol_fetch(grid: LightvolGrid, node: vec3<u32>, j: u32) -> vec3<f32> {
    let index = (node.z * grid.dims.y + node.y) * grid.dims.x + node.x;
    let at = 3u * (index * grid.dims.w + j);
    return vec3<f32>(lightvol_volume_coeffs[at], lightvol_volume_coeffs[at + 1u], lightvol_volume_coeffs[at + 2u]);
}

// The groups' coefficients in the native layout: [group][node][coeff][rgb] f32 (the EXR's
// group parts in group order).
@group(0) @binding(8) var<storage, read> lightvol_group_coeffs: array<f32>;

fn lightvol_fetch_group(grid: LightvolGrid, node: vec3<u32>, j: u32, g: u32, groups: u32) -> vec3<f32> {
    let nodes = grid.dims.x * grid.dims.y * grid.dims.z;
    let index = (node.z * grid.dims.y + node.y) * grid.dims.x + node.x;
    let at = 3u * ((g * nodes + index) * grid.dims.w + j);
    return vec3<f32>(lightvol_group_coeffs[at], lightvol_group_coeffs[at + 1u], lightvol_group_coeffs[at + 2u]);
}
";

const ENTRY: &str = r"
// Queries: packed xyz points and normals, packed RGB results; the count is the length of
// the result array / 3; the lookup: 0 lightvol_irradiance, 1 lightvol_irradiance_valid,
// 2 lightvol_irradiance_reach, 3-5 the same of the light groups' relit volume. (Tests run this; an engine calls the lookups directly.)
@group(0) @binding(0) var<storage, read> lightvol_grid: LightvolGrid;
@group(0) @binding(2) var<storage, read> lightvol_points: array<f32>;
@group(0) @binding(3) var<storage, read> lightvol_normals: array<f32>;
@group(0) @binding(4) var<storage, read_write> lightvol_result: array<f32>;
@group(0) @binding(7) var<storage, read> lightvol_lookup: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = gid.x;
    if 3u * q >= arrayLength(&lightvol_result) {
        return;
    }
    let p = vec3<f32>(lightvol_points[3u * q], lightvol_points[3u * q + 1u], lightvol_points[3u * q + 2u]);
    let n = vec3<f32>(lightvol_normals[3u * q], lightvol_normals[3u * q + 1u], lightvol_normals[3u * q + 2u]);
    var e: vec3<f32>;
    switch lightvol_lookup[0] {
        case 1u: {
            e = lightvol_irradiance_valid(lightvol_grid, p, n);
        }
        case 2u: {
            e = lightvol_irradiance_reach(lightvol_grid, p, n);
        }
        case 3u: {
            e = lightvol_irradiance_groups(lightvol_grid, p, n);
        }
        case 4u: {
            e = lightvol_irradiance_groups_valid(lightvol_grid, p, n);
        }
        case 5u: {
            e = lightvol_irradiance_groups_reach(lightvol_grid, p, n);
        }
        default: {
            e = lightvol_irradiance(lightvol_grid, p, n);
        }
    }
    lightvol_result[3u * q] = e.x;
    lightvol_result[3u * q + 1u] = e.y;
    lightvol_result[3u * q + 2u] = e.z;
}
";

/// The WGSL source for `layout` (module docs): what engines include.
#[must_use]
pub fn wgsl_source(layout: Layout) -> String {
    let fetch = match layout {
        Layout::Ktx2 => FETCH_TEXTURE,
        Layout::Native => FETCH_NATIVE,
    };
    format!(
        "// lightvol volume sampling ({} layout), generated by lightvol-gpu {}.\n{}{COMMON}{CORE}{WEIGHTS}{fetch}{ENTRY}",
        match layout {
            Layout::Ktx2 => "KTX2 RGBA16F",
            Layout::Native => "native f32",
        },
        env!("CARGO_PKG_VERSION"),
        constants()
    )
}

/// The source the device tests run for `layout`: [`wgsl_source`] with the KTX2 texture
/// replaced by its stored texels in a storage buffer (decoded by `unpack2x16float`, exactly
/// as the hardware decodes RGBA16F), so that everything but `textureLoad` itself runs.
#[must_use]
pub fn selftest_source(layout: Layout) -> String {
    match layout {
        Layout::Ktx2 => format!(
            "// lightvol volume sampling, device test.\n{}{COMMON}{CORE}{WEIGHTS}{FETCH_F16_BUFFER}{ENTRY}",
            constants()
        ),
        Layout::Native => wgsl_source(Layout::Native),
    }
}

fn parse_and_validate(src: &str, what: &str) -> Result<(naga::Module, naga::valid::ModuleInfo), GpuError> {
    validate_with(src, what, naga::valid::Capabilities::empty())
}

fn validate_with(
    src: &str,
    what: &str,
    caps: naga::valid::Capabilities,
) -> Result<(naga::Module, naga::valid::ModuleInfo), GpuError> {
    let module = naga::front::wgsl::parse_str(src)
        .map_err(|e| GpuError::Invalid(format!("{what}: WGSL parse error: {}", e.emit_to_string(src))))?;
    let info =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps).validate(&module).map_err(
            |e| GpuError::Invalid(format!("{what}: WGSL validation error: {}", e.emit_to_string(src))),
        )?;
    Ok((module, info))
}

/// The sampling code for `layout` in `language`: the WGSL source, or naga's translation of
/// the validated module. The GLSL is parsed and validated again by naga's GLSL front end;
/// naga has no HLSL front end, so the HLSL is checked only as the translation of the
/// validated module.
///
/// # Errors
/// [`GpuError::Invalid`] with naga's diagnostic (a bug in the source or in naga).
pub fn shader_source(language: Language, layout: Layout) -> Result<String, GpuError> {
    translate(wgsl_source(layout), language)
}

/// WGSL `src` validated, and translated by naga into `language` (see [`shader_source`]).
pub(crate) fn translate(src: String, language: Language) -> Result<String, GpuError> {
    let (module, info) = parse_and_validate(&src, "lightvol sampling")?;
    match language {
        Language::Wgsl => Ok(src),
        Language::Hlsl => {
            let options = naga::back::hlsl::Options {
                shader_model: naga::back::hlsl::ShaderModel::V5_1,
                fake_missing_bindings: true,
                ..naga::back::hlsl::Options::default()
            };
            let mut out = String::new();
            naga::back::hlsl::Writer::new(&mut out, &options, &naga::back::hlsl::PipelineOptions::default())
                .write(&module, &info, None)
                .map_err(|e| GpuError::Invalid(format!("HLSL backend: {e}")))?;
            Ok(format!("// lightvol volume sampling, HLSL (translated from WGSL by naga).\n{out}"))
        }
        Language::Glsl => {
            // `layout(binding = N)` for WGSL's `@binding(N)` (all in group 0).
            let binding_map = (0..BINDINGS as u8)
                .map(|b| (naga::ResourceBinding { group: 0, binding: u32::from(b) }, b))
                .collect();
            let options = naga::back::glsl::Options {
                version: naga::back::glsl::Version::Desktop(450),
                binding_map,
                ..naga::back::glsl::Options::default()
            };
            let pipeline = naga::back::glsl::PipelineOptions {
                shader_stage: naga::ShaderStage::Compute,
                entry_point: "main".into(),
                multiview: None,
            };
            let mut out = String::new();
            let mut w = naga::back::glsl::Writer::new(
                &mut out,
                &module,
                &info,
                &options,
                &pipeline,
                naga::proc::BoundsCheckPolicies::default(),
            )
            .map_err(|e| GpuError::Invalid(format!("GLSL backend: {e}")))?;
            w.write().map_err(|e| GpuError::Invalid(format!("GLSL backend: {e}")))?;
            validate_glsl(&out)?;
            Ok(out)
        }
    }
}

/// Parses and validates GLSL (compute stage) with naga's GLSL front end (see the note on
/// `readonly` inside).
///
/// # Errors
/// [`GpuError::Invalid`] with the parse or validation errors.
pub fn validate_glsl(src: &str) -> Result<(), GpuError> {
    // naga's GLSL front end implements neither the `readonly` buffer qualifier its own
    // backend writes (it changes access, not meaning) nor combined `sampler3D` uniforms
    // (Vulkan GLSL's separate texture and sampler, combined at the call, mean the same
    // fetch), so both are rewritten before parsing.
    let mut src = src.replace("readonly buffer", "buffer");
    // Float and unsigned textures (`sampler3D`, `usampler3D`).
    for kind in ["", "u"] {
        let combined: Vec<String> = src
            .lines()
            .filter_map(|l| {
                l.split(&format!("uniform {kind}sampler3D "))
                    .nth(1)
                    .map(|n| n.trim_end_matches(';').trim().to_owned())
            })
            .collect();
        for name in combined {
            src = src
                .replace(
                    &format!("uniform {kind}sampler3D {name};"),
                    &format!(
                        "uniform {kind}texture3D {name}_t;\nlayout(binding = 15) uniform sampler {name}_s;"
                    ),
                )
                .replace(
                    &format!("texelFetch({name},"),
                    &format!("texelFetch({kind}sampler3D({name}_t, {name}_s),"),
                );
        }
    }
    let mut frontend = naga::front::glsl::Frontend::default();
    let module = frontend
        .parse(&naga::front::glsl::Options::from(naga::ShaderStage::Compute), &src)
        .map_err(|e| GpuError::Invalid(format!("GLSL parse error: {e:?}")))?;
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
        .validate(&module)
        .map_err(|e| GpuError::Invalid(format!("GLSL validation error: {e:?}")))?;
    Ok(())
}

/// SPIR-V of [`selftest_source`] for the device tests.
///
/// # Errors
/// As [`shader_source`].
pub fn selftest_spirv(layout: Layout) -> Result<Vec<u32>, GpuError> {
    selftest_spirv_of(&selftest_source(layout), "lightvol sampling self-test")
}

/// SPIR-V 1.0 of a device-test source `src` (named `what` in errors), validated with the
/// float16-in-float32 capability that `unpack2x16float` (the f16 decode of stored KTX2
/// texels) needs.
pub(crate) fn selftest_spirv_of(src: &str, what: &str) -> Result<Vec<u32>, GpuError> {
    let (module, info) = validate_with(src, what, naga::valid::Capabilities::SHADER_FLOAT16_IN_FLOAT32)?;
    let options = naga::back::spv::Options {
        lang_version: (1, 0),
        flags: naga::back::spv::WriterFlags::empty(),
        ..naga::back::spv::Options::default()
    };
    naga::back::spv::write_vec(&module, &info, &options, None)
        .map_err(|e| GpuError::Invalid(format!("SPIR-V backend: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every language and layout comes out, validated (WGSL and GLSL by naga's front ends).
    #[test]
    fn every_language_validates() {
        for layout in [Layout::Ktx2, Layout::Native] {
            for lang in [Language::Wgsl, Language::Hlsl, Language::Glsl] {
                let s = shader_source(lang, layout).unwrap_or_else(|e| panic!("{lang:?} {layout:?}: {e}"));
                for f in [
                    "lightvol_irradiance",
                    "lightvol_irradiance_valid",
                    "lightvol_irradiance_reach",
                    "lightvol_irradiance_groups",
                    "lightvol_irradiance_groups_reach",
                ] {
                    assert!(s.contains(f), "{lang:?} {layout:?}: {f}");
                }
            }
            assert!(selftest_spirv(layout).unwrap()[0] == 0x0723_0203);
        }
        // Negative control: the GLSL check really rejects broken code.
        let broken =
            "#version 450\nlayout(local_size_x = 1) in;\nvoid main() { float x = undefined_name * 2.0; }\n";
        assert!(validate_glsl(broken).is_err());
        assert!(
            validate_glsl("#version 450\nlayout(local_size_x = 1) in;\nvoid main() { float x = 2.0; }\n")
                .is_ok()
        );
    }

    /// The literals read back to the host's f32 constants.
    #[test]
    fn literals_round_trip() {
        for v in [1.0f32, 0.282_094_8, -0.5, 1e-30, 3.0e10] {
            assert_eq!(lit(v).parse::<f32>().unwrap(), v);
        }
        let src = wgsl_source(Layout::Native);
        let lobe = std::f32::consts::PI;
        assert!(src.contains(&lit(lobe)), "A_0 = π appears");
        // One cell plus lightvol-volume's 1e-6, rounded to f32 once.
        assert!(src.contains(&format!("const LIGHTVOL_REACH_EDGE = {};", lit(1.000_001))), "reach edge");
    }
}
