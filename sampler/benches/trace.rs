//! Closest-hit throughput on a procedural scene of more than one million triangles, with 1
//! and 2 threads (incoherent, GI-like rays). Reports rays per second through divan's item
//! counter; Mrays/s = items/s / 1e6.

use std::sync::OnceLock;

use divan::{Bencher, counter::ItemsCount};
use lightvol_sampler::{BuildQuality, DVec2, DVec3, Material, Scene, SceneBuilder, Tracer};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::sampling::sample_uniform_sphere;
use rayon::prelude::*;

fn main() {
    divan::main();
}

/// Rays per benchmark iteration.
const RAYS: usize = 200_000;

/// A 708 × 708-quad heightfield (1,002,528 triangles) plus 400 boxes (4,800 triangles).
type Terrain = (Scene, Tracer, Vec<(DVec3, DVec3)>);

fn scene() -> &'static Terrain {
    static S: OnceLock<Terrain> = OnceLock::new();
    S.get_or_init(|| {
        let mut b = SceneBuilder::new("terrain");
        let m = b.add_material(Material::diffuse("t", [0.5; 3])).unwrap();
        let n = 708;
        let size = 200.0;
        let h = |i: usize, j: usize| {
            let (x, y) = (i as f64 / n as f64 * 12.0, j as f64 / n as f64 * 12.0);
            3.0 * (x.sin() * y.cos()) + 1.5 * (2.3 * x + 0.7 * y).sin()
        };
        let p = |i: usize, j: usize| {
            DVec3::new(
                i as f64 / n as f64 * size - size / 2.0,
                j as f64 / n as f64 * size - size / 2.0,
                h(i, j),
            )
        };
        for i in 0..n {
            for j in 0..n {
                b.add_triangle([p(i, j), p(i + 1, j), p(i + 1, j + 1)], [DVec2::ZERO; 3], m).unwrap();
                b.add_triangle([p(i, j), p(i + 1, j + 1), p(i, j + 1)], [DVec2::ZERO; 3], m).unwrap();
            }
        }
        let mut rng = SplitMix64::new(1);
        for _ in 0..400 {
            let c = DVec3::new(rng.range(-90.0, 90.0), rng.range(-90.0, 90.0), rng.range(0.0, 6.0));
            let e = DVec3::new(rng.range(0.5, 4.0), rng.range(0.5, 4.0), rng.range(1.0, 10.0));
            b.add_box(c - e, c + e, m, true, false).unwrap();
        }
        let s = b.build().unwrap();
        let t = Tracer::new(&s);
        let rays = (0..RAYS)
            .map(|_| {
                let o = DVec3::new(rng.range(-95.0, 95.0), rng.range(-95.0, 95.0), rng.range(2.0, 12.0));
                (o, DVec3::from_array(sample_uniform_sphere([rng.next_f64(), rng.next_f64()])))
            })
            .collect();
        eprintln!("scene: {} triangles", s.triangles.len());
        (s, t, rays)
    })
}

#[divan::bench(args = [1, 2], sample_count = 5, sample_size = 1)]
fn closest_hit(bencher: Bencher<'_, '_>, threads: usize) {
    let (_, tracer, rays) = scene();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    bencher.counter(ItemsCount::new(RAYS)).bench(|| {
        pool.install(|| {
            rays.par_chunks(1024)
                .map(|c| {
                    c.iter().filter(|(o, d)| tracer.closest_hit(*o, *d, 0.0, f64::INFINITY).is_some()).count()
                })
                .sum::<usize>()
        })
    });
}

#[divan::bench(args = [1, 2], sample_count = 5, sample_size = 1)]
fn occluded(bencher: Bencher<'_, '_>, threads: usize) {
    let (_, tracer, rays) = scene();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    bencher.counter(ItemsCount::new(RAYS)).bench(|| {
        pool.install(|| {
            rays.par_chunks(1024)
                .map(|c| c.iter().filter(|(o, d)| tracer.occluded(*o, *d, 0.0, 50.0)).count())
                .sum::<usize>()
        })
    });
}

/// BVH build presets compared on one thread (build time is not measured here).
#[divan::bench(args = ["fast", "medium", "slow"], sample_count = 3, sample_size = 1)]
fn closest_hit_by_build(bencher: Bencher<'_, '_>, quality: &str) {
    let (scene, _, rays) = scene();
    let q = match quality {
        "fast" => BuildQuality::Fast,
        "slow" => BuildQuality::Slow,
        _ => BuildQuality::Medium,
    };
    let tracer = Tracer::with_quality(scene, q);
    bencher.counter(ItemsCount::new(RAYS)).bench(|| {
        rays.iter().filter(|(o, d)| tracer.closest_hit(*o, *d, 0.0, f64::INFINITY).is_some()).count()
    });
}
