//! The command line is a thin shell over the library crates: its only public items are the
//! entry points, and its modules import one another without circles.

use std::collections::{BTreeMap, BTreeSet};
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

/// `crate::NAME` references of each module, as edges between modules.
fn imports() -> BTreeMap<String, BTreeSet<String>> {
    let src = sources();
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (file, text) in &src {
        let targets = edges.entry(file.clone()).or_default();
        for (at, _) in text.match_indices("crate::") {
            let rest = &text[at + "crate::".len()..];
            let name: String = rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
            if name != *file && src.contains_key(&name) {
                targets.insert(name);
            }
        }
    }
    edges
}

/// A circle through `edges`, if any (depth-first search).
fn circle(edges: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        n: &str,
        edges: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(n) {
            Some(2) => return None,
            Some(1) => {
                let start = path.iter().position(|p| p == n).unwrap();
                let mut c = path[start..].to_vec();
                c.push(n.to_owned());
                return Some(c);
            }
            _ => {}
        }
        state.insert(n.to_owned(), 1);
        path.push(n.to_owned());
        for m in edges.get(n).into_iter().flatten() {
            if let Some(c) = visit(m, edges, state, path) {
                return Some(c);
            }
        }
        path.pop();
        state.insert(n.to_owned(), 2);
        None
    }
    let mut state = BTreeMap::new();
    edges.keys().find_map(|n| visit(n, edges, &mut state, &mut Vec::new()))
}

#[test]
fn modules_import_each_other_without_circles() {
    let edges = imports();
    // The reader sees real imports (the verbs use the option modules).
    assert!(edges["cmd_bake"].contains("bake_args"), "{edges:?}");
    assert_eq!(circle(&edges), None);
    // And the search finds a circle where there is one.
    let mut looped = edges.clone();
    looped.get_mut("bake_args").unwrap().insert("cmd_bake".into());
    assert!(circle(&looped).is_some());
}
