//! Tiled layouts: one glTF scene repeated on a grid of tiles, written as a new glTF that
//! shares the source's binary data. Every mesh of the source is then placed once per tile,
//! so the loader stores it once and instances it ([`crate::instance`]): a 32 × 32 layout of
//! a 63,720-triangle room places 65 M triangles and stores 63,720.
//!
//! The tiles lie in the file's horizontal plane (glTF is +Y up: tile `(i, j)` is moved by
//! `(i · pitch, 0, j · pitch)`), each a root node whose children are copies of the source
//! scene's node trees. Buffers and images keep their data: the GLB binary chunk is written
//! once beside the layout, external files are referred to by absolute path.

use std::path::{Path, PathBuf};

use serde_json::{Map, Value, json};

use crate::error::SceneError;
use crate::load::gltf::container;

/// The most nodes a layout writes: 2^21 (2,097,152; each is a JSON object while the file is
/// assembled, a few hundred bytes). A layout that would write more is refused before it is
/// assembled: a 32 × 32 layout of the 17-mesh occlusion room writes 18,432.
pub const MAX_LAYOUT_NODES: u64 = 1 << 21;

/// Writes `<dir>/<stem>_<nx>x<ny>.gltf` (and its `.bin` when the source is a GLB): the
/// default scene of `src` repeated on `counts[0] × counts[1]` tiles `pitch` apart. Returns
/// the glTF's path. Files are written whole or not at all.
///
/// # Errors
/// [`SceneError::NotFound`]/[`SceneError::Io`] for unreadable or unwritable files,
/// [`SceneError::Gltf`] for a source that does not parse or has no scene to repeat, and
/// [`SceneError::NonFinite`] for a pitch that is not finite or counts of zero, and
/// [`SceneError::Gltf`] for a layout of more than [`MAX_LAYOUT_NODES`] nodes.
pub fn write_grid_layout(
    src: &Path,
    dir: &Path,
    counts: [u32; 2],
    pitch: f64,
) -> Result<PathBuf, SceneError> {
    if !pitch.is_finite() || counts.contains(&0) {
        return Err(SceneError::NonFinite { what: format!("layout of {counts:?} tiles at pitch {pitch}") });
    }
    if !src.is_file() {
        return Err(SceneError::NotFound(src.to_owned()));
    }
    let io = |path: &Path| {
        let path = path.to_owned();
        move |source| SceneError::Io { path, source }
    };
    let gerr = |message: String| SceneError::Gltf { path: src.to_owned(), message };
    let bytes = std::fs::read(src).map_err(io(src))?;
    let doc = container::parse(&bytes).map_err(gerr)?;
    let stem = src.file_stem().map_or_else(|| "scene".to_owned(), |s| s.to_string_lossy().into_owned());
    let name = format!("{stem}_{}x{}", counts[0], counts[1]);
    let src_dir = src.parent().map(Path::to_path_buf).unwrap_or_default();
    let src_dir = std::fs::canonicalize(&src_dir).unwrap_or(src_dir);
    let mut json = doc.json;
    let root = json.as_object_mut().ok_or_else(|| gerr("the JSON root is not an object".into()))?;

    // Buffers: the GLB chunk goes to a .bin beside the layout; files by absolute path.
    let bin_name = format!("{name}.bin");
    let mut bin = None;
    for b in root.get_mut("buffers").and_then(Value::as_array_mut).into_iter().flatten() {
        match b.get("uri").and_then(Value::as_str) {
            None => {
                let blob = doc
                    .blob
                    .as_ref()
                    .ok_or_else(|| gerr("a buffer has no uri and there is no GLB chunk".into()))?;
                b["uri"] = json!(bin_name);
                bin = Some(blob);
            }
            Some(u) if !u.starts_with("data:") => b["uri"] = json!(src_dir.join(u).to_string_lossy()),
            Some(_) => {}
        }
    }
    for img in root.get_mut("images").and_then(Value::as_array_mut).into_iter().flatten() {
        if let Some(u) = img.get("uri").and_then(Value::as_str)
            && !u.starts_with("data:")
        {
            img["uri"] = json!(src_dir.join(u).to_string_lossy());
        }
    }

    // The source scene's roots, repeated under one root node per tile.
    let nodes: Vec<Value> = root.get("nodes").and_then(Value::as_array).cloned().unwrap_or_default();
    let scene_index = root.get("scene").and_then(Value::as_u64).unwrap_or(0) as usize;
    let roots: Vec<u64> = root
        .get("scenes")
        .and_then(|s| s.get(scene_index))
        .and_then(|s| s.get("nodes"))
        .and_then(Value::as_array)
        .map(|a| a.iter().filter_map(Value::as_u64).collect())
        .ok_or_else(|| gerr(format!("scene {scene_index} does not exist or has no nodes")))?;
    // One tile's nodes (its root and copies of the scene's trees), counted before anything
    // is assembled.
    let mut per_tile = Vec::new();
    for &r in &roots {
        copy_tree(&nodes, r, &mut per_tile).map_err(gerr)?;
    }
    let total = (per_tile.len() as u64 + 1) * u64::from(counts[0]) * u64::from(counts[1]);
    if total > MAX_LAYOUT_NODES {
        return Err(gerr(format!(
            "a {}x{} layout writes {total} nodes, more than the {MAX_LAYOUT_NODES} a layout may have",
            counts[0], counts[1]
        )));
    }
    drop(per_tile);
    let mut out: Vec<Value> = Vec::new();
    let mut tiles = Vec::new();
    for j in 0..counts[1] {
        for i in 0..counts[0] {
            let mut children = Vec::with_capacity(roots.len());
            for &r in &roots {
                children.push(copy_tree(&nodes, r, &mut out).map_err(gerr)?);
            }
            let mut tile = Map::new();
            tile.insert("name".into(), json!(format!("tile_{i}_{j}")));
            tile.insert("translation".into(), json!([f64::from(i) * pitch, 0.0, f64::from(j) * pitch]));
            tile.insert("children".into(), json!(children));
            tiles.push(out.len());
            out.push(Value::Object(tile));
        }
    }
    root.insert("nodes".into(), Value::Array(out));
    root.insert("scenes".into(), json!([{ "name": name, "nodes": tiles }]));
    root.insert("scene".into(), json!(0));

    std::fs::create_dir_all(dir).map_err(io(dir))?;
    if let Some(blob) = bin {
        write_whole(&dir.join(&bin_name), blob)?;
    }
    let path = dir.join(format!("{name}.gltf"));
    let text = serde_json::to_vec(&json).map_err(|e| gerr(e.to_string()))?;
    write_whole(&path, &text)?;
    Ok(path)
}

/// Copies the tree under node `n` to the end of `out` (children first), returning the
/// copy's index.
fn copy_tree(nodes: &[Value], n: u64, out: &mut Vec<Value>) -> Result<u64, String> {
    let mut depth = 0usize;
    copy_rec(nodes, n, out, &mut depth)
}

fn copy_rec(nodes: &[Value], n: u64, out: &mut Vec<Value>, depth: &mut usize) -> Result<u64, String> {
    /// Node trees deeper than this are refused (the loader walks any depth, but a layout
    /// of such a file is not worth a deep recursion).
    const MAX_DEPTH: usize = 256;
    *depth += 1;
    if *depth > MAX_DEPTH {
        return Err(format!("node trees deeper than {MAX_DEPTH} are not repeated"));
    }
    let node = nodes.get(n as usize).ok_or_else(|| format!("node {n} does not exist"))?;
    let mut copy = node.clone();
    if let Some(children) = node.get("children").and_then(Value::as_array) {
        let mut new = Vec::with_capacity(children.len());
        for c in children.iter().filter_map(Value::as_u64) {
            new.push(copy_rec(nodes, c, out, depth)?);
        }
        copy["children"] = json!(new);
    }
    *depth -= 1;
    out.push(copy);
    Ok(out.len() as u64 - 1)
}

/// Writes `bytes` to `path` through a temporary file in the same directory, renamed into
/// place once complete.
fn write_whole(path: &Path, bytes: &[u8]) -> Result<(), SceneError> {
    lightvol_volume::io::util::write_atomic(path, bytes)
        .map_err(|e| SceneError::Io { path: path.to_owned(), source: std::io::Error::other(e.to_string()) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LoadOptions;
    use crate::load::gltf::load_gltf;

    /// A 3 × 2 layout of the vendored occlusion room places its 17 meshes 6 times each:
    /// 6 × 63,720 triangles placed, 63,720 stored, 102 instances, each tile moved by the
    /// pitch along the file's X and Z (the world's X and −Y, +Z up).
    #[test]
    fn layout_instances_every_mesh_per_tile() {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes/occlusion_room/room.glb");
        let dir = tempfile::tempdir().unwrap();
        let path = write_grid_layout(&src, dir.path(), [3, 2], 10.0).unwrap();
        assert_eq!(path.file_name().unwrap(), "room_3x2.gltf");
        let one = load_gltf(&src, &LoadOptions::default()).unwrap();
        let s = load_gltf(&path, &LoadOptions::default()).unwrap();
        assert_eq!((one.triangle_count(), one.instances.len()), (63_720, 0));
        assert_eq!((s.triangle_count(), s.unique_triangle_count()), (6 * 63_720, 63_720));
        assert_eq!((s.instances.len(), s.prototypes.len(), s.triangles.len()), (6 * 17, 17, 0));
        let (lo1, hi1) = one.bounds();
        let (lo, hi) = s.bounds();
        // +Y up: file X → world X, file Z → world −Y.
        let expect_hi = hi1 + glam::DVec3::new(20.0, 0.0, 0.0);
        let expect_lo = lo1 - glam::DVec3::new(0.0, 10.0, 0.0);
        assert!(
            (hi - expect_hi).abs().max_element() < 1e-9 && (lo - expect_lo).abs().max_element() < 1e-9,
            "{lo} {hi}"
        );
        // Counts from the JSON alone agree.
        let json: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let c = crate::estimate::gltf_counts(&json);
        assert_eq!((c.triangles(), c.prototype_triangles, c.instances), (6 * 63_720, 63_720, 102));
        assert!(matches!(
            write_grid_layout(&src, dir.path(), [0, 2], 10.0),
            Err(SceneError::NonFinite { .. })
        ));
        // Too many nodes: refused in one line, nothing written.
        let big = dir.path().join("big");
        let e = write_grid_layout(&src, &big, [100_000, 100_000], 10.0).unwrap_err().to_string();
        assert!(e.contains("more than the 2097152 a layout may have") && !e.contains('\n'), "{e}");
        assert!(!big.exists());
    }
}
