//! `bake-surface --shard K/N` writes each basis's texel shard; `--from-shards` assembles
//! them into maps whose every file (EXR, JSON, KTX2) is the whole bake's, byte for byte, in
//! any shard order; incomplete and foreign sets are refused in one line.

mod surface_util;

use std::collections::BTreeMap;
use std::path::Path;
use std::process::ExitCode;

use surface_util::{plane, write_gltf};

fn s(p: &Path) -> &str {
    p.to_str().expect("test paths are UTF-8")
}

fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x != "lvtex"))
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
        .collect()
}

#[test]
fn surface_shards_assemble_to_the_whole_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let gltf = write_gltf(d, "planes.gltf", &[plane("floor"), plane("floor_copy")]);
    let base = [
        "bake-surface",
        s(&gltf),
        "--basis",
        "hbasis_mod4,sh9",
        "--texels-per-unit",
        "3",
        "--samples",
        "6",
        "--quiet",
        "--encode",
        "ktx2",
        "--sky",
        "0.3,0.4,0.6",
        "--sun",
        "1,0.3,-0.2:4",
    ];
    let run = |extra: &[&str]| -> Result<ExitCode, String> {
        let mut a: Vec<&str> = base.to_vec();
        a.extend_from_slice(extra);
        surface_util::run(&a)
    };
    let whole = d.join("whole");
    assert_eq!(run(&["-o", s(&whole), "--threads", "1"]), Ok(ExitCode::SUCCESS));
    let whole2 = d.join("whole2");
    assert_eq!(run(&["-o", s(&whole2), "--threads", "2"]), Ok(ExitCode::SUCCESS));
    let w = files(&whole);
    assert!(files(&whole2) == w, "1 and 2 threads differ");
    // 1 and 7 shards (shards alternating between 1 and 2 threads, assembled in reverse and
    // shuffled order) give the whole bake's files too.
    for n in [1u32, 7] {
        let dir_n = d.join(format!("shards{n}"));
        for k in 0..n {
            let t = (1 + k % 2).to_string();
            assert_eq!(
                run(&["--shard", &format!("{k}/{n}"), "--threads", &t, "-o", s(&dir_n)]),
                Ok(ExitCode::SUCCESS)
            );
        }
        let mut lvtex: Vec<String> = std::fs::read_dir(&dir_n)
            .unwrap()
            .map(|e| e.unwrap().path().to_string_lossy().into_owned())
            .collect();
        lvtex.sort();
        assert_eq!(lvtex.len(), 2 * n as usize);
        let len = lvtex.len();
        let shuffled: Vec<String> = (0..len).map(|i| lvtex[(i * 5 + 3) % len].clone()).collect();
        let out = d.join(format!("merged{n}"));
        let mut a = vec!["-o", s(&out), "--from-shards"];
        a.extend(shuffled.iter().map(String::as_str));
        assert_eq!(run(&a), Ok(ExitCode::SUCCESS));
        assert!(files(&out) == w, "{n} shards: the assembled files differ from the whole bake's");
    }
    let shards = d.join("shards");
    for k in [2, 0, 1] {
        assert_eq!(run(&["--shard", &format!("{k}/3"), "-o", s(&shards)]), Ok(ExitCode::SUCCESS));
    }
    let mut lvtex: Vec<String> = std::fs::read_dir(&shards)
        .unwrap()
        .map(|e| e.unwrap().path().to_string_lossy().into_owned())
        .collect();
    lvtex.sort();
    assert_eq!(lvtex.len(), 6, "3 shards × 2 bases: {lvtex:?}");
    lvtex.reverse();
    let merged = d.join("merged");
    let mut a = vec!["-o", s(&merged), "--from-shards"];
    a.extend(lvtex.iter().map(String::as_str));
    assert_eq!(run(&a), Ok(ExitCode::SUCCESS));
    let m = files(&merged);
    assert!(!w.is_empty());
    assert_eq!(w.keys().collect::<Vec<_>>(), m.keys().collect::<Vec<_>>());
    for (name, bytes) in &w {
        assert!(m[name] == *bytes, "{name} differs between the whole and the merged bake");
    }
    // Incomplete: one shard of sh9 left out.
    let partial: Vec<&str> =
        lvtex.iter().map(String::as_str).filter(|p| !p.contains("texels-sh9-1-of-3")).collect();
    let out = d.join("partial");
    let mut a = vec!["-o", s(&out), "--from-shards"];
    a.extend(partial);
    let e = run(&a).unwrap_err();
    assert!(e.contains("shards 1 of 3 of sh9 are missing"), "{e}");
    assert!(!out.exists());
    // Another seed is another bake.
    let mut a = vec!["-o", s(&out), "--seed", "9", "--from-shards"];
    a.extend(lvtex.iter().map(String::as_str));
    let e = run(&a).unwrap_err();
    assert!(e.contains("another scene or other options"), "{e}");
}
