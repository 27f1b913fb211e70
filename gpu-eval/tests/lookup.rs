//! GPU volume lookup against lightvol-volume's CPU lookup (agreement to 1e-5 relative), and
//! a validation-clean run under the Khronos validation layer.
//!
//! Every test gets its device from `lightvol_gpu::gpu_or_skip()`: without Vulkan it prints
//! `skipped: no Vulkan device (...)` and passes, unless `LIGHTVOL_REQUIRE_GPU=1`.
//!
//! **Test volumes.** [`TEST_VOLUME`] picks the volume the comparisons run on:
//! [`TestVolume::BakedCity`] (default) bakes lightvol-sampler's built-in
//! city on a small grid with the paper's domain-of-interest method (a few seconds);
//! [`TestVolume::Synthetic`] uses smooth seeded random coefficients
//! (`lightvol_gpu::synthetic::smooth_random_volume`), whose irradiance is positive and
//! well-conditioned everywhere. `gpu_lookup_matches_cpu_on_synthetic_volume` always runs on
//! the synthetic one too.

use lightvol_core::samples::samples;

use std::sync::Mutex;

use lightvol_core::progress::BakeControl;
use lightvol_gpu::lookup::Quantity;
use lightvol_gpu::synthetic::{clear_of_reach_decisions, random_masks, random_queries, smooth_random_volume};
use lightvol_gpu::{GpuError, VolumeLookup, gpu_or_skip};
use lightvol_sampler::{BakeSettings, Method, bake};
use lightvol_scene::TransportSettings;
use lightvol_sh::eval::eval_into;
use lightvol_sh::index::sh_lm;
use lightvol_sh::irradiance::cosine_lobe_factor;
use lightvol_volume::{GridSpec, IrradianceVolume, Placement};

/// Which volume the comparisons run on (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TestVolume {
    /// The built-in city baked by lightvol-sampler (`Method::DoiPaper`, 7×7×4 nodes).
    BakedCity,
    /// `smooth_random_volume`: positive irradiance everywhere, seeded.
    Synthetic,
}

const TEST_VOLUME: TestVolume = TestVolume::BakedCity;

/// GPU within 1e-5 relative of the CPU lookup. Both sides are f32 with the
/// same operations in the same order; the differences come from FMA contraction by the
/// driver and are a few f32 ulps (6e-8) of the sum of the absolute terms.
const GPU_VS_CPU_REL: f64 = 1e-5;

/// Queries per comparison: lavapipe is slow and CI has 2 cores; 4096 random queries
/// per configuration cover every cell of the small test grids many times.
const QUERIES: usize = 4096;

/// Fraction of the box added on each side for query points, so ~1/3 of the queries fall
/// outside the box and exercise clamping.
const MARGIN: f64 = 0.15;

/// Rotation about z by 30 degrees, anisotropic scale, translation.
fn placement() -> Placement {
    let (s, c) = 30f64.to_radians().sin_cos();
    Placement::new([[2.0 * c, -s, 0.0, 10.0], [2.0 * s, c, 0.0, -4.0], [0.0, 0.0, 0.5, 1.0]]).unwrap()
}

/// The built-in city baked with `coeffs` coefficients (cached: each bake runs once per
/// test binary).
fn baked_city(coeffs: usize) -> IrradianceVolume {
    static CACHE: Mutex<Vec<(usize, IrradianceVolume)>> = Mutex::new(Vec::new());
    let mut cache = CACHE.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some((_, v)) = cache.iter().find(|(c, _)| *c == coeffs) {
        return v.clone();
    }
    let city = lightvol_scene::builtin::city();
    let tracer = lightvol_scene::Tracer::new(&city.scene);
    let transport = lightvol_scene::Transport::new(&city.scene, &tracer, TransportSettings::default());
    let grid = GridSpec::new([-14.0, -14.0, -1.0], [14.0, 14.0, 11.0], [7, 7, 4]).unwrap();
    let settings = BakeSettings {
        method: Method::DoiPaper,
        samples: samples(16),
        coeffs,
        seed: 8,
        ..Default::default()
    };
    let (vol, _) = bake(&transport, &grid, &settings, &BakeControl::default()).unwrap().finish();
    cache.push((coeffs, vol.clone()));
    vol
}

fn test_volume(source: TestVolume, coeffs: usize, placed: bool, seed: u64) -> IrradianceVolume {
    let vol = match source {
        TestVolume::BakedCity => baked_city(coeffs),
        TestVolume::Synthetic => {
            let spec = GridSpec::new([-1.0, 0.0, 2.0], [3.0, 1.5, 5.0], [9, 6, 7]).unwrap();
            smooth_random_volume(spec, coeffs, seed).unwrap()
        }
    };
    if !placed {
        return vol;
    }
    let (spec, coeffs, data, weights, _) = vol.into_parts();
    IrradianceVolume::new(spec.with_placement(placement()), coeffs, data, weights).unwrap()
}

/// `Σ_j |f_j Y_j(n)| |L_j(x)|` per channel: the magnitude scale of the lookup's rounding
/// error (equal to |E| when no terms cancel).
fn term_magnitude(vol: &IrradianceVolume, q: Quantity, p: [f32; 3], n: [f32; 3]) -> [f64; 3] {
    let k = vol.coeffs();
    let mut l = vec![0.0f32; 3 * k];
    vol.coeffs_at(p, &mut l);
    let mut y = vec![0.0f64; k];
    eval_into(vol.bands(), n.map(f64::from), &mut y);
    std::array::from_fn(|ch| {
        (0..k)
            .map(|j| {
                let f = if q == Quantity::Irradiance { cosine_lobe_factor(sh_lm(j).0) } else { 1.0 };
                (f * y[j]).abs() * f64::from(l[3 * j + ch]).abs()
            })
            .sum()
    })
}

/// What one comparison found.
struct Agreement {
    /// Worst plain relative error over well-conditioned values.
    worst_rel: f64,
    /// Values (query × channel) with |E| ≥ M/4, where the plain relative check applies.
    well_conditioned: usize,
    /// Values bit-identical to the CPU f32 lookup.
    identical: usize,
}

/// Compares GPU and CPU on random queries: every value within `GPU_VS_CPU_REL` of its
/// term magnitude, and within `GPU_VS_CPU_REL` relative where it is not a cancellation.
fn compare(lookup: &VolumeLookup, vol: &IrradianceVolume, q: Quantity, seed: u64) -> Agreement {
    let (points, dirs) = random_queries(vol.spec(), QUERIES, MARGIN, seed);
    let gpu = lookup.evaluate(q, &points, &dirs).unwrap();
    let mut cpu = vec![[0.0f32; 3]; QUERIES];
    match q {
        Quantity::Irradiance => vol.irradiance_batch(&points, &dirs, &mut cpu).unwrap(),
        Quantity::Radiance => vol.radiance_batch(&points, &dirs, &mut cpu).unwrap(),
    }
    let mut a = Agreement { worst_rel: 0.0, well_conditioned: 0, identical: 0 };
    for i in 0..QUERIES {
        let m = term_magnitude(vol, q, points[i], dirs[i]);
        let reference = match q {
            Quantity::Irradiance => {
                vol.irradiance_reference(points[i].map(f64::from), dirs[i].map(f64::from))
            }
            Quantity::Radiance => vol.radiance_reference(points[i].map(f64::from), dirs[i].map(f64::from)),
        };
        for ch in 0..3 {
            let (g, c) = (f64::from(gpu[i][ch]), f64::from(cpu[i][ch]));
            a.identical += usize::from(gpu[i][ch] == cpu[i][ch]);
            // Every query: error within 1e-5 of the term magnitude.
            assert!(
                (g - c).abs() <= GPU_VS_CPU_REL * m[ch],
                "{q:?} query {i} ch {ch}: gpu {g} cpu {c} (scale {})",
                m[ch]
            );
            // The f64 Algorithm 1 reference too (f32 rounding on both sides).
            assert!(
                (g - reference[ch]).abs() <= GPU_VS_CPU_REL * m[ch],
                "{q:?} query {i}: gpu {g} ref {}",
                reference[ch]
            );
            // Plain relative error where the value is not a cancellation (|E| >= M / 4).
            if c.abs() >= 0.25 * m[ch] && m[ch] > 0.0 {
                a.well_conditioned += 1;
                let rel = (g - c).abs() / c.abs();
                assert!(rel <= GPU_VS_CPU_REL, "{q:?} query {i} ch {ch}: relative error {rel:e}");
                a.worst_rel = a.worst_rel.max(rel);
            }
        }
    }
    a
}

fn compare_all(source: TestVolume) {
    let Some(ctx) = gpu_or_skip() else { return };
    for coeffs in [4, 9, 16] {
        for placed in [false, true] {
            let vol = test_volume(source, coeffs, placed, 100 + coeffs as u64);
            let lookup = VolumeLookup::new(&ctx, &vol).unwrap();
            for q in [Quantity::Irradiance, Quantity::Radiance] {
                let a = compare(&lookup, &vol, q, 7 * coeffs as u64 + u64::from(placed));
                let n = 3 * QUERIES;
                println!(
                    "{source:?}, {coeffs} coeffs, placed {placed}, {q:?}: worst relative error {:.2e} \
                     over {} of {n} well-conditioned values; {} of {n} bit-identical",
                    a.worst_rel, a.well_conditioned, a.identical
                );
                // Guard against a vacuous plain-relative check: most irradiance values must
                // be well-conditioned (the synthetic volume's are, everywhere); radiance of a
                // noisy 16-sample bake cancels more often (measured: 43% well-conditioned
                // for 16 coefficients), so it needs a quarter.
                let need = if q == Quantity::Irradiance { n / 2 } else { n / 4 };
                assert!(
                    a.well_conditioned >= need,
                    "only {} of {n} well-conditioned values",
                    a.well_conditioned
                );
                if source == TestVolume::Synthetic && q == Quantity::Irradiance {
                    assert_eq!(a.well_conditioned, n);
                }
            }
        }
    }
}

/// The evaluator on a volume with a random validity mask and one with a random node reach
/// ([`random_masks`]; placed, 9 coefficients): irradiance and radiance against the CPU
/// lookup of the same volume, within [`GPU_VS_CPU_REL`] of the batch's largest value, and
/// the weights change over a tenth of the results (an evaluator that ignored them would
/// return the plain volume's).
#[test]
fn gpu_lookup_weights_validity_and_reach_like_the_cpu() {
    let Some(ctx) = gpu_or_skip() else { return };
    let plain = test_volume(TestVolume::Synthetic, 9, true, 21);
    let spec = plain.spec().clone();
    let (mask, reach) = random_masks(spec.node_count(), 22);
    let plain_lookup = VolumeLookup::new(&ctx, &plain).unwrap();
    for (name, vol) in [
        ("validity", plain.clone().with_validity(mask).unwrap()),
        ("reach", plain.clone().with_reach(reach).unwrap()),
    ] {
        let lookup = VolumeLookup::new(&ctx, &vol).unwrap();
        for q in [Quantity::Irradiance, Quantity::Radiance] {
            let (points, dirs) = random_queries(&spec, QUERIES, MARGIN, 23);
            let gpu = lookup.evaluate(q, &points, &dirs).unwrap();
            let base = plain_lookup.evaluate(q, &points, &dirs).unwrap();
            let mut cpu = vec![[0.0f32; 3]; QUERIES];
            match q {
                Quantity::Irradiance => vol.irradiance_batch(&points, &dirs, &mut cpu).unwrap(),
                Quantity::Radiance => vol.radiance_batch(&points, &dirs, &mut cpu).unwrap(),
            }
            let normal = |i: usize| (q == Quantity::Irradiance).then_some(dirs[i]);
            let (mut worst, mut scale, mut compared, mut changed) = (0.0f64, 0.0f64, 0usize, 0usize);
            for i in (0..QUERIES)
                .filter(|&i| name == "validity" || clear_of_reach_decisions(&spec, points[i], normal(i)))
            {
                compared += 1;
                let mut differs = false;
                for ch in 0..3 {
                    worst = worst.max((f64::from(gpu[i][ch]) - f64::from(cpu[i][ch])).abs());
                    scale = scale.max(f64::from(cpu[i][ch]).abs());
                    differs |= (gpu[i][ch] - base[i][ch]).abs() > 1e-3 * cpu[i][ch].abs();
                }
                changed += usize::from(differs);
            }
            let rel = worst / scale;
            println!(
                "{name}, {q:?}: {compared} queries, {changed} changed by the weights, max |GPU − CPU| / max = {rel:.2e}"
            );
            assert!(compared > QUERIES * 9 / 10, "{name} {q:?}: only {compared} queries compared");
            assert!(changed > QUERIES / 10, "{name} {q:?}: only {changed} queries changed");
            assert!(scale > 0.0 && rel <= GPU_VS_CPU_REL, "{name} {q:?}: {rel:e}");
        }
    }
}

/// GPU vs CPU lookup on [`TEST_VOLUME`] (the baked city): 4, 9 and 16 coefficients, with and
/// without a placement, irradiance and radiance.
#[test]
fn gpu_lookup_matches_cpu_for_all_orders_and_placements() {
    compare_all(TEST_VOLUME);
}

/// The same comparison on the synthetic volume, where every value is well-conditioned.
#[test]
fn gpu_lookup_matches_cpu_on_synthetic_volume() {
    compare_all(TestVolume::Synthetic);
}

#[test]
fn resident_batches_rerun_and_match_single_shot() {
    let Some(ctx) = gpu_or_skip() else { return };
    let vol = test_volume(TEST_VOLUME, 9, false, 3);
    let lookup = VolumeLookup::new(&ctx, &vol).unwrap();
    let (points, dirs) = random_queries(vol.spec(), 1000, MARGIN, 9);
    let once = lookup.irradiance(&points, &dirs).unwrap();
    let mut batch = lookup.batch(&points, &dirs).unwrap();
    assert_eq!(batch.read().unwrap(), vec![[0.0; 3]; 1000], "results start zeroed");
    let stats = lookup.run(&mut batch, Quantity::Irradiance, 3).unwrap();
    assert_eq!(stats.repeats, 3);
    assert!(stats.wall_seconds > 0.0);
    // Same device, same code, same inputs: bit-identical.
    assert_eq!(batch.read().unwrap(), once);
    lookup.run(&mut batch, Quantity::Radiance, 1).unwrap();
    assert_eq!(batch.read().unwrap(), lookup.radiance(&points, &dirs).unwrap());
}

#[test]
fn nodes_reproduce_stored_radiance_and_edge_queries_clamp() {
    let Some(ctx) = gpu_or_skip() else { return };
    let vol = test_volume(TestVolume::Synthetic, 4, false, 21);
    let lookup = VolumeLookup::new(&ctx, &vol).unwrap();
    let spec = vol.spec().clone();
    // Every node, straight up: radiance = Σ_j c_ij Y_j(+z), where only j = 0, 2 are non-zero.
    let mut points = Vec::new();
    for node in 0..spec.node_count() {
        let [i, j, k] = spec.node_coords(node);
        points.push(spec.node_position_world(i, j, k).map(|v| v as f32));
    }
    // Far outside the box and NaN coordinates: clamp like the CPU.
    points.extend([[1e6, -1e6, 3.0], [f32::NAN, 0.5, f32::NAN], [-1e30, 1e30, f32::INFINITY]]);
    let dirs = vec![[0.0, 0.0, 1.0]; points.len()];
    let gpu = lookup.radiance(&points, &dirs).unwrap();
    let y00 = 0.5 / std::f64::consts::PI.sqrt();
    let y10 = (3.0 / (4.0 * std::f64::consts::PI)).sqrt();
    for node in 0..spec.node_count() {
        for ch in 0..3 {
            let c = vol.coeff_rgb(node, 0)[ch];
            let z = vol.coeff_rgb(node, 2)[ch];
            let want = y00 * f64::from(c) + y10 * f64::from(z);
            let got = f64::from(gpu[node][ch]);
            assert!((got - want).abs() <= GPU_VS_CPU_REL * want.abs(), "node {node}: {got} vs {want}");
        }
    }
    for (i, p) in points.iter().enumerate().skip(spec.node_count()) {
        let cpu = vol.radiance(*p, [0.0, 0.0, 1.0]);
        for ch in 0..3 {
            let rel = f64::from((gpu[i][ch] - cpu[ch]).abs() / cpu[ch].abs());
            assert!(rel <= GPU_VS_CPU_REL, "edge query {p:?}: gpu {:?} cpu {cpu:?}", gpu[i]);
        }
    }
}

#[test]
fn bad_inputs_are_errors() {
    let Some(ctx) = gpu_or_skip() else { return };
    let vol = test_volume(TEST_VOLUME, 9, false, 1);
    let lookup = VolumeLookup::new(&ctx, &vol).unwrap();
    assert!(lookup.irradiance(&[], &[]).unwrap().is_empty());
    assert!(matches!(lookup.irradiance(&[[0.0; 3]; 2], &[[0.0, 0.0, 1.0]]), Err(GpuError::Invalid(_))));
}

/// The Khronos validation layer reports no errors for context creation,
/// uploads, pipeline creation, dispatches and readbacks.
#[test]
fn validation_layer_reports_no_errors() {
    let Some(ctx) = lightvol_gpu::testing::validated_context_or_skip() else { return };
    assert!(ctx.validation_enabled());
    for coeffs in [4, 16] {
        let vol = test_volume(TEST_VOLUME, coeffs, true, 5);
        let lookup = VolumeLookup::new(&ctx, &vol).unwrap();
        let (points, dirs) = random_queries(vol.spec(), 300, MARGIN, 2);
        let mut batch = lookup.batch(&points, &dirs).unwrap();
        lookup.run(&mut batch, Quantity::Irradiance, 2).unwrap();
        let out = batch.read().unwrap();
        assert_eq!(out.len(), 300);
    }
    assert_eq!(ctx.validation_errors(), 0, "validation errors: {:#?}", ctx.validation_messages());
}
