//! The batched kernels (`batch.rs`, used by the pipeline passes) against the one-receiver
//! kernels of `kernel.rs`: every lane runs the same f32 operations in the same order, so
//! the passes must equal the one-receiver kernels bit for bit (no tolerance).

use lightvol_proxies::kernel::{Accum, Kernel, KernelIndirect, PreparedProxy, prepare};
use lightvol_proxies::light::DistantLight;
use lightvol_proxies::light::{FnLight, LightField};
use lightvol_proxies::pipeline::{accumulate_pass, bin_proxies, exponentiate_pass, incident_pass, total};
use lightvol_proxies::proxy::SphereProxy;
use lightvol_proxies::receiver_scene::{ReceiverBuffer, Scene};
use lightvol_sh::lowdisc::SplitMix64;

/// The default scene's character plus seeded spheres around it, some crossing the floor and
/// walls (the replacement rule) and some containing receivers.
fn proxies(scene: &Scene, extra: usize) -> Vec<SphereProxy> {
    let mut s = scene.proxies.clone();
    let mut rng = SplitMix64::new(3);
    for _ in 0..extra {
        let c = [rng.range(-2.5, 1.0), rng.range(0.0, 3.1), rng.range(-0.1, 1.8)];
        s.push(SphereProxy::new(c, rng.range(0.05, 0.3), [0.6, 0.5, 0.4]));
    }
    s
}

fn check<const N: usize>(indirect: KernelIndirect, tile: usize) {
    let scene = Scene::default_scene();
    let light = DistantLight(scene.light.sh::<N>());
    let p = proxies(&scene, 14);
    let prepared: Vec<PreparedProxy<N>> = prepare(&p, &light);
    let kernel = Kernel::<N>::new(24.0, 11.0, indirect);
    // Widths that are not multiples of the batch or the tile exercise partial batches.
    let (w, h) = (70, 45);
    let buf = ReceiverBuffer::render(&scene, w, h);
    let bins = bin_proxies(&scene.camera.frame(), w, h, &p, 24.0, tile);
    let acc = accumulate_pass(&kernel, &buf, &bins, &prepared);
    let inc = exponentiate_pass(&kernel, &buf, &acc, &light);
    // The fused pass, with the uniform light and with a light that varies over the scene.
    let fused = incident_pass(&kernel, &buf, &bins, &prepared, &light);
    assert!(fused.iter().zip(&inc).all(|(f, i)| *f == total(i)), "fused pass differs");
    let varying = FnLight(|p: [f64; 3]| {
        let mut l = light.0;
        l.0[1].0[0] *= 1.0 + 0.2 * p[0].sin() + 0.1 * p[2];
        l
    });
    assert!(varying.uniform().is_none());
    let inc_v = exponentiate_pass(&kernel, &buf, &acc, &varying);
    let fused_v = incident_pass(&kernel, &buf, &bins, &prepared, &varying);
    assert!(fused_v.iter().zip(&inc_v).all(|(f, i)| *f == total(i)), "fused pass differs (varying light)");
    assert!(fused_v != fused, "the varying light must change the result");
    let m = kernel.light_matrix(&core::array::from_fn(|c| light.0.0[c].0.map(|v| v as f32)));
    let (mut touched, mut squared) = (0, 0);
    for i in 0..w * h {
        let mut one = Accum::<N>::default();
        if buf.valid(i) {
            let (x, y) = (i % w, i / w);
            let list = &bins.lists[(y / tile) * bins.tiles_x + x / tile];
            kernel.accumulate(buf.position[i], buf.normal[i], &prepared, list, &mut one);
        }
        assert!(acc[i] == one, "receiver {i}: batched accumulation differs\n{:?}\n{one:?}", acc[i]);
        if !buf.valid(i) {
            continue;
        }
        touched += usize::from(one.count > 0);
        let norm = one.log_vis[1..].iter().map(|v| v * v).sum::<f32>().sqrt();
        squared += usize::from(norm > 0.2);
        let expect = kernel.finish_with(&one, &m);
        assert!(inc[i] == expect, "receiver {i}: batched exponentiation differs");
    }
    // The frame exercises the kernels: proxies touch many receivers, with squarings.
    assert!(touched > 300 && squared > 100, "{touched} touched, {squared} with squarings");
}

#[test]
fn batched_passes_equal_one_receiver_kernels_16() {
    check::<16>(KernelIndirect::Averaged, 8);
}

#[test]
fn batched_passes_equal_one_receiver_kernels_9() {
    check::<9>(KernelIndirect::AveragedPaperFit, 7);
}

#[test]
fn batched_passes_equal_one_receiver_kernels_shadows_only() {
    check::<16>(KernelIndirect::None, 16);
}

/// The lane evaluation of the SH basis repeats lightvol-sh's generated code operation for
/// operation: equal bits at seeded directions (and at the poles and axes).
#[test]
fn lane_basis_equals_generated_code() {
    use lightvol_proxies::lanes::{BasisRecurrence, LANES, eval_basis_lanes};
    use lightvol_sh::eval::eval_basis;
    use lightvol_sh::sampling::sample_uniform_sphere;
    let k = BasisRecurrence::new();
    let mut rng = SplitMix64::new(17);
    let mut dirs: Vec<[f32; 3]> = vec![[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]];
    while dirs.len() < 4096 {
        dirs.push(sample_uniform_sphere([rng.next_f64(), rng.next_f64()]).map(|v| v as f32));
    }
    for chunk in dirs.chunks(LANES) {
        let lanes = |a: usize| core::array::from_fn(|l| chunk[l][a]);
        let (x, y, z) = (lanes(0), lanes(1), lanes(2));
        let b16 = eval_basis_lanes::<16>(&k, &x, &y, &z);
        let b9 = eval_basis_lanes::<9>(&k, &x, &y, &z);
        for (l, d) in chunk.iter().enumerate() {
            let e16 = eval_basis::<f32, 16>(*d);
            let e9 = eval_basis::<f32, 9>(*d);
            for j in 0..16 {
                assert_eq!(b16[j][l].to_bits(), e16[j].to_bits(), "coefficient {j} at {d:?}");
            }
            for j in 0..9 {
                assert_eq!(b9[j][l].to_bits(), e9[j].to_bits(), "coefficient {j} at {d:?}");
            }
        }
    }
}

/// Proxies with a radius that is not positive (zero, negative, NaN) are skipped by the
/// one-receiver kernel (`proxy::view_f32`'s guard) and by the batched kernel alike: adding
/// them to every list changes no accumulator bit.
#[test]
fn degenerate_radii_add_nothing() {
    use lightvol_proxies::batch::ReceiverBatch;
    use lightvol_proxies::lanes::LANES;
    let scene = Scene::default_scene();
    let light = DistantLight(scene.light.sh::<16>());
    let kernel = Kernel::<16>::new(24.0, 11.0, KernelIndirect::Averaged);
    let mut prepared: Vec<PreparedProxy<16>> = prepare(&scene.proxies, &light);
    let clean: Vec<u32> = (0..prepared.len() as u32).collect();
    // Copies of the character's spheres, where they do touch receivers, with bad radii.
    for (k, r) in [0.0, -0.0, -0.3, f32::NAN].into_iter().enumerate() {
        let mut p = prepared[k * 3];
        p.radius = r;
        prepared.push(p);
    }
    let dirty: Vec<u32> = (0..prepared.len() as u32).collect();
    let buf = ReceiverBuffer::render(&scene, 48, 36);
    let (mut one, mut lanes) = (vec![Accum::<16>::default(); LANES], vec![Accum::<16>::default(); LANES]);
    let mut touched = 0;
    for start in (0..buf.position.len()).step_by(LANES) {
        let end = (start + LANES).min(buf.position.len());
        let batch = ReceiverBatch::gather(&buf.position[start..end], &buf.normal[start..end], |k| {
            buf.valid(start + k)
        });
        kernel.accumulate_batch(&batch, &prepared, &clean, &mut one);
        kernel.accumulate_batch(&batch, &prepared, &dirty, &mut lanes);
        assert!(one == lanes, "receivers {start}..{end}: batched accumulation changed");
        for (k, i) in (start..end).enumerate() {
            let (mut a, mut b) = (Accum::<16>::default(), Accum::<16>::default());
            if buf.valid(i) {
                kernel.accumulate(buf.position[i], buf.normal[i], &prepared, &clean, &mut a);
                kernel.accumulate(buf.position[i], buf.normal[i], &prepared, &dirty, &mut b);
            }
            assert!(a == b && a == lanes[k], "receiver {i}: accumulation changed");
            touched += usize::from(a.count > 0);
        }
    }
    assert!(touched > 100, "{touched}");
}
