//! Every traversal kernel this machine runs returns the scalar kernel's hits, bit for bit
//! (triangle, distance, barycentrics, faces), and the same occlusion answers, on a seeded
//! proptest set of 100,000 rays over the vendored scenes (one level and two), the built-in
//! city, and a synthetic scene of alpha-tested, transparent and mirrored instanced
//! triangles. Rays start anywhere in the scene's box or on a surface, and half of them aim
//! at a vertex or an edge of a random triangle, where kernels are most likely to differ.

use std::path::Path;

use glam::DAffine3;
use lightvol_scene::{
    AlphaMode, BuildQuality, DVec2, DVec3, Isa, Levels, LoadOptions, Material, Scene, SceneBuilder, Tracer,
    builtin, load_scene,
};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::sampling::sample_uniform_sphere;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed, TestRunner};

/// Proptest cases per scene and rays per case: 7 scenes × 16 × 900 ≈ 100,000 rays.
const CASES: u32 = 16;
const RAYS_PER_CASE: usize = 900;

fn vendored(rel: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes").join(rel);
    load_scene(&path, &LoadOptions::default()).unwrap()
}

/// Random triangles with alpha-tested (textured MASK), transparent (BLEND) and opaque
/// materials, directly placed and as instances of two prototypes (one mirrored).
fn alpha_instanced() -> Scene {
    let mut rng = SplitMix64::new(21);
    let mut b = SceneBuilder::new("alpha");
    let tex = lightvol_scene::base_color::Texture::from_linear(2, 2, vec![[1.0; 3]; 4])
        .unwrap()
        .with_alpha(vec![0.0, 0.9, 0.2, 1.0])
        .unwrap();
    let t = b.add_texture(tex);
    let mut leaf = Material::diffuse("leaf", [0.5; 3]).two_sided();
    leaf.albedo_texture = Some(t);
    leaf.alpha_mode = AlphaMode::Mask { cutoff: 0.5 };
    let mut pane = Material::diffuse("pane", [0.5; 3]);
    pane.alpha_mode = AlphaMode::Blend;
    pane.alpha = 0.4;
    let ms = [
        b.add_material(leaf).unwrap(),
        b.add_material(pane).unwrap(),
        b.add_material(Material::diffuse("wall", [0.5; 3])).unwrap(),
    ];
    let uv = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(0.0, 1.0)];
    let tri = |rng: &mut SplitMix64, c: DVec3| {
        let mut p = || c + DVec3::new(rng.range(-1.5, 1.5), rng.range(-1.5, 1.5), rng.range(-1.5, 1.5));
        [p(), p(), p()]
    };
    for i in 0..1500 {
        let c = DVec3::new(rng.range(-8.0, 8.0), rng.range(-8.0, 8.0), rng.range(-8.0, 8.0));
        let v = tri(&mut rng, c);
        b.add_triangle(v, uv, ms[i % 3]).unwrap();
    }
    for k in 0..2 {
        let p = b.add_prototype(&format!("proto{k}"));
        for i in 0..300 {
            let c = DVec3::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
            let v = tri(&mut rng, c);
            b.add_prototype_triangle(p, v, uv, ms[(i + k) % 3]).unwrap();
        }
        for j in 0..6 {
            let at = DVec3::new(rng.range(-6.0, 6.0), rng.range(-6.0, 6.0), rng.range(-6.0, 6.0));
            let mirror = if (j + k) % 2 == 0 { DVec3::ONE } else { DVec3::new(-1.0, 1.0, 1.0) };
            let m = DAffine3::from_scale_rotation_translation(
                mirror * rng.range(0.5, 1.5),
                glam::DQuat::from_rotation_y(rng.range(0.0, 6.0)),
                at,
            );
            b.add_instance(p, m).unwrap();
        }
    }
    b.build().unwrap()
}

/// A seeded batch of rays over `scene`: origins in its box or on a triangle, directions
/// uniform or aimed at a vertex or an edge point of a random triangle.
fn rays(scene: &Scene, seed: u64) -> Vec<(DVec3, DVec3, f64)> {
    let mut rng = SplitMix64::new(seed);
    let (lo, hi) = scene.bounds();
    let n = scene.triangle_count() as f64;
    let pick =
        |rng: &mut SplitMix64| scene.triangle((rng.next_f64() * n) as u32 % scene.triangle_count() as u32);
    (0..RAYS_PER_CASE)
        .map(|i| {
            let o = if i % 2 == 0 {
                lo + (hi - lo) * DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64())
            } else {
                let t = pick(&mut rng);
                let n = t.normal();
                t.point(rng.next_f64() * 0.5, rng.next_f64() * 0.5) + n * 1e-4 * (hi - lo).length()
            };
            let d = match i % 4 {
                0 | 1 => DVec3::from_array(sample_uniform_sphere([rng.next_f64(), rng.next_f64()])),
                2 => pick(&mut rng).v[(rng.next_f64() * 3.0) as usize % 3] - o,
                _ => {
                    let t = pick(&mut rng);
                    let s = rng.next_f64();
                    t.v[0] + (t.v[1] - t.v[0]) * s - o
                }
            };
            let d = if d.length() > 1e-12 { d.normalize() } else { DVec3::Z };
            let tmax = if i % 3 == 0 { rng.next_f64() * (hi - lo).length() } else { f64::INFINITY };
            (o, d, tmax)
        })
        .collect()
}

/// Runs the proptest for one scene: one tracer per kernel, each ray traced by all.
fn kernels_agree(name: &str, scene: &Scene, levels: Levels) {
    let tracers: Vec<(Isa, Tracer)> = Isa::available()
        .into_iter()
        .map(|isa| {
            let mut t = Tracer::build(scene, BuildQuality::Medium, levels);
            t.set_isa(isa).unwrap();
            (isa, t)
        })
        .collect();
    if tracers.len() < 3 {
        eprintln!("{name}: this machine runs only {:?}; the others are not compared", Isa::available());
    }
    let config =
        Config { cases: CASES, rng_seed: RngSeed::Fixed(17), failure_persistence: None, ..Config::default() };
    let hits = std::cell::Cell::new(0usize);
    TestRunner::new(config)
        .run(&any::<u64>(), |seed| {
            for (o, d, tmax) in rays(scene, seed) {
                let (_, reference) = &tracers[0];
                let want = reference.closest_hit(o, d, 0.0, tmax);
                let blocked = reference.occluded(o, d, 0.0, tmax);
                prop_assert_eq!(blocked, want.is_some(), "{}: occlusion vs closest at {} {}", name, o, d);
                hits.set(hits.get() + usize::from(want.is_some()));
                for (isa, t) in &tracers[1..] {
                    prop_assert_eq!(
                        t.closest_hit(o, d, 0.0, tmax),
                        want,
                        "{} {}: at {} {} tmax {}",
                        name,
                        isa,
                        o,
                        d,
                        tmax
                    );
                    prop_assert_eq!(
                        t.occluded(o, d, 0.0, tmax),
                        blocked,
                        "{} {}: occlusion at {} {}",
                        name,
                        isa,
                        o,
                        d
                    );
                }
            }
            Ok(())
        })
        .unwrap();
    // Hits and misses both occur in quantity.
    let total = CASES as usize * RAYS_PER_CASE;
    assert!(hits.get() > total / 5 && hits.get() < total, "{name}: {} of {total} rays hit", hits.get());
}

#[test]
fn kernels_agree_on_the_breakfast_room_in_one_level_and_two() {
    let s = vendored("breakfast_room/BreakfastRoom.gltf");
    kernels_agree("breakfast room, one level", &s, Levels::One);
    kernels_agree("breakfast room, two levels", &s, Levels::Two);
}

#[test]
fn kernels_agree_on_the_occlusion_room_zdm2_and_living_room() {
    kernels_agree("occlusion room", &vendored("occlusion_room/room.glb"), Levels::Auto);
    kernels_agree("zdm2", &vendored("zdm2/zdm2.glb"), Levels::Auto);
    kernels_agree("living room", &vendored("living_room/living_room.glb"), Levels::Auto);
}

#[test]
fn kernels_agree_on_alpha_tested_instances_and_the_city() {
    let s = alpha_instanced();
    assert!(s.is_instanced());
    kernels_agree("alpha, two levels", &s, Levels::Two);
    kernels_agree("city", &builtin("city").unwrap().scene, Levels::Auto);
}
