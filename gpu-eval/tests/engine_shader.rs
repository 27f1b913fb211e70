//! The engine sampling code (`lightvol_gpu::engine_shader`) on the device, against the CPU
//! lookup: for both texel layouts and 4, 9 and 16 coefficients, 10,000 random points
//! (a third of them outside the box, exercising the clamp) and unit normals, on a placed
//! (rotated, anisotropically scaled, translated) grid.
//!
//! The KTX2 layout runs on the texels exactly as the export stores them (RGBA16F slabs,
//! decoded by `unpack2x16float` as the hardware decodes them), and is compared with the
//! CPU lookup of the volume the KTX2 file reads back to (the same f16-rounded values).
//!
//! The validity-weighted and the node-reach lookups (`lightvol_irradiance_valid`,
//! `lightvol_irradiance_reach`) run on a volume with a random validity mask and a random
//! node reach, against the CPU lookup of the same volume with the mask or the reach.
//!
//! The light-group lookups (`lightvol_irradiance_groups`, `_groups_valid`, `_groups_reach`)
//! run on three random groups with mixed-sign RGB scales (as a sky transfer's are), from
//! the native layout and from the stacked KTX2 texels, against the CPU lookup of the
//! volume [`GroupedVolume::relit`] gives (from the f16-rounded layers for KTX2).
//!
//! Without Vulkan the tests say so in one line and pass, unless `LIGHTVOL_REQUIRE_GPU=1`.

use lightvol_gpu::engine_shader::{BINDINGS, Layout, grid_words, selftest_spirv};
use lightvol_gpu::lookup::validity_words;
use lightvol_gpu::pipeline::groups_for;
use lightvol_gpu::synthetic::{clear_of_reach_decisions, random_masks, random_queries, smooth_random_volume};
use lightvol_gpu::{ComputePipeline, GpuBuffer, GpuContext, gpu_or_skip};
use lightvol_volume::io::ktx2::{ktx2_from_bytes, ktx2_to_bytes};
use lightvol_volume::slab::slab_texels;
use lightvol_volume::slab::{layers_from_stacked_texels, stacked_slab_texels};
use lightvol_volume::{FileFormat, GridSpec, GroupedVolume, IrradianceVolume, Placement};

/// Queries per configuration.
const QUERIES: usize = 10_000;

/// GPU against the CPU f32 lookup, relative to the largest irradiance of the batch: both
/// are f32 evaluations of the same sums in a different order (the engine code evaluates
/// the basis once and interpolates coefficient by coefficient; the CPU interpolates all
/// coefficients then shades), a few f32 ulps (1.2e-7) times the ~16 terms of the sum and
/// the conditioning of the trilinear weights.
const GPU_VS_CPU_REL: f64 = 2e-5;

/// The test entry point's lookup selector: plain, validity-weighted, node reach.
const PLAIN: u32 = 0;
const VALID: u32 = 1;
const REACH: u32 = 2;

/// The test entry point's light-group lookups: plain, validity-weighted, node reach.
const GROUPS: u32 = 3;
const GROUPS_VALID: u32 = 4;
const GROUPS_REACH: u32 = 5;

/// The buffers of bindings 5-9: every node valid, every node reaching a cell (the plain
/// lookup reads neither), the lookup selector, and one light group of zeros at scale 0
/// (read by the group lookups only).
fn unused_masks(ctx: &GpuContext, nodes: usize, lookup: u32) -> [GpuBuffer; 5] {
    [
        ctx.upload(&vec![u32::MAX; nodes.div_ceil(32)]).unwrap(),
        ctx.upload(&vec![1.0f32; 6 * nodes]).unwrap(),
        ctx.upload(&[lookup]).unwrap(),
        ctx.upload(&vec![0u32; 16 * 3 * nodes]).unwrap(),
        ctx.upload(&[0.0f32; 4]).unwrap(),
    ]
}

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
        let pipeline = ComputePipeline::new(&ctx, name, &spirv, BINDINGS).unwrap();
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
            let [valid, reach, lookup, group_data, group_scales] =
                unused_masks(&ctx, spec.node_count(), PLAIN);
            pipeline
                .dispatch(
                    &[&grid, &texels, &p, &n, &out, &valid, &reach, &lookup, &group_data, &group_scales],
                    groups_for(QUERIES as u64, 65_535),
                    1,
                )
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
                .dispatch(
                    &[&wrong, &texels, &p, &n, &out, &valid, &reach, &lookup, &group_data, &group_scales],
                    groups_for(QUERIES as u64, 65_535),
                    1,
                )
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

#[test]
fn validity_and_reach_lookups_match_the_cpu_on_the_device() {
    let Some(ctx) = gpu_or_skip() else { return };
    let spirv = selftest_spirv(Layout::Native).unwrap();
    let pipeline = ComputePipeline::new(&ctx, "engine_masks", &spirv, BINDINGS).unwrap();
    let spec =
        GridSpec::new([-1.0, 0.0, 2.0], [3.0, 1.5, 5.0], [9, 6, 7]).unwrap().with_placement(placement());
    let nodes = spec.node_count();
    let vol = smooth_random_volume(spec.clone(), 9, 4).unwrap();
    let (mask, node_reach) = random_masks(nodes, 5);
    let (points, normals) = random_queries(&spec, QUERIES, 0.15, 6);
    let words = validity_words(mask.as_slice());
    let reach_values: Vec<f32> = (0..nodes).flat_map(|i| node_reach.node(i)).collect();
    let grid = ctx.upload(&grid_words(&spec, 9)).unwrap();
    let coeffs: Vec<u32> = vol.data().iter().map(|v| v.to_bits()).collect();
    let texels = ctx.upload(&coeffs).unwrap();
    let p = ctx.upload(points.as_flattened()).unwrap();
    let n = ctx.upload(normals.as_flattened()).unwrap();
    let valid = ctx.upload(&words).unwrap();
    let reach = ctx.upload(&reach_values).unwrap();
    let [_, _, _, group_data, group_scales] = unused_masks(&ctx, nodes, PLAIN);
    let run = |lookup: u32| -> Vec<f32> {
        let out = ctx.zeroed_buffer(12 * QUERIES as u64).unwrap();
        let which = ctx.upload(&[lookup]).unwrap();
        pipeline
            .dispatch(
                &[&grid, &texels, &p, &n, &out, &valid, &reach, &which, &group_data, &group_scales],
                groups_for(QUERIES as u64, 65_535),
                1,
            )
            .unwrap();
        out.read(0, 3 * QUERIES).unwrap()
    };
    let plain = run(PLAIN);
    for (lookup, name, cpu_vol) in [
        (VALID, "validity", vol.clone().with_validity(mask.clone()).unwrap()),
        (REACH, "reach", vol.clone().with_reach(node_reach.clone()).unwrap()),
    ] {
        let gpu = run(lookup);
        let (mut worst, mut scale, mut compared, mut changed) = (0.0f64, 0.0f64, 0usize, 0usize);
        for q in (0..QUERIES)
            .filter(|&q| lookup == VALID || clear_of_reach_decisions(&spec, points[q], Some(normals[q])))
        {
            compared += 1;
            let want = cpu_vol.irradiance(points[q], normals[q]);
            let mut differs = false;
            for ch in 0..3 {
                worst = worst.max((f64::from(gpu[3 * q + ch]) - f64::from(want[ch])).abs());
                scale = scale.max(f64::from(want[ch]).abs());
                differs |= (gpu[3 * q + ch] - plain[3 * q + ch]).abs() > 1e-3 * want[ch].abs();
            }
            changed += usize::from(differs);
        }
        let rel = worst / scale;
        eprintln!(
            "{name}: {compared} queries, {changed} changed by the weights, max |GPU − CPU| / max |E| = {rel:.2e}"
        );
        assert!(
            compared > QUERIES * 9 / 10,
            "{name}: only {compared} queries clear of the reach's decisions"
        );
        // The weights matter: a lookup that ignored them would match the plain one.
        assert!(changed > QUERIES / 10, "{name}: only {changed} queries changed");
        assert!(scale > 0.0 && rel < GPU_VS_CPU_REL, "{name}: {rel:e}");
    }
}

/// GPU against the CPU for the relit lookups: `Σ_g s_g E_g` in f32 on the device against
/// the f64 sum rounded once on the CPU, so the bound is [`GPU_VS_CPU_REL`] relative to
/// `Σ_g |s_g| |E_g|` (the sum's conditioning with mixed-sign scales), not to `|E|`.
fn relit_error(gpu: &[f32], want: &[[f32; 3]], conditioning: &[[f64; 3]], queries: &[usize]) -> f64 {
    queries
        .iter()
        .flat_map(|&q| (0..3).map(move |c| (q, c)))
        .map(|(q, c)| (f64::from(gpu[3 * q + c]) - f64::from(want[q][c])).abs() / conditioning[q][c])
        .fold(0.0, f64::max)
}

#[test]
fn light_group_lookups_match_the_cpu_relit_volume_on_the_device() {
    let Some(ctx) = gpu_or_skip() else { return };
    let spec =
        GridSpec::new([-1.0, 0.0, 2.0], [3.0, 1.5, 5.0], [9, 6, 7]).unwrap().with_placement(placement());
    let nodes = spec.node_count();
    let (mask, node_reach) = random_masks(nodes, 7);
    let total = smooth_random_volume(spec.clone(), 9, 8).unwrap();
    let layers: Vec<Vec<f32>> =
        (0..3).map(|g| smooth_random_volume(spec.clone(), 9, 10 + g).unwrap().data().to_vec()).collect();
    let scales = [[0.5, 1.0, 2.0], [-0.3, 0.25, 0.7], [1.5, -0.2, 0.6]];
    let (points, normals) = random_queries(&spec, QUERIES, 0.15, 9);
    let grid = ctx.upload(&grid_words(&spec, 9)).unwrap();
    let p = ctx.upload(points.as_flattened()).unwrap();
    let n = ctx.upload(normals.as_flattened()).unwrap();
    let valid = ctx.upload(&validity_words(mask.as_slice())).unwrap();
    let reach_values: Vec<f32> = (0..nodes).flat_map(|i| node_reach.node(i)).collect();
    let reach = ctx.upload(&reach_values).unwrap();
    let scale_words = |s: &[[f64; 3]]| -> Vec<f32> {
        s.iter().flat_map(|c| [c[0] as f32, c[1] as f32, c[2] as f32, 0.0]).collect()
    };
    for layout in [Layout::Native, Layout::Ktx2] {
        let spirv = selftest_spirv(layout).unwrap();
        let pipeline = ComputePipeline::new(&ctx, "engine_groups", &spirv, BINDINGS).unwrap();
        let (whole, group_words, cpu_layers): (Vec<u32>, Vec<u32>, Vec<Vec<f32>>) = match layout {
            Layout::Native => (
                total.data().iter().map(|v| v.to_bits()).collect(),
                layers.iter().flatten().map(|v| v.to_bits()).collect(),
                layers.clone(),
            ),
            Layout::Ktx2 => {
                let refs: Vec<&[f32]> = layers.iter().map(Vec::as_slice).collect();
                let bytes = stacked_slab_texels(&total, &refs).unwrap();
                let rounded = layers_from_stacked_texels(spec.res(), 9, 3, &bytes, FileFormat::Ktx2).unwrap();
                let words = |b: &[u8]| -> Vec<u32> {
                    b.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect()
                };
                (words(&slab_texels(&total).unwrap()), words(&bytes), rounded)
            }
        };
        let grouped =
            GroupedVolume::new(total.clone(), vec!["a".into(), "b".into(), "c".into()], cpu_layers.clone())
                .unwrap();
        let texels = ctx.upload(&whole).unwrap();
        let group_data = ctx.upload(&group_words).unwrap();
        let run = |lookup: u32, s: &[[f64; 3]]| -> Vec<f32> {
            let out = ctx.zeroed_buffer(12 * QUERIES as u64).unwrap();
            let which = ctx.upload(&[lookup]).unwrap();
            let sc = ctx.upload(&scale_words(s)).unwrap();
            pipeline
                .dispatch(
                    &[&grid, &texels, &p, &n, &out, &valid, &reach, &which, &group_data, &sc],
                    groups_for(QUERIES as u64, 65_535),
                    1,
                )
                .unwrap();
            out.read(0, 3 * QUERIES).unwrap()
        };
        let relit = grouped.relit(&scales).unwrap();
        for (lookup, name) in
            [(GROUPS, "groups"), (GROUPS_VALID, "groups+validity"), (GROUPS_REACH, "groups+reach")]
        {
            let with = |v: IrradianceVolume| match lookup {
                GROUPS_VALID => v.with_validity(mask.clone()).unwrap(),
                GROUPS_REACH => v.with_reach(node_reach.clone()).unwrap(),
                _ => v,
            };
            let cpu_relit = with(relit.clone());
            let cpu_groups: Vec<IrradianceVolume> = (0..3).map(|g| with(grouped.group(g))).collect();
            let queries: Vec<usize> = (0..QUERIES)
                .filter(|&q| {
                    lookup != GROUPS_REACH || clear_of_reach_decisions(&spec, points[q], Some(normals[q]))
                })
                .collect();
            assert!(queries.len() > QUERIES * 9 / 10, "{name}: only {} queries compared", queries.len());
            let want: Vec<[f32; 3]> =
                (0..QUERIES).map(|q| cpu_relit.irradiance(points[q], normals[q])).collect();
            let conditioning: Vec<[f64; 3]> = (0..QUERIES)
                .map(|q| {
                    let e: Vec<[f32; 3]> =
                        cpu_groups.iter().map(|v| v.irradiance(points[q], normals[q])).collect();
                    std::array::from_fn(|c| (0..3).map(|g| (scales[g][c] * f64::from(e[g][c])).abs()).sum())
                })
                .collect();
            let gpu = run(lookup, &scales);
            let rel = relit_error(&gpu, &want, &conditioning, &queries);
            eprintln!("{layout:?} {name}: max |GPU − CPU| / Σ|s E| = {rel:.2e}");
            assert!(rel < GPU_VS_CPU_REL, "{layout:?} {name}: {rel:e}");
            // Negative control: the scales in another group order are another lighting.
            let swapped = run(lookup, &[scales[1], scales[2], scales[0]]);
            let off = relit_error(&swapped, &want, &conditioning, &queries);
            assert!(off > 100.0 * GPU_VS_CPU_REL, "{layout:?} {name}: swapped scales give only {off:e}");
        }
    }
}
