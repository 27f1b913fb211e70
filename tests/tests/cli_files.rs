//! The CLI's file verbs (info, export) end to end, and their error handling.

use std::process::ExitCode;

use lightvol_volume::exr_io::{ExrOptions, write_exr};
use lightvol_volume::{GridSpec, IrradianceVolume};

fn run(args: &[&str]) -> anyhow_like::Result {
    lightvol::run_from_args(std::iter::once("lightvol").chain(args.iter().copied()))
        .map_err(|e| lightvol::one_line(&e))
}

mod anyhow_like {
    pub type Result = std::result::Result<std::process::ExitCode, String>;
}

fn sample_volume(dir: &std::path::Path) -> std::path::PathBuf {
    let spec = GridSpec::new([0.0, 0.0, 0.0], [2.0, 1.0, 1.0], [3, 2, 2]).unwrap();
    let vol = IrradianceVolume::from_fn(spec, 9, |p| (0..9).map(|j| [p[0] + j as f64, p[1], 0.5]).collect())
        .unwrap();
    let path = dir.join("v.exr");
    write_exr(&path, &vol, &ExrOptions::default()).unwrap();
    path
}

#[test]
fn info_and_export_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let v = sample_volume(dir.path());
    let v = v.to_str().unwrap();
    assert_eq!(run(&["info", v, "--json"]), Ok(ExitCode::SUCCESS));
    for (fmt, ext) in [("ktx2", "ktx2"), ("dds", "dds"), ("bevy", "ktx2"), ("json", "json")] {
        let out = dir.path().join(format!("out_{fmt}.{ext}"));
        assert_eq!(run(&["export", v, "--format", fmt, "-o", out.to_str().unwrap()]), Ok(ExitCode::SUCCESS));
        assert!(out.metadata().unwrap().len() > 0, "{fmt} output is empty");
    }
    // KTX2 reads back to the same coefficients within f16 precision.
    let back = lightvol_volume::ktx2_io::read_ktx2(&dir.path().join("out_ktx2.ktx2")).unwrap();
    let orig = lightvol_volume::exr_io::read_exr(std::path::Path::new(v)).unwrap();
    for (a, b) in back.data().iter().zip(orig.data()) {
        // f16 has an 11-bit significand: relative error below 2^-11.
        assert!((a - b).abs() <= b.abs() * 4.9e-4 + 1e-7);
    }
}

#[test]
fn bad_input_gives_one_clear_error_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.exr");
    let err = run(&["info", missing.to_str().unwrap()]).unwrap_err();
    assert!(err.contains("missing.exr"), "{err}");
    assert!(!err.contains('\n'));
    // A malformed file: text pretending to be EXR.
    let bad = dir.path().join("bad.exr");
    std::fs::write(&bad, b"not an exr file at all").unwrap();
    let err = run(&["info", bad.to_str().unwrap()]).unwrap_err();
    assert!(err.contains("bad.exr"), "{err}");
    let out = dir.path().join("never.ktx2");
    assert!(
        run(&["export", bad.to_str().unwrap(), "--format", "ktx2", "-o", out.to_str().unwrap()]).is_err()
    );
    assert!(!out.exists(), "no output file after a failed export");
    // Unknown verb / format: clap's error, one line.
    assert!(run(&["frobnicate"]).is_err());
    assert!(run(&["export", "x.exr", "--format", "png", "-o", "y"]).is_err());
}
