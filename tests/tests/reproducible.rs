//! Byte-reproducible outputs: every file the `lightvol` verbs write (EXR volumes, adaptive
//! and gradient EXRs, merged shards, KTX2, DDS and its sidecar, Bevy, JSON exports, surface
//! EXR/JSON/PNG/KTX2/BC maps, renders, `inspect -o`, `compare` plates, panels and views) comes out
//! with identical bytes when the same command runs twice on the same input, in one process
//! and in two separate processes (the `exr` crate keeps custom attributes in a `HashMap`
//! whose random seed differs per map and per process; the EXR writers put them in a fixed
//! order).
//!
//! Shard files are included: accumulators (`.lvacc`, also of central-gradient and adaptive
//! level-0 shards), adaptive level files (`.lvref`) and surface texel shards (`.lvtex`). One exception, a measurement rather
//! than data: `compare`'s `report.json` holds the wall time of each method (`"seconds"`),
//! compared here with those fields left out.

mod common;
mod surface_util;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use common::{ok, s};
use surface_util::{plane, write_gltf};

/// Set in the child processes of [`separate_processes_write_identical_files`]: the folder
/// [`child_process_writes`] writes into.
const CHILD_OUT: &str = "LIGHTVOL_REPRODUCIBLE_CHILD_OUT";
/// The scene folder the child processes share (inputs are the same files for both runs).
const CHILD_SCENES: &str = "LIGHTVOL_REPRODUCIBLE_CHILD_SCENES";

/// Grid and sample count of every volume bake here: tiny, only the bytes matter.
const BAKE: [&str; 7] = ["--res", "4,4,4", "--samples", "4", "--seed", "7", "--quiet"];

/// The inputs both runs read: a one-plane glTF with lightmap UVs.
fn write_scenes(dir: &Path) -> PathBuf {
    write_gltf(dir, "plane.gltf", &[plane("floor")])
}

/// `lightvol bake builtin:city` with [`BAKE`] and `extra`, into `out`.
fn bake(out: &Path, extra: &[&str]) {
    let mut args = vec!["bake", "builtin:city"];
    args.extend_from_slice(&BAKE);
    args.extend_from_slice(extra);
    args.extend_from_slice(&["-o", s(out)]);
    ok(&args);
}

/// Runs every writing verb once into `out` (created), reading the scene `gltf`.
fn write_everything(out: &Path, gltf: &Path) {
    std::fs::create_dir_all(out).unwrap();
    let f = |name: &str| out.join(name);
    // Volumes: uniform, with gradients, adaptive, and a merge of two shards.
    bake(&f("v.exr"), &[]);
    bake(&f("grad.exr"), &["--gradients"]);
    bake(&f("oct.exr"), &["--adaptive", "--max-level", "1"]);
    bake(&f("shard0.exr"), &["--shard", "0/2"]);
    bake(&f("shard1.exr"), &["--shard", "1/2"]);
    ok(&["merge", s(&f("shard0.exr")), s(&f("shard1.exr")), "-o", s(&f("merged.exr"))]);
    // Shard files of the other modes: central gradients, and an adaptive bake's level 0 and
    // level 1 (.lvacc, .lvref).
    bake(&f("central0.exr"), &["--gradients", "central", "--shard", "0/2"]);
    let adaptive = ["--adaptive", "--max-level", "1", "--depth-rays", "4"];
    let mut a0 = adaptive.to_vec();
    a0.extend(["--shard", "0/1"]);
    bake(&f("oct-l0.exr"), &a0);
    let l0 = f("oct-l0.lvacc");
    let mut a1 = adaptive.to_vec();
    a1.extend(["--shard", "0/1", "--level", "1", "--from-shards", s(&l0)]);
    bake(&f("oct-l1.exr"), &a1);
    // Engine exports of the uniform and the adaptive volume.
    for format in ["ktx2", "dds", "bevy", "json"] {
        ok(&["export", s(&f("v.exr")), "--format", format, "-o", s(&f(&format!("v.{format}")))]);
        ok(&["export", s(&f("oct.exr")), "--format", format, "-o", s(&f(&format!("oct.{format}")))]);
    }
    // Sampling code for engines, in each language.
    for lang in ["wgsl", "hlsl", "glsl"] {
        ok(&["shader", "--lang", lang, "--layout", "ktx2", "-o", s(&f(&format!("sample.{lang}")))]);
    }
    // What the loader understood, as JSON and as text.
    ok(&["inspect", s(gltf), "--json", "-o", s(&f("inspect.json"))]);
    ok(&["inspect", s(gltf), "-o", s(&f("inspect.txt"))]);
    // A render shaded by the volume.
    ok(&[
        "render",
        "builtin:city",
        "--volume",
        s(&f("v.exr")),
        "--width",
        "16",
        "--height",
        "12",
        "-o",
        s(&f("view.png")),
    ]);
    // A linear HDR render (EXR) of the path-traced view.
    ok(&[
        "render",
        "builtin:city",
        "--reference",
        "--reference-samples",
        "2",
        "--width",
        "8",
        "--height",
        "6",
        "--quantity",
        "irradiance",
        "-o",
        s(&f("view.exr")),
    ]);
    // Surface maps: EXR + JSON, and each texture encoding.
    let light = ["--sky", "0.25,0.35,0.6", "--sun", "1,0.1,-0.2:5"];
    for (dir, encode) in [
        ("maps", &[][..]),
        ("maps_png", &["--encode", "png"][..]),
        ("maps_ktx2", &["--encode", "ktx2"][..]),
        ("maps_bc", &["--encode", "ktx2", "--compress", "bc1,bc7"][..]),
    ] {
        let maps = f(dir);
        let mut args = vec!["bake-surface", s(gltf), "--basis", "hbasis_mod4,sh9", "--texels-per-unit", "2"];
        args.extend_from_slice(&["--samples", "8", "--quiet", "-o", s(&maps)]);
        args.extend_from_slice(&light);
        args.extend_from_slice(encode);
        assert_eq!(surface_util::run(&args), Ok(ExitCode::SUCCESS), "{args:?}");
    }
    // A texel shard of the surface bake (.lvtex).
    let texel_shards = f("texel_shards");
    let mut args =
        vec!["bake-surface", s(gltf), "--basis", "sh9", "--texels-per-unit", "2", "--samples", "8"];
    args.extend_from_slice(&["--quiet", "--shard", "0/2", "-o", s(&texel_shards)]);
    args.extend_from_slice(&light);
    assert_eq!(surface_util::run(&args), Ok(ExitCode::SUCCESS), "{args:?}");
    // The lightmapped render of those maps.
    let (maps, view) = (f("maps"), f("surface_view"));
    let mut args = vec!["render", s(gltf), "--surface", s(&maps)];
    args.extend_from_slice(&["--camera", "0,1,0:0,0,0:40", "--width", "8", "--height", "6"]);
    args.extend_from_slice(&["--reference-samples", "2", "-o", s(&view)]);
    args.extend_from_slice(&light);
    ok(&args);
    // The method comparison: plate, panels, views, report.
    ok(&[
        "compare",
        "builtin:city",
        "--res",
        "4,4,4",
        "--samples",
        "8",
        "--plate-res",
        "8",
        "--reference-samples",
        "4",
        "--camera",
        "overview",
        "--view-width",
        "16",
        "--view-height",
        "12",
        "--view-samples",
        "2",
        "--quiet",
        "-o",
        s(&f("compare")),
    ]);
}

/// Every file under `dir`, by path relative to it, with its bytes.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().replace('\\', "/");
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// A JSON value without its `"seconds"` fields (at any depth).
fn without_timings(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(m) => {
            m.remove("seconds");
            m.values_mut().for_each(without_timings);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(without_timings),
        _ => {}
    }
}

/// Asserts that two runs wrote the same files with the same bytes (names the first
/// differing file and byte); `compare/report.json` is compared without its timings.
fn assert_same_files(a: &Path, b: &Path) {
    let (fa, fb) = (files(a), files(b));
    let names = |f: &BTreeMap<String, Vec<u8>>| f.keys().cloned().collect::<Vec<_>>();
    assert_eq!(names(&fa), names(&fb), "the two runs wrote different files");
    let mut compared = 0;
    for (name, x) in &fa {
        let y = &fb[name];
        if name == "compare/report.json" {
            let parse = |bytes: &[u8]| {
                let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
                without_timings(&mut v);
                v
            };
            assert_eq!(parse(x), parse(y), "{name}: differs beyond its timings");
            continue;
        }
        if x != y {
            let at = x.iter().zip(y).position(|(p, q)| p != q).unwrap_or(x.len().min(y.len()));
            panic!("{name}: the two runs differ (lengths {} and {}; first at byte {at})", x.len(), y.len());
        }
        compared += 1;
    }
    // Everything written above, bar the report: make sure the walk saw the files.
    for must in [
        "v.exr",
        "grad.exr",
        "oct.exr",
        "merged.exr",
        "shard0.lvacc",
        "central0.lvacc",
        "oct-l0.lvacc",
        "oct-l1.lvref",
        "v.ktx2",
        "v.dds",
        "v.dds.json",
        "v.bevy",
        "v.bevy.json",
        "sample.wgsl",
        "sample.hlsl",
        "sample.glsl",
        "view.exr",
    ] {
        assert!(fa.contains_key(must), "{must} was not written");
    }
    for must in [
        "inspect.json",
        "inspect.txt",
        "view.png",
        "maps/sh9.exr",
        "maps/sh9.json",
        "compare/plate.exr",
        "compare/view_overview_doi.png",
        "compare/view_overview_reference.png",
    ] {
        assert!(fa.contains_key(must), "{must} was not written");
    }
    assert!(fa.keys().any(|k| k.starts_with("maps_png/") && k.ends_with(".png")));
    assert!(fa.keys().any(|k| k.starts_with("texel_shards/") && k.ends_with(".lvtex")));
    assert!(fa.keys().any(|k| k.starts_with("maps_bc/") && k.ends_with(".bc7.ktx2")));
    assert!(fa.keys().any(|k| k.starts_with("surface_view/") && k.ends_with(".png")));
    assert!(compared > 40, "only {compared} files compared");
}

/// Two runs in this process: identical files.
#[test]
fn repeated_runs_write_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    let gltf = write_scenes(dir.path());
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    write_everything(&a, &gltf);
    write_everything(&b, &gltf);
    assert_same_files(&a, &b);
}

/// Two runs in separate processes (this test binary started again, running only
/// [`child_process_writes`]): the hash seeds differ per process, and the files still agree.
#[test]
fn separate_processes_write_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    write_scenes(dir.path());
    let exe = std::env::current_exe().unwrap();
    let outs = [dir.path().join("a"), dir.path().join("b")];
    for out in &outs {
        let child = Command::new(&exe)
            .args(["child_process_writes", "--exact", "--test-threads", "1", "--quiet"])
            .env(CHILD_OUT, out)
            .env(CHILD_SCENES, dir.path())
            .output()
            .unwrap();
        assert!(
            child.status.success(),
            "the child process failed ({}):\n{}{}",
            child.status,
            String::from_utf8_lossy(&child.stdout),
            String::from_utf8_lossy(&child.stderr)
        );
        assert!(out.join("v.exr").is_file(), "the child process wrote nothing (test not found?)");
    }
    assert_same_files(&outs[0], &outs[1]);
}

/// The child process of [`separate_processes_write_identical_files`]: writes everything
/// into the folder named by [`CHILD_OUT`]. Without that variable (a normal test run) it does
/// nothing.
#[test]
fn child_process_writes() {
    let (Some(out), Some(scenes)) = (std::env::var_os(CHILD_OUT), std::env::var_os(CHILD_SCENES)) else {
        return;
    };
    write_everything(Path::new(&out), &Path::new(&scenes).join("plane.gltf"));
}
