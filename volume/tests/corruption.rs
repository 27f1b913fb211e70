//! Random byte mutations and truncations of valid files give an
//! `Err`, never a panic — and never a silently different volume.
//!
//! For every format, a small valid file is damaged by proptest (fixed RNG seed, so the
//! cases are the same on every run): up to 8 random byte overwrites, or a truncation. The
//! reader must return `Err`, or (when the damage hit bytes the reader ignores, e.g.
//! padding or an unused standard EXR attribute) exactly the original volume. Truncations
//! must always be `Err`; every edit of an accumulator shard must be `Err`. Volumes with a
//! validity mask get the same treatment in the EXR and the KTX2 sidecar. 1,300 cases in
//! total.

mod common;

use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

use lightvol_volume::io::accumulator::{accumulator_from_bytes, accumulator_to_bytes};
use lightvol_volume::io::bevy::{BevyFormat, BevyVolume, bevy_from_bytes, bevy_to_bytes};
use lightvol_volume::io::dds::{dds_from_bytes, dds_sidecar, dds_to_bytes};
use lightvol_volume::io::exr::{ExrCompression, ExrOptions, ExrSample, exr_from_bytes, exr_to_bytes};
use lightvol_volume::io::ktx2::{ktx2_from_bytes, ktx2_to_bytes};
use lightvol_volume::io::sidecar::Sidecar;
use lightvol_volume::{IrradianceVolume, ValidityMask};

fn config(cases: u32) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(0x11a7_0001),
        failure_persistence: None,
        // Shrinking a failure is cheap here and gives the smallest damaging edit.
        ..Config::default()
    }
}

fn volume() -> IrradianceVolume {
    common::random_volume(4, [3, 2, 2], 2024)
}

/// [`volume`] with a validity mask (nodes 1, 4, 7, 10 invalid).
fn masked_volume() -> IrradianceVolume {
    volume().with_validity(ValidityMask::new((0..12).map(|i| i % 3 != 1).collect())).unwrap()
}

/// Applies `edits` (position taken modulo the length, byte XOR-ed with a non-zero mask so
/// each edit really changes the byte).
fn mutate(bytes: &[u8], edits: &[(usize, u8)]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    for &(pos, mask) in edits {
        let i = pos % out.len();
        out[i] ^= mask.max(1);
    }
    out
}

fn edits() -> impl Strategy<Value = Vec<(usize, u8)>> {
    prop::collection::vec((any::<usize>(), any::<u8>()), 1..=8)
}

/// `Err`, or exactly `original` (bit for bit).
fn err_or_same(
    result: Result<IrradianceVolume, lightvol_volume::VolumeError>,
    original: &IrradianceVolume,
) -> bool {
    match result {
        Err(_) => true,
        Ok(v) => {
            v.spec() == original.spec()
                && v.metadata() == original.metadata()
                && v.data().iter().map(|x| x.to_bits()).eq(original.data().iter().map(|x| x.to_bits()))
                && v.weights().iter().map(|x| x.to_bits()).eq(original.weights().iter().map(|x| x.to_bits()))
                && v.validity() == original.validity()
        }
    }
}

proptest! {
    #![proptest_config(config(150))]

    #[test]
    fn exr_zip_mutations(e in edits()) {
        let vol = volume();
        let bytes = exr_to_bytes(&vol, &ExrOptions::default()).unwrap();
        prop_assert!(err_or_same(exr_from_bytes(&mutate(&bytes, &e)), &vol));
    }

    #[test]
    fn exr_uncompressed_f16_mutations(e in edits()) {
        let vol = volume();
        let opts = ExrOptions { sample: ExrSample::F16, compression: ExrCompression::None };
        let bytes = exr_to_bytes(&vol, &opts).unwrap();
        let original = exr_from_bytes(&bytes).unwrap();
        prop_assert!(err_or_same(exr_from_bytes(&mutate(&bytes, &e)), &original));
    }

    #[test]
    fn ktx2_mutations(e in edits()) {
        let vol = volume();
        let bytes = ktx2_to_bytes(&vol).unwrap();
        let original = ktx2_from_bytes(&bytes).unwrap();
        prop_assert!(err_or_same(ktx2_from_bytes(&mutate(&bytes, &e)), &original));
    }

    #[test]
    fn dds_and_sidecar_mutations(e in edits(), hit_sidecar in any::<bool>()) {
        let vol = volume();
        let bytes = dds_to_bytes(&vol).unwrap();
        let json = dds_sidecar(&vol, None).unwrap().to_json();
        let original = dds_from_bytes(&bytes, &Sidecar::from_json(&json).unwrap()).unwrap();
        if hit_sidecar {
            let damaged = mutate(json.as_bytes(), &e);
            // Damage that is not UTF-8 is rejected by `read_sidecar` before parsing.
            if let Ok(text) = std::str::from_utf8(&damaged) {
                let r = Sidecar::from_json(text).and_then(|s| dds_from_bytes(&bytes, &s));
                prop_assert!(err_or_same(r, &original));
            }
        } else {
            let s = Sidecar::from_json(&json).unwrap();
            prop_assert!(err_or_same(dds_from_bytes(&mutate(&bytes, &e), &s), &original));
        }
    }

    #[test]
    fn masked_exr_uncompressed_mutations(e in edits()) {
        let vol = masked_volume();
        let opts = ExrOptions { sample: ExrSample::F32, compression: ExrCompression::None };
        let bytes = exr_to_bytes(&vol, &opts).unwrap();
        prop_assert!(err_or_same(exr_from_bytes(&mutate(&bytes, &e)), &vol));
    }

    #[test]
    fn masked_ktx2_mutations(e in edits()) {
        let vol = masked_volume();
        let bytes = ktx2_to_bytes(&vol).unwrap();
        let original = ktx2_from_bytes(&bytes).unwrap();
        prop_assert!(original.validity().is_some());
        prop_assert!(err_or_same(ktx2_from_bytes(&mutate(&bytes, &e)), &original));
    }

    #[test]
    fn accumulator_shard_mutations_are_always_errors(e in edits()) {
        // The shard checksum covers every byte, so every edit must be rejected.
        let vol = volume();
        let mut acc = lightvol_volume::Accumulator::new(vol.spec().clone(), 4).unwrap();
        acc.add_sample([0.0, 1.0, 3.0], [1.0, 2.0, 3.0], &[0.5, -0.25, 0.125, 1.0]);
        let bytes = accumulator_to_bytes(&acc, vol.metadata()).unwrap();
        prop_assert!(accumulator_from_bytes(&mutate(&bytes, &e)).is_err());
    }

    #[test]
    fn bevy_mutations(e in edits()) {
        let vol = common::physical_volume(4, [3, 2, 2], 5);
        let bytes = bevy_to_bytes(&vol, BevyFormat::Rgba16f).unwrap();
        let original: BevyVolume = bevy_from_bytes(&bytes).unwrap();
        match bevy_from_bytes(&mutate(&bytes, &e)) {
            Err(_) => {}
            Ok(b) => prop_assert_eq!(b, original),
        }
    }
}

proptest! {
    #![proptest_config(config(50))]

    #[test]
    fn truncations_are_always_errors(cut in any::<prop::sample::Index>()) {
        let vol = volume();
        let exr = exr_to_bytes(&vol, &ExrOptions::default()).unwrap();
        prop_assert!(exr_from_bytes(&exr[..cut.index(exr.len())]).is_err());
        let ktx = ktx2_to_bytes(&vol).unwrap();
        prop_assert!(ktx2_from_bytes(&ktx[..cut.index(ktx.len())]).is_err());
        let dds = dds_to_bytes(&vol).unwrap();
        let side = dds_sidecar(&vol, None).unwrap();
        prop_assert!(dds_from_bytes(&dds[..cut.index(dds.len())], &side).is_err());
        let json = side.to_json();
        prop_assert!(Sidecar::from_json(&json[..cut.index(json.len())]).is_err());
        let bevy = bevy_to_bytes(&common::physical_volume(4, [3, 2, 2], 5), BevyFormat::Rgba16f).unwrap();
        prop_assert!(bevy_from_bytes(&bevy[..cut.index(bevy.len())]).is_err());
    }
}
