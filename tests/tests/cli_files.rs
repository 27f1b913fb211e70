//! The CLI's file verbs (info, export) end to end, and their error handling.

use std::process::ExitCode;

use lightvol_volume::io::exr::{ExrOptions, write_exr};
use lightvol_volume::{GridSpec, IrradianceVolume};

fn run(args: &[&str]) -> anyhow_like::Result {
    lightvol::run_from_args(std::iter::once("lightvol").chain(args.iter().copied()))
        .map_err(|e| format!("{e:#}").replace('\n', " "))
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
    let back = lightvol_volume::io::ktx2::read_ktx2(&dir.path().join("out_ktx2.ktx2")).unwrap();
    let orig = lightvol_volume::io::exr::read_exr(std::path::Path::new(v)).unwrap();
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

/// `render -o view.exr` writes linear HDR values, unscaled: the shaded pixel is emission +
/// radiosity, the radiosity is albedo · E / π ≤ E for albedo ≤ 1, and background pixels
/// are the sky only in the shaded image; `--light indirect` darkens the path-traced view.
#[test]
fn render_writes_linear_hdr_exr_per_quantity() {
    let dir = tempfile::tempdir().unwrap();
    let read = |p: &std::path::Path| -> Vec<[f32; 3]> {
        let img = exr::prelude::read_all_flat_layers_from_file(p).expect("an EXR");
        let layer = &img.layer_data[0];
        let ch = |name: &str| -> Vec<f32> {
            let c = layer.channel_data.list.iter().find(|c| c.name.to_string() == name).expect(name);
            c.sample_data.values_as_f32().collect()
        };
        let (r, g, b) = (ch("R"), ch("G"), ch("B"));
        (0..r.len()).map(|i| [r[i], g[i], b[i]]).collect()
    };
    let shot = |q: &str, light: &str| {
        let out = dir.path().join(format!("{q}-{light}.exr"));
        let args = [
            "render",
            "builtin:city",
            "--reference",
            "--reference-samples",
            "8",
            "--width",
            "24",
            "--height",
            "16",
            "--camera",
            "-14,-14,2:0,0,9:70",
            "--quantity",
            q,
            "--light",
            light,
            "-o",
            out.to_str().unwrap(),
        ];
        assert_eq!(run(&args), Ok(ExitCode::SUCCESS), "{args:?}");
        read(&out)
    };
    let (shaded, radiosity, irradiance) =
        (shot("shaded", "all"), shot("radiosity", "all"), shot("irradiance", "all"));
    assert_eq!(shaded.len(), 24 * 16);
    let (mut surface, mut sky) = (0, 0);
    for i in 0..shaded.len() {
        for c in 0..3 {
            assert!(radiosity[i][c] <= irradiance[i][c] + 1e-6, "pixel {i}: ρE/π above E");
        }
        if irradiance[i] == [0.0; 3] && radiosity[i] == [0.0; 3] {
            sky += 1;
            assert!(shaded[i].iter().any(|&v| v > 0.0), "the sky shows in the shaded view");
        } else {
            surface += 1;
            // The city has no emitters: shaded = radiosity exactly.
            assert_eq!(shaded[i], radiosity[i], "pixel {i}");
        }
    }
    assert!(surface > 0 && sky > 0, "{surface} surface and {sky} sky pixels");
    // The alpha channel tells a miss (0) from a surface (1), whatever the surface's value.
    let img = exr::prelude::read_all_flat_layers_from_file(dir.path().join("irradiance-all.exr")).unwrap();
    let alpha: Vec<f32> = img.layer_data[0]
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == "A")
        .expect("an alpha channel")
        .sample_data
        .values_as_f32()
        .collect();
    assert_eq!(alpha.len(), irradiance.len());
    for i in 0..alpha.len() {
        assert!(alpha[i] == 0.0 || alpha[i] == 1.0, "pixel {i}: alpha {}", alpha[i]);
        if alpha[i] == 0.0 {
            assert_eq!(irradiance[i], [0.0; 3], "pixel {i}: a miss has no irradiance");
        }
    }
    let covered = alpha.iter().filter(|&&a| a == 1.0).count();
    assert_eq!(covered, surface, "surfaces by alpha and by value (the city has no black surface)");
    let indirect = shot("irradiance", "indirect");
    let sum = |v: &[[f32; 3]]| v.iter().map(|p| f64::from(p[0] + p[1] + p[2])).sum::<f64>();
    assert!(sum(&indirect) < 0.8 * sum(&irradiance), "indirect light only is not darker");
}
