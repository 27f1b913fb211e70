use glam::DVec3;
use lightvol_sampler::scene_setup::{LightOverrides, SceneSource, load};
use lightvol_scene::bvh::Tracer;
use lightvol_scene::qmc::Qmc;
use lightvol_sh::sampling::sample_uniform_sphere;
fn main() {
    let src = SceneSource::File {
        path: "data/scenes/breakfast_room/BreakfastRoom.gltf".into(),
        options: Default::default(),
    };
    let l = load(&src, u128::MAX, &LightOverrides::default()).unwrap();
    let tr = Tracer::new(&l.scene);
    let min = [-1.544, -2.016, 0.25];
    let max = [1.710, 2.169, 2.75];
    let res = [8usize, 10, 6];
    let sp = DVec3::new((max[0] - min[0]) / 7.0, (max[1] - min[1]) / 9.0, (max[2] - min[2]) / 5.0);
    let n = 16384u64;
    for k in 0..res[2] {
        for j in 0..res[1] {
            for i in 0..res[0] {
                let x =
                    DVec3::new(min[0] + i as f64 * sp.x, min[1] + j as f64 * sp.y, min[2] + k as f64 * sp.z);
                let h = Qmc::<2>::new(7, (i + 8 * j + 80 * k) as u64);
                let (mut near, mut far) = (0u64, 0u64);
                for s in 0..n {
                    let d = DVec3::from_array(sample_uniform_sphere(h.point(s)));
                    if let Some(b) = tr.closest_hit(x, d, 0.0, f64::INFINITY).filter(|h| h.back_face) {
                        if (d * b.t).abs().cmple(sp).all() { near += 1 } else { far += 1 }
                    }
                }
                if near + far > 0 {
                    println!(
                        "node {i},{j},{k} x={:.2},{:.2},{:.2} near {:.5} far {:.4}",
                        x.x,
                        x.y,
                        x.z,
                        near as f64 / n as f64,
                        far as f64 / n as f64
                    );
                }
            }
        }
    }
}
