//! Instanced geometry against its flattened copy ([`Scene::flattened`]): the two-level
//! tracer gives the same hit or miss, the same triangle and the same faces for every ray,
//! with distances equal to f32 rounding; the f64 reference is the same exactly; and a bake
//! of either scene agrees within a stated tolerance, bit-identically across thread counts.

use lightvol_core::samples::samples;

use glam::{DAffine3, DMat3, DQuat};
use lightvol_core::progress::BakeControl;
use lightvol_sampler::{BakeSettings, Method, bake};
use lightvol_scene::builder::box_faces;
use lightvol_scene::lights::Environment;
use lightvol_scene::{
    AlphaMode, BuildQuality, DVec2, DVec3, Levels, Material, Scene, SceneBuilder, Tracer, Transport,
    TransportSettings,
};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::GridSpec;
use proptest::prelude::*;

/// Scene extent: instances are placed within about ±20 m.
const EXTENT: f64 = 40.0;

/// Distances of the two tracers agree to this: a few f32 ulps of the scene's extent (the
/// instanced side intersects in the prototype's frame, after an f64 transform of the ray;
/// the flattened side in the world frame, after rounding the placed vertices to f32).
const T_TOL: f64 = 16.0 * f32::EPSILON as f64 * EXTENT;

/// Rays start here: a hit within f32 rounding of the origin (about 1e-6 m, in two frames
/// that round differently) may be found in one scene and not the other; 2e-4 m stays well
/// clear of that.
const TMIN: f64 = 2e-4;

/// Normals agree to f64 rounding of the normal matrix (both sides normalise in f64).
const NORMAL_TOL: f64 = 1e-9;

/// A house: a box without a floor (single-sided, outward; the ground is its floor, so that
/// no two surfaces coincide and every closest hit is well defined), a double-sided roof plane, an emissive
/// lamp and a BLEND window pane, plus some loose triangles.
fn house(b: &mut SceneBuilder, p: u32, mats: [u32; 4], rng: &mut SplitMix64) {
    let [wall, roof, lamp, pane] = mats;
    let uv = [DVec2::ZERO, DVec2::X, DVec2::ONE];
    for q in box_faces(DVec3::new(-2.0, -1.5, 0.0), DVec3::new(2.0, 1.5, 3.0), true, true) {
        b.add_prototype_triangle(p, [q[0], q[1], q[2]], uv, wall).unwrap();
        b.add_prototype_triangle(p, [q[0], q[2], q[3]], uv, wall).unwrap();
    }
    let r = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    b.add_prototype_triangle(p, [r(-2.5, -2.0, 3.5), r(2.5, -2.0, 3.5), r(0.0, 2.0, 4.2)], uv, roof).unwrap();
    b.add_prototype_triangle(p, [r(-0.3, -1.6, 2.0), r(0.3, -1.6, 2.0), r(0.0, -1.6, 2.4)], uv, lamp)
        .unwrap();
    b.add_prototype_triangle(p, [r(2.2, -1.0, 0.5), r(2.2, 1.0, 0.5), r(2.2, 0.0, 2.5)], uv, pane).unwrap();
    for _ in 0..40 {
        let o = DVec3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(0.0, 4.0));
        let mut q = || o + DVec3::new(rng.range(-0.5, 0.5), rng.range(-0.5, 0.5), rng.range(-0.5, 0.5));
        let v = [q(), q(), q()];
        b.add_prototype_triangle(p, v, uv, wall).unwrap();
    }
}

/// A ground plane placed directly, and nine houses: rotated, scaled non-uniformly,
/// mirrored, and one at a large offset, with a second, smaller prototype.
fn town() -> Scene {
    town_with(true)
}

/// [`town`], with an opaque pane when `blend` is false.
fn town_with(blend: bool) -> Scene {
    let mut rng = SplitMix64::new(7);
    let mut b = SceneBuilder::new("town");
    let wall = b.add_material(Material::diffuse("wall", [0.6, 0.5, 0.4])).unwrap();
    let roof = b.add_material(Material::diffuse("roof", [0.3, 0.3, 0.35]).two_sided()).unwrap();
    let lamp = b.add_material(Material::emitter("lamp", [0.0; 3], [20.0, 18.0, 15.0])).unwrap();
    let mut glass = Material::diffuse("glass", [0.9; 3]);
    if blend {
        glass.alpha_mode = AlphaMode::Blend;
    }
    glass.alpha = 0.4;
    let pane = b.add_material(glass).unwrap();
    let ground = b.add_material(Material::diffuse("ground", [0.4; 3])).unwrap();
    b.add_quad(
        [
            DVec3::new(-20.0, -20.0, 0.0),
            DVec3::new(20.0, -20.0, 0.0),
            DVec3::new(20.0, 20.0, 0.0),
            DVec3::new(-20.0, 20.0, 0.0),
        ],
        ground,
    )
    .unwrap();
    let big = b.add_prototype("house");
    house(&mut b, big, [wall, roof, lamp, pane], &mut rng);
    let small = b.add_prototype("shed");
    for _ in 0..30 {
        let o = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(0.0, 2.0));
        let mut q = || o + DVec3::new(rng.range(-0.6, 0.6), rng.range(-0.6, 0.6), rng.range(-0.6, 0.6));
        let v = [q(), q(), q()];
        b.add_prototype_triangle(small, v, [DVec2::ZERO; 3], wall).unwrap();
    }
    let place = |s: DVec3, turn: f64, t: DVec3| {
        DAffine3::from_scale_rotation_translation(s, DQuat::from_rotation_z(turn), t)
    };
    let placements = [
        (big, place(DVec3::ONE, 0.0, DVec3::new(-10.0, -10.0, 0.0))),
        (big, place(DVec3::ONE, 0.7, DVec3::new(0.0, -10.0, 0.0))),
        (big, place(DVec3::new(1.5, 0.8, 1.2), 2.1, DVec3::new(10.0, -10.0, 0.0))),
        (big, place(DVec3::new(-1.0, 1.0, 1.0), 0.3, DVec3::new(-10.0, 0.0, 0.0))),
        (big, place(DVec3::ONE, -1.3, DVec3::new(0.0, 0.0, 0.0))),
        (big, place(DVec3::new(1.0, -1.3, 0.9), 3.0, DVec3::new(10.0, 0.0, 0.0))),
        (
            big,
            DAffine3::from_mat3_translation(
                DMat3::from_cols(
                    DVec3::new(1.0, 0.2, 0.0),
                    DVec3::new(-0.3, 1.1, 0.1),
                    DVec3::new(0.0, 0.0, 0.9),
                ),
                DVec3::new(-10.0, 10.0, 0.0),
            ),
        ),
        (small, place(DVec3::splat(2.0), 0.4, DVec3::new(0.0, 10.0, 0.0))),
        (small, place(DVec3::ONE, 1.0, DVec3::new(10.0, 10.0, 0.0))),
    ];
    for (p, m) in placements {
        b.add_instance(p, m).unwrap();
    }
    b.environment = Environment::UniformSky { sky: [1.0, 1.0, 1.2], ground: None };
    b.build().unwrap()
}

/// The two-level tracer (the town is small enough that [`Levels::Auto`] would flatten it).
fn two_level(s: &Scene) -> Tracer {
    Tracer::build(s, BuildQuality::Medium, Levels::Two)
}

fn random_ray(rng: &mut SplitMix64) -> (DVec3, DVec3) {
    let o = DVec3::new(rng.range(-22.0, 22.0), rng.range(-22.0, 22.0), rng.range(-1.0, 8.0));
    let d = DVec3::from_array(sample_uniform_sphere([rng.next_f64(), rng.next_f64()]));
    (o, d)
}

#[test]
fn the_town_is_instanced_as_built() {
    let s = town();
    let f = s.flattened();
    assert_eq!((s.triangles.len(), s.prototypes.len(), s.instances.len()), (2, 2, 9));
    assert_eq!(s.unique_triangle_count(), 2 + (10 + 3 + 40) + 30);
    assert_eq!(s.triangle_count(), 2 + 7 * 53 + 2 * 30);
    assert_eq!((f.triangles.len(), f.instances.len()), (s.triangle_count(), 0));
    // The same triangles in the same order, and the same bounds.
    for i in 0..s.triangle_count() as u32 {
        assert_eq!(s.triangle(i), f.triangles[i as usize]);
        assert_eq!(s.stored_triangle(i).material, f.triangles[i as usize].material);
    }
    assert_eq!(s.bounds(), f.bounds());
    let tracer = two_level(&s);
    assert_eq!((tracer.len(), tracer.unique_len(), tracer.placements()), (s.triangle_count(), 85, 10));
    // Small enough to flatten: one level over the placed triangles.
    let auto = Tracer::new(&s);
    assert_eq!(
        (auto.len(), auto.unique_len(), auto.placements()),
        (s.triangle_count(), s.triangle_count(), 1)
    );
    // The mirrored instance keeps its front faces outward: a ray from outside its box's
    // +X wall meets a front face.
    let m = &s.instances[3];
    assert!(m.mirrored());
    let centre = m.to_world.transform_point3(DVec3::new(0.0, 0.0, 1.0));
    let out = m.to_world.transform_vector3(DVec3::X).normalize();
    let h = tracer.closest_hit(centre + out * 6.0, -out, 0.0, 10.0).unwrap();
    assert!(!h.from_behind, "{h:?}");
    let h = tracer.closest_hit(centre, out, 0.0, 10.0).unwrap();
    assert!(h.from_behind && h.back_face, "{h:?}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 100, rng_seed: proptest::test_runner::RngSeed::Fixed(0x1257), ..ProptestConfig::default() })]

    /// 100 cases × 1000 rays: hit or miss, triangle, faces, occlusion and (to f32
    /// rounding) distance and barycentrics agree between the instanced and the flattened
    /// scene; the brute-force loop over the instanced scene agrees with its BVH exactly.
    #[test]
    fn instanced_and_flattened_agree(seed in any::<u64>()) {
        thread_local! {
            static TRACERS: (Scene, Tracer, Tracer) = {
                let s = town();
                let (a, b) = (two_level(&s), Tracer::new(&s.flattened()));
                (s, a, b)
            };
        }
        TRACERS.with(|(scene, inst, flat)| {
            let mut rng = SplitMix64::new(seed);
            for k in 0..1000 {
                let (o, d) = random_ray(&mut rng);
                let tmax = if k % 2 == 0 { f64::INFINITY } else { rng.range(0.0, 30.0) };
                let (a, b) = (inst.closest_hit(o, d, TMIN, tmax), flat.closest_hit(o, d, TMIN, tmax));
                prop_assert_eq!(a.is_some(), b.is_some(), "hit/miss differs at {} {}", o, d);
                prop_assert_eq!(inst.occluded(o, d, TMIN, tmax), flat.occluded(o, d, TMIN, tmax));
                if k % 10 == 0 {
                    let c = inst.closest_hit_brute_force(o, d, TMIN, tmax);
                    prop_assert_eq!(a.map(|h| h.t), c.map(|h| h.t));
                }
                let (Some(a), Some(b)) = (a, b) else { continue };
                prop_assert!((a.t - b.t).abs() < T_TOL, "t {} vs {}", a.t, b.t);
                if a.triangle != b.triangle {
                    // Only a tie within rounding may pick another triangle.
                    let p = scene.triangle(a.triangle).point(a.bary[0], a.bary[1]);
                    prop_assert!((p - (o + d * b.t)).length() < 4.0 * T_TOL);
                    continue;
                }
                prop_assert_eq!((a.from_behind, a.back_face, a.single_sided), (b.from_behind, b.back_face, b.single_sided));
                prop_assert!((a.normal - b.normal).length() < NORMAL_TOL, "{} vs {}", a.normal, b.normal);
                // Barycentrics to f32 rounding relative to the triangle's size (≥ 0.1 m).
                prop_assert!((a.bary[0] - b.bary[0]).abs() < 10.0 * T_TOL && (a.bary[1] - b.bary[1]).abs() < 10.0 * T_TOL,
                    "{:?} vs {:?}", a.bary, b.bary);
            }
            Ok(())
        })?;
    }
}

/// The f64 reference reads the placed triangles, so it is the same on both scenes bit for
/// bit; and it agrees with the f32 tracer.
#[test]
fn f64_reference_is_the_flattened_one() {
    let s = town();
    let (inst, flat) = (two_level(&s), Tracer::new(&s.flattened()));
    let mut rng = SplitMix64::new(99);
    let mut hits = 0;
    for _ in 0..400 {
        let (o, d) = random_ray(&mut rng);
        let (a, b) =
            (inst.closest_hit_f64(o, d, 0.0, f64::INFINITY), flat.closest_hit_f64(o, d, 0.0, f64::INFINITY));
        assert_eq!(
            a.map(|h| (h.triangle, h.t.to_bits(), h.from_behind)),
            b.map(|h| (h.triangle, h.t.to_bits(), h.from_behind))
        );
        if let (Some(a), Some(c)) = (a, inst.closest_hit(o, d, 0.0, f64::INFINITY)) {
            hits += 1;
            assert!((a.t - c.t).abs() < T_TOL, "{} {}", a.t, c.t);
        }
    }
    assert!(hits > 100, "{hits}");
}

fn grid() -> GridSpec {
    GridSpec::new([-18.0, -18.0, 0.25], [18.0, 18.0, 6.25], [7, 7, 3]).unwrap()
}

fn baked(scene: &Scene, threads: usize) -> Vec<f32> {
    baked_with(scene, threads, Levels::Two)
}

fn baked_with(scene: &Scene, threads: usize, levels: Levels) -> Vec<f32> {
    let tracer = Tracer::build(scene, BuildQuality::Medium, levels);
    let t = Transport::new(scene, &tracer, TransportSettings::default());
    let s = BakeSettings { method: Method::DoiPaper, samples: samples(16), seed: 5, ..Default::default() };
    let out = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| bake(&t, &grid(), &s, &BakeControl::default()).unwrap());
    out.finish().0.data().to_vec()
}

/// A doi bake (sky, the lamps, two bounces) of the instanced town equals the flattened
/// town's within [`BAKE_REL_TOL`] of the largest coefficient, and is bit-identical on 1 and
/// 2 threads. Traced through one level (the instances written out inside the tracer), it
/// is the flattened town's bake bit for bit.
#[test]
fn instanced_bake_equals_the_flattened_bake() {
    /// Normals are bit-identical, hit points move by f32 rounding of the transform (about
    /// 1e-6 m here), which moves the next ray's origin and the lights' falloff by as much.
    /// The two scenes round differently, so a ray that grazes an edge can hit in one and
    /// miss in the other (a ray-by-ray comparison of 400,000 rays leaving the town's
    /// surfaces found 2: one at an edge two coplanar triangles share, one grazing back
    /// into its own plane); such a ray moves one node's coefficient by its share of that
    /// node's paths. Measured: 2.4e-4 of 3.5 (6.9e-5 relative); the bound is about 3×.
    const BAKE_REL_TOL: f64 = 2e-4;
    let s = town();
    let a = baked(&s, 1);
    assert_eq!(a, baked(&s, 2));
    let b = baked(&s.flattened(), 1);
    assert_eq!(baked_with(&s, 1, Levels::One), b);
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(0.0f64, |m, &x| m.max(f64::from(x).abs()));
    assert!(scale > 0.1, "{scale}");
    let worst = a.iter().zip(&b).map(|(&x, &y)| (f64::from(x) - f64::from(y)).abs()).fold(0.0, f64::max);
    eprintln!("instanced vs flattened bake: max |difference| {worst:.3e} of max |coefficient| {scale:.3}");
    assert!(worst <= BAKE_REL_TOL * scale, "{worst} > {BAKE_REL_TOL} x {scale}");
}

/// Textured albedo at a hit's barycentrics is the flattened scene's, under a mirroring
/// instance too (its placed vertices 1 and 2 are the stored 2 and 1).
#[test]
fn albedo_follows_the_placed_vertex_order() {
    use lightvol_scene::base_color::Texture;
    let mut b = SceneBuilder::new("tex");
    let tex =
        Texture::from_linear(2, 2, vec![[0.1, 0.2, 0.3], [0.9, 0.1, 0.1], [0.1, 0.8, 0.2], [0.4, 0.4, 0.9]])
            .unwrap();
    let t = b.add_texture(tex);
    let mut m = Material::diffuse("painted", [1.0; 3]);
    m.albedo_texture = Some(t);
    let m = b.add_material(m).unwrap();
    let p = b.add_prototype("tile");
    let uv = [DVec2::new(0.1, 0.1), DVec2::new(0.9, 0.2), DVec2::new(0.3, 0.95)];
    b.add_prototype_triangle(p, [DVec3::ZERO, DVec3::X, DVec3::Y], uv, m).unwrap();
    b.add_instance(p, DAffine3::IDENTITY).unwrap();
    b.add_instance(p, DAffine3::from_scale(DVec3::new(-1.0, 1.0, 1.0))).unwrap();
    let s = b.build().unwrap();
    assert!(s.instances[1].mirrored());
    let f = s.flattened();
    for tri in 0..2 {
        for (u, v) in [(0.1, 0.2), (0.7, 0.1), (0.2, 0.6), (0.0, 0.0)] {
            // The UV interpolation sums its terms in another order: f64 rounding.
            let (a, c) = (s.albedo(tri, u, v), f.albedo(tri, u, v));
            assert!(
                a.iter().zip(c).all(|(x, y)| (x - y).abs() < 1e-12),
                "triangle {tri} at ({u}, {v}): {a:?} {c:?}"
            );
        }
    }
    // Not symmetric in (u, v), so the swap is exercised.
    assert_ne!(f.albedo(1, 0.7, 0.1), f.albedo(1, 0.1, 0.7));
}
