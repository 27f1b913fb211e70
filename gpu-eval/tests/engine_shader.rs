//! The engine sampling code (`lightvol_gpu::engine_shader`) on the device, against the CPU
//! lookup: for both texel layouts and 4, 9 and 16 coefficients, 10,000 random points
//! (a third of them outside the box, exercising the clamp) and unit normals, on a placed
//! (rotated, anisotropically scaled, translated) grid.
//!
//! The KTX2 layout runs on the texels exactly as the export stores them (RGBA16F slabs,
//! decoded by `unpack2x16float` as the hardware decodes them), and is compared with the
//! CPU lookup of the volume the KTX2 file reads back to (the same f16-rounded values).
//! Without Vulkan the test says so in one line and passes, unless `LIGHTVOL_REQUIRE_GPU=1`.

use lightvol_gpu::engine_shader::{Layout, grid_words, selftest_spirv};
use lightvol_gpu::pipeline::groups_for;
use lightvol_gpu::synthetic::{random_queries, smooth_random_volume};
use lightvol_gpu::{ComputePipeline, gpu_or_skip};
use lightvol_volume::io::ktx2::{ktx2_from_bytes, ktx2_to_bytes};
use lightvol_volume::slab::slab_texels;
use lightvol_volume::{GridSpec, Placement};

/// Queries per configuration.
const QUERIES: usize = 10_000;

/// GPU against the CPU f32 lookup, relative to the largest irradiance of the batch: both
/// are f32 evaluations of the same sums in a different order (the engine code evaluates
/// the basis once and interpolates coefficient by coefficient; the CPU interpolates all
/// coefficients then shades), a few f32 ulps (1.2e-7) times the ~16 terms of the sum and
/// the conditioning of the trilinear weights.
const GPU_VS_CPU_REL: f64 = 2e-5;

fn placement() -> Placement {
    let (s, c) = 30f64.to_radians().sin_cos();
    Placement::new([[2.0 * c, -s, 0.0, 10.0], [2.0 * s, c, 0.0, -4.0], [0.0, 0.0, 0.5, 1.0]]).unwrap()
}

#[test]
fn engine_sampling_code_matches_the_cpu_lookup_on_the_device() {
    let Some(ctx) = gpu_or_skip() else { return };
    for layout in [Layout::Native, Layout::Ktx2] {
        let spirv = selftest_spirv(layout).unwrap();
        let name = match layout {
            Layout::Native => "engine_native",
            Layout::Ktx2 => "engine_ktx2",
        };
        let pipeline = ComputePipeline::new(&ctx, name, &spirv, 5).unwrap();
        for (coeffs, seed) in [(4usize, 1u64), (9, 2), (16, 3)] {
            let spec = GridSpec::new([-1.0, 0.0, 2.0], [3.0, 1.5, 5.0], [9, 6, 7])
                .unwrap()
                .with_placement(placement());
            let vol = smooth_random_volume(spec.clone(), coeffs, seed).unwrap();
            let (cpu_vol, data): (_, Vec<u32>) = match layout {
                Layout::Native => (vol.clone(), vol.data().iter().map(|v| v.to_bits()).collect()),
                Layout::Ktx2 => {
                    let bytes = slab_texels(&vol).unwrap();
                    let words =
                        bytes.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
                    (ktx2_from_bytes(&ktx2_to_bytes(&vol).unwrap()).unwrap(), words)
                }
            };
            let (points, normals) = random_queries(&spec, QUERIES, 0.15, seed);
            let grid = ctx.upload(&grid_words(&spec, coeffs)).unwrap();
            let texels = ctx.upload(&data).unwrap();
            let p = ctx.upload(points.as_flattened()).unwrap();
            let n = ctx.upload(normals.as_flattened()).unwrap();
            let out = ctx.zeroed_buffer(12 * QUERIES as u64).unwrap();
            pipeline
                .dispatch(&[&grid, &texels, &p, &n, &out], groups_for(QUERIES as u64, 65_535), 1)
                .unwrap();
            let gpu: Vec<f32> = out.read(0, 3 * QUERIES).unwrap();
            let mut worst = 0.0f64;
            let mut scale = 0.0f64;
            for q in 0..QUERIES {
                let want = cpu_vol.irradiance(points[q], normals[q]);
                for ch in 0..3 {
                    worst = worst.max((f64::from(gpu[3 * q + ch]) - f64::from(want[ch])).abs());
                    scale = scale.max(f64::from(want[ch]).abs());
                }
            }
            // The results are real irradiances, not an untouched buffer.
            assert!(
                gpu.iter().filter(|v| v.abs() > 1e-3 * scale as f32).count() > QUERIES,
                "{name}: empty results"
            );
            let rel = worst / scale;
            eprintln!("{name}, {coeffs} coefficients: max |GPU − CPU| / max |E| = {rel:.2e}");
            assert!(scale > 0.0 && rel < GPU_VS_CPU_REL, "{name} {coeffs}: {rel:e}");
            // Negative control: the grid block of another resolution (nodes misaddressed)
            // is caught by the same comparison.
            let wrong_spec = GridSpec::new([-1.0, 0.0, 2.0], [3.0, 1.5, 5.0], [6, 9, 7])
                .unwrap()
                .with_placement(placement());
            let wrong = ctx.upload(&grid_words(&wrong_spec, coeffs)).unwrap();
            pipeline
                .dispatch(&[&wrong, &texels, &p, &n, &out], groups_for(QUERIES as u64, 65_535), 1)
                .unwrap();
            let bad: Vec<f32> = out.read(0, 3 * QUERIES).unwrap();
            let bad_err =
                (0..3 * QUERIES).map(|i| (f64::from(bad[i]) - f64::from(gpu[i])).abs()).fold(0.0, f64::max)
                    / scale;
            assert!(
                bad_err > 100.0 * GPU_VS_CPU_REL,
                "{name} {coeffs}: a misaddressed grid gives only {bad_err:e}"
            );
        }
    }
}
