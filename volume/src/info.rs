//! What a volume file holds, as one JSON description (`lightvol info --json`): the grid in
//! the scene file's frame, the SH layout, the bake metadata, the zero-weight nodes, the
//! memory at run time (\[Oat05\], "GPU Memory Requirements": 3 n² floats per sample, four
//! times that with gradients), the validity mask, and for an octree (\[Oat05\], "Adaptive
//! Octree Subdivision") its parameters, level histogram and memory against the uniform grid
//! of its finest level.

use std::path::Path;

use serde::Serialize;
use serde_json::{Value, json};

use crate::adaptive::AdaptiveVolume;
use crate::encode::Encoding;
use crate::error::VolumeError;
use crate::field::{AnyVolume, open};
use crate::io::sidecar::Sidecar;
use crate::reach::NodeReach;
use crate::validity::ValidityMask;
use crate::volume::{floats_per_sample, sample_bytes};

/// The SH convention every description states.
pub const SH_CONVENTION: &str = "real orthonormal, index l(l+1)+m, no Condon-Shortley phase, +z polar";

/// One row of \[Oat05\]'s floats-per-sample table.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct FloatsRow {
    /// SH order (bands).
    pub order: usize,
    /// Floats per sample without gradients (`3 n²`).
    pub floats: usize,
    /// Floats per sample with gradients (`4 · 3 n²`).
    pub floats_with_gradients: usize,
}

/// \[Oat05\]'s "GPU Memory Requirements" rows for orders 3 and 6, and for `extra_order` (the
/// file's), computed from [`floats_per_sample`].
#[must_use]
pub fn floats_table(extra_order: usize) -> Vec<FloatsRow> {
    let mut orders = vec![3, 6];
    if !orders.contains(&extra_order) {
        orders.insert(0, extra_order);
    }
    orders
        .into_iter()
        .map(|n| FloatsRow {
            order: n,
            floats: floats_per_sample(n, false),
            floats_with_gradients: floats_per_sample(n, true),
        })
        .collect()
}

/// Run-time bytes of the uniform grid at the octree's finest resolution ([`sample_bytes`]).
#[must_use]
pub fn finest_uniform_bytes(vol: &AdaptiveVolume) -> usize {
    let nodes = vol.finest_res().iter().map(|&n| n as usize).product::<usize>();
    sample_bytes(nodes, vol.base().bands(), false)
}

/// The octree section of a description and of the JSON export.
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

/// The description of a brick volume: its layout and memory ([`crate::bricks`]).
fn describe_bricks(vol: &crate::bricks::BrickVolume, path: &Path) -> Value {
    json!({
        "kind": "bricks",
        "file": described_file_name(path),
        "coeffs": vol.coeffs(),
        "brick_cells": vol.brick_cells(),
        "brick_probes": vol.brick_probes(),
        "finest_level": vol.finest_level(),
        "bricks": vol.bricks().len(),
        "bricks_per_level": vol.bricks_per_level(),
        "stream_cells": vol.stream_cells().len(),
        "indirection_res": vol.indirection_res(),
        "probe_bytes": vol.probe_bytes(),
        "indirection_bytes": vol.indirection_bytes(),
        "metadata": vol.metadata(),
    })
}

/// The description of `vol`, read from `path` (`"kind"`: `uniform`, `adaptive` or `bricks`).
///
/// # Errors
/// [`VolumeError`] when the grid cannot be expressed in the file's frame.
pub fn describe(vol: &AnyVolume, path: &Path) -> Result<Value, VolumeError> {
    let (vol, grads) = match vol {
        AnyVolume::Adaptive(vol) => return describe_adaptive(vol, path),
        AnyVolume::Bricks(vol) => return Ok(describe_bricks(vol, path)),
        AnyVolume::Uniform(vol) => (vol, None),
        AnyVolume::Gradient(g) => (&g.volume, Some(&g.gradients)),
    };
    let has_grads = grads.is_some();
    let floats = floats_per_sample(vol.bands(), has_grads);
    // Coordinates in the scene file's frame (the file stores the internal one).
    let frame = vol.metadata().frame;
    let spec = &crate::frame::grid_in_file_frame(vol.spec(), frame)?;
    let (min, max) = spec.bounds();
    let zero_weight = vol.weights().iter().filter(|&&w| w == 0.0).count();
    let mask_bytes = vol.validity().map_or(0, ValidityMask::memory_bytes);
    let validity =
        vol.validity().map(|m| json!({ "invalid_nodes": m.invalid_count(), "memory_bytes": mask_bytes }));
    let reach_bytes = vol.reach().map_or(0, NodeReach::memory_bytes);
    let reach =
        vol.reach().map(|r| json!({ "limited_nodes": r.limited_count(), "memory_bytes": reach_bytes }));
    Ok(json!({
        "file": path.display().to_string(),
        "kind": "uniform",
        "grid": { "frame": frame, "res": spec.res(), "bounds": [min, max], "cell_size": spec.cell_size(),
                  "nodes": spec.node_count(), "placement": spec.placement().map(|p| p.to_world_matrix()) },
        "sh": { "coeffs": vol.coeffs(), "bands": vol.bands(),
                "convention": SH_CONVENTION,
                "frame": "z-up (lightvol's internal frame; exports are in the grid's frame)",
                "quantity": "incident radiance" },
        "bake": vol.metadata(),
        "zero_weight_nodes": zero_weight,
        "memory_bytes": vol.memory_bytes(),
        "gradients": has_grads,
        "validity": validity,
        "reach": reach,
        "memory": { "floats_per_node": floats, "bytes_per_node": floats * 4,
                    "runtime_bytes": sample_bytes(vol.spec().node_count(), vol.bands(), has_grads) + mask_bytes + reach_bytes,
                    "gradient_bytes": grads.as_ref().map_or(0, |g| g.memory_bytes()),
                    "floats_per_sample_by_order": floats_table(vol.bands()) },
    }))
}

/// [`describe`] of the file at `path` ([`crate::open`]).
///
/// # Errors
/// [`VolumeError`]: the file cannot be read, or its grid not expressed in its frame.
pub fn describe_file(path: &Path) -> Result<Value, VolumeError> {
    describe(&open(path)?, path)
}

fn describe_adaptive(vol: &AdaptiveVolume, path: &Path) -> Result<Value, VolumeError> {
    let base = vol.base();
    // The base grid in the scene file's frame (the file stores the internal one).
    let frame = vol.metadata().frame;
    let spec = &crate::frame::grid_in_file_frame(base.spec(), frame)?;
    let (min, max) = spec.bounds();
    Ok(json!({
        "file": path.display().to_string(),
        "kind": "adaptive",
        "grid": { "frame": frame, "res": spec.res(), "bounds": [min, max], "cell_size": spec.cell_size(),
                  "nodes": spec.node_count(), "placement": spec.placement().map(|p| p.to_world_matrix()) },
        "sh": { "coeffs": base.coeffs(), "bands": base.bands(),
                "convention": SH_CONVENTION,
                "quantity": "incident radiance" },
        "bake": vol.metadata(),
        "zero_weight_nodes": base.weights().iter().filter(|&&w| w == 0.0).count(),
        "memory_bytes": vol.memory_bytes(),
        "gradients": false,
        "octree": octree_json(vol),
    }))
}

/// The JSON export of an octree: the base grid's sidecar (naming the native file at
/// `source`) plus the octree section ([`octree_json`]); the octree itself stays in the
/// native EXR.
///
/// # Errors
/// [`VolumeError`] when the sidecar cannot be serialized.
pub fn adaptive_export_json(vol: &AdaptiveVolume, source: &Path) -> Result<Value, VolumeError> {
    let sc = Sidecar::describe(
        vol.base(),
        Encoding::F32,
        described_file_name(source),
        "native-exr-adaptive: base grid parts sh00.. and weight, plus octreeNN (fine surpluses) and splitNN parts",
    );
    let mut v = serde_json::to_value(&sc).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
    if let Value::Object(m) = &mut v {
        m.insert("octree".into(), octree_json(vol));
    }
    Ok(v)
}

/// The sidecar's `storage.file` for the volume at `source`: its file name, without the
/// directories (the sidecar describes the file beside it), so that exports of one volume
/// are the same bytes wherever it lies and no local path is stored.
#[must_use]
pub fn described_file_name(source: &Path) -> Option<String> {
    source.file_name().map(|n| n.to_string_lossy().into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// \[Oat05\]'s table, from its definition: RGB SH of order n has 3 n² floats, and every
    /// coefficient's gradient adds 3 more per float (4 × in all). Order 3: 27 / 108;
    /// order 6: 108 / 432.
    #[test]
    fn floats_table_matches_the_definition() {
        let t = floats_table(3);
        assert_eq!(t.len(), 2);
        for r in &t {
            let sh = 3 * r.order * r.order;
            assert_eq!(r.floats, sh);
            assert_eq!(r.floats_with_gradients, sh + 3 * sh);
        }
        assert_eq!((t[0].floats, t[0].floats_with_gradients), (27, 108));
        assert_eq!((t[1].floats, t[1].floats_with_gradients), (108, 432));
        assert_eq!(floats_table(2)[0].floats, 12);
    }

    #[test]
    fn file_names_drop_the_directories() {
        assert_eq!(described_file_name(Path::new("/a/b/vol.exr")).as_deref(), Some("vol.exr"));
        assert_eq!(described_file_name(Path::new("/")), None);
    }
}
