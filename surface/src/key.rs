//! Where a lightmap bake came from: the text of every setting that changes its maps, hashed
//! with the scene's geometry (`lightvol_scene::fingerprint::scene_hash`) so that texel shards
//! of one bake recognise each other and shards of another bake are refused.

use lightvol_scene::fingerprint::{VERSION, lighting_fingerprint};
use lightvol_scene::{Scene, TransportSettings};

/// The settings text of a surface bake: its settings' debug text, the lighting
/// fingerprint ([`lighting_fingerprint`]), and the lightvol [`VERSION`].
#[must_use]
pub fn surface_key(scene: &Scene, settings: &impl std::fmt::Debug, transport: &TransportSettings) -> String {
    format!("{settings:?} {} lightvol={VERSION}", lighting_fingerprint(scene, transport))
}
