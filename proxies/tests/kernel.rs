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
