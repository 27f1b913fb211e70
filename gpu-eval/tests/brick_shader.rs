//! The brick sampling code (`lightvol_gpu::brick_shader`) on the device, against the CPU
//! lookup of the same brick volume (`BrickVolume::irradiance`): an octree of a smooth field
//! with a sharp bump, baked for a +Y-up scene file (so that the file-frame maps are a real
//! rotation), resampled into bricks of 2 and 4 cells, with and without a budget that mixes
//! levels; 10,000 random queries each, a sixth of the box's size beyond it on every side.
//! The shader reads the atlas and indirection texels exactly as the export stores them.
//!
//! Without Vulkan the test says so in one line and passes, unless `LIGHTVOL_REQUIRE_GPU=1`.

use lightvol_gpu::brick_shader::{BRICK_BINDINGS, brick_selftest_spirv, brick_words};
use lightvol_gpu::pipeline::groups_for;
use lightvol_gpu::{ComputePipeline, gpu_or_skip};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_volume::adaptive::level_grid;
use lightvol_volume::bricks::{BrickParams, BrickVolume, bricks_from_octree};
use lightvol_volume::io::bricks::{atlas_slots, brick_texels};
use lightvol_volume::up_axis::UpAxis;
use lightvol_volume::{AdaptiveVolume, BakeMetadata, GridSpec, IrradianceVolume, LevelSamples, OctreeParams};

/// Queries per configuration.
const QUERIES: usize = 10_000;

/// GPU against the CPU f32 lookup, relative to the largest irradiance of the batch: the
/// engine-shader bound (a few f32 ulps times the ~16 terms and the trilinear weights'
/// conditioning), and the position's own rounding: the GPU maps a file-frame point with one
/// f32 affine map, the CPU with the placement then the box scale, a few ulps of the
/// coordinate apart, times the field's slope (below 10 per cell here).
const GPU_VS_CPU_REL: f64 = 2e-5;

/// Where the two roundings of the position fall on either side of an indirection texel
/// boundary (within 1e-4 texel), the two lookups read neighbouring bricks, which agree to
/// the half-float rounding of a stitched probe: 2^-11 of the largest coefficient, times
/// the ~16 shading terms.
const SEAM_REL: f64 = 16.0 / 2048.0;

fn field(x: [f64; 3], q: usize) -> f64 {
    let c = [1.2, 0.7, 3.1];
    let r2: f64 = (0..3).map(|a| (x[a] - c[a]).powi(2)).sum();
    let smooth = 1.0 + 0.3 * (x[0] * 1.3).sin() + 0.2 * x[2];
    (smooth + 2.0 * (-r2 / 0.05).exp())
        * (1.0 + 0.05 * q as f64)
        * if q.is_multiple_of(3) { 1.0 } else { 0.3 }
}

fn octree(coeffs: usize) -> AdaptiveVolume {
    let spec = GridSpec::new([-1.0, 0.0, 2.0], [3.0, 1.5, 5.0], [6, 5, 4]).unwrap();
    let base = IrradianceVolume::from_fn(spec.clone(), coeffs, |x| {
        (0..coeffs).map(|j| std::array::from_fn(|ch| field(x, 3 * j + ch))).collect()
    })
    .unwrap();
    let params = OctreeParams { max_level: 2, cull_tolerance: 0.002, ..OctreeParams::default() };
    let mut oct = lightvol_volume::build_adaptive(
        base,
        &params,
        |c| {
            Ok::<_, lightvol_volume::VolumeError>(
                (0..c.cells().len()).map(|i| c.corner_change(i) / 0.4).collect(),
            )
        },
        |level, nodes| {
            let g = level_grid(&spec, level)?;
            let mut s = LevelSamples::default();
            for &n in nodes {
                let x = g.node_position_world(n[0], n[1], n[2]);
                s.values.extend((0..coeffs * 3).map(|q| field(x, q)));
                s.weights.push(1.0);
            }
            Ok(s)
        },
    )
    .unwrap();
    let meta = BakeMetadata { frame: UpAxis::Y, ..oct.metadata().clone() };
    oct.set_metadata(meta);
    oct
}

fn queries(vol: &BrickVolume, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let (lo, hi) = vol.spec().bounds();
    let mut rng = SplitMix64::new(seed);
    let mut p = Vec::with_capacity(QUERIES);
    let mut n = Vec::with_capacity(QUERIES);
    for _ in 0..QUERIES {
        p.push(std::array::from_fn(|a| {
            let pad = (hi[a] - lo[a]) / 6.0;
            rng.range(lo[a] - pad, hi[a] + pad)
        }));
        n.push(lightvol_sh::sampling::sample_uniform_sphere([rng.next_f64(), rng.next_f64()]));
    }
    (p, n)
}

/// Whether the point's texel coordinate lies within 1e-4 of a texel boundary.
fn near_seam(vol: &BrickVolume, p: [f64; 3]) -> bool {
    let (lo, hi) = vol.spec().bounds();
    let res = vol.spec().res();
    let to_texel = f64::from(1u32 << vol.finest_level()) / f64::from(vol.brick_cells());
    (0..3).any(|a| {
        let u = (p[a] - lo[a]) / (hi[a] - lo[a]) * f64::from(res[a] - 1);
        // A clamped coordinate is the box face on both sides.
        let t = u * to_texel;
        u > 0.0 && u < f64::from(res[a] - 1) && (t - t.round()).abs() < 1e-4
    })
}

#[test]
fn brick_sampling_code_matches_the_cpu_lookup_on_the_device() {
    let Some(ctx) = gpu_or_skip() else { return };
    for (coeffs, seed) in [(9usize, 1u64), (4, 2), (16, 3)] {
        let oct = octree(coeffs);
        let full = bricks_from_octree(
            &oct,
            &BrickParams { cells: 2, merge_tolerance: 0.0, ..BrickParams::default() },
        )
        .unwrap()
        .0;
        let budget = full.probe_bytes() / 2;
        for params in [
            BrickParams { cells: 2, merge_tolerance: 0.0, ..BrickParams::default() },
            BrickParams { cells: 2, merge_tolerance: 0.0, max_probe_bytes: Some(budget) },
            BrickParams::default(),
        ] {
            let (vol, report) = bricks_from_octree(&oct, &params).unwrap();
            let levels = report.bricks_per_level.iter().filter(|&&n| n > 0).count();
            let name = format!(
                "{coeffs} coefficients, {} cells, {} bricks on {levels} levels",
                params.cells,
                vol.bricks().len()
            );
            let slots = atlas_slots(vol.bricks().len());
            let pipeline =
                ComputePipeline::new(&ctx, "bricks", &brick_selftest_spirv(slots).unwrap(), BRICK_BINDINGS)
                    .unwrap();
            let (_, atlas, ind) = brick_texels(&vol).unwrap();
            let words = |b: &[u8]| -> Vec<u32> {
                b.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect()
            };
            let (points, normals) = queries(&vol, seed);
            let up = UpAxis::Y;
            let file_p: Vec<f32> = points.iter().flat_map(|&p| up.to_file(p).map(|v| v as f32)).collect();
            let file_n: Vec<f32> = normals.iter().flat_map(|&n| up.to_file(n).map(|v| v as f32)).collect();
            let block = ctx.upload(&brick_words(&vol)).unwrap();
            let atlas = ctx.upload(&words(&atlas)).unwrap();
            let ind = ctx.upload(&words(&ind)).unwrap();
            let p = ctx.upload(&file_p).unwrap();
            let n = ctx.upload(&file_n).unwrap();
            let out = ctx.zeroed_buffer(12 * QUERIES as u64).unwrap();
            let unused = ctx.upload(&[0u32; 4]).unwrap();
            let dispatch = |block: &lightvol_gpu::GpuBuffer| -> Vec<f32> {
                pipeline
                    .dispatch(
                        &[block, &atlas, &p, &n, &out, &unused, &unused, &unused, &ind],
                        groups_for(QUERIES as u64, 65_535),
                        1,
                    )
                    .unwrap();
                out.read(0, 3 * QUERIES).unwrap()
            };
            let gpu = dispatch(&block);
            let cpu: Vec<[f32; 3]> = points
                .iter()
                .zip(&normals)
                .map(|(p, n)| vol.irradiance(p.map(|v| v as f32), n.map(|v| v as f32)))
                .collect();
            let scale = cpu.iter().flatten().fold(0.0f64, |m, &v| m.max(f64::from(v).abs()));
            let (mut worst, mut worst_seam, mut seams) = (0.0f64, 0.0f64, 0usize);
            for q in 0..QUERIES {
                let d = (0..3)
                    .map(|c| (f64::from(gpu[3 * q + c]) - f64::from(cpu[q][c])).abs())
                    .fold(0.0, f64::max);
                if near_seam(&vol, points[q]) {
                    seams += 1;
                    worst_seam = worst_seam.max(d);
                } else {
                    worst = worst.max(d);
                }
            }
            let (rel, rel_seam) = (worst / scale, worst_seam / scale);
            eprintln!(
                "{name}: max |GPU − CPU| / max |E| = {rel:.2e} ({seams} queries at texel seams: {rel_seam:.2e})"
            );
            assert!(scale > 0.0 && rel < GPU_VS_CPU_REL, "{name}: {rel:e}");
            assert!(rel_seam < SEAM_REL, "{name}: at seams {rel_seam:e}");
            assert!(seams < QUERIES / 100, "{name}: {seams} queries near seams");
            // Negative control: a block whose finest level is one too low reads every
            // brick at the wrong place, and the same comparison catches it.
            let mut wrong = brick_words(&vol);
            wrong[31] = wrong[31].saturating_sub(1);
            wrong[28] = wrong[28].div_ceil(2);
            let bad = dispatch(&ctx.upload(&wrong).unwrap());
            let bad_err =
                (0..3 * QUERIES).map(|i| (f64::from(bad[i]) - f64::from(gpu[i])).abs()).fold(0.0, f64::max)
                    / scale;
            assert!(bad_err > 100.0 * GPU_VS_CPU_REL, "{name}: a wrong block gives only {bad_err:e}");
        }
    }
}
