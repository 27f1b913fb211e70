//! Splatting ([SGNS07] §4.1): a proxy's tile bins cover every receiver inside its sphere of
//! influence, so binning never drops a contribution.

use lightvol_proxies::pipeline::bin_proxies;
use lightvol_proxies::proxy::SphereProxy;
use lightvol_proxies::receiver_scene::{ReceiverBuffer, Scene};
use lightvol_sh::lowdisc::SplitMix64;

#[test]
fn bins_cover_the_sphere_of_influence() {
    let scene = Scene::default_scene();
    let (w, h, tile) = (96, 72, 8);
    let buf = ReceiverBuffer::render(&scene, w, h);
    let cam = scene.camera.frame();
    let mut rng = SplitMix64::new(11);
    let proxies: Vec<SphereProxy> = (0..40)
        .map(|_| {
            let c = [rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(0.0, 2.5)];
            SphereProxy::new(c, rng.range(0.02, 0.3), [0.5; 3])
        })
        .collect();
    let eta = 6.0;
    let bins = bin_proxies(&cam, w, h, &proxies, eta, tile);
    let mut covered = 0;
    for (k, p) in proxies.iter().enumerate() {
        for i in 0..w * h {
            if !buf.valid(i) {
                continue;
            }
            let q = buf.position[i].map(f64::from);
            let d2: f64 = (0..3).map(|a| (q[a] - p.center[a]).powi(2)).sum();
            if d2 < (eta * p.radius).powi(2) {
                covered += 1;
                let (x, y) = (i % w, i / w);
                let list = &bins.lists[(y / tile) * bins.tiles_x + x / tile];
                assert!(list.contains(&(k as u32)), "proxy {k} missing at pixel ({x}, {y})");
            }
        }
    }
    assert!(covered > 100, "the test must exercise some coverage: {covered}");
    // Lists are in ascending proxy order (the per-receiver summation order).
    assert!(bins.lists.iter().all(|l| l.windows(2).all(|p| p[0] < p[1])));
}
