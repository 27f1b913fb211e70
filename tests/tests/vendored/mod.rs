//! The vendored real scenes (`data/scenes`), for the tests that run every one of them.

use std::path::{Path, PathBuf};

/// Every vendored real scene, relative to `data/scenes`.
pub const VENDORED_SCENES: [&str; 5] = [
    "breakfast_room/BreakfastRoom.gltf",
    "occlusion_room/room.glb",
    "living_room/living_room.glb",
    "zdm2/zdm2.glb",
    "cornell_original/CornellBox-Original.obj",
];

/// The path of vendored scene `rel` ([`VENDORED_SCENES`]).
pub fn vendored(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes").join(rel)
}
