//! Engine exports in both source frames: every texture reads back through `open` to the
//! native volume's lookups, every texture has its sidecar beside it, and the sidecars give
//! the grid exactly as `info` does, in the same frame.

mod common;

use std::path::Path;

use lightvol_sh::lowdisc::SplitMix64;
use lightvol_volume::export::{ExportFormat, export};
use lightvol_volume::frame::FileGrid;
use lightvol_volume::io::bevy::{BevyFormat, read_bevy};
use lightvol_volume::io::sidecar::{read_sidecar, sidecar_path};
use lightvol_volume::up_axis::UpAxis;
use lightvol_volume::{AnyVolume, BakeMetadata, EngineLookup, IrradianceVolume, open};

/// f16 texels: 2^-11 relative rounding per coefficient; an irradiance sums nine of them
/// with factors up to π against values that stay above a tenth of their size
/// ([`common::physical_volume`]), so 2e-3 relative to the largest channel bounds it.
const F16_REL: f64 = 2e-3;

fn volume(up: UpAxis) -> IrradianceVolume {
    let vol = common::physical_volume(9, [5, 4, 6], 11);
    let meta = BakeMetadata { frame: up, ..vol.metadata().clone() };
    vol.with_metadata(meta)
}

/// A grid as `info` prints it: `res`, `bounds` and `frame`.
type InfoGrid = (Vec<u32>, Vec<Vec<f64>>, String);

fn info_grid(path: &Path) -> InfoGrid {
    let v = lightvol_volume::info::describe_file(path).unwrap();
    let g = &v["grid"];
    (
        serde_json::from_value(g["res"].clone()).unwrap(),
        serde_json::from_value(g["bounds"].clone()).unwrap(),
        g["frame"].as_str().unwrap().to_string(),
    )
}

fn file_grid_tuple(g: &FileGrid) -> InfoGrid {
    (g.res.to_vec(), g.bounds.iter().map(|b| b.to_vec()).collect(), g.frame.name().to_string())
}

/// Random points inside the grid and unit normals.
fn queries(vol: &IrradianceVolume, n: usize) -> Vec<([f64; 3], [f64; 3])> {
    let (lo, hi) = vol.spec().bounds();
    let mut r = SplitMix64::new(5);
    (0..n)
        .map(|_| {
            let p = std::array::from_fn(|a| r.range(lo[a], hi[a]));
            let d: [f64; 3] = std::array::from_fn(|_| r.range(-1.0, 1.0));
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-9);
            (p, d.map(|v| v / l))
        })
        .collect()
}

/// The volume of `up`'s frame, written as the native EXR in `dir`, and the grid `info`
/// prints for it.
fn native_file(dir: &Path, up: UpAxis) -> (IrradianceVolume, std::path::PathBuf, InfoGrid) {
    let vol = volume(up);
    let native = dir.join(format!("v-{}.exr", up.name()));
    lightvol_volume::io::exr::write_exr(&native, &vol, &Default::default()).unwrap();
    let want = info_grid(&native);
    (vol, native, want)
}

/// `path` opens through `open` to `vol`'s grid and frame and to its lookups within f16
/// rounding, at random points and normals.
fn reads_back_to(vol: &IrradianceVolume, path: &Path, label: &str) {
    let AnyVolume::Uniform(back) = open(path).unwrap() else { panic!("{label}: a uniform grid") };
    assert_eq!(back.spec(), vol.spec(), "{label}");
    assert_eq!(back.metadata().frame, vol.metadata().frame, "{label}");
    for (p, n) in queries(vol, 400) {
        let a = vol.irradiance_reference(p, n);
        let b = back.irradiance_reference(p, n);
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for ch in 0..3 {
            assert!((a[ch] - b[ch]).abs() <= F16_REL * scale, "{label}: {a:?} vs {b:?}");
        }
    }
}

/// KTX2 and DDS of a Y-up and of a Z-up volume read back through `open` in the native
/// file's (internal) frame: the same lookups to f16 rounding. Before the readers turned the
/// texture's file-frame data back, a Y-up KTX2 was looked up in the wrong axes.
#[test]
fn textures_read_back_to_the_native_lookups_in_both_frames() {
    let dir = tempfile::tempdir().unwrap();
    for up in [UpAxis::Y, UpAxis::Z] {
        let vol = volume(up);
        for (format, ext) in [(ExportFormat::Ktx2, "ktx2"), (ExportFormat::Dds, "dds")] {
            let path = dir.path().join(format!("v-{}.{ext}", up.name()));
            export(&AnyVolume::Uniform(vol.clone()), Path::new("v.exr"), format, None, &path).unwrap();
            reads_back_to(&vol, &path, &format!("{ext} {}", up.name()));
        }
    }
}

/// Every texture export writes its JSON sidecar beside it, and the sidecar's `file_grid`
/// is the grid `info` prints for the native file and for the export itself (same
/// resolution, bounds and frame); the textures of a Y-up scene run along the file's axes,
/// with no rotation in the sidecar's transform.
#[test]
fn every_texture_has_a_sidecar_that_agrees_with_info() {
    let dir = tempfile::tempdir().unwrap();
    for up in [UpAxis::Y, UpAxis::Z] {
        let (vol, native, want) = native_file(dir.path(), up);
        if up == UpAxis::Y {
            // The file's axes: internal (x, y, z) res (5, 4, 6) is file (x, z, y).
            assert_eq!(want.0, vec![5, 6, 4]);
        }
        for (format, ext) in
            [(ExportFormat::Ktx2, "ktx2"), (ExportFormat::Dds, "dds"), (ExportFormat::Json, "json")]
        {
            let path = dir.path().join(format!("e-{}.{ext}", up.name()));
            export(&AnyVolume::Uniform(vol.clone()), &native, format, None, &path).unwrap();
            let side = if format == ExportFormat::Json { path.clone() } else { sidecar_path(&path) };
            let sidecar =
                read_sidecar(&side).unwrap_or_else(|e| panic!("{ext} sidecar {}: {e}", side.display()));
            assert_eq!(file_grid_tuple(sidecar.file_grid.as_ref().unwrap()), want, "{ext} {}", up.name());
            assert_eq!(sidecar.lookup, EngineLookup::Lightvol.name(), "{ext} names lightvol's lookup");
            if format != ExportFormat::Json {
                assert_eq!(sidecar.grid.to_world, None, "{ext}: a file-axis texture needs no transform");
                assert_eq!(sidecar.grid.res.to_vec(), want.0);
                assert_eq!(info_grid(&path), want, "info of the {ext} export");
            }
        }
        let bevy = dir.path().join(format!("b-{}.ktx2", up.name()));
        export(
            &AnyVolume::Uniform(vol.clone()),
            &native,
            ExportFormat::Bevy(BevyFormat::Rgba16f),
            None,
            &bevy,
        )
        .unwrap();
        let info = read_bevy(&bevy).unwrap().info;
        assert_eq!(info.res.to_vec(), want.0, "the Bevy texture runs along the file's axes");
        assert_eq!(info.transform.rotation, [0.0, 0.0, 0.0, 1.0]);
        assert_eq!(info.lookup, EngineLookup::Bevy.name());
        assert!(sidecar_path(&bevy).exists());
    }
}

/// three.js's atlas of a Y-up and of a Z-up volume reads back through `open` to the
/// native lookups (f16), its placement puts three's cell-centre probes on lightvol's nodes,
/// and its sidecar and key/value entry give the grid `info` prints, in the file's axes.
#[test]
fn three_atlas_reads_back_and_places_probes_on_the_nodes() {
    use lightvol_volume::io::three::{atlas_depth, read_three};
    let dir = tempfile::tempdir().unwrap();
    for up in [UpAxis::Y, UpAxis::Z] {
        let (vol, native, want) = native_file(dir.path(), up);
        let path = dir.path().join(format!("t-{}.ktx2", up.name()));
        export(&AnyVolume::Uniform(vol.clone()), &native, ExportFormat::Three, None, &path).unwrap();
        reads_back_to(&vol, &path, &format!("three {}", up.name()));
        let (info, _) = read_three(&path).unwrap();
        assert_eq!(info.resolution.to_vec(), want.0, "three's resolution is the file grid");
        assert_eq!(info.lookup, "three");
        // Probe i of three's box sits at min + (i + 1/2) · size / res: the file grid's node i.
        for a in 0..3 {
            let (lo, hi) = (want.1[0][a], want.1[1][a]);
            let n = f64::from(want.0[a]);
            let first = info.bounds[0][a] + 0.5 * info.size[a] / n;
            let last = info.bounds[0][a] + (n - 0.5) * info.size[a] / n;
            let tol = 1e-12 * (hi - lo).abs().max(1.0);
            assert!(
                (first - lo).abs() <= tol && (last - hi).abs() <= tol,
                "axis {a}: {first}..{last} vs {lo}..{hi}"
            );
            assert!((info.position[a] - (lo + hi) / 2.0).abs() <= tol);
        }
        assert_eq!(atlas_depth(want.0[2]), 7 * (want.0[2] + 2));
        let sidecar = read_sidecar(&sidecar_path(&path)).expect("three's sidecar");
        assert_eq!(file_grid_tuple(sidecar.file_grid.as_ref().unwrap()), want);
        assert_eq!(sidecar.lookup, EngineLookup::Three.name());
        assert_eq!(sidecar.grid.to_world, None, "three's atlas runs along the file's axes");
        assert_eq!(info_grid(&path), want, "info of the three export");
    }
}

/// three.js cannot rotate a probe grid: a placed volume is refused in one line, and no
/// file is left behind.
#[test]
fn three_refuses_a_placed_grid_in_one_line() {
    use lightvol_volume::grid::{GridSpec, Placement};
    let dir = tempfile::tempdir().unwrap();
    let vol = volume(UpAxis::Z);
    let (c, s) = (0.6f64, 0.8f64);
    let spec = GridSpec::new([0.0; 3], [1.0; 3], vol.spec().res())
        .unwrap()
        .with_placement(Placement::new([[c, -s, 0.0, 1.0], [s, c, 0.0, 2.0], [0.0, 0.0, 1.0, 0.0]]).unwrap());
    let placed =
        IrradianceVolume::new(spec, vol.coeffs(), vol.data().to_vec(), vec![1.0; vol.spec().node_count()])
            .unwrap();
    let path = dir.path().join("placed.ktx2");
    let err = export(&AnyVolume::Uniform(placed), Path::new("v.exr"), ExportFormat::Three, None, &path)
        .unwrap_err()
        .to_string();
    assert!(err.contains("three.js") && !err.contains('\n'), "{err}");
    assert!(!path.exists() && !sidecar_path(&path).exists(), "nothing written");
}

/// An order-2 volume (4 coefficients) goes into three's L2 atlas zero-padded: it reads back
/// with 9 coefficients whose lookups are the native volume's (f16).
#[test]
fn three_pads_an_order_two_volume() {
    let dir = tempfile::tempdir().unwrap();
    let vol = common::physical_volume(4, [4, 5, 3], 3);
    let path = dir.path().join("l1.ktx2");
    export(&AnyVolume::Uniform(vol.clone()), Path::new("v.exr"), ExportFormat::Three, None, &path).unwrap();
    let AnyVolume::Uniform(back) = open(&path).unwrap() else { panic!("a uniform grid") };
    assert_eq!(back.coeffs(), 9);
    for i in 0..back.spec().node_count() {
        assert!(back.node(i)[12..].iter().all(|&c| c == 0.0), "node {i}: the L2 band is zero");
    }
    for (p, n) in queries(&vol, 200) {
        let a = vol.irradiance_reference(p, n);
        let b = back.irradiance_reference(p, n);
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for ch in 0..3 {
            assert!((a[ch] - b[ch]).abs() <= F16_REL * scale, "{a:?} vs {b:?}");
        }
    }
}
