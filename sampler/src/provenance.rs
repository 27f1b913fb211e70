//! Where a baked volume came from: the text of every setting that changes the result
//! ([`bake_key`]), hashed with the scene's geometry ([`scene_hash`]) so that shards of one
//! bake recognise each other and files of another bake are refused, and the
//! [`BakeMetadata`] every volume file carries.

use lightvol_core::samples::Samples;
use lightvol_volume::{BakeMetadata, GridSpec};

use crate::adaptive::AdaptiveSettings;
use lightvol_scene::fingerprint::{VERSION, lighting_fingerprint, scene_hash};
use lightvol_scene::{Scene, TransportSettings, UpAxis};

/// The settings text of a volume bake: the grid, the method label, samples, coefficients,
/// the path settings and the lighting fingerprint ([`lighting_fingerprint`]), the adaptive
/// settings of an octree bake, and the lightvol [`VERSION`].
#[must_use]
pub fn bake_key(
    scene: &Scene,
    grid: &GridSpec,
    label: &str,
    samples: Samples,
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

/// The metadata of a volume baked from `scene` (in the file frame `frame`) under the method
/// name `label`, keyed by [`bake_key`] ([`scene_hash`] of it): `sampling_rays` traced,
/// `seed`, shard `(k, n)`; callers add the typed record of its settings
/// ([`BakeRequest::record`](crate::request::BakeRequest::record)) as `settings`.
#[must_use]
pub fn bake_metadata(
    scene: &Scene,
    frame: UpAxis,
    key: &str,
    label: &str,
    sampling_rays: u64,
    seed: u64,
    shard: (u32, u32),
) -> BakeMetadata {
    BakeMetadata {
        method: label.to_owned(),
        sampling_rays,
        seed,
        shard_index: shard.0,
        shard_count: shard.1,
        scene_hash: scene_hash(scene, key),
        units: "relative".into(),
        frame,
        settings: None,
    }
}
