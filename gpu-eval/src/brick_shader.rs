//! Shader functions for engines that sample a brick export (lightvol-volume's `bricks` and
//! `io::bricks`): one WGSL source, translated by naga into HLSL and GLSL, and run on the
//! device by the tests against the CPU lookup.
//!
//! The source ([`brick_wgsl_source`]) holds:
//!
//! - `LightvolBricks`: the map from the scene file's positions to base-cell units, the
//!   rotation of file directions into the SH frame, the box, the indirection grid and the
//!   atlas layout ([`brick_words`] fills it from a `BrickVolume`; every value is also in the
//!   export's JSON description);
//! - `lightvol_brick_entry(t)`: the indirection texel (atlas slot in xyz, level in w), by
//!   `textureLoad` from the RGBA8 unsigned `STEM.indirection.ktx2`;
//! - `lightvol_brick_fetch(b, slot, probe, j)`: coefficient `j` of a brick's probe from the
//!   RGBA16F atlas `STEM.ktx2`, texel `(slot.x·P + x, slot.y·P + y, j·az·P + slot.z·P + z)`;
//! - `lightvol_irradiance_bricks(b, p, n)`: the indirection lookup, trilinear interpolation
//!   inside the brick (Kontkanen & Laine 2006, Eq. 2) and `E = Σ_j A_l(j) Y_j(n) c_j`
//!   (Eq. 3), exactly the steps of the CPU lookup (`BrickVolume::coeffs_at`);
//! - a compute entry point `main` for the tests.
//!
//! Positions and normals are in the scene file's frame, as engines have them.

use lightvol_volume::bricks::BrickVolume;
use lightvol_volume::io::bricks::{atlas_slots, describe};

use crate::engine_shader::{COMMON, Language, constants, selftest_spirv_of, translate};
use crate::error::GpuError;

/// Words of the `LightvolBricks` block ([`brick_words`]).
pub const BRICK_WORDS: usize = 36;

/// Bindings of the brick sources' group 0: the block, the atlas, the test entry point's
/// points, normals and results, and (binding 8) the indirection texture.
pub const BRICK_BINDINGS: u32 = 9;

/// The `LightvolBricks` block of `vol`: the description's `world_to_units` and
/// `normal_to_sh` rows (f64 rounded once to f32), the box's cells per axis and
/// `2^finest / brick_cells`, the indirection's texels per axis and the finest level, the
/// brick size, the atlas's slots along z and the coefficient count.
#[must_use]
pub fn brick_words(vol: &BrickVolume) -> [u32; BRICK_WORDS] {
    let d = describe(vol);
    let mut w = [0u32; BRICK_WORDS];
    for r in 0..3 {
        for c in 0..4 {
            w[4 * r + c] = (d.world_to_units[r][c] as f32).to_bits();
        }
        for c in 0..3 {
            w[12 + 4 * r + c] = (d.normal_to_sh[r][c] as f32).to_bits();
        }
    }
    let res = vol.spec().res();
    for a in 0..3 {
        w[24 + a] = ((res[a] - 1) as f32).to_bits();
        w[28 + a] = vol.indirection_res()[a];
    }
    w[27] = ((1u32 << vol.finest_level()) as f32 / vol.brick_cells() as f32).to_bits();
    w[31] = vol.finest_level();
    w[32] = vol.brick_cells();
    w[33] = atlas_slots(vol.bricks().len())[2];
    w[34] = vol.coeffs() as u32;
    w
}

const CORE: &str = include_str!("../shaders/bricks.wgsl");

const FETCH_TEXTURE: &str = r"
// The export's textures: STEM.ktx2 (RGBA16F atlas) and STEM.indirection.ktx2 (RGBA8 unsigned).
@group(0) @binding(1) var lightvol_brick_atlas: texture_3d<f32>;
@group(0) @binding(8) var lightvol_brick_indirection: texture_3d<u32>;

fn lightvol_brick_entry(t: vec3<u32>) -> vec4<u32> {
    return textureLoad(lightvol_brick_indirection, vec3<i32>(t), 0);
}

fn lightvol_brick_fetch(b: LightvolBricks, slot: vec3<u32>, q: vec3<u32>, j: u32) -> vec3<f32> {
    let p = b.atlas.x + 1u;
    let t = vec3<u32>(slot.x * p + q.x, slot.y * p + q.y, j * b.atlas.y * p + slot.z * p + q.z);
    return textureLoad(lightvol_brick_atlas, vec3<i32>(t), 0).rgb;
}
";

const FETCH_BUFFERS: &str = r"
// The textures' texels as stored, in storage buffers, decoded as the hardware decodes them:
// the atlas two u32 words per RGBA16F texel, the indirection one u32 per RGBA8 texel.
@group(0) @binding(1) var<storage, read> lightvol_brick_atlas: array<u32>;
@group(0) @binding(8) var<storage, read> lightvol_brick_indirection: array<u32>;

fn lightvol_brick_entry(t: vec3<u32>) -> vec4<u32> {
    let dims = lightvol_bricks.indirection.xyz;
    let v = lightvol_brick_indirection[(t.z * dims.y + t.y) * dims.x + t.x];
    return vec4<u32>(v & 255u, (v >> 8u) & 255u, (v >> 16u) & 255u, v >> 24u);
}

fn lightvol_brick_fetch(b: LightvolBricks, slot: vec3<u32>, q: vec3<u32>, j: u32) -> vec3<f32> {
    let p = b.atlas.x + 1u;
    let slots = b.atlas.y;
    let width = lightvol_brick_width * p;
    let height = lightvol_brick_height * p;
    let t = vec3<u32>(slot.x * p + q.x, slot.y * p + q.y, j * slots * p + slot.z * p + q.z);
    let texel = (t.z * height + t.y) * width + t.x;
    let rg = unpack2x16float(lightvol_brick_atlas[2u * texel]);
    let ba = unpack2x16float(lightvol_brick_atlas[2u * texel + 1u]);
    return vec3<f32>(rg.x, rg.y, ba.x);
}
";

const ENTRY: &str = r"
// Queries: packed xyz points and normals (the scene file's frame), packed RGB results.
@group(0) @binding(0) var<storage, read> lightvol_bricks: LightvolBricks;
@group(0) @binding(2) var<storage, read> lightvol_points: array<f32>;
@group(0) @binding(3) var<storage, read> lightvol_normals: array<f32>;
@group(0) @binding(4) var<storage, read_write> lightvol_result: array<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = gid.x;
    if 3u * q >= arrayLength(&lightvol_result) {
        return;
    }
    let p = vec3<f32>(lightvol_points[3u * q], lightvol_points[3u * q + 1u], lightvol_points[3u * q + 2u]);
    let n = vec3<f32>(lightvol_normals[3u * q], lightvol_normals[3u * q + 1u], lightvol_normals[3u * q + 2u]);
    let e = lightvol_irradiance_bricks(lightvol_bricks, p, n);
    lightvol_result[3u * q] = e.x;
    lightvol_result[3u * q + 1u] = e.y;
    lightvol_result[3u * q + 2u] = e.z;
}
";

/// The WGSL source engines include (module docs).
#[must_use]
pub fn brick_wgsl_source() -> String {
    format!(
        "// lightvol brick volume sampling, generated by lightvol-gpu {}.\n{}{COMMON}{CORE}{FETCH_TEXTURE}{ENTRY}",
        env!("CARGO_PKG_VERSION"),
        constants()
    )
}

/// The brick sampling code in `language` (WGSL, or naga's HLSL or GLSL translation).
///
/// # Errors
/// [`GpuError::Invalid`] with naga's diagnostic.
pub fn brick_shader_source(language: Language) -> Result<String, GpuError> {
    translate(brick_wgsl_source(), language)
}

/// The source the device tests run for an atlas of `slots` slots per axis: the textures
/// replaced by their texels in storage buffers (so everything but `textureLoad` runs).
#[must_use]
pub fn brick_selftest_source(slots: [u32; 3]) -> String {
    format!(
        "// lightvol brick volume sampling, device test.\n{}const lightvol_brick_width = {}u;\nconst lightvol_brick_height = {}u;\n{COMMON}{CORE}{FETCH_BUFFERS}{ENTRY}",
        constants(),
        slots[0],
        slots[1]
    )
}

/// SPIR-V of [`brick_selftest_source`].
///
/// # Errors
/// As [`brick_shader_source`].
pub fn brick_selftest_spirv(slots: [u32; 3]) -> Result<Vec<u32>, GpuError> {
    selftest_spirv_of(&brick_selftest_source(slots), "lightvol brick self-test")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_language_validates() {
        for lang in [Language::Wgsl, Language::Hlsl, Language::Glsl] {
            let s = brick_shader_source(lang).unwrap_or_else(|e| panic!("{lang:?}: {e}"));
            assert!(s.contains("lightvol_irradiance_bricks"), "{lang:?}");
        }
        assert_eq!(brick_selftest_spirv([3, 3, 2]).unwrap()[0], 0x0723_0203);
    }
}
