//! The workspace keeps its shape: in no crate do modules import one another in a circle
//! (directly or through others), no crate holds more than [`MAX_CRATE_SHARE`] of the
//! workspace's library lines, and no source file outside generated code is longer than
//! [`MAX_FILE_LINES`]. Read from the sources themselves, so a move that breaks the shape
//! fails here before anyone draws the graph.
//!
//! A module's imports are the paths it names that start at its crate (`crate::a::b`,
//! `use crate::{a, b::c}`) or its parent (`super::x`), each resolved to the longest module
//! prefix; a name the crate root re-exports (`crate::Scene`) is an import of the module that
//! defines it, and other paths to the root are not imports of a module. Unit-test
//! code (`#[cfg(test)] mod tests { … }` at the end of a file, test files mounted under it)
//! is left out: tests may reach back into what they test.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Largest share of the workspace's library lines one crate may hold: a crate past it is
/// several ideas (the scene, the sampler and the comparisons were once one crate of 40%).
const MAX_CRATE_SHARE: f64 = 0.30;

/// Longest source file, in lines: a module past ~600 lines usually holds two concepts; 700
/// leaves room for a test module at its end.
const MAX_FILE_LINES: usize = 700;

/// A module: its path inside the crate (`["io", "exr"]`; empty for the root).
type Module = Vec<String>;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The workspace members, from the root manifest's `members = [...]`.
fn members() -> Vec<String> {
    let manifest = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    let start = manifest.find("members = [").expect("a members list");
    let list = &manifest[start + "members = [".len()..];
    let list = &list[..list.find(']').unwrap()];
    let out: Vec<String> =
        list.split(',').map(|m| m.trim().trim_matches('"').to_owned()).filter(|m| !m.is_empty()).collect();
    assert!(out.len() >= 10, "{out:?}");
    out
}

/// Every `.rs` file under `dir`, recursively.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else { return out };
    for e in entries {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(rust_files(&p));
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
    out.sort();
    out
}

/// Whether `path` (under a crate's `src/`) is unit-test code mounted by `#[cfg(test)]`:
/// `tests.rs`, `*_tests.rs`, or a file of a `tests/` folder.
fn is_test_file(src: &Path, path: &Path) -> bool {
    let rel = path.strip_prefix(src).unwrap();
    let name = rel.file_stem().unwrap().to_string_lossy();
    name == "tests" || name.ends_with("_tests") || rel.components().any(|c| c.as_os_str() == "tests")
}

/// The file's text without its trailing unit-test module and without `//` comments.
fn library_text(text: &str) -> String {
    let cut = text.find("#[cfg(test)]\nmod tests {").unwrap_or(text.len());
    text[..cut].lines().map(|l| l.split("//").next().unwrap_or("")).collect::<Vec<_>>().join("\n")
}

/// The module a source file defines.
fn module_of(src: &Path, path: &Path) -> Module {
    let rel = path.strip_prefix(src).unwrap().with_extension("");
    let mut m: Module = rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    if matches!(m.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        m.pop();
    }
    m
}

fn is_ident_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// The paths (as segments) that `text` names from `crate::` and from `super::` (repeated
/// `super::super::` go up as many levels), resolved against `module`; use-groups
/// `{a, b::c}` are expanded one level deep.
fn named_paths(text: &str, module: &Module) -> Vec<Module> {
    let chars: Vec<char> = text.chars().collect();
    let starts_at =
        |i: usize, word: &str| word.chars().enumerate().all(|(k, c)| chars.get(i + k) == Some(&c));
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let fresh = i == 0 || !(is_ident_char(chars[i - 1]) || chars[i - 1] == ':');
        let mut segs: Module = Vec::new();
        let mut j = i;
        if fresh && starts_at(i, "crate::") {
            j += "crate::".len();
        } else if fresh && starts_at(i, "super::") {
            let mut up = 0;
            while starts_at(j, "super::") {
                up += 1;
                j += "super::".len();
            }
            segs.extend(module[..module.len().saturating_sub(up)].iter().cloned());
        } else {
            i += 1;
            continue;
        }
        loop {
            if chars.get(j) == Some(&'{') {
                let group: String = chars[j + 1..].iter().take_while(|c| **c != '}').collect();
                for item in group.split(',') {
                    let item = item.trim().split(" as ").next().unwrap_or("").trim();
                    if !item.is_empty() && item != "self" {
                        let mut s = segs.clone();
                        s.extend(item.split("::").map(|x| x.trim().to_owned()));
                        out.push(s);
                    }
                }
                break;
            }
            let seg: String = chars[j..].iter().take_while(|c| is_ident_char(**c)).collect();
            if seg.is_empty() {
                break;
            }
            j += seg.chars().count();
            segs.push(seg);
            if !starts_at(j, "::") {
                break;
            }
            j += 2;
        }
        out.push(segs);
        i = j.max(i + 1);
    }
    out
}

/// One crate's modules and the modules each imports.
fn import_graph(src: &Path) -> BTreeMap<Module, BTreeSet<Module>> {
    let files: Vec<PathBuf> = rust_files(src).into_iter().filter(|p| !is_test_file(src, p)).collect();
    let modules: BTreeSet<Module> = files.iter().map(|p| module_of(src, p)).collect();
    let longest = |path: &Module| -> Option<Module> {
        (1..=path.len()).rev().map(|k| path[..k].to_vec()).find(|m| modules.contains(m))
    };
    // The crate root's re-exports (`pub use a::b::Name;`): `crate::Name` is an import of `a::b`.
    let root_text = ["lib.rs", "main.rs"].iter().find_map(|f| std::fs::read_to_string(src.join(f)).ok());
    let mut reexports: BTreeMap<String, Module> = BTreeMap::new();
    for stmt in library_text(&root_text.unwrap_or_default()).split(';') {
        let Some(rest) = stmt.trim().strip_prefix("pub use ") else { continue };
        let rest = rest.trim_start_matches("crate::").trim_start_matches("self::");
        let (base, items) = match rest.split_once("::{") {
            Some((b, i)) => (b, i.trim_end_matches('}').split(',').map(str::trim).collect::<Vec<_>>()),
            None => match rest.rsplit_once("::") {
                Some((b, i)) => (b, vec![i.trim()]),
                None => continue,
            },
        };
        let base: Module = base.split("::").map(|x| x.trim().to_owned()).collect();
        for item in items {
            let (path, name) = match item.split_once(" as ") {
                Some((p, n)) => (p.trim(), n.trim()),
                None => (item, item.rsplit("::").next().unwrap_or(item)),
            };
            let mut full = base.clone();
            full.extend(path.split("::").map(|x| x.trim().to_owned()));
            if let Some(m) = longest(&full) {
                reexports.insert(name.to_owned(), m);
            }
        }
    }
    let resolve = |path: &Module| -> Option<Module> {
        match path.first().and_then(|n| reexports.get(n)) {
            Some(m) if !modules.contains(&path[..1]) => Some(m.clone()),
            _ => longest(path),
        }
    };
    let mut graph = BTreeMap::new();
    for f in &files {
        let m = module_of(src, f);
        let text = library_text(&std::fs::read_to_string(f).unwrap());
        let edges: BTreeSet<Module> =
            named_paths(&text, &m).iter().filter_map(resolve).filter(|t| *t != m && !t.is_empty()).collect();
        graph.insert(m, edges);
    }
    graph
}

/// A circle of `graph`, if any: modules each importing the next, the last the first.
fn circle(graph: &BTreeMap<Module, BTreeSet<Module>>) -> Option<Vec<Module>> {
    fn visit(
        n: &Module,
        graph: &BTreeMap<Module, BTreeSet<Module>>,
        state: &mut BTreeMap<Module, u8>,
        path: &mut Vec<Module>,
    ) -> Option<Vec<Module>> {
        match state.get(n) {
            Some(2) => return None,
            Some(_) => {
                let start = path.iter().position(|p| p == n).unwrap();
                return Some(path[start..].to_vec());
            }
            None => {}
        }
        state.insert(n.clone(), 1);
        path.push(n.clone());
        for m in graph.get(n).into_iter().flatten() {
            if let Some(c) = visit(m, graph, state, path) {
                return Some(c);
            }
        }
        path.pop();
        state.insert(n.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    graph.keys().find_map(|n| visit(n, graph, &mut state, &mut Vec::new()))
}

#[test]
fn no_crate_has_an_import_circle() {
    let mut found = Vec::new();
    let mut edges = 0;
    for m in members() {
        let src = root().join(&m).join("src");
        let graph = import_graph(&src);
        edges += graph.values().map(BTreeSet::len).sum::<usize>();
        if let Some(c) = circle(&graph) {
            found.push(format!("{m}: {}", c.iter().map(|x| x.join("::")).collect::<Vec<_>>().join(" -> ")));
        }
    }
    // The reader sees the workspace's real imports (hundreds of them)...
    assert!(edges > 300, "only {edges} imports read");
    assert!(found.is_empty(), "modules that import each other in a circle:\n{}", found.join("\n"));
}

/// The search finds a circle where there is one (through a use-group and a
/// `super::super::` path), and not in unit-test code.
#[test]
fn a_planted_circle_is_found() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::create_dir_all(src.join("io")).unwrap();
    std::fs::write(
        src.join("lib.rs"),
        "pub mod grid;\npub mod io;\npub use grid::Grid;\npub use io::exr::{write as put};\n",
    )
    .unwrap();
    std::fs::write(src.join("grid.rs"), "use crate::{put, Grid};\n").unwrap();
    std::fs::write(src.join("io/mod.rs"), "pub mod exr;\n").unwrap();
    let exr = src.join("io/exr.rs");
    std::fs::write(
        &exr,
        "pub fn write() {}\n#[cfg(test)]\nmod tests {\n    use super::super::super::grid;\n}\n",
    )
    .unwrap();
    let graph = import_graph(src);
    let grid = vec!["grid".to_owned()];
    let io_exr = vec!["io".to_owned(), "exr".to_owned()];
    assert_eq!(graph[&grid], BTreeSet::from([io_exr.clone()]), "{graph:?}");
    assert!(circle(&graph).is_none(), "a test module may import back: {graph:?}");
    std::fs::write(&exr, "use super::super::grid;\npub fn write() {}\n").unwrap();
    let graph = import_graph(src);
    assert_eq!(graph[&io_exr], BTreeSet::from([grid.clone()]), "{graph:?}");
    assert_eq!(circle(&graph), Some(vec![grid, io_exr]));
}

#[test]
fn no_crate_holds_more_than_its_share() {
    let mut lines = BTreeMap::new();
    for m in members() {
        let src = root().join(&m).join("src");
        let n: usize = rust_files(&src)
            .iter()
            .filter(|p| !is_test_file(&src, p))
            .map(|p| library_text(&std::fs::read_to_string(p).unwrap()).lines().count())
            .sum();
        lines.insert(m, n);
    }
    let total: usize = lines.values().sum();
    assert!(total > 30_000, "{lines:?}");
    for (m, n) in &lines {
        let share = *n as f64 / total as f64;
        assert!(share <= MAX_CRATE_SHARE, "{m} holds {n} of {total} library lines ({:.0}%)", 100.0 * share);
    }
}

#[test]
fn no_source_file_is_too_long() {
    let mut long = Vec::new();
    let mut read = 0;
    for m in members() {
        for p in rust_files(&root().join(&m)) {
            if p.components().any(|c| c.as_os_str() == "target") {
                continue;
            }
            let text = std::fs::read_to_string(&p).unwrap();
            read += 1;
            if text.starts_with("// @generated") {
                continue;
            }
            let n = text.lines().count();
            if n > MAX_FILE_LINES {
                long.push(format!("{}: {n} lines", p.strip_prefix(root()).unwrap_or(&p).display()));
            }
        }
    }
    assert!(read > 200, "only {read} files read");
    assert!(long.is_empty(), "files over {MAX_FILE_LINES} lines:\n{}", long.join("\n"));
}
