//! The memory estimate of an instanced layout (in its own process: the tracer-peak test
//! beside it measures this process's resident memory).

use lightvol_scene::estimate::{BVH_BUILD_BYTES_PER_TRIANGLE, SceneMemory, tracer_bytes_per_triangle};

/// The estimate of the 32 × 32 layout of the vendored occlusion room (1,024 rooms of 17
/// meshes, each mesh placed once per room), from its JSON: the loader stores each mesh
/// once, so the model counts 63,720 stored triangles and 17,408 instances, never the 65 M
/// placed triangles. Flattened (as the surface bake loads it) it is 65 M triangles' worth.
#[test]
fn layout_estimate_counts_unique_triangles_and_instances() {
    use lightvol_scene::estimate::{TLAS_BYTES_PER_PLACEMENT, estimate_scene, instance_bytes};
    let room =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes/occlusion_room/room.glb");
    let dir = tempfile::tempdir().unwrap();
    let path = lightvol_scene::layout::write_grid_layout(&room, dir.path(), [32, 32], 10.0).unwrap();
    let m = estimate_scene(&path, false).unwrap();
    let (unique, instances) = (63_720u64, 1_024 * 17);
    assert_eq!(
        (m.triangles, m.unique_triangles, m.instances, m.vertices),
        (1_024 * unique, unique, instances, 0)
    );
    // By the model, from the sizes of the types: a stored triangle is a 128-byte
    // `Triangle`; an instance is a 152-byte `Instance` (prototype u32, 12-f64 affine map,
    // first u32, f64 bounds) and the loader's 136-byte (mesh, 4x4 matrix) record. The
    // tracer keeps 192 bytes per stored triangle (half of a 160-byte four-triangle leaf pack
    // and its four u32 slots, an f64 normal with its flag in 32 bytes, the f64 vertices)
    // and the build 320 more; 552 per placement.
    assert_eq!(instance_bytes(), 152 + 136);
    assert_eq!(m.geometry_bytes, unique * 128 + instances * 288);
    assert_eq!(
        m.tracer_bytes,
        unique * (tracer_bytes_per_triangle() + BVH_BUILD_BYTES_PER_TRIANGLE)
            + instances * TLAS_BYTES_PER_PLACEMENT
    );
    assert_eq!(m.texture_bytes, 0);
    assert_eq!(tracer_bytes_per_triangle(), (160 + 16) / 2 + 32 + 72);
    assert_eq!(TLAS_BYTES_PER_PLACEMENT, 552);
    // 53 MiB in all, from 65 M placed triangles:
    // 63,720 × (128 + 192 + 320) + 17,408 × (288 + 552).
    assert_eq!(m.total(), 63_720 * 640 + 17_408 * 840);
    assert_eq!(m.total(), 55_403_520);
    let flat = estimate_scene(&path, true).unwrap();
    assert_eq!(flat, SceneMemory::from_counts(1_024 * unique, flat.vertices, 0));
    assert!(flat.total() > 16 << 30, "{}", flat.total());
}
