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

/// The KTX2 export (its embedded sidecar) and the DDS sidecar carry the reach, at version
/// 4; a sidecar that claims an older version with a reach, or whose limited count disagrees
/// with its values, is refused.
#[test]
fn ktx2_and_dds_carry_the_reach() {
    use lightvol_volume::io::dds::{dds_from_bytes, dds_sidecar, dds_to_bytes};
    use lightvol_volume::io::ktx2::{ktx2_from_bytes, ktx2_to_bytes};
    use lightvol_volume::io::sidecar::ReachJson;
    let plain = common::random_volume(4, [3, 4, 2], 9);
    let reach = random_reach(&plain, 4);
    let vol = plain.clone().with_reach(reach.clone()).unwrap();
    assert_eq!(ktx2_from_bytes(&ktx2_to_bytes(&vol).unwrap()).unwrap().reach(), Some(&reach));
    assert_eq!(ktx2_from_bytes(&ktx2_to_bytes(&plain).unwrap()).unwrap().reach(), None);
    let sidecar = dds_sidecar(&vol, Some("v.dds".into())).unwrap();
    assert_eq!(sidecar.version, REACH_VERSION);
    let dds = dds_to_bytes(&vol).unwrap();
    assert_eq!(dds_from_bytes(&dds, &sidecar).unwrap().reach(), Some(&reach));
    let mut old = sidecar.clone();
    old.version = REACH_VERSION - 1;
    assert!(old.validate().unwrap_err().to_string().contains("no reach section"));
    let mut miscounted = sidecar.clone();
    miscounted.reach = Some(ReachJson { limited_nodes: reach.limited_count() + 1, ..ReachJson::of(&reach) });
    assert!(miscounted.validate().unwrap_err().to_string().contains("limited nodes"));
}

/// Shard accumulators over disjoint nodes carry their nodes' reach, in memory and in shard
/// files (version 3, streamed or read whole), and merge into the whole bake's reach; a
/// node no shard recorded reaches a full cell; an accumulator with a reach does not merge
/// with one without.
#[test]
fn shard_files_carry_the_reach_and_merge_it() {
    use lightvol_volume::Accumulator;
    use lightvol_volume::io::accumulator::{
        accumulator_from_bytes, accumulator_to_bytes, merge_accumulator_file,
    };
    let spec = lightvol_volume::GridSpec::new([0.0; 3], [1.0; 3], [3, 2, 2]).unwrap();
    let n = spec.node_count();
    let reach_of = |node: usize| -> [f32; 6] { std::array::from_fn(|d| ((node * 6 + d) % 11) as f32 / 10.0) };
    let basis = [0.5, 0.1, -0.2, 0.3];
    let mut whole = Accumulator::new(spec.clone(), 4).unwrap();
    let mut halves = [Accumulator::new(spec.clone(), 4).unwrap(), Accumulator::new(spec.clone(), 4).unwrap()];
    for node in 0..n {
        for acc in [&mut whole, &mut halves[usize::from(node >= n / 2)]] {
            acc.add(node, 1.0, [1.0, 2.0, 3.0], &basis);
            acc.set_reach(node, reach_of(node));
        }
    }
    let want = NodeReach::new((0..n).map(reach_of).collect()).unwrap();
    assert_eq!(whole.reach(), Some(want.clone()));
    assert_eq!(whole.finalize().0.reach(), Some(&want));
    // The first half alone: the other nodes reach a full cell.
    let first = halves[0].reach().unwrap();
    for node in 0..n {
        assert_eq!(first.node(node), if node < n / 2 { reach_of(node) } else { [1.0; 6] }, "node {node}");
    }
    let mut merged = halves[0].clone();
    merged.merge(&halves[1]).unwrap();
    assert_eq!(merged.reach(), Some(want.clone()));
    // Shard files.
    let meta = lightvol_volume::BakeMetadata::default();
    let bytes: Vec<Vec<u8>> = halves.iter().map(|h| accumulator_to_bytes(h, &meta).unwrap()).collect();
    assert_eq!(u16::from_le_bytes([bytes[0][6], bytes[0][7]]), 3, "a shard file with a reach is version 3");
    let (back, _) = accumulator_from_bytes(&bytes[0]).unwrap();
    assert_eq!(back, halves[0]);
    let dir = std::env::temp_dir().join(format!("lightvol-reach-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let paths: Vec<_> = (0..2).map(|i| dir.join(format!("{i}.lvacc"))).collect();
    for (p, b) in paths.iter().zip(&bytes) {
        std::fs::write(p, b).unwrap();
    }
    let (streamed, _) = merge_accumulator_file(None, &paths[0]).unwrap();
    let (streamed, _) = merge_accumulator_file(Some(streamed), &paths[1]).unwrap();
    assert_eq!(streamed.reach(), Some(want));
    // Without a reach: no merge either way.
    let mut plain = Accumulator::new(spec, 4).unwrap();
    plain.add(0, 1.0, [1.0; 3], &basis);
    assert!(plain.clone().merge(&halves[0]).is_err());
    assert!(halves[0].clone().merge(&plain).is_err());
    std::fs::write(&paths[1], accumulator_to_bytes(&plain, &meta).unwrap()).unwrap();
    let (first, _) = merge_accumulator_file(None, &paths[0]).unwrap();
    assert!(merge_accumulator_file(Some(first), &paths[1]).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}
