//! The scene-memory model of `lightvol_scene::estimate` against what building the tracer
//! really takes: the peak-RSS growth of `Tracer::new` on 400,000 triangles lies below the
//! model's tracer bytes and above half of them (so the estimate refuses nothing that would
//! fit with room to spare, and never lets through what would not).
//!
//! Resident memory comes from `/proc/self/status` (Linux); elsewhere the test says so and
//! checks nothing.

mod common;

use common::{reset_peak, status_bytes};
use lightvol_scene::builder::SceneBuilder;
use lightvol_scene::estimate::{BVH_BUILD_BYTES_PER_TRIANGLE, SceneMemory, tracer_bytes_per_triangle};
use lightvol_scene::material::Material;
use lightvol_scene::{DVec2, DVec3, Tracer};

const TRIANGLES: usize = 400_000;

#[test]
fn tracer_estimate_bounds_the_measured_peak() {
    if status_bytes("VmRSS:") == 0 {
        eprintln!("memory not measured: no /proc/self/status");
        return;
    }
    let mut b = SceneBuilder::new("soup");
    let m = b.add_material(Material::diffuse("grey", [0.5; 3])).unwrap();
    // Small triangles scattered over a 100 m cube (a seeded LCG: reproducible).
    let mut s = 12345u64;
    let mut next = || {
        s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..TRIANGLES {
        let o = DVec3::new(next(), next(), next()) * 100.0;
        let v = [o, o + DVec3::new(0.3, next() * 0.3, 0.0), o + DVec3::new(0.0, 0.3, next() * 0.3)];
        b.add_triangle(v, [DVec2::ZERO; 3], m).unwrap();
    }
    let scene = b.build().unwrap();
    let before = status_bytes("VmRSS:");
    reset_peak();
    let tracer = Tracer::new(&scene);
    let peak = status_bytes("VmHWM:").saturating_sub(before) as f64;
    let model = SceneMemory::from_counts(TRIANGLES as u64, 0, 0).tracer_bytes as f64;
    let per = peak / TRIANGLES as f64;
    eprintln!(
        "tracer build: {per:.0} bytes per triangle measured, model {} (arrays {} + build {BVH_BUILD_BYTES_PER_TRIANGLE})",
        model / TRIANGLES as f64,
        tracer_bytes_per_triangle()
    );
    assert!(
        peak <= model,
        "the build took {per:.0} B/triangle, more than the model's {}",
        model / TRIANGLES as f64
    );
    assert!(
        peak >= 0.5 * model,
        "the model ({} B/triangle) is over twice the measured {per:.0}",
        model / TRIANGLES as f64
    );
    drop(tracer);
}
