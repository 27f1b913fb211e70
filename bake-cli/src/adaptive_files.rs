//! Adaptive (octree) volume files in the file verbs (\[Oat05\], "Adaptive Octree
//! Subdivision"): what `info` prints about them, how `export` writes them, and why `merge`
//! refuses them.
//!
//! - `info`: the base grid, the octree parameters, the level histogram (cells, leaves,
//!   split cells, created / stored / culled nodes per level) and the memory
//!   (`AdaptiveVolume::memory_bytes`: coefficients, base weights, one 8-byte key per fine
//!   node, split bitmaps) against the uniform grid of the finest level.
//! - `export --format json`: the sidecar of the base grid plus an `octree` section; the
//!   octree itself stays in the native EXR the sidecar names (JSON holds the description,
//!   the EXR the data).
//! - `export --format ktx2|dds|bevy`: these formats hold one uniform grid, so the octree is
//!   resampled (`AdaptiveVolume::to_uniform`: the exact f64 lookup at every node, rounded
//!   to f32) at `--res NX,NY,NZ`, by default the finest level's resolution, which
//!   reproduces every finest-level node exactly. The resolution is printed.
//! - `merge`: an adaptive volume is refused with a clear error; sharded adaptive bakes are
//!   assembled level by level by `bake --adaptive --from-shards` instead.

use std::path::Path;

use anyhow::Context;
use lightvol_volume::encode::Encoding;
use lightvol_volume::gradient::sample_bytes;
use lightvol_volume::io::sidecar::Sidecar;
use lightvol_volume::{AdaptiveVolume, IrradianceVolume};
use serde_json::{Value, json};

/// Run-time bytes of the uniform grid at the finest level's resolution (3 n² floats per
/// node, \[Oat05\] "GPU Memory Requirements (Constant Store)", as
/// `lightvol_volume::gradient::sample_bytes` counts them), for comparison in `info`.
#[must_use]
pub fn finest_uniform_bytes(vol: &AdaptiveVolume) -> usize {
    let nodes = vol.finest_res().iter().map(|&n| n as usize).product::<usize>();
    sample_bytes(nodes, vol.base().bands(), false)
}

/// The octree section of `info --json` and of the JSON export.
#[must_use]
pub fn octree_json(vol: &AdaptiveVolume) -> Value {
    let p = vol.params();
    json!({
        "min_level": p.min_level,
        "max_level": p.max_level,
        "levels_used": vol.max_level(),
        "cull_tolerance": p.cull_tolerance,
        "memory_budget": p.memory_budget,
        "value_scale": vol.value_scale(),
        "finest_res": vol.finest_res(),
        "stored_nodes": vol.stored_nodes(),
        "levels": vol.level_stats(),
        "memory_bytes": vol.memory_bytes(),
        "index_bytes": vol.index_bytes(),
        "finest_uniform_bytes": finest_uniform_bytes(vol),
        "representation": "hierarchical surpluses on nested grids: level l has (n-1)*2^l+1 nodes per axis; lookup = sum over levels of the trilinear interpolation of the level's stored surpluses",
    })
}

/// `info --json` of an adaptive file.
pub fn describe(vol: &AdaptiveVolume, path: &Path) -> anyhow::Result<Value> {
    let base = vol.base();
    // The base grid in the scene file's frame (the file stores the internal one).
    let frame = vol.metadata().frame;
    let spec = &lightvol_volume::frame::grid_in_file_frame(base.spec(), frame)
        .with_context(|| format!("{}: grid in the {} frame", path.display(), frame.name()))?;
    let (min, max) = spec.bounds();
    Ok(json!({
        "file": path.display().to_string(),
        "kind": "adaptive",
        "grid": { "frame": frame, "res": spec.res(), "bounds": [min, max], "cell_size": spec.cell_size(),
                  "nodes": spec.node_count(), "placement": spec.placement().map(|p| p.to_world_matrix()) },
        "sh": { "coeffs": base.coeffs(), "bands": base.bands(),
                "convention": "real orthonormal, index l(l+1)+m, no Condon-Shortley phase, +z polar",
                "quantity": "incident radiance" },
        "bake": vol.metadata(),
        "zero_weight_nodes": base.weights().iter().filter(|&&w| w == 0.0).count(),
        "memory_bytes": vol.memory_bytes(),
        "gradients": false,
        "octree": octree_json(vol),
    }))
}

/// The text lines `info` prints for the octree section.
pub fn print_octree(info: &Value) {
    let o = &info["octree"];
    println!(
        "octree      levels {}..{} (finest used {}), cull tolerance {} x value scale {:.4}, budget {}",
        o["min_level"],
        o["max_level"],
        o["levels_used"],
        o["cull_tolerance"],
        o["value_scale"].as_f64().unwrap_or(f64::NAN),
        o["memory_budget"].as_u64().map_or_else(|| "none".to_owned(), |b| format!("{b} bytes"))
    );
    println!("            level    cells   leaves    split  created   stored   culled    empty");
    for l in o["levels"].as_array().into_iter().flatten() {
        let n = |k: &str| l[k].as_u64().unwrap_or(0);
        println!(
            "            {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}",
            n("level"),
            n("cells"),
            n("leaves"),
            n("split"),
            n("created_nodes"),
            n("stored_nodes"),
            n("culled_nodes"),
            n("empty_nodes")
        );
    }
    let r = &o["finest_res"];
    println!(
        "memory      {} bytes ({} stored nodes: coefficients, base weights, 8-byte keys, split bitmaps; lookup index {} bytes more); uniform {}x{}x{} grid of the finest level: {} bytes",
        o["memory_bytes"], o["stored_nodes"], o["index_bytes"], r[0], r[1], r[2], o["finest_uniform_bytes"]
    );
}

/// The JSON export: the base grid's sidecar (naming the native file) plus the octree
/// section.
pub fn export_json(vol: &AdaptiveVolume, source: &Path) -> anyhow::Result<Value> {
    let sc = Sidecar::describe(
        vol.base(),
        Encoding::F32,
        described_file_name(source),
        "native-exr-adaptive: base grid parts sh00.. and weight, plus octreeNN (fine surpluses) and splitNN parts",
    );
    let mut v = serde_json::to_value(&sc)?;
    if let Value::Object(m) = &mut v {
        m.insert("octree".into(), octree_json(vol));
    }
    Ok(v)
}

/// The sidecar's `storage.file` for the volume at `source`: its file name, without the
/// directories (the sidecar describes the file beside it, as the DDS export's does), so that
/// exports of one volume are the same bytes wherever it lies and no local path is stored.
#[must_use]
pub fn described_file_name(source: &Path) -> Option<String> {
    source.file_name().map(|n| n.to_string_lossy().into_owned())
}

/// Resamples for a uniform-only format at `res` (default: the finest level's), returning
/// the volume and the resolution used.
pub fn resample(vol: &AdaptiveVolume, res: Option<[u32; 3]>) -> anyhow::Result<(IrradianceVolume, [u32; 3])> {
    let res = res.unwrap_or_else(|| vol.finest_res());
    let uniform = vol.to_uniform(Some(res)).context("resampling the adaptive volume")?;
    Ok((uniform, res))
}
