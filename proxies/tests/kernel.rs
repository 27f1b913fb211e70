//! The f32 pipeline kernels against the f64 reference shader, and determinism across thread
//! counts.

use lightvol_proxies::accumulate::{ExpMethod, IndirectMethod, ShadeOptions, shade_receiver};
use lightvol_proxies::kernel::{Accum, Kernel, KernelIndirect, light_f32, prepare};
use lightvol_proxies::light::DistantLight;
use lightvol_proxies::pipeline::{accumulate_pass, bin_proxies, exponentiate_pass, shade_rgb9, total};
use lightvol_proxies::receiver_scene::{ReceiverBuffer, Scene};
use lightvol_proxies::tables::SmoothClamp;
use lightvol_sh::lowdisc::SplitMix64;

/// f32 accumulation of up to 18 proxies and an f32 HYB (up to 6 squarings) against f64:
/// relative to the unshadowed shading. Measured worst 3.9e-5.
const F32_VS_F64: f64 = 1e-4;

#[test]
fn kernel_matches_reference_shader() {
    let scene = Scene::default_scene();
    let light = DistantLight(scene.light.sh::<16>());
    let (es, ei) = (28.0, 13.0);
    let kernel = Kernel::<16>::new(es, ei, KernelIndirect::Averaged);
    let prepared = prepare(&scene.proxies, &light);
    let all: Vec<u32> = (0..prepared.len() as u32).collect();
    let opts = ShadeOptions {
        indirect: IndirectMethod::Averaged,
        exp: ExpMethod::Hyb,
        shadow_clamp: Some(SmoothClamp::new(es)),
        indirect_clamp: Some(SmoothClamp::new(ei)),
    };
    let mut rng = SplitMix64::new(5);
    let mut worst = 0.0f64;
    for k in 0..400 {
        // Floor points around the character's feet, and wall points behind it.
        let (p, n) = if k % 2 == 0 {
            ([rng.range(-1.6, 0.4), rng.range(0.6, 2.6), 0.0], [0.0, 0.0, 1.0])
        } else {
            ([rng.range(-1.6, 0.4), 3.0, rng.range(0.0, 2.0)], [0.0, -1.0, 0.0])
        };
        let r = shade_receiver::<16>(p, n, &scene.proxies, &light, &opts);
        let mut acc = Accum::<16>::default();
        let pf = p.map(|v| v as f32);
        let nf = n.map(|v| v as f32);
        kernel.accumulate(pf, nf, &prepared, &all, &mut acc);
        let inc = kernel.finish(&acc, &light_f32(&light, pf));
        let fast = shade_rgb9(&total(&inc), nf, [1.0; 3]);
        for c in 0..3 {
            let f = f64::from(fast[c]) * std::f64::consts::PI;
            worst = worst.max((f - r.total()[c]).abs() / r.unshadowed[c]);
        }
    }
    println!("f32 kernel vs f64 reference: {worst:.2e}");
    assert!(worst < F32_VS_F64);
}

#[test]
fn passes_are_identical_across_thread_counts() {
    let scene = Scene::default_scene();
    let light = DistantLight(scene.light.sh::<16>());
    let kernel = Kernel::<16>::new(28.0, 13.0, KernelIndirect::Averaged);
    let prepared = prepare(&scene.proxies, &light);
    let buf = ReceiverBuffer::render(&scene, 64, 48);
    let bins = bin_proxies(&scene.camera.frame(), 64, 48, &scene.proxies, 28.0, 8);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let acc = accumulate_pass(&kernel, &buf, &bins, &prepared);
            exponentiate_pass(&kernel, &buf, &acc, &light)
        })
    };
    let (a, b) = (run(1), run(3));
    assert!(a == b, "results differ between 1 and 3 threads");
    // Some receivers are shadowed (DC of O_p * L below 95% of L's).
    let l0 = light.0.0[0].0[0] as f32;
    let shadowed = a.iter().enumerate().filter(|(i, x)| buf.valid(*i) && x.shadowed[0] < 0.95 * l0).count();
    assert!(shadowed > 10, "{shadowed}");
}

/// The exposed tables are the ones the kernel uses: zero below 1/η, the scaled table above.
#[test]
fn exposed_tables() {
    use lightvol_proxies::tables::{ProxyTables, TABLE_ENTRIES, Table, table_alpha};
    let k = Kernel::<16>::new(20.0, 10.0, KernelIndirect::Averaged);
    let (olog, vis, omega, d) = k.tables();
    assert!(olog.len() == TABLE_ENTRIES && vis.len() == TABLE_ENTRIES && omega.len() == TABLE_ENTRIES);
    let t = ProxyTables::shared::<16>();
    let i = TABLE_ENTRIES - 1;
    let scale1 = (4.0 * std::f64::consts::PI / 3.0).sqrt();
    assert!((f64::from(olog[i][1]) - t.entry(Table::LogVisibility, i)[1] * scale1).abs() < 1e-5);
    assert!((f64::from(d[i][1]) - t.entry(Table::Averaged, i)[1] * scale1).abs() < 1e-6);
    let below = (0..TABLE_ENTRIES).filter(|&i| table_alpha(i) < 0.05).collect::<Vec<_>>();
    assert!(below.iter().all(|&i| olog[i] == [0.0; 4]));
    assert!(
        (0..TABLE_ENTRIES).filter(|&i| table_alpha(i) < 0.1).all(|i| vis[i] == [0.0; 4] && omega[i] == 0.0)
    );
}

/// The kernel's f32 HYB (`Kernel::exp_hyb`, squaring by its packed schedule) against the f64
/// reference `lightvol_sh::shexp::exp_hyb` (squaring by `gaunt::product`), relative to the
/// reference's norm, on log visibilities of one to eight accumulated table entries
/// (what the accumulation pass produces). The f32 inputs are exact in f64, so the difference
/// is f32 rounding (about 6e-8 per operation) amplified by HYB's squarings (each doubles a
/// relative error; these take up to 8). Measured worst: 3.5e-5 at both orders, about `2^8`
/// times f32's 6e-8, twice over; 1e-4 leaves a factor of about 3.
const F32_HYB_VS_F64: f64 = 1e-4;

fn kernel_hyb_error<const N: usize>() -> f64 {
    use lightvol_proxies::accumulate::shared_ol_table;
    use lightvol_proxies::tables::{ProxyTables, TABLE_ENTRIES, Table};
    use lightvol_sh::coeffs::Sh;
    use lightvol_sh::eval::eval_basis;
    use lightvol_sh::sampling::sample_uniform_sphere;
    use lightvol_sh::shexp::{HYB_NORM_THRESHOLD, exp_hyb, hyb_start};
    use lightvol_sh::zonal::zh_scale;
    let kernel = Kernel::<N>::new(28.0, 13.0, KernelIndirect::Averaged);
    let t = ProxyTables::shared::<N>();
    let mut rng = SplitMix64::new(11);
    let (mut worst, mut squarings) = (0.0f64, 0u32);
    for _ in 0..2000 {
        let mut f = [0.0f32; N];
        for _ in 0..1 + (rng.next_f64() * 8.0) as usize {
            let i = (rng.next_f64() * (TABLE_ENTRIES - 1) as f64) as usize;
            let z = t.entry(Table::LogVisibility, i);
            let y = eval_basis::<f64, N>(sample_uniform_sphere([rng.next_f64(), rng.next_f64()]));
            for (j, fj) in f.iter_mut().enumerate() {
                let l = j.isqrt();
                *fj += (z[l] * zh_scale(l as u32) * y[j]) as f32;
            }
        }
        let reference = exp_hyb(shared_ol_table::<N>(), &Sh(f.map(f64::from)), HYB_NORM_THRESHOLD);
        let fast = Sh(kernel.exp_hyb(&f).map(f64::from));
        worst = worst.max((fast - reference).norm() / reference.norm());
        squarings = squarings.max(hyb_start(shared_ol_table::<N>(), &f, HYB_NORM_THRESHOLD).squarings);
    }
    println!("order {}: kernel f32 HYB vs f64 HYB {worst:.2e} ({squarings} squarings at most)", N.isqrt());
    worst
}

#[test]
fn kernel_hyb_matches_f64_reference() {
    assert!(kernel_hyb_error::<9>() < F32_HYB_VS_F64);
    assert!(kernel_hyb_error::<16>() < F32_HYB_VS_F64);
}
