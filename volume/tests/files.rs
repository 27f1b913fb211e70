//! EXR, KTX2 and DDS round trips (read back with the same crates),
//! and the Bevy export reproduces E(±axis) at every voxel to f16 precision.

mod common;

use lightvol_volume::io::exr::{ExrCompression, ExrOptions, ExrSample, exr_from_bytes, read_exr, write_exr};
use lightvol_volume::{IrradianceVolume, VolumeError};

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// f16 round-to-nearest: relative error at most 2^-11 for normal values, absolute 2^-25
/// below the normal range.
fn f16_close(a: f32, b: f32) -> bool {
    (f64::from(a) - f64::from(b)).abs() <= (f64::from(a).abs() * 2f64.powi(-11)).max(2f64.powi(-25))
}

#[test]
fn exr_f32_round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    for coeffs in [4, 9, 16] {
        let vol = common::random_volume(coeffs, [5, 3, 4], 7 + coeffs as u64);
        for compression in [ExrCompression::Zip, ExrCompression::Piz, ExrCompression::None] {
            let path = dir.path().join(format!("v{coeffs}.exr"));
            write_exr(&path, &vol, &ExrOptions { sample: ExrSample::F32, compression }).unwrap();
            let back = read_exr(&path).unwrap();
            assert_eq!(bits(back.data()), bits(vol.data()), "{coeffs} {compression:?}");
            assert_eq!(bits(back.weights()), bits(vol.weights()));
            assert_eq!(back.spec(), vol.spec());
            assert_eq!(back.metadata(), vol.metadata());
            assert_eq!(back, vol);
        }
    }
    // Only the target file remains: no temporary files left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3);
}

#[test]
fn exr_f16_round_trip_within_half_precision() {
    let vol = common::random_volume(9, [4, 4, 3], 3);
    let bytes = lightvol_volume::io::exr::exr_to_bytes(
        &vol,
        &ExrOptions { sample: ExrSample::F16, ..Default::default() },
    )
    .unwrap();
    let back = exr_from_bytes(&bytes).unwrap();
    for (a, b) in vol.data().iter().zip(back.data()) {
        assert!(f16_close(*a, *b), "{a} vs {b}");
    }
    assert_eq!(bits(back.weights()), bits(vol.weights()));
}

#[test]
fn exr_is_readable_by_the_exr_crate_as_layers() {
    // Read back with the exr crate's generic reader: one layer per coefficient plus weight.
    let vol = common::random_volume(4, [3, 2, 2], 1);
    let bytes = lightvol_volume::io::exr::exr_to_bytes(&vol, &ExrOptions::default()).unwrap();
    use exr::prelude::{ReadChannels, ReadLayers};
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(&bytes))
        .unwrap();
    assert_eq!(image.layer_data.len(), 5);
    let l2 = image.layer_data.iter().find(|l| l.attributes.layer_name.as_ref().unwrap().eq("sh02")).unwrap();
    assert_eq!(l2.size, exr::math::Vec2(3, 4));
    let g = l2.channel_data.list.iter().find(|c| c.name.to_string() == "G").unwrap();
    // Pixel (x, y + ny z) = node (x, y, z): node (2, 1, 1) = flat 2 + 3 (1 + 2) = 11.
    let px: Vec<f32> = g.sample_data.values_as_f32().collect();
    assert_eq!(px[2 + 3 * 3], vol.coeff_rgb(11, 2)[1]);
}

#[test]
fn exr_rejects_garbage_and_values_out_of_range() {
    assert!(matches!(exr_from_bytes(b""), Err(VolumeError::Malformed { .. })));
    assert!(matches!(exr_from_bytes(b"not an exr file at all"), Err(VolumeError::Malformed { .. })));
    let spec = lightvol_volume::GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
    let big = IrradianceVolume::from_fn(spec, 4, |_| vec![[1e6, 0.0, 0.0]; 4]).unwrap();
    assert!(
        lightvol_volume::io::exr::exr_to_bytes(
            &big,
            &ExrOptions { sample: ExrSample::F16, ..Default::default() }
        )
        .is_err()
    );
    let dir = tempfile::tempdir().unwrap();
    assert!(matches!(read_exr(&dir.path().join("missing.exr")), Err(VolumeError::Io { .. })));
}

mod ktx2_dds_bevy {
    use super::*;
    use lightvol_volume::io::bevy::{
        BevyFormat, Face, ambient_cubes, bevy_from_bytes, bevy_to_bytes, bevy_world_from_probe, read_bevy,
        write_bevy,
    };
    use lightvol_volume::io::dds::{dds_from_bytes, dds_sidecar, dds_to_bytes, read_dds, write_dds};
    use lightvol_volume::io::ktx2::{
        KTX2_SIDECAR_KEY, ktx2_from_bytes, ktx2_to_bytes, read_ktx2, write_ktx2,
    };
    use lightvol_volume::io::sidecar::sidecar_path;

    fn assert_f16_equal(a: &IrradianceVolume, b: &IrradianceVolume) {
        assert_eq!(a.spec(), b.spec());
        assert_eq!(a.coeffs(), b.coeffs());
        assert_eq!(a.metadata(), b.metadata());
        for (x, y) in a.data().iter().zip(b.data()) {
            assert!(f16_close(*x, *y), "{x} vs {y}");
        }
        for (x, y) in a.weights().iter().zip(b.weights()) {
            assert!(f16_close(*x, *y), "{x} vs {y}");
        }
    }

    #[test]
    fn ktx2_round_trip_and_ktx2_crate_reads_it() {
        let dir = tempfile::tempdir().unwrap();
        for coeffs in [4, 9, 16] {
            let vol = common::random_volume(coeffs, [4, 3, 5], coeffs as u64);
            let path = dir.path().join("v.ktx2");
            write_ktx2(&path, &vol).unwrap();
            let back = read_ktx2(&path).unwrap();
            assert_f16_equal(&vol, &back);
            // The ktx2 crate's reader sees a valid RGBA16F 3D texture with our layout.
            let bytes = std::fs::read(&path).unwrap();
            let r = ktx2::Reader::new(&bytes[..]).unwrap();
            let h = r.header();
            assert_eq!(h.format, Some(ktx2::Format::R16G16B16A16_SFLOAT));
            assert_eq!([h.pixel_width, h.pixel_height, h.pixel_depth], [4, 3, 5 * coeffs as u32]);
            assert!(r.key_value_data().any(|(k, _)| k == KTX2_SIDECAR_KEY));
            // KTXwriter is stored NUL-terminated, as the KTX2 specification requires.
            assert_eq!(
                r.writer().map(|w| w.trim_end_matches('\0')),
                Some(lightvol_volume::io::ktx2::KTX2_WRITER)
            );
            let level = r.levels().next().unwrap();
            // Texel (x, y, j nz + z) of coefficient j = 2, node (1, 2, 3): red channel.
            let (x, y, z, j) = (1usize, 2usize, 3usize, 2usize);
            let t = ((j * 5 + z) * 3 + y) * 4 + x;
            let red = half::f16::from_le_bytes([level.data[8 * t], level.data[8 * t + 1]]).to_f32();
            assert_eq!(red, half::f16::from_f32(vol.coeff_rgb(x + 4 * (y + 3 * z), j)[0]).to_f32());
        }
    }

    #[test]
    fn dds_round_trip_and_ddsfile_reads_it() {
        let dir = tempfile::tempdir().unwrap();
        let vol = common::random_volume(9, [3, 4, 2], 77);
        let path = dir.path().join("v.dds");
        write_dds(&path, &vol).unwrap();
        assert!(sidecar_path(&path).exists());
        let back = read_dds(&path).unwrap();
        assert_f16_equal(&vol, &back);
        let dds = ddsfile::Dds::read(std::fs::File::open(&path).unwrap()).unwrap();
        assert_eq!(dds.get_dxgi_format(), Some(ddsfile::DxgiFormat::R16G16B16A16_Float));
        assert_eq!([dds.get_width(), dds.get_height(), dds.get_depth()], [3, 4, 18]);
        // A sidecar for another grid is rejected.
        let other = common::random_volume(9, [3, 4, 3], 1);
        assert!(dds_from_bytes(&dds_to_bytes(&vol).unwrap(), &dds_sidecar(&other, None).unwrap()).is_err());
        assert!(dds_from_bytes(&dds_to_bytes(&vol).unwrap(), &dds_sidecar(&vol, None).unwrap()).is_ok());
        // Missing sidecar: an I/O error, not a panic.
        std::fs::remove_file(sidecar_path(&path)).unwrap();
        assert!(matches!(read_dds(&path), Err(VolumeError::Io { .. })));
    }

    #[test]
    fn ktx2_rejects_truncation_and_bad_data() {
        let vol = common::random_volume(4, [2, 2, 2], 5);
        let bytes = ktx2_to_bytes(&vol).unwrap();
        assert!(ktx2_from_bytes(&bytes[..bytes.len() - 1]).is_err());
        assert!(ktx2_from_bytes(&bytes[..100]).is_err());
        let spec = lightvol_volume::GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let big = IrradianceVolume::from_fn(spec, 4, |_| vec![[7e4, 0.0, 0.0]; 4]).unwrap();
        assert!(ktx2_to_bytes(&big).is_err());
        // A NaN texel (f16 0x7e00) in the level data is rejected.
        let mut nan = bytes.clone();
        let n = nan.len();
        nan[n - 2..].copy_from_slice(&[0x00, 0x7e]);
        assert!(matches!(
            ktx2_from_bytes(&nan),
            Err(VolumeError::NonFinite { .. }) | Err(VolumeError::Malformed { .. })
        ));
    }

    #[test]
    fn bevy_export_reproduces_axis_irradiance() {
        let dir = tempfile::tempdir().unwrap();
        let vol = common::physical_volume(9, [4, 3, 5], 12);
        let path = dir.path().join("bevy.ktx2");
        write_bevy(&path, &vol, BevyFormat::Rgba16f).unwrap();
        let bevy = read_bevy(&path).unwrap();
        assert_eq!(bevy.info.res, [4, 3, 5]);
        let spec = vol.spec();
        let mut rng = lightvol_sh::lowdisc::SplitMix64::new(3);
        for node in 0..spec.node_count() {
            let [i, j, k] = spec.node_coords(node);
            let x = spec.node_position_world(i, j, k);
            for (fi, face) in Face::ALL.iter().enumerate() {
                // Independent evaluation: the volume's f64 Algorithm 1 reference at the node,
                // in Bevy's units (E/π: the radiance of a white Lambertian surface).
                let want = vol.irradiance_reference(x, face.dir()).map(|v| v / std::f64::consts::PI);
                for ch in 0..3 {
                    let got = bevy.cubes[node][fi][ch];
                    // One f16 rounding (2^-11 relative) after an f32 rounding (2^-24) of
                    // an f64 sum that differs from the reference's only in order.
                    let tol = want[ch].abs() * (2f64.powi(-11) + 2f64.powi(-23));
                    assert!(
                        (f64::from(got) - want[ch]).abs() <= tol,
                        "node {node} {face:?} ch {ch}: {got} vs {}",
                        want[ch]
                    );
                }
            }
            // Valve's blend on an axis returns that side exactly.
            let e = bevy.shade(node, [0.0, -1.0, 0.0]);
            assert_eq!(e, bevy.cubes[node][3]);
            let n = lightvol_sh::sampling::sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let s = bevy.shade(node, n.map(|v| v as f32));
            assert!(s.iter().all(|v| v.is_finite() && *v > 0.0));
        }
        // The layout: side -Y of voxel (1, 2, 3) is texel (1, 2 + 3, 3 + 5).
        assert_eq!(Face::NegY.texel([1, 2, 3], [4, 3, 5]), [1, 5, 8]);
        assert_eq!(Face::PosZ.texel([1, 2, 3], [4, 3, 5]), [1, 2, 13]);
        // The ktx2 crate reads the texture as Rx x 2Ry x 3Rz.
        let bytes = std::fs::read(&path).unwrap();
        let h = ktx2::Reader::new(&bytes[..]).unwrap().header();
        assert_eq!([h.pixel_width, h.pixel_height, h.pixel_depth], [4, 6, 15]);
        assert_eq!(bevy_from_bytes(&bevy_to_bytes(&vol, BevyFormat::Rgba16f).unwrap()).unwrap(), bevy);
        assert_eq!(ambient_cubes(&vol).len(), 60);
    }

    #[test]
    fn bevy_probe_transform_maps_voxel_centres_to_nodes() {
        let vol = common::random_volume(4, [4, 3, 5], 2);
        let spec = vol.spec();
        let m = bevy_world_from_probe(spec);
        let res = spec.res();
        for node in [0, 7, spec.node_count() - 1] {
            let v = spec.node_coords(node);
            // Bevy: voxel centre at (v + 0.5)/R - 0.5 in the probe's unit cube.
            let u: [f64; 3] = std::array::from_fn(|a| (f64::from(v[a]) + 0.5) / f64::from(res[a]) - 0.5);
            let w: [f64; 3] =
                std::array::from_fn(|r| m[r][0] * u[0] + m[r][1] * u[1] + m[r][2] * u[2] + m[r][3]);
            let want = spec.node_position_world(v[0], v[1], v[2]);
            for a in 0..3 {
                assert!((w[a] - want[a]).abs() < 1e-12, "{w:?} vs {want:?}");
            }
        }
    }
}
