use super::*;
use crate::builder::SceneBuilder;
use crate::material::Material;
use glam::DVec2;
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::sampling::sample_uniform_sphere;

/// A soup of random triangles plus a closed box, some double-sided.
fn soup(n: usize, seed: u64) -> Scene {
    let mut rng = SplitMix64::new(seed);
    let mut b = SceneBuilder::new("soup");
    let one = b.add_material(Material::diffuse("one", [0.5; 3])).unwrap();
    let two = b.add_material(Material::diffuse("two", [0.5; 3]).two_sided()).unwrap();
    for i in 0..n {
        let c = DVec3::new(rng.range(-10.0, 10.0), rng.range(-10.0, 10.0), rng.range(-10.0, 10.0));
        let mut p = || c + DVec3::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
        let v = [p(), p(), p()];
        b.add_triangle(v, [DVec2::ZERO; 3], if i % 3 == 0 { two } else { one }).unwrap();
    }
    b.add_box(DVec3::splat(-3.0), DVec3::splat(3.0), one, true, false).unwrap();
    b.build().unwrap()
}

/// Every kernel's traversal returns exactly the hit of a brute-force loop over all
/// triangles (the same watertight test, the least `(t, triangle)` pair), and both agree
/// with the f64 reference to f32 precision.
#[test]
fn bvh_matches_brute_force() {
    let scene = soup(2000, 1);
    let mut tr = Tracer::new(&scene);
    let mut rng = SplitMix64::new(2);
    let (mut hits, mut back) = (0, 0);
    for _ in 0..3000 {
        let o = DVec3::new(rng.range(-14.0, 14.0), rng.range(-14.0, 14.0), rng.range(-14.0, 14.0));
        let d = DVec3::from_array(sample_uniform_sphere([rng.next_f64(), rng.next_f64()]));
        let b = tr.closest_hit_brute_force(o, d, 0.0, f64::INFINITY);
        for isa in Isa::available() {
            tr.set_isa(isa).unwrap();
            assert_eq!(tr.closest_hit(o, d, 0.0, f64::INFINITY), b, "{isa} at {o} {d}");
            assert_eq!(tr.occluded(o, d, 0.0, f64::INFINITY), b.is_some(), "{isa} at {o} {d}");
        }
        let c = tr.closest_hit_f64(o, d, 0.0, f64::INFINITY);
        match (b, c) {
            (None, None) => {}
            (Some(a), Some(c)) => {
                hits += 1;
                back += usize::from(a.back_face);
                // f32 vs f64: t agrees to f32 precision of the scene scale (~30 units).
                assert!((a.t - c.t).abs() < 1e-4 * (1.0 + c.t), "{} {}", a.t, c.t);
                if a.triangle == c.triangle {
                    assert_eq!(a.back_face, c.back_face);
                    assert!((a.bary[0] - c.bary[0]).abs() < 1e-3 && (a.bary[1] - c.bary[1]).abs() < 1e-3);
                    let p = scene.triangles[a.triangle as usize].point(a.bary[0], a.bary[1]);
                    assert!((p - (o + d * a.t)).length() < 1e-3);
                }
            }
            other => panic!("disagreement at {o} {d}: {other:?}"),
        }
    }
    // The test must exercise both outcomes and both faces.
    assert!(hits > 1000 && back > 100, "{hits} {back}");
}

/// Shadow queries agree with the closest hit; tmax excludes farther geometry.
#[test]
fn occlusion_matches_closest_hit() {
    let scene = soup(500, 3);
    let tr = Tracer::new(&scene);
    let mut rng = SplitMix64::new(4);
    for _ in 0..2000 {
        let o = DVec3::new(rng.range(-14.0, 14.0), rng.range(-14.0, 14.0), rng.range(-14.0, 14.0));
        let d = DVec3::from_array(sample_uniform_sphere([rng.next_f64(), rng.next_f64()]));
        let tmax = rng.range(0.0, 20.0);
        let closest = tr.closest_hit_brute_force(o, d, 0.0, tmax);
        assert_eq!(tr.occluded(o, d, 0.0, tmax), closest.is_some());
    }
}

/// Barycentrics follow the scene's vertex order even though the BVH reorders
/// triangles (the `primitive_indices` pitfall).
#[test]
fn barycentrics_and_ids_in_scene_order() {
    let mut b = SceneBuilder::new("two");
    let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
    for k in 0..50 {
        let z = f64::from(k);
        b.add_triangle(
            [DVec3::new(0.0, 0.0, z), DVec3::new(4.0, 0.0, z), DVec3::new(0.0, 2.0, z)],
            [DVec2::ZERO; 3],
            m,
        )
        .unwrap();
    }
    let s = b.build().unwrap();
    let tr = Tracer::new(&s);
    for k in 0..50 {
        let h = tr.closest_hit(DVec3::new(1.0, 0.5, f64::from(k) + 0.5), -DVec3::Z, 0.0, 1.0).unwrap();
        assert_eq!(h.triangle, k);
        // Point (1, 0.5) = 0.25·v1 + 0.25·v2 + 0.5·v0.
        assert!((h.bary[0] - 0.25).abs() < 1e-6 && (h.bary[1] - 0.25).abs() < 1e-6, "{:?}", h.bary);
        assert!(!h.back_face && (h.t - 0.5).abs() < 1e-6);
        let h = tr.closest_hit(DVec3::new(1.0, 0.5, f64::from(k) - 0.5), DVec3::Z, 0.0, 1.0).unwrap();
        assert!(h.triangle == k && h.back_face && h.from_behind);
    }
}
