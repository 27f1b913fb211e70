//! `lightvol render` writes the bytes it wrote before its view moved into
//! lightvol-view's renderer: the hashes below were recorded with the renderer of
//! `cmd_render.rs` as it was before the move, on a volume written here from a closed-form
//! field (so that no bake enters the hashes), for the volume-shaded and the path-traced
//! view, PNG and EXR, every pixel quantity. They were recorded on x86-64 Linux: the camera's
//! `tan` and the paths' `sin`/`cos` come from the platform's libm, which elsewhere may round
//! differently in the last bit.

mod common;

use std::path::Path;

use common::{ok, s};
use lightvol_core::hash::fnv1a;
use lightvol_scene::builtin;
use lightvol_volume::IrradianceVolume;
use lightvol_volume::io::exr::{ExrOptions, write_exr};

/// A volume on the maze's recommended grid whose coefficients are polynomials of position
/// (every coefficient, every channel; no libm function, so the file is the same bytes on
/// every platform), so that the renders depend on the lookup everywhere.
fn field_volume(path: &Path) {
    let grid = builtin::maze().grid;
    let vol = IrradianceVolume::from_fn(grid, 9, |p| {
        (0..9)
            .map(|j| {
                let j = j as f64;
                let base = if j == 0.0 { 2.5 } else { 0.3 / (1.0 + j) };
                [0.0, 1.0, 2.0].map(|c| {
                    base * (1.0 + 0.05 * c) + 0.002 * (j + 1.0) * p[0] - 0.001 * (c + 1.0) * p[1] * p[2]
                })
            })
            .collect()
    })
    .unwrap();
    write_exr(path, &vol, &ExrOptions::default()).unwrap();
}

fn hash(path: &Path) -> String {
    format!("{:016x}", fnv1a(&std::fs::read(path).unwrap()))
}

/// Volume-shaded views (default camera, PNG; a look-at camera, irradiance as linear EXR;
/// radiosity) and path-traced views (EXR on one thread with another seed, PNG with one
/// bounce, a fixed exposure and no progress bar) hash as before. (The EXR pins changed once
/// when the EXRs gained their coverage alpha channel, and the look-at irradiance EXR once
/// when the tracer's triangle test became watertight: hit points moved by f32 rounding, the
/// pixels by at most 1.5e-6 of 4.9; the PNGs of the same views did not change.)
#[test]
fn render_outputs_are_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("field.exr");
    field_volume(&vol);
    let f = |name: &str| dir.path().join(name);
    let v = s(&vol);
    let cases: [(&str, Vec<&str>, &str); 5] = [
        ("shaded.png", vec!["--volume", v, "--width", "40", "--height", "24"], "6a3e3bbcee6c7ddf"),
        (
            "irradiance.exr",
            vec!["--volume", v, "--width", "36", "--quantity", "irradiance", "--camera=-8,-8,6:0,0,0.5:60"],
            "9541327c5d2a654a",
        ),
        (
            "radiosity.png",
            vec!["--volume", v, "--width", "32", "--height", "20", "--quantity", "radiosity"],
            "fe295a4fd4728fe2",
        ),
        (
            "reference.exr",
            vec![
                "--reference",
                "--reference-samples",
                "3",
                "--width",
                "32",
                "--height",
                "20",
                "--seed",
                "7",
                "--threads",
                "1",
            ],
            "fe3dbe98a4400665",
        ),
        (
            "reference.png",
            vec![
                "--reference",
                "--reference-samples",
                "2",
                "--width",
                "32",
                "--height",
                "20",
                "--bounces",
                "1",
                "--exposure",
                "2",
                "--quiet",
            ],
            "3d4eb27bb0172d16",
        ),
    ];
    let mut got = Vec::new();
    for (name, extra, _) in &cases {
        let out = f(name);
        let mut args = vec!["render", "builtin:maze"];
        args.extend(extra);
        args.extend(["-o", s(&out)]);
        ok(&args);
        got.push(hash(&out));
    }
    let want: Vec<&str> = cases.iter().map(|c| c.2).collect();
    println!("{:?}", cases.iter().map(|c| c.0).zip(&got).collect::<Vec<_>>());
    assert_eq!(got, want);
}
