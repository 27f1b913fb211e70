//! The node reach in files and in placed grids: the native EXR carries it exactly (f32 and
//! f16 coefficient files alike) at format version 4, and a placed grid's lookups apply it
//! through the placement like an unplaced one's.

mod common;

use lightvol_sh::lowdisc::SplitMix64;
use lightvol_volume::io::exr::{ExrOptions, ExrSample, exr_from_bytes, exr_to_bytes};
use lightvol_volume::io::sidecar::{REACH_VERSION, format_version};
use lightvol_volume::{IrradianceVolume, NodeReach, ValidityMask};

/// Agreement of lookups at a point and at its image through a placement and back.
const PLACEMENT_TOL: f64 = 1e-12;

/// A reach of pseudo-random values in [0, 1] (some exactly 1) for every node of `vol`.
fn random_reach(vol: &IrradianceVolume, seed: u64) -> NodeReach {
    let mut rng = SplitMix64::new(seed);
    let n = vol.spec().node_count();
    NodeReach::new(
        (0..n)
            .map(|_| std::array::from_fn(|_| if rng.next_f64() < 0.5 { 1.0 } else { rng.next_f64() as f32 }))
            .collect(),
    )
    .unwrap()
}

#[test]
fn exr_files_carry_the_reach_exactly() {
    let plain = common::random_volume(9, [5, 4, 3], 21);
    let reach = random_reach(&plain, 3);
    let vol = plain.clone().with_reach(reach.clone()).unwrap();
    assert_eq!(format_version(&vol), REACH_VERSION);
    for sample in [ExrSample::F32, ExrSample::F16] {
        let options = ExrOptions { sample, ..ExrOptions::default() };
        let back = exr_from_bytes(&exr_to_bytes(&vol, &options).unwrap()).unwrap();
        assert_eq!(back.reach(), Some(&reach), "{sample:?}");
        // A file of the volume without its reach reads back without one.
        let bare = exr_from_bytes(&exr_to_bytes(&plain, &options).unwrap()).unwrap();
        assert_eq!(bare.reach(), None);
    }
    // With a validity mask as well, both travel.
    let both = vol.clone().with_validity(ValidityMask::new((0..60).map(|i| i % 7 != 0).collect())).unwrap();
    let back = exr_from_bytes(&exr_to_bytes(&both, &ExrOptions::default()).unwrap()).unwrap();
    assert_eq!(back, both);
}

/// A random reach on a placed grid (rotated, stretched along z): lookups on the placed grid
/// equal the unplaced grid's at the corresponding points, so the reach is read in grid
/// axes whatever the placement.
#[test]
fn placed_grids_apply_the_reach_in_grid_axes() {
    let vol = common::random_volume(4, [3, 3, 3], 5);
    let reach = random_reach(&vol, 9);
    let placed = vol.clone().with_reach(reach.clone()).unwrap();
    let spec = vol.spec();
    let unplaced_spec = lightvol_volume::GridSpec::new(spec.bounds().0, spec.bounds().1, spec.res()).unwrap();
    let unplaced = IrradianceVolume::new(unplaced_spec, 4, vol.data().to_vec(), vol.weights().to_vec())
        .unwrap()
        .with_reach(reach)
        .unwrap();
    let mut rng = SplitMix64::new(12);
    let (lo, hi) = spec.bounds();
    for _ in 0..200 {
        let g: [f64; 3] = std::array::from_fn(|a| rng.range(lo[a], hi[a]));
        let w = spec.to_world(g);
        // Without a normal (coefficients) the test point is the query itself. The world
        // round trip moves the point by a few ulps, so the weights differ by as much: O(1)
        // coefficients agree to far better than PLACEMENT_TOL (a corner left out on one side
        // only would differ by O(0.1)).
        let (a, b) = (placed.coeffs_reference(w), unplaced.coeffs_reference(g));
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < PLACEMENT_TOL, "at grid point {g:?}: {a:?} vs {b:?}");
        }
    }
}
