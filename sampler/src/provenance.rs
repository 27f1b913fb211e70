//! Where a baked file came from: a short stable hash of the scene geometry and of every
//! setting that changes the result ([`scene_hash`], [`bake_key`], [`surface_key`]), so that
//! shards of one bake recognise each other and files of another bake are refused, and the
//! [`BakeMetadata`] every volume file carries.
//!
//! The hash is FNV-1a ([`lightvol_core::hash`]) over the triangle vertices, the instance
//! placements and the settings' text. It identifies a bake; it is not a checksum of the
//! file.

use lightvol_core::hash::Fnv1a;
use lightvol_volume::{BakeMetadata, GridSpec};

use crate::adaptive::AdaptiveSettings;
use crate::surface::lighting_fingerprint;
use crate::{Scene, TransportSettings, UpAxis};

/// The lightvol version written into every key: a file baked by another version is
/// another bake.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// FNV-1a over the geometry of `scene` (every stored triangle's vertices, every instance's
/// prototype and placement, as little-endian f64) followed by `extra`, as 16 hex digits.
#[must_use]
pub fn scene_hash(scene: &Scene, extra: &str) -> String {
    let mut h = Fnv1a::default();
    for t in scene.triangles.iter().chain(scene.prototypes.iter().flat_map(|p| &p.triangles)) {
        for v in t.v {
            for c in v.to_array() {
                h.write(&c.to_le_bytes());
            }
        }
    }
    for i in &scene.instances {
        h.write(&i.prototype.to_le_bytes());
        for c in i.to_world.to_cols_array() {
            h.write(&c.to_le_bytes());
        }
    }
    h.write(extra.as_bytes());
    format!("{:016x}", h.finish())
}

/// The settings text of a volume bake: the grid, the method label, samples, coefficients,
/// the path settings and the lighting fingerprint ([`lighting_fingerprint`]), the adaptive
/// settings of an octree bake, and [`VERSION`].
#[must_use]
pub fn bake_key(
    scene: &Scene,
    grid: &GridSpec,
    label: &str,
    samples: u32,
    coeffs: usize,
    transport: &TransportSettings,
    adaptive: Option<&AdaptiveSettings>,
) -> String {
    let adaptive = adaptive.map_or_else(String::new, |a| format!(" {a:?}"));
    format!(
        "{:?} {:?} {label} {samples} coeffs={coeffs} bounces={} {}{adaptive} lightvol={VERSION}",
        grid.bounds(),
        grid.res(),
        transport.label(),
        lighting_fingerprint(scene, transport),
    )
}

/// The settings text of a surface bake: its settings' debug text, the lighting
/// fingerprint, and [`VERSION`].
#[must_use]
pub fn surface_key(scene: &Scene, settings: &impl std::fmt::Debug, transport: &TransportSettings) -> String {
    format!("{settings:?} {} lightvol={VERSION}", lighting_fingerprint(scene, transport))
}

/// The metadata of a volume baked from `scene` (in the file frame `frame`) under the method
/// name `label`, keyed by [`bake_key`] ([`scene_hash`] of it): `samples` sampling rays,
/// `seed`, shard `(k, n)`; callers add the typed record of its settings
/// ([`BakeRequest::record`](crate::request::BakeRequest::record)) as `settings`.
#[must_use]
pub fn bake_metadata(
    scene: &Scene,
    frame: UpAxis,
    key: &str,
    label: &str,
    samples: u64,
    seed: u64,
    shard: (u32, u32),
) -> BakeMetadata {
    BakeMetadata {
        method: label.to_owned(),
        samples,
        seed,
        shard_index: shard.0,
        shard_count: shard.1,
        scene_hash: scene_hash(scene, key),
        units: "relative".into(),
        frame,
        settings: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hash_is_fnv1a_of_the_vertices_then_the_text() {
        // The same bytes laid out in one buffer and hashed at once.
        let maze = crate::builtin("maze").unwrap().scene;
        assert!(maze.instances.is_empty() && maze.prototypes.is_empty());
        let mut bytes: Vec<u8> = maze
            .triangles
            .iter()
            .flat_map(|t| t.v)
            .flat_map(|v| v.to_array())
            .flat_map(f64::to_le_bytes)
            .collect();
        bytes.extend_from_slice(b"key");
        assert_eq!(scene_hash(&maze, "key"), format!("{:016x}", lightvol_core::hash::fnv1a(&bytes)));
        assert_ne!(scene_hash(&maze, "key"), scene_hash(&maze, "kez"));
    }
}
