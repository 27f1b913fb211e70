//! Structure-aware fuzzing of the glTF loader ([`load_gltf_slice`]).
//!
//! Requirement: 1,000 proptest mutations of a real glTF's JSON and of a GLB's bytes give
//! `Ok` or a one-line error, never a panic or an abort. Two properties run [`JSON_CASES`] +
//! [`GLB_CASES`] = 1,000 cases from a fixed ChaCha seed ([`SEED`]), so a run and its failures
//! reproduce exactly; nothing is persisted between runs.
//!
//! **What is mutated, and why.** The loader is driven by the JSON: every index, offset,
//! count and stride in it decides what is read and how much is allocated, so most mutations
//! are structural edits of the JSON tree rather than random bytes, which would mostly stop
//! at the JSON parser.
//! - `data/scenes/breakfast_room/BreakfastRoom.gltf`, whole (34 nodes, 14 meshes, 64
//!   accessors, 14 materials, cameras, textures, `extensionsUsed`) except that every
//!   primitive is cut to its first [`TRIANGLES_PER_PRIMITIVE`] triangles, the buffer rebuilt
//!   with the same layout (one interleaved vertex view of stride 32, one index view) and
//!   embedded as a `data:` URI, and the three raster images replaced by a 1×1 PNG `data:`
//!   URI: a load takes milliseconds instead of loading 262k triangles and 2 MB of JPEG each
//!   time, through the same code. Files are read relative to the scene's folder, so a
//!   mutated URI can name the real `.bin`, a real JPEG, a missing file or `/dev/zero`.
//! - `data/scenes/living_room/living_room.glb` (5k triangles), split into its chunks.
//!
//! **JSON mutations** ([`JsonMutation`], 1 to [`MAX_MUTATIONS`] per document): a field of a
//! glTF object chosen by what the object is ([`FIELDS`]: `count`, `byteOffset`,
//! `byteLength`, `byteStride`, `componentType`, `type`, `bufferView`, `sparse`, `mode`,
//! `indices`, `children`, `matrix`, `uri`, `extensionsRequired`, ...) set to a value of its
//! kind pushed to an extreme (0, -1, 2^27/3 at the loader's accessor cap, 4294967295, 2^53,
//! u64::MAX, 1e308, indices just past the end) or to a value of the wrong type; any value
//! replaced, deleted, nudged (±1, ×2^20, negated, turned into a string) or copied over
//! another; nodes linked into cycles, self-loops and shared children; array elements
//! duplicated up to 64 times (primitives and nodes sharing accessors); accessors stripped of
//! their buffer view with a large count (zeros the file does not store); `data:` URIs
//! truncated or given bad base64; a number token of the text rewritten (`1e999`, `NaN`), the
//! text cut or a byte inserted; words of the binary buffer set to NaN, infinity or
//! out-of-range indices. Values include arrays nested past serde_json's limit, strings with
//! line breaks (errors that quote names must stay one line), sparse blocks, extension
//! objects (`KHR_lights_punctual`, `EXT_mesh_gpu_instancing`, `KHR_texture_transform`,
//! Draco) and unknown required extensions.
//!
//! **GLB mutations** ([`GlbCase`]): the JSON chunk mutated as above and re-packed into a
//! valid container (so that the mutation reaches the loader, not only the header check),
//! words of the BIN chunk overwritten, the chunk layout changed (no BIN, BIN first, two JSON
//! chunks, an unknown chunk, unpadded JSON, trailing bytes), then bytes flipped in the
//! header, the JSON or the BIN, the file truncated, and the magic, version, length and chunk
//! length/type words set to extremes (0, u32::MAX, off by one).
//!
//! **Checks per case.** The call returns (a panic fails the case: proptest catches it and
//! shrinks the input); an `Err` displays as one non-empty line; an `Ok` scene has finite
//! vertices, lights and cameras; the load's peak resident memory stays under
//! [`CASE_MEMORY_BUDGET`] plus [`BYTES_PER_TRIANGLE`] per triangle it returns, i.e. memory is
//! explained by the scene the file describes. The two failures proptest cannot catch, a load
//! that would exhaust memory and a load that never ends, are turned into a test failure
//! that prints the case by a watchdog thread ([`HARD_MEMORY_LIMIT`] on the resident size,
//! [`CASE_TIME_LIMIT`]; see `common::status_bytes`).
//!
//! A valid file can still describe a scene too large for memory (`EXT_mesh_gpu_instancing`
//! over a large stored accessor multiplies a mesh thousands of times); the loader flattens
//! what it is given, and such a case, should a seed produce one, is a scene-size question
//! rather than a parsing bug.

use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap};
use std::fmt::Debug;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, Once, OnceLock};
use std::time::{Duration, Instant};

#[path = "../common/mod.rs"]
mod common;
mod fixtures;
mod glb;
mod guard;
mod mutations;
mod paths;
mod running;
mod values;

use common::{reset_peak, status_bytes};
use fixtures::*;
use glb::*;
use guard::*;
use mutations::*;
use paths::*;
use running::*;
use values::*;

use lightvol_scene::load::gltf::load_gltf_slice;
use lightvol_scene::{LoadOptions, PunctualLight};
use proptest::prelude::*;
use proptest::sample::{Index, select};
use proptest::test_runner::{Config, RngAlgorithm, TestCaseResult, TestRng, TestRunner};
use serde_json::{Map, Value, json};

/// Cases of the `.gltf` JSON property.
pub(crate) const JSON_CASES: u32 = 500;
/// Cases of the `.glb` property.
pub(crate) const GLB_CASES: u32 = 500;
/// The ChaCha seed of both properties (32 bytes).
pub(crate) const SEED: &[u8; 32] = b"lightvol glTF loader fuzz seed 1";
/// Triangles kept per primitive of the breakfast room.
pub(crate) const TRIANGLES_PER_PRIMITIVE: usize = 8;
/// Most JSON mutations applied to one document.
pub(crate) const MAX_MUTATIONS: usize = 4;
/// Most heap one case may hold at once beyond what was live before it (the fixtures load in
/// a few MiB; an input the loader lets allocate more is a finding).
pub(crate) const CASE_MEMORY_BUDGET: usize = 256 << 20;
/// What each triangle of a loaded scene may add to [`CASE_MEMORY_BUDGET`] (one costs about
/// 360 bytes at the loader's peak: vertices, face, triangle, reference).
pub(crate) const BYTES_PER_TRIANGLE: usize = 1024;
/// Live heap past which the process stops with the case printed instead of exhausting memory.
pub(crate) const HARD_MEMORY_LIMIT: usize = 1536 << 20;
/// A case running longer than this is a hang: the process stops with the case printed.
pub(crate) const CASE_TIME_LIMIT: Duration = Duration::from_secs(60);
/// The loader's cap on one accessor's values (`load::gltf::accessor::MAX_ACCESSOR_VALUES`),
/// for counts just under and over it.
pub(crate) const MAX_ACCESSOR_VALUES: u64 = 1 << 27;
/// Stands for the (mutated) binary buffer's `data:` URI until the document is serialized.
pub(crate) const BIN_PLACEHOLDER: &str = "@BIN@";
/// A valid 1×1 grey-alpha PNG.
pub(crate) const TINY_PNG: &str = "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAQAAAC1HAwCAAAAC0lEQVR42mNkYAAAAAYAAjCB0C8AAAAASUVORK5CYII=";

/// The trimmed breakfast room loads as it is, with the triangles kept.
#[test]
fn breakfast_room_fixture_loads() {
    let _serial = SERIAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let (f, kept) = breakfast_room();
    let (text, _) = mutated(&f, &[], &[], None);
    let scene = load_gltf_slice(&text, Some(&f.base), "fixture", &LoadOptions::default())
        .expect("trimmed document loads");
    assert_eq!(scene.report.unique_triangles, kept);
    assert_eq!(scene.cameras.len(), 3);
    assert_eq!(scene.textures.len(), 3, "the three base-colour textures decode");
}

/// [`JSON_CASES`] mutations of the breakfast room's JSON (and of its embedded buffer).
#[test]
fn mutated_gltf_json_is_ok_or_one_line_error() {
    watchdog();
    let _serial = SERIAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let (f, _) = breakfast_room();
    run("gltf JSON", JSON_CASES, json_case(), |case, outcomes| {
        let (text, _) = mutated(&f, &case.json, &case.bin, case.text.as_ref());
        outcomes.record(&check(&text, &f.base, &case)?);
        Ok(())
    });
}

/// [`GLB_CASES`] mutations of the living room GLB: its JSON chunk, its BIN chunk, its chunk
/// layout and its bytes.
#[test]
fn mutated_glb_is_ok_or_one_line_error() {
    watchdog();
    let _serial = SERIAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let f = living_room();
    let unmutated =
        GlbCase { json: vec![], bin: vec![], text: None, layout: Layout::Standard, bytes: vec![] };
    let triangles =
        load_gltf_slice(&glb_bytes(&f, &unmutated), Some(&f.base), "fixture", &LoadOptions::default())
            .expect("the re-packed GLB loads")
            .report
            .unique_triangles;
    assert!(triangles > 4000, "{triangles} triangles");
    run("GLB", GLB_CASES, glb_case(), |case, outcomes| {
        let bytes = glb_bytes(&f, &case);
        outcomes.record(&check(&bytes, &f.base, &case)?);
        Ok(())
    });
}
