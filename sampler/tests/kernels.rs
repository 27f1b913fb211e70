//! A bake's output is bit-identical whichever traversal kernel the tracer runs: every
//! kernel this machine can run (scalar, SSE2, AVX2) bakes the built-in city (sky, sun,
//! lamps, bounces; one BVH level) and the instanced town of the built-in interior with the
//! default method, and the volumes' coefficients are compared bit for bit.

use lightvol_core::progress::BakeControl;
use lightvol_core::samples::samples;
use lightvol_sampler::{BakeSettings, Method, bake};
use lightvol_scene::{BuildQuality, Isa, Levels, Scene, Tracer, Transport, TransportSettings, builtin};
use lightvol_volume::GridSpec;

fn bake_with(scene: &Scene, grid: &GridSpec, isa: Isa, levels: Levels) -> Vec<u32> {
    let mut tracer = Tracer::build(scene, BuildQuality::Medium, levels);
    tracer.set_isa(isa).unwrap();
    assert_eq!(tracer.isa(), isa);
    let t = Transport::new(scene, &tracer, TransportSettings::default());
    let s = BakeSettings { method: Method::Doi, samples: samples(64), seed: 3, ..Default::default() };
    let out = bake(&t, grid, &s, &BakeControl::default()).unwrap();
    out.finish().0.data().iter().map(|x| x.to_bits()).collect()
}

fn same_bytes_on_every_kernel(name: &str, scene: &Scene, grid: &GridSpec, levels: Levels) {
    let available = Isa::available();
    if available.len() < Isa::ALL.len() {
        eprintln!("{name}: this machine runs only {available:?}; the other kernels are not compared");
    }
    let reference = bake_with(scene, grid, Isa::Scalar, levels);
    assert!(reference.iter().any(|&b| f32::from_bits(b) != 0.0), "{name}: an empty bake compares nothing");
    for isa in available.into_iter().skip(1) {
        let got = bake_with(scene, grid, isa, levels);
        let differ = got.iter().zip(&reference).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{name}: {differ} of {} coefficients differ with {isa}", reference.len());
    }
}

#[test]
fn bakes_are_bit_identical_on_every_kernel() {
    let city = builtin("city").unwrap();
    let grid = GridSpec::new([-18.0, -18.0, 0.25], [18.0, 18.0, 6.25], [6, 6, 3]).unwrap();
    same_bytes_on_every_kernel("city", &city.scene, &grid, Levels::Auto);
    let interior = builtin("interior").unwrap();
    let (lo, hi) = interior.scene.bounds();
    let grid = GridSpec::new(lo.to_array(), hi.to_array(), [5, 5, 4]).unwrap();
    same_bytes_on_every_kernel("interior, two levels", &interior.scene, &grid, Levels::Two);
}
