//! Frame time of the CPU image-space pipeline: 256 × 256 receivers (display 512 × 512) on
//! the default scene with 8, 32 and 128 proxies, split into accumulation (binning included),
//! exponentiation and upsampling (bilateral upsampling and display shading). `frame` runs the
//! fused accumulation-and-exponentiation pass into reused buffers (what a renderer does);
//! `frame_separate_passes` chains the separate passes, each allocating its output. η derived for
//! 1/256 at order 4 (shadows) and order 3 (indirect).

use std::sync::OnceLock;

use lightvol_proxies::compare::CompareConfig;
use lightvol_proxies::kernel::{Accum, Incident, Kernel, KernelIndirect, PreparedProxy, prepare};
use lightvol_proxies::light::DistantLight;
use lightvol_proxies::oracle::shadow_eta_for_light;
use lightvol_proxies::pipeline::{
    accumulate_pass, bin_proxies, exponentiate_pass, incident_pass_into, shade_display, shade_display_into,
    total,
};
use lightvol_proxies::proxy::SphereProxy;
use lightvol_proxies::receiver_scene::{ReceiverBuffer, Scene, character};
use lightvol_sh::lowdisc::SplitMix64;

fn main() {
    divan::main();
}

const COUNTS: [usize; 3] = [8, 32, 128];

/// `n` proxies: the built-in character's spheres first, then seeded spheres around it.
fn proxies(n: usize) -> Vec<SphereProxy> {
    let mut s = character([-0.6, 1.6, 0.0]);
    let mut rng = SplitMix64::new(7);
    while s.len() < n {
        let c = [rng.range(-2.5, 1.0), rng.range(0.0, 2.8), rng.range(0.1, 1.8)];
        s.push(SphereProxy::new(c, rng.range(0.08, 0.2), [0.6, 0.5, 0.4]));
    }
    s.truncate(n);
    s
}

struct Setup {
    scene: Scene,
    coarse: ReceiverBuffer,
    fine: ReceiverBuffer,
    light: DistantLight<16>,
    kernel: Kernel<16>,
    eta: f64,
    /// Shadow η specialised to the scene's light (§4.1), indirect η unchanged.
    kernel_light: Kernel<16>,
    eta_light: f64,
}

fn setup() -> &'static Setup {
    static S: OnceLock<Setup> = OnceLock::new();
    S.get_or_init(|| {
        let scene = Scene::default_scene();
        let cfg = CompareConfig::derived::<16>(512, 512, 1.0 / 256.0);
        let light = DistantLight(scene.light.sh::<16>());
        let eta_light = shadow_eta_for_light::<16>(&light.0, 1.0 / 256.0).eta;
        Setup {
            kernel_light: Kernel::<16>::new(eta_light, cfg.eta_indirect, KernelIndirect::Averaged),
            eta_light: eta_light.max(cfg.eta_indirect),
            coarse: ReceiverBuffer::render(&scene, 256, 256),
            fine: ReceiverBuffer::render(&scene, 512, 512),
            light: DistantLight(scene.light.sh::<16>()),
            kernel: Kernel::<16>::new(cfg.eta_shadow, cfg.eta_indirect, KernelIndirect::Averaged),
            eta: cfg.eta_shadow.max(cfg.eta_indirect),
            scene,
        }
    })
}

fn accumulate(s: &Setup, p: &[SphereProxy], prepared: &[PreparedProxy<16>]) -> Vec<Accum<16>> {
    let bins = bin_proxies(&s.scene.camera.frame(), 256, 256, p, s.eta, 16);
    accumulate_pass(&s.kernel, &s.coarse, &bins, prepared)
}

#[divan::bench(args = COUNTS)]
fn accumulation(bencher: divan::Bencher<'_, '_>, n: usize) {
    let s = setup();
    let p = proxies(n);
    let prepared = prepare(&p, &s.light);
    bencher.bench(|| accumulate(s, &p, &prepared));
}

#[divan::bench(args = COUNTS)]
fn exponentiation(bencher: divan::Bencher<'_, '_>, n: usize) {
    let s = setup();
    let p = proxies(n);
    let prepared = prepare(&p, &s.light);
    let acc = accumulate(s, &p, &prepared);
    bencher.bench(|| exponentiate_pass(&s.kernel, &s.coarse, &acc, &s.light));
}

#[divan::bench(args = COUNTS)]
fn upsampling(bencher: divan::Bencher<'_, '_>, n: usize) {
    let s = setup();
    let p = proxies(n);
    let prepared = prepare(&p, &s.light);
    let acc = accumulate(s, &p, &prepared);
    let inc: Vec<Incident> = exponentiate_pass(&s.kernel, &s.coarse, &acc, &s.light);
    let tot: Vec<_> = inc.iter().map(total).collect();
    bencher.bench(|| shade_display(&s.coarse, &tot, &s.fine, |_| [0.0; 27]));
}

/// The whole frame as a renderer runs it: binning, the fused accumulation and
/// exponentiation pass, and upsampling with display shading, into buffers reused from frame
/// to frame.
#[divan::bench(args = COUNTS)]
fn frame(bencher: divan::Bencher<'_, '_>, n: usize) {
    let s = setup();
    let p = proxies(n);
    let mut incident = vec![[0.0f32; 27]; 256 * 256];
    let mut shaded = vec![[0.0f32; 3]; 512 * 512];
    bencher.bench_local(|| {
        let prepared = prepare(&p, &s.light);
        let bins = bin_proxies(&s.scene.camera.frame(), 256, 256, &p, s.eta, 16);
        incident_pass_into(&s.kernel, &s.coarse, &bins, &prepared, &s.light, &mut incident);
        shade_display_into(&s.coarse, &incident, &s.fine, |_| [0.0; 27], &mut shaded)
    });
}

/// The frame through the separate passes, each returning a new vector (accumulators and
/// per-receiver results stored between the passes).
#[divan::bench(args = COUNTS)]
fn frame_separate_passes(bencher: divan::Bencher<'_, '_>, n: usize) {
    let s = setup();
    let p = proxies(n);
    bencher.bench(|| {
        let prepared = prepare(&p, &s.light);
        let acc = accumulate(s, &p, &prepared);
        let inc = exponentiate_pass(&s.kernel, &s.coarse, &acc, &s.light);
        let tot: Vec<_> = inc.iter().map(total).collect();
        shade_display(&s.coarse, &tot, &s.fine, |_| [0.0; 27])
    });
}

/// The whole frame with the shadow η specialised to the light (19.2 instead of 28.1).
#[divan::bench(args = COUNTS)]
fn frame_light_eta(bencher: divan::Bencher<'_, '_>, n: usize) {
    let s = setup();
    let p = proxies(n);
    let mut incident = vec![[0.0f32; 27]; 256 * 256];
    let mut shaded = vec![[0.0f32; 3]; 512 * 512];
    bencher.bench_local(|| {
        let prepared = prepare(&p, &s.light);
        let bins = bin_proxies(&s.scene.camera.frame(), 256, 256, &p, s.eta_light, 16);
        incident_pass_into(&s.kernel_light, &s.coarse, &bins, &prepared, &s.light, &mut incident);
        shade_display_into(&s.coarse, &incident, &s.fine, |_| [0.0; 27], &mut shaded)
    });
}
