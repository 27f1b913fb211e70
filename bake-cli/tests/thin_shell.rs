//! The command line is a thin shell over the library crates: its only public items are the
//! entry points. (That its modules import one another without circles, like every crate's,
//! is the workspace's `tests/tests/workspace_structure.rs`.)

use std::collections::BTreeMap;
use std::path::Path;

/// The public items the crate may have: its entry points.
const ENTRY_POINTS: [&str; 2] = ["pub fn run_from_args", "pub fn main_with_args"];

fn sources() -> BTreeMap<String, String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "rs") {
            let name = p.file_stem().unwrap().to_string_lossy().into_owned();
            out.insert(name, std::fs::read_to_string(&p).unwrap());
        }
    }
    assert!(out.len() > 10, "read {} source files from {}", out.len(), dir.display());
    out
}

#[test]
fn only_the_entry_points_are_public() {
    let mut public = Vec::new();
    for (file, text) in sources() {
        for (i, line) in text.lines().enumerate() {
            let t = line.trim_start();
            if t.starts_with("pub ") && !ENTRY_POINTS.iter().any(|e| t.starts_with(e)) {
                public.push(format!("{file}.rs:{}: {t}", i + 1));
            }
        }
    }
    assert!(public.is_empty(), "public items beyond the entry points:\n{}", public.join("\n"));
    let lib = &sources()["lib"];
    for e in ENTRY_POINTS {
        assert!(lib.contains(e), "lib.rs lost its entry point `{e}`");
    }
}
