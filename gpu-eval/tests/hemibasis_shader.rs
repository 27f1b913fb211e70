//! The hemispherical-basis lightmap snippets (`lightvol_hemibasis::shader::wgsl`) on the
//! device, the way an engine samples `bake-surface --encode png|ktx2` maps: 8-bit texels,
//! the DC plane in an `_SRGB` format (decoded to linear by the texture unit, emulated here
//! with the IEC 61966-2-1 curve), the other planes `UNORM` (`v / 255`), then the snippet's
//! `lv_TAG_irradiance_stored`. Compared, for every basis and 2,000 random tangent-space
//! normals and texel sets, with the CPU path of the exported maps: `Encoding::decode_u8`
//! with `DcTransfer::Srgb` and the basis evaluated in f64. Without Vulkan the test says so
//! in one line and passes, unless `LIGHTVOL_REQUIRE_GPU=1`.

use lightvol_gpu::pipeline::groups_for;
use lightvol_gpu::{ComputePipeline, gpu_or_skip};
use lightvol_hemibasis::encode::{DcTransfer, Encoding};
use lightvol_hemibasis::{HemiBasis, by_name};
use lightvol_sh::lowdisc::SplitMix64;

const QUERIES: usize = 2000;

/// Device (f32, the basis as printed constants) against the f64 CPU path, relative to the
/// largest |E|: f32 rounding (6e-8) of ≤ 16 products of O(1) terms and of the sRGB curve
/// (measured on lavapipe: 1.7e-7 to 2.0e-7).
const GPU_VS_CPU_REL: f64 = 2e-6;

/// The compute wrapper: texels as u32 (one byte per channel, RGBA8 as stored), the DC
/// plane linearised as an `_SRGB` format would, the rest as `UNORM`.
fn wrapper(basis: &dyn HemiBasis) -> String {
    let tag = basis.tag();
    let k = basis.len();
    let dc = basis.dc_index().map_or("0xffffffffu".to_owned(), |d| format!("{d}u"));
    format!(
        r"{snippet}
@group(0) @binding(0) var<storage, read> params: array<f32>;
@group(0) @binding(1) var<storage, read> texels: array<u32>;
@group(0) @binding(2) var<storage, read> normals: array<f32>;
@group(0) @binding(3) var<storage, read> unused: array<f32>;
@group(0) @binding(4) var<storage, read_write> result: array<f32>;

fn srgb_to_linear(v: f32) -> f32 {{
    if v <= 0.04045 {{ return v / 12.92; }}
    return pow((v + 0.055) / 1.055, 2.4);
}}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {{
    let q = gid.x;
    if 3u * q >= arrayLength(&result) {{ return; }}
    var t: array<vec3<f32>, {k}>;
    for (var i = 0u; i < {k}u; i++) {{
        let packed = texels[q * {k}u + i];
        var c = vec3<f32>(f32(packed & 255u), f32((packed >> 8u) & 255u), f32((packed >> 16u) & 255u)) / 255.0;
        if i == {dc} {{ c = vec3<f32>(srgb_to_linear(c.x), srgb_to_linear(c.y), srgb_to_linear(c.z)); }}
        t[i] = c;
    }}
    let n = vec3<f32>(normals[3u * q], normals[3u * q + 1u], normals[3u * q + 2u]);
    let e = lv_{tag}_irradiance_stored(n, t, {k}u, params[0], params[1]);
    result[3u * q] = e.x;
    result[3u * q + 1u] = e.y;
    result[3u * q + 2u] = e.z;
}}
",
        snippet = lightvol_hemibasis::shader::wgsl(basis)
    )
}

fn spirv(src: &str) -> Vec<u32> {
    let module = naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)));
    let info =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty())
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)));
    let options = naga::back::spv::Options { lang_version: (1, 0), ..naga::back::spv::Options::default() };
    naga::back::spv::write_vec(&module, &info, &options, None).unwrap()
}

#[test]
fn hemibasis_snippets_decode_exported_maps_like_the_cpu() {
    let Some(ctx) = gpu_or_skip() else { return };
    let bases: Vec<Box<dyn HemiBasis>> =
        [("sh", 9), ("hl2", 3), ("hsh", 9), ("hbasis_mod", 6), ("hbasis", 4), ("makhotkin", 9)]
            .iter()
            .filter_map(|(name, k)| by_name(name, *k))
            .collect();
    assert!(bases.len() >= 4, "the default features compile these bases in");
    let enc = Encoding { range: 0.75, dc: DcTransfer::Srgb, quantize_8bit: true };
    let inv_scale = 1.75f32;
    for basis in &bases {
        let k = basis.len();
        let mut rng = SplitMix64::new(k as u64 * 131 + basis.tag().len() as u64);
        let texels: Vec<[u8; 3]> =
            (0..QUERIES * k).map(|_| std::array::from_fn(|_| (rng.next_f64() * 255.99) as u8)).collect();
        let normals: Vec<[f32; 3]> = (0..QUERIES)
            .map(|_| {
                // Uniform on the upper hemisphere (tangent space, +z out of the surface).
                let d = lightvol_sh::sampling::sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
                [d[0] as f32, d[1] as f32, d[2].abs() as f32]
            })
            .collect();
        let words: Vec<u32> = texels
            .iter()
            .map(|t| u32::from(t[0]) | (u32::from(t[1]) << 8) | (u32::from(t[2]) << 16))
            .collect();
        let pipeline =
            ComputePipeline::new(&ctx, "hemibasis_snippet", &spirv(&wrapper(basis.as_ref())), 5).unwrap();
        let params = ctx.upload(&[enc.range as f32, inv_scale]).unwrap();
        let tb = ctx.upload(&words).unwrap();
        let nb = ctx.upload(normals.as_flattened()).unwrap();
        let unused = ctx.upload(&[0.0f32]).unwrap();
        let out = ctx.zeroed_buffer(12 * QUERIES as u64).unwrap();
        pipeline
            .dispatch(&[&params, &tb, &nb, &unused, &out], groups_for(QUERIES as u64, 65_535), 1)
            .unwrap();
        let gpu: Vec<f32> = out.read(0, 3 * QUERIES).unwrap();
        let (mut worst, mut scale) = (0.0f64, 0.0f64);
        let mut b = vec![0.0f64; k];
        for q in 0..QUERIES {
            let coeffs = enc.decode_u8(basis.as_ref(), &texels[q * k..(q + 1) * k]);
            basis.eval_f64(normals[q].map(f64::from), &mut b);
            for ch in 0..3 {
                let want: f64 = (0..k).map(|i| coeffs[i][ch] * b[i]).sum::<f64>() * f64::from(inv_scale);
                worst = worst.max((f64::from(gpu[3 * q + ch]) - want).abs());
                scale = scale.max(want.abs());
            }
        }
        let rel = worst / scale;
        eprintln!("{}: max |GPU − CPU| / max |E| = {rel:.2e}", basis.tag());
        assert!(scale > 0.0 && rel < GPU_VS_CPU_REL, "{}: {rel:e}", basis.tag());
    }
}
