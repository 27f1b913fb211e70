//! Byte-reproducible files: every writer of this crate gives identical bytes when it writes
//! the same volume twice, and EXR headers list their attributes in one fixed order (the
//! `exr` crate keeps custom attributes in a randomly seeded `HashMap`; each write builds new
//! maps, so repeated writes in one process already see different hash seeds).

mod common;

use lightvol_volume::encode::Encoding;
use lightvol_volume::gradient::VolumeGradients;
use lightvol_volume::io::bevy::{BevyFormat, bevy_to_bytes};
use lightvol_volume::io::dds::{dds_sidecar, dds_to_bytes, write_dds};
use lightvol_volume::io::exr::{
    ExrCompression, ExrOptions, ExrSample, canonical_attribute_order, exr_from_bytes,
    exr_from_bytes_with_gradients, exr_to_bytes, exr_to_bytes_with_gradients, header_attribute_names,
};
use lightvol_volume::io::ktx2::ktx2_to_bytes;
use lightvol_volume::io::sidecar::Sidecar;

/// Writes per check: with about twenty custom attributes, two independently seeded maps
/// iterate in the same order with negligible probability, so a writer that leaked the map
/// order would fail on the first repeat.
const REPEATS: usize = 6;

/// Asserts that `write` gives the same bytes every time (naming the first differing byte).
fn assert_reproducible(what: &str, write: impl Fn() -> Vec<u8>) -> Vec<u8> {
    let first = write();
    for _ in 1..REPEATS {
        let again = write();
        if again != first {
            let at =
                first.iter().zip(&again).position(|(a, b)| a != b).unwrap_or(first.len().min(again.len()));
            panic!(
                "{what}: a repeated write differs (lengths {} and {}; first at byte {at})",
                first.len(),
                again.len()
            );
        }
    }
    first
}

/// Standard attributes first (in the exr crate's order), then the custom ones sorted by name.
fn assert_canonical_order(what: &str, bytes: &[u8]) {
    let headers = header_attribute_names(bytes).unwrap();
    assert!(!headers.is_empty(), "{what}: no headers");
    for (i, names) in headers.iter().enumerate() {
        let custom_from = names.iter().position(|n| n.starts_with("lightvol.")).unwrap_or(names.len());
        let custom = &names[custom_from..];
        assert!(custom.iter().all(|n| n.starts_with("lightvol.")), "{what} part {i}: {names:?}");
        assert!(custom.windows(2).all(|w| w[0] < w[1]), "{what} part {i}: custom not sorted: {custom:?}");
        assert!(names[..custom_from].contains(&"channels".to_owned()), "{what} part {i}: {names:?}");
    }
}

#[test]
fn exr_writes_are_byte_identical_with_sorted_attributes() {
    for coeffs in [4, 9, 16] {
        let vol = common::random_volume(coeffs, [4, 3, 2], 40 + coeffs as u64);
        for sample in [ExrSample::F32, ExrSample::F16] {
            for compression in [ExrCompression::Zip, ExrCompression::Piz, ExrCompression::None] {
                let options = ExrOptions { sample, compression };
                let what = format!("{coeffs} coefficients, {sample:?}, {compression:?}");
                let bytes = assert_reproducible(&what, || exr_to_bytes(&vol, &options).unwrap());
                assert_canonical_order(&what, &bytes);
                let headers = header_attribute_names(&bytes).unwrap();
                assert_eq!(headers.len(), coeffs + 1, "{what}: one part per coefficient and the weights");
                // The image attributes sit in every part, the same attributes in the same
                // place; the first part also has its three sh_* attributes.
                assert!(headers[0].contains(&"lightvol.sh_index".to_owned()));
                assert!(headers[0].contains(&"lightvol.checksum".to_owned()));
                // Still a valid file that reads back to the volume.
                let back = exr_from_bytes(&bytes).unwrap();
                if sample == ExrSample::F32 {
                    assert_eq!(back, vol, "{what}");
                }
            }
        }
    }
}

#[test]
fn exr_with_gradients_is_byte_identical() {
    let vol = common::random_volume(9, [3, 3, 2], 5);
    let n = vol.spec().node_count();
    let data = (0..n * 9 * 9).map(|i| (i as f32 * 0.37).sin()).collect();
    let grad = VolumeGradients::new(&vol, data).unwrap();
    let bytes = assert_reproducible("gradients", || {
        exr_to_bytes_with_gradients(&vol, Some(&grad), &ExrOptions::default()).unwrap()
    });
    assert_canonical_order("gradients", &bytes);
    let (back, back_grad) = exr_from_bytes_with_gradients(&bytes).unwrap();
    assert_eq!(back, vol);
    assert_eq!(back_grad.unwrap().data(), grad.data());
}

#[test]
fn engine_exports_and_sidecars_are_byte_identical() {
    let vol = common::random_volume(9, [3, 4, 2], 17);
    assert_reproducible("ktx2", || ktx2_to_bytes(&vol).unwrap());
    assert_reproducible("dds", || dds_to_bytes(&vol).unwrap());
    assert_reproducible("dds sidecar", || {
        dds_sidecar(&vol, Some("v.dds".into())).unwrap().to_json().into_bytes()
    });
    assert_reproducible("bevy", || bevy_to_bytes(&vol, BevyFormat::Rgba16f).unwrap());
    assert_reproducible("json sidecar", || {
        Sidecar::describe(&vol, Encoding::F32, Some("v.exr".into()), "native-exr").to_json().into_bytes()
    });
    // Through the file writers too (temporary file and rename): the DDS and its sidecar.
    let dir = tempfile::tempdir().unwrap();
    let [a, b] = ["a", "b"].map(|d| {
        std::fs::create_dir(dir.path().join(d)).unwrap();
        let p = dir.path().join(d).join("v.dds");
        write_dds(&p, &vol).unwrap();
        (std::fs::read(&p).unwrap(), std::fs::read(p.with_extension("dds.json")).unwrap())
    });
    assert!(a == b, "write_dds wrote different files");
}

/// The reordering is idempotent, keeps the file readable and errors on anything that is not
/// an EXR header list without touching the bytes.
#[test]
fn canonical_order_is_idempotent_and_rejects_garbage() {
    let vol = common::random_volume(4, [2, 2, 2], 3);
    let bytes = exr_to_bytes(&vol, &ExrOptions::default()).unwrap();
    let mut again = bytes.clone();
    canonical_attribute_order(&mut again).unwrap();
    assert_eq!(again, bytes);
    for cut in [0, 3, 8, 20, 200] {
        let mut part = bytes[..cut.min(bytes.len())].to_vec();
        let before = part.clone();
        assert!(canonical_attribute_order(&mut part).is_err(), "cut at {cut}");
        assert_eq!(part, before, "an error leaves the bytes as they were");
    }
    let mut text = b"not an exr file at all".to_vec();
    assert!(canonical_attribute_order(&mut text).is_err());
}
