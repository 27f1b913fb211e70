//! Closest-hit throughput on a procedural scene of more than one million triangles, with 1
//! and 2 threads (incoherent, GI-like rays). Reports rays per second through divan's item
//! counter; Mrays/s = items/s / 1e6.

use std::sync::OnceLock;

use divan::{Bencher, counter::ItemsCount};
use lightvol_scene::{BuildQuality, DVec2, DVec3, Material, Scene, SceneBuilder, Tracer};
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

/// Rays per iteration of the alpha benchmark.
const ALPHA_RAYS: usize = 100_000;

/// A canopy of 20,000 random leaf quads (40,000 triangles) with a disc-shaped alpha mask
/// (about 21% of each quad transparent), as `OPAQUE`, `MASK` and `BLEND` (alpha 0.5)
/// versions of the same geometry, plus rays from below into it.
fn canopy(mode: &str) -> (Tracer, Vec<(DVec3, DVec3)>) {
    use lightvol_scene::AlphaMode;
    use lightvol_scene::base_color::Texture;
    let n = 64u32;
    let alpha: Vec<f32> = (0..n * n)
        .map(|i| {
            let (x, y) = (f64::from(i % n) + 0.5 - 32.0, f64::from(i / n) + 0.5 - 32.0);
            if x * x + y * y < 32.0 * 32.0 { 1.0 } else { 0.0 }
        })
        .collect();
    let tex = Texture::from_linear(n, n, vec![[0.2, 0.6, 0.2]; (n * n) as usize])
        .unwrap()
        .with_alpha(alpha)
        .unwrap();
    let mut b = SceneBuilder::new("canopy");
    let t = b.add_texture(tex);
    let mut m = Material::diffuse("leaf", [1.0; 3]).two_sided();
    m.albedo_texture = Some(t);
    m.alpha_mode = match mode {
        "mask" => AlphaMode::Mask { cutoff: 0.5 },
        "blend" => AlphaMode::Blend,
        _ => AlphaMode::Opaque,
    };
    if mode == "blend" {
        m.alpha = 0.5;
    }
    let m = b.add_material(m).unwrap();
    let mut rng = SplitMix64::new(7);
    let uv = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(1.0, 1.0), DVec2::new(0.0, 1.0)];
    for _ in 0..20_000 {
        let c = DVec3::new(rng.range(-10.0, 10.0), rng.range(-10.0, 10.0), rng.range(4.0, 8.0));
        let u = DVec3::from_array(sample_uniform_sphere([rng.next_f64(), rng.next_f64()])) * 0.3;
        let v = u.any_orthonormal_vector() * 0.3;
        let q = [c - u - v, c + u - v, c + u + v, c - u + v];
        b.add_triangle([q[0], q[1], q[2]], [uv[0], uv[1], uv[2]], m).unwrap();
        b.add_triangle([q[0], q[2], q[3]], [uv[0], uv[2], uv[3]], m).unwrap();
    }
    let s = b.build().unwrap();
    let rays = (0..ALPHA_RAYS)
        .map(|_| {
            let o = DVec3::new(rng.range(-8.0, 8.0), rng.range(-8.0, 8.0), 0.0);
            let d = DVec3::from_array(sample_uniform_sphere([rng.next_f64(), rng.next_f64()]));
            (o, DVec3::new(d.x, d.y, d.z.abs()))
        })
        .collect();
    (Tracer::new(&s), rays)
}

/// Closest hits into a leaf canopy, one thread: the cost of the alpha test against the same
/// geometry traced opaque (compare the `opaque`, `mask` and `blend` rows).
#[divan::bench(args = ["opaque", "mask", "blend"], sample_count = 5, sample_size = 1)]
fn alpha(bencher: Bencher<'_, '_>, mode: &str) {
    let (tracer, rays) = canopy(mode);
    bencher.counter(ItemsCount::new(ALPHA_RAYS)).bench(|| {
        rays.iter().filter(|(o, d)| tracer.closest_hit(*o, *d, 0.0, f64::INFINITY).is_some()).count()
    });
}
