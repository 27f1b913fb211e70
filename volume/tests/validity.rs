//! Validity masks: the lookups leave invalid corners out (against a value computed by hand),
//! a mask that drops nothing changes no bit, the f32 and f64 lookups agree, and the mask
//! survives the native EXR, KTX2 and DDS files; a version-1 file (no mask) still loads and
//! is still written byte for byte.

mod common;

use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::frame::UpAxis;
use lightvol_volume::gradient::VolumeGradients;
use lightvol_volume::io::dds::{dds_from_bytes, dds_sidecar, dds_to_bytes};
use lightvol_volume::io::exr::{
    ExrOptions, ExrSample, exr_from_bytes, exr_from_bytes_with_gradients, exr_to_bytes,
    exr_to_bytes_with_gradients,
};
use lightvol_volume::io::ktx2::{ktx2_from_bytes, ktx2_to_bytes};
use lightvol_volume::io::sidecar::VALIDITY_VERSION;
use lightvol_volume::{BakeMetadata, GridSpec, IrradianceVolume, ValidityMask, VolumeError};

/// `π · Y_00`: irradiance per unit `L_00` (Ramamoorthi & Hanrahan 2001; `A_0 = π`).
const PI_Y00: f64 = std::f64::consts::PI * 0.282_094_791_773_878_14;
/// The f64 reference against a value computed by hand from exact binary-fraction weights:
/// only the rounding of a dozen products and sums of O(10) numbers.
const HAND_F64_TOL: f64 = 1e-12;
/// The f32 path against the same value: f32 coefficients (exact here, small integers),
/// f32 weights of exact fractions, f32 sums of O(10) numbers: a few ulps of 10 at 2^-24.
const HAND_F32_TOL: f64 = 1e-5;
/// f32 against f64 lookups with renormalised weights: the unmasked lookups agree to
/// relative 1e-5 of the magnitude scale (~10 coefficients of O(1)); dividing by the valid
/// weight `s` scales the f32 weights' absolute error (~1e-6: the grid coordinate is rounded
/// to 2^-24 of up to ~10 cell units) by `1/s`.
const F32_VS_F64_REL: f64 = 1e-5;
/// Below this valid weight the f32 fractions cannot resolve the renormalised weights
/// (their ~1e-6 error becomes a large share of `s`); such queries are left out of the
/// f32-against-f64 comparison (each lookup is still a convex combination of valid corners).
const MIN_VALID_WEIGHT: f64 = 1e-3;

/// A 3×3×3 grid of unit cells from the origin; node `i` holds `L_00 = 1 + i` in red, `2 + i`
/// in green and `-i` in blue (exact in f32), every other coefficient 0.
fn dc_volume() -> IrradianceVolume {
    let spec = GridSpec::new([0.0; 3], [2.0; 3], [3, 3, 3]).unwrap();
    let n = spec.node_count();
    let mut data = vec![0.0f32; n * 27];
    for i in 0..n {
        data[i * 27] = 1.0 + i as f32;
        data[i * 27 + 1] = 2.0 + i as f32;
        data[i * 27 + 2] = -(i as f32);
    }
    IrradianceVolume::new(spec, 9, data, vec![1.0; n]).unwrap()
}

fn bits3(v: [f32; 3]) -> [u32; 3] {
    v.map(f32::to_bits)
}

/// The point `(0.25, 0.5, 0.75)` in the cell at the origin, corners 0 (node 0) and 5 (node
/// `1 + 9` = 10) invalid. By hand: fractions `(¼, ½, ¾)`, so the weights of corners
/// 0..8 (`c = dx + 2dy + 4dz`) are `3/32, 1/32, 3/32, 1/32, 9/32, 3/32, 9/32, 3/32`; corners
/// 0 and 5 drop out and the rest are divided by `26/32`. The corner nodes are
/// `0, 1, 3, 4, 9, 10, 12, 13`, so the red `L_00` is
/// `(1·2 + 3·4 + 1·5 + 9·10 + 9·13 + 3·14) / 26 = 268/26` (the `1 + i` of nodes 1, 3, 4, 9,
/// 12, 13 with weights 1, 3, 1, 9, 9, 3 in 32nds).
#[test]
fn masked_lookup_equals_the_hand_computed_weighting() {
    let mask = ValidityMask::new((0..27).map(|i| i != 0 && i != 10).collect());
    let vol = dc_volume().with_validity(mask.clone()).unwrap();
    let p = [0.25, 0.5, 0.75];
    let up = [0.0, 0.0, 1.0];
    let w = [(1.0, 2.0), (3.0, 4.0), (1.0, 5.0), (9.0, 10.0), (9.0, 13.0), (3.0, 14.0)];
    let red: f64 = w.iter().map(|(a, b)| a * b).sum::<f64>() / 26.0;
    assert_eq!(red, 268.0 / 26.0);
    // Green is red + 1, blue is 1 - red (the weights sum to 1).
    let want = [red, red + 1.0, 1.0 - red].map(|l| PI_Y00 * l);
    let slow = vol.irradiance_reference(p, up);
    let fast = vol.irradiance(p.map(|v| v as f32), up.map(|v| v as f32));
    for ch in 0..3 {
        assert!((slow[ch] - want[ch]).abs() <= HAND_F64_TOL, "{slow:?} vs {want:?}");
        assert!((f64::from(fast[ch]) - want[ch]).abs() <= HAND_F32_TOL, "{fast:?} vs {want:?}");
    }
    // The interpolated coefficients are the same weighting.
    let mut c = [0.0f32; 27];
    vol.coeffs_at(p.map(|v| v as f32), &mut c);
    assert!((f64::from(c[0]) - red).abs() <= HAND_F32_TOL);
    assert!((vol.coeffs_reference(p)[0] - red).abs() <= HAND_F64_TOL);
    assert_eq!(vol.sh_at::<9>(p.map(|v| v as f32)).unwrap().0[0].0[0], c[0]);
    // The invalid corners' values do not matter at all.
    let mut scrambled = vol.clone();
    for bad in [0, 10] {
        scrambled.set_node(bad, &[1e3; 27]).unwrap();
    }
    assert_eq!(scrambled.irradiance_reference(p, up), slow);
    assert_eq!(bits3(scrambled.irradiance(p.map(|v| v as f32), [0.0, 0.0, 1.0])), bits3(fast));
    // Without the mask the same point reads them (plain trilinear): 3/32 and 3/32 of 1e3.
    let mut plain = scrambled.clone();
    plain.set_validity(None).unwrap();
    assert!(plain.irradiance_reference(p, up)[0] > PI_Y00 * 50.0);
}

/// Every corner valid, or every corner invalid: the plain trilinear weights, bit for bit,
/// on every path (scalar, batched, reference, coefficients). Also at a point where only
/// invalid corners have weight (a node that is invalid).
#[test]
fn masks_that_drop_nothing_change_no_bit() {
    let plain = common::random_volume(9, [5, 4, 3], 11);
    let n = plain.spec().node_count();
    let all = plain.clone().with_validity(ValidityMask::new(vec![true; n])).unwrap();
    let none = plain.clone().with_validity(ValidityMask::new(vec![false; n])).unwrap();
    let mut rng = SplitMix64::new(4);
    let (lo, hi) = plain.spec().bounds();
    let pts: Vec<[f32; 3]> = (0..999)
        .map(|_| plain.spec().to_world(std::array::from_fn(|a| rng.range(lo[a] - 0.3, hi[a] + 0.3))))
        .map(|p| p.map(|v| v as f32))
        .collect();
    let dirs: Vec<[f32; 3]> = (0..pts.len())
        .map(|_| sample_uniform_sphere([rng.next_f64(), rng.next_f64()]).map(|v| v as f32))
        .collect();
    let mut want = vec![[0.0f32; 3]; pts.len()];
    plain.irradiance_batch(&pts, &dirs, &mut want).unwrap();
    for vol in [&all, &none] {
        let mut got = vec![[0.0f32; 3]; pts.len()];
        vol.irradiance_batch(&pts, &dirs, &mut got).unwrap();
        for q in 0..pts.len() {
            assert_eq!(bits3(got[q]), bits3(want[q]));
            assert_eq!(bits3(vol.radiance(pts[q], dirs[q])), bits3(plain.radiance(pts[q], dirs[q])));
            let (p, d) = (pts[q].map(f64::from), dirs[q].map(f64::from));
            assert_eq!(vol.irradiance_reference(p, d), plain.irradiance_reference(p, d));
            assert_eq!(vol.coeffs_reference(p), plain.coeffs_reference(p));
        }
    }
    // At the centre node of the unplaced grid (an exact grid position) with that node
    // invalid and its neighbours valid: only that node has weight, so the valid weight is
    // 0 and the lookup is plain (the node's own value).
    let dc = dc_volume();
    let one = dc.clone().with_validity(ValidityMask::new((0..27).map(|i| i != 13).collect())).unwrap();
    let e = one.irradiance([1.0; 3], [0.0, 0.0, 1.0]);
    assert_eq!(bits3(e), bits3(dc.irradiance([1.0; 3], [0.0, 0.0, 1.0])));
    assert!((f64::from(e[0]) - PI_Y00 * 14.0).abs() <= HAND_F32_TOL, "{e:?}");
    assert_eq!(
        one.irradiance_reference([1.0; 3], [0.0, 0.0, 1.0]),
        dc.irradiance_reference([1.0; 3], [0.0, 0.0, 1.0])
    );
}

/// With a mask that drops corners in most cells: batched equals scalar bit for bit on any
/// thread count, and the f32 lookups agree with the f64 reference (module constants).
#[test]
fn masked_fast_paths_match_each_other_and_the_reference() {
    for coeffs in [4, 9, 16] {
        let vol = common::random_volume(coeffs, [6, 5, 4], 20 + coeffs as u64);
        let n = vol.spec().node_count();
        let mask = ValidityMask::new((0..n).map(|i| (i * 7) % 5 != 1).collect());
        let vol = vol.with_validity(mask.clone()).unwrap();
        let mut rng = SplitMix64::new(5);
        let (lo, hi) = vol.spec().bounds();
        let grid_pts: Vec<[f64; 3]> =
            (0..3001).map(|_| std::array::from_fn(|a| rng.range(lo[a], hi[a]))).collect();
        let pts: Vec<[f32; 3]> = grid_pts.iter().map(|g| vol.spec().to_world(*g).map(|v| v as f32)).collect();
        let dirs: Vec<[f32; 3]> = (0..pts.len())
            .map(|_| sample_uniform_sphere([rng.next_f64(), rng.next_f64()]).map(|v| v as f32))
            .collect();
        let scalar: Vec<[f32; 3]> = pts.iter().zip(&dirs).map(|(p, d)| vol.irradiance(*p, *d)).collect();
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut e = vec![[0.0; 3]; pts.len()];
            let mut l = vec![[0.0; 3]; pts.len()];
            pool.install(|| {
                vol.irradiance_batch(&pts, &dirs, &mut e).unwrap();
                vol.radiance_batch(&pts, &dirs, &mut l).unwrap();
            });
            for q in 0..pts.len() {
                assert_eq!(bits3(e[q]), bits3(scalar[q]), "{threads} threads");
                assert_eq!(bits3(l[q]), bits3(vol.radiance(pts[q], dirs[q])));
            }
        }
        let mut dropped = 0;
        for q in 0..pts.len() {
            let p = pts[q].map(f64::from);
            let (nodes, w) = vol.spec().trilinear_world(p);
            let s: f64 = (0..8).filter(|&c| mask.is_valid(nodes[c])).map(|c| w[c]).sum();
            if (0..8).any(|c| !mask.is_valid(nodes[c]) && w[c] > 0.0) {
                dropped += 1;
            }
            if s < MIN_VALID_WEIGHT {
                continue;
            }
            let slow = vol.irradiance_reference(p, dirs[q].map(f64::from));
            let tol = F32_VS_F64_REL * 10.0 * coeffs as f64 / s.min(1.0);
            for ch in 0..3 {
                assert!((f64::from(scalar[q][ch]) - slow[ch]).abs() <= tol, "{:?} vs {slow:?}", scalar[q]);
            }
        }
        assert!(dropped > pts.len() / 2, "the mask must drop corners in most queries ({dropped})");
    }
}

/// `vol` without the typed settings record (whose files are version 3 whatever the mask).
fn without_settings(vol: IrradianceVolume) -> IrradianceVolume {
    let meta = BakeMetadata { settings: None, ..vol.metadata().clone() };
    vol.with_metadata(meta)
}

/// The typed settings record makes a file version 3 (so that an older reader refuses it as
/// newer), travels through the EXR, the KTX2 sidecar and the shard file unchanged, and a
/// record in a file that claims an older version is refused.
#[test]
fn settings_records_are_version_3_and_round_trip() {
    let vol = common::random_volume(9, [4, 3, 5], 8);
    assert!(vol.metadata().settings.is_some());
    assert_eq!(lightvol_volume::io::sidecar::format_version(&vol), 3);
    assert_eq!(lightvol_volume::io::sidecar::format_version(&without_settings(vol.clone())), 1);
    let exr = exr_to_bytes(&vol, &ExrOptions::default()).unwrap();
    assert_eq!(exr_from_bytes(&exr).unwrap().metadata(), vol.metadata());
    assert_eq!(ktx2_from_bytes(&ktx2_to_bytes(&vol).unwrap()).unwrap().metadata(), vol.metadata());
    let mut sidecar = dds_sidecar(&vol, None).unwrap();
    assert_eq!(sidecar.version, 3);
    sidecar.version = 2;
    assert!(sidecar.validate().unwrap_err().to_string().contains("settings record"));
}

fn mask_for(vol: &IrradianceVolume) -> ValidityMask {
    ValidityMask::new((0..vol.spec().node_count()).map(|i| i % 3 != 0).collect())
}

/// The native file keeps the mask (f32 and f16 samples, with and without gradients), marks
/// it as version 2 and covers it by the checksum; a volume without a mask stays version 1.
#[test]
fn exr_round_trip_preserves_the_mask() {
    let plain = without_settings(common::random_volume(9, [4, 3, 5], 8));
    let vol = plain.clone().with_validity(mask_for(&plain)).unwrap();
    for sample in [ExrSample::F32, ExrSample::F16] {
        let options = ExrOptions { sample, ..Default::default() };
        let back = exr_from_bytes(&exr_to_bytes(&vol, &options).unwrap()).unwrap();
        assert_eq!(back.validity(), vol.validity(), "{sample:?}");
        assert_eq!(exr_from_bytes(&exr_to_bytes(&plain, &options).unwrap()).unwrap().validity(), None);
    }
    let back = exr_from_bytes(&exr_to_bytes(&vol, &ExrOptions::default()).unwrap()).unwrap();
    assert_eq!(back, vol);
    let grads = VolumeGradients::zeros(&vol);
    let bytes = exr_to_bytes_with_gradients(&vol, Some(&grads), &ExrOptions::default()).unwrap();
    let (back, g) = exr_from_bytes_with_gradients(&bytes).unwrap();
    assert_eq!(back, vol);
    assert_eq!(g.unwrap(), grads);
    let version = |bytes: &[u8]| {
        let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false).unwrap();
        let h = &meta.headers[0];
        h.own_attributes
            .other
            .iter()
            .chain(&h.shared_attributes.other)
            .find(|(k, _)| k.as_slice() == b"lightvol.version")
            .map(|(_, v)| v.clone())
            .unwrap()
    };
    let masked_bytes = exr_to_bytes(&vol, &ExrOptions::default()).unwrap();
    assert_eq!(version(&masked_bytes), exr::meta::attribute::AttributeValue::I32(VALIDITY_VERSION as i32));
    assert_eq!(
        version(&exr_to_bytes(&plain, &ExrOptions::default()).unwrap()),
        exr::meta::attribute::AttributeValue::I32(1)
    );
}

/// `tests/data/version1.exr` was written before validity masks existed (the 4-coefficient
/// `random_volume` of seed 1 on 3×2×2 nodes, f32, ZIP): it loads as that volume without a
/// mask, and writing that volume gives the same bytes (files without a mask are unchanged).
#[test]
fn version_1_file_loads_without_a_mask_and_is_written_unchanged() {
    let old = include_bytes!("data/version1.exr");
    let vol = exr_from_bytes(old).unwrap();
    assert_eq!(vol.validity(), None);
    // The file predates the typed settings record too.
    let expected = common::random_volume(4, [3, 2, 2], 1);
    let meta = BakeMetadata { settings: None, ..expected.metadata().clone() };
    assert_eq!(vol, expected.with_metadata(meta));
    assert_eq!(exr_to_bytes(&vol, &ExrOptions::default()).unwrap(), old.to_vec());
}

/// The engine exports carry the mask in their sidecar (in the scene file's frame too: the
/// frame rotates the SH, not the node order), its checksum covers it, and a sidecar whose
/// bits were changed consistently is caught by the checksum.
#[test]
fn ktx2_and_dds_carry_the_mask() {
    let plain = without_settings(common::random_volume(4, [3, 4, 2], 9));
    let meta = BakeMetadata { frame: UpAxis::Y, ..plain.metadata().clone() };
    let vol = plain.clone().with_validity(mask_for(&plain)).unwrap().with_metadata(meta);
    let back = ktx2_from_bytes(&ktx2_to_bytes(&vol).unwrap()).unwrap();
    assert_eq!(back.validity(), vol.validity());
    assert_eq!(ktx2_from_bytes(&ktx2_to_bytes(&plain).unwrap()).unwrap().validity(), None);
    let sidecar = dds_sidecar(&vol, Some("v.dds".into())).unwrap();
    assert_eq!(sidecar.version, VALIDITY_VERSION);
    let dds = dds_to_bytes(&vol).unwrap();
    assert_eq!(dds_from_bytes(&dds, &sidecar).unwrap().validity(), vol.validity());
    // Swap one valid and one invalid node: the count still agrees, the checksum does not.
    let mut flags = vol.validity().unwrap().as_slice().to_vec();
    flags.swap(0, 1);
    let mut damaged = sidecar.clone();
    damaged.validity = Some(lightvol_volume::io::sidecar::ValidityJson::of(&ValidityMask::new(flags)));
    let err = dds_from_bytes(&dds, &damaged).unwrap_err();
    assert!(matches!(err, VolumeError::Malformed { .. }) && err.to_string().contains("checksum"), "{err}");
}
