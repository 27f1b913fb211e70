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

mod common;

use common::{reset_peak, status_bytes};
use lightvol_scene::load::gltf::load_gltf_slice;
use lightvol_scene::{LoadOptions, PunctualLight};
use proptest::prelude::*;
use proptest::sample::{Index, select};
use proptest::test_runner::{Config, RngAlgorithm, TestCaseResult, TestRng, TestRunner};
use serde_json::{Map, Value, json};

/// Cases of the `.gltf` JSON property.
const JSON_CASES: u32 = 500;
/// Cases of the `.glb` property.
const GLB_CASES: u32 = 500;
/// The ChaCha seed of both properties (32 bytes).
const SEED: &[u8; 32] = b"lightvol glTF loader fuzz seed 1";
/// Triangles kept per primitive of the breakfast room.
const TRIANGLES_PER_PRIMITIVE: usize = 8;
/// Most JSON mutations applied to one document.
const MAX_MUTATIONS: usize = 4;
/// Most heap one case may hold at once beyond what was live before it (the fixtures load in
/// a few MiB; an input the loader lets allocate more is a finding).
const CASE_MEMORY_BUDGET: usize = 256 << 20;
/// What each triangle of a loaded scene may add to [`CASE_MEMORY_BUDGET`] (one costs about
/// 360 bytes at the loader's peak: vertices, face, triangle, reference).
const BYTES_PER_TRIANGLE: usize = 1024;
/// Live heap past which the process stops with the case printed instead of exhausting memory.
const HARD_MEMORY_LIMIT: usize = 1536 << 20;
/// A case running longer than this is a hang: the process stops with the case printed.
const CASE_TIME_LIMIT: Duration = Duration::from_secs(60);
/// The loader's cap on one accessor's values (`load::gltf::accessor::MAX_ACCESSOR_VALUES`),
/// for counts just under and over it.
const MAX_ACCESSOR_VALUES: u64 = 1 << 27;
/// Stands for the (mutated) binary buffer's `data:` URI until the document is serialized.
const BIN_PLACEHOLDER: &str = "@BIN@";
/// A valid 1×1 grey-alpha PNG.
const TINY_PNG: &str = "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAQAAAC1HAwCAAAAC0lEQVR42mNkYAAAAAYAAjCB0C8AAAAASUVORK5CYII=";

// ---------------------------------------------------------------------------------------
// Memory and time guard.

/// The case being run, for the watchdog to print.
static CURRENT_CASE: Mutex<String> = Mutex::new(String::new());
/// When the running case started (nanoseconds since [`epoch`], plus one; 0: none running).
static CASE_STARTED: AtomicU64 = AtomicU64::new(0);
/// The properties share the process's memory figures, so they take turns.
static SERIAL: Mutex<()> = Mutex::new(());

fn epoch() -> Instant {
    static E: OnceLock<Instant> = OnceLock::new();
    *E.get_or_init(Instant::now)
}

fn watchdog() {
    static START: Once = Once::new();
    START.call_once(|| {
        epoch();
        std::thread::spawn(|| {
            loop {
                std::thread::sleep(Duration::from_millis(50));
                let resident = status_bytes("VmRSS:");
                let why = if resident > HARD_MEMORY_LIMIT {
                    format!("holds {} MiB resident (limit {} MiB)", resident >> 20, HARD_MEMORY_LIMIT >> 20)
                } else {
                    match CASE_STARTED.load(Ordering::Relaxed) {
                        0 => continue,
                        t if epoch().elapsed().as_nanos() as u64 + 1 - t
                            > CASE_TIME_LIMIT.as_nanos() as u64 =>
                        {
                            format!("ran longer than {CASE_TIME_LIMIT:?}")
                        }
                        _ => continue,
                    }
                };
                let case = CURRENT_CASE.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone();
                eprintln!("gltf_fuzz: the loader {why}; that is a loader bug. The case:\n{case}");
                std::process::exit(101);
            }
        });
    });
}

/// Marks a case as running until dropped (also when the loader panics).
struct Running;

impl Running {
    fn start(case: &dyn Debug) -> Self {
        *CURRENT_CASE.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = format!("{case:#?}");
        CASE_STARTED.store(epoch().elapsed().as_nanos() as u64 + 1, Ordering::Relaxed);
        Self
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        CASE_STARTED.store(0, Ordering::Relaxed);
    }
}

// ---------------------------------------------------------------------------------------
// Fixtures.

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes")
}

fn u64_of(v: &Value) -> usize {
    v.as_u64().expect("fixture field is an unsigned integer") as usize
}

/// A document to mutate: its JSON, its binary buffer, and the folder its files are read from.
struct Fixture {
    json: Value,
    bin: Vec<u8>,
    base: PathBuf,
}

/// The breakfast room with every primitive cut to its first [`TRIANGLES_PER_PRIMITIVE`]
/// triangles (vertices renumbered, same interleaved layout), the buffer as
/// [`BIN_PLACEHOLDER`] and the raster images as [`TINY_PNG`]. Also returns the number of
/// triangles kept (what the loader reports as `unique_triangles`).
fn breakfast_room() -> (Fixture, usize) {
    let base = scenes_dir().join("breakfast_room");
    let text = std::fs::read(base.join("BreakfastRoom.gltf")).expect("vendored BreakfastRoom.gltf");
    let old = std::fs::read(base.join("BreakfastRoom.bin")).expect("vendored BreakfastRoom.bin");
    let mut json: Value = serde_json::from_slice(&text).expect("BreakfastRoom.gltf is JSON");
    let views = json["bufferViews"].clone();
    assert_eq!(views.as_array().map(Vec::len), Some(2), "one vertex view, one index view");
    let (vertex_view, index_view) = (&views[0], &views[1]);
    let stride = u64_of(&vertex_view["byteStride"]);
    let (mut vertices, mut indices) = (Vec::new(), Vec::new());
    let mut kept = 0;
    let meshes = json["meshes"].as_array().expect("meshes").len();
    for m in 0..meshes {
        let prims = json["meshes"][m]["primitives"].as_array().expect("primitives").len();
        for p in 0..prims {
            let prim = json["meshes"][m]["primitives"][p].clone();
            // Indices: the first triangles, renumbered in order of first use.
            let ia = u64_of(&prim["indices"]);
            let acc = &json["accessors"][ia];
            assert_eq!((acc["componentType"].as_u64(), acc["bufferView"].as_u64()), (Some(5125), Some(1)));
            let at = u64_of(&index_view["byteOffset"]) + acc["byteOffset"].as_u64().unwrap_or(0) as usize;
            let n = u64_of(&acc["count"]).min(3 * TRIANGLES_PER_PRIMITIVE);
            let mut renumber: HashMap<u32, u32> = HashMap::new();
            let mut order = Vec::new();
            let index_start = indices.len();
            for k in 0..n {
                let o = at + 4 * k;
                let v = u32::from_le_bytes(old[o..o + 4].try_into().expect("4 bytes"));
                let next = renumber.len() as u32;
                let new = *renumber.entry(v).or_insert_with(|| {
                    order.push(v);
                    next
                });
                indices.extend_from_slice(&new.to_le_bytes());
            }
            kept += n / 3;
            json["accessors"][ia]["byteOffset"] = json!(index_start);
            json["accessors"][ia]["count"] = json!(n);
            // Attributes: the used vertices, each attribute at its old offset within the stride.
            let attrs: Vec<usize> =
                prim["attributes"].as_object().expect("attributes").values().map(u64_of).collect();
            let first =
                attrs.iter().map(|&a| u64_of(&json["accessors"][a]["byteOffset"])).min().expect("attributes");
            let vertex_start = vertices.len();
            vertices.resize(vertex_start + order.len() * stride, 0);
            for &a in &attrs {
                let acc = &json["accessors"][a];
                assert_eq!(
                    (acc["componentType"].as_u64(), acc["bufferView"].as_u64()),
                    (Some(5126), Some(0))
                );
                let components = match acc["type"].as_str() {
                    Some("VEC2") => 2,
                    Some("VEC3") => 3,
                    Some("VEC4") => 4,
                    t => panic!("attribute type {t:?}"),
                };
                let rel = u64_of(&acc["byteOffset"]) - first;
                assert!(rel + 4 * components <= stride);
                let mut lo = vec![f64::INFINITY; components];
                let mut hi = vec![f64::NEG_INFINITY; components];
                for (new, &old_v) in order.iter().enumerate() {
                    let src = u64_of(&vertex_view["byteOffset"])
                        + u64_of(&acc["byteOffset"])
                        + old_v as usize * stride;
                    let dst = vertex_start + rel + new * stride;
                    vertices[dst..dst + 4 * components].copy_from_slice(&old[src..src + 4 * components]);
                    for c in 0..components {
                        let x = f64::from(f32::from_le_bytes(
                            old[src + 4 * c..src + 4 * c + 4].try_into().expect("4 bytes"),
                        ));
                        lo[c] = lo[c].min(x);
                        hi[c] = hi[c].max(x);
                    }
                }
                let acc = &mut json["accessors"][a];
                acc["byteOffset"] = json!(vertex_start + rel);
                acc["count"] = json!(order.len());
                if acc.get("min").is_some() {
                    acc["min"] = json!(lo);
                    acc["max"] = json!(hi);
                }
            }
        }
    }
    json["bufferViews"][0]["byteOffset"] = json!(0);
    json["bufferViews"][0]["byteLength"] = json!(vertices.len());
    json["bufferViews"][1]["byteOffset"] = json!(vertices.len());
    json["bufferViews"][1]["byteLength"] = json!(indices.len());
    vertices.extend_from_slice(&indices);
    json["buffers"] = json!([{"byteLength": vertices.len(), "uri": BIN_PLACEHOLDER}]);
    for image in json["images"].as_array_mut().expect("images") {
        if matches!(image["mimeType"].as_str(), Some("image/jpeg" | "image/png")) {
            image["uri"] = json!(TINY_PNG);
            image["mimeType"] = json!("image/png");
        }
    }
    (Fixture { json, bin: vertices, base }, kept)
}

const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// The living room GLB split into its JSON and BIN chunks.
fn living_room() -> Fixture {
    let base = scenes_dir().join("living_room");
    let glb = std::fs::read(base.join("living_room.glb")).expect("vendored living_room.glb");
    let word = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().expect("4 bytes"));
    assert_eq!(&glb[..4], b"glTF");
    let (mut json, mut bin) = (None, None);
    let mut at = 12;
    while at < glb.len() {
        let (len, kind) = (word(at) as usize, word(at + 4));
        let data = &glb[at + 8..at + 8 + len];
        match kind {
            CHUNK_JSON => json = Some(serde_json::from_slice(data).expect("GLB JSON chunk")),
            CHUNK_BIN => bin = Some(data.to_vec()),
            _ => {}
        }
        at += 8 + len.next_multiple_of(4);
    }
    Fixture { json: json.expect("JSON chunk"), bin: bin.expect("BIN chunk"), base }
}

// ---------------------------------------------------------------------------------------
// Values.

/// Unsigned integers that break index, offset and size arithmetic.
fn adversarial_u64() -> BoxedStrategy<u64> {
    let m = MAX_ACCESSOR_VALUES;
    prop_oneof![
        // Small: mostly valid indices and counts, some just past the end of an array.
        5 => 0u64..=72,
        3 => select(vec![
            96, 127, 128, 255, 256, 4095, 4096, 32767, 65535, 65536, 1 << 20, 1 << 24,
            m / 16, m / 16 + 1, m / 9, m / 4, m / 3, m / 3 + 1, m / 2, m, m + 1,
            (1 << 31) - 1, 1 << 31, u64::from(u32::MAX) - 3, u64::from(u32::MAX), 1 << 32,
            1 << 53, (1 << 53) + 1, i64::MAX as u64, u64::MAX - 7, u64::MAX,
        ]),
        1 => any::<u32>().prop_map(u64::from),
        1 => any::<u64>(),
    ]
    .boxed()
}

fn int_value() -> BoxedStrategy<Value> {
    prop_oneof![
        8 => adversarial_u64().prop_map(Value::from),
        1 => select(vec![-1i64, -2, -3, -4, -32768, i64::from(i32::MIN), i64::MIN]).prop_map(Value::from),
    ]
    .boxed()
}

fn float_value() -> BoxedStrategy<Value> {
    prop_oneof![
        3 => select(vec![
            1e308, -1e308, f64::MAX, f64::MIN, f64::MIN_POSITIVE, 5e-324, -0.0, 0.5, 1.5, -1.5,
            0.999_999, 1e-40, 3.402_823_5e38, 3.5e38, 1e20, 4_294_967_295.5, 9_007_199_254_740_993.0,
            std::f64::consts::PI, 1e-300,
        ])
        .prop_map(Value::from),
        1 => any::<f64>().prop_filter("JSON numbers are finite", |x| x.is_finite()).prop_map(Value::from),
    ]
    .boxed()
}

fn string_value() -> BoxedStrategy<Value> {
    prop_oneof![
        4 => select(vec![
            "", " ", "SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4", "VEC1", "VEC5", "vec3",
            "VEC3 ", "OPAQUE", "MASK", "BLEND", "perspective", "orthographic", "point", "spot",
            "directional", "2.0", "1.0", "0", "-1", "4294967296", "1e308", "NaN", "null",
            "a\nb", "line one\nline two\r\nthree", "\t\n\u{b}\u{c}\r", "\u{0}", "\u{85}\u{2028}x",
            "é日本", "\u{1F600}", "../../../../../../../../etc/passwd", "%", "%00", "\\n",
        ])
        .prop_map(Value::from),
        1 => "[a-z_\n]{0,12}".prop_map(Value::from),
        1 => (1usize..3000).prop_map(|n| Value::from("x".repeat(n))),
    ]
    .boxed()
}

/// `[[[...]]]` nested `depth` deep (serde_json refuses more than 128 levels).
fn deep_array(depth: usize) -> Value {
    let mut v = json!(0);
    for _ in 0..depth {
        v = Value::Array(vec![v]);
    }
    v
}

fn leaf_value() -> BoxedStrategy<Value> {
    prop_oneof![
        6 => int_value(),
        2 => float_value(),
        2 => string_value(),
        1 => any::<bool>().prop_map(Value::Bool),
        1 => Just(Value::Null),
        1 => Just(json!([])),
        1 => Just(json!({})),
        1 => prop_oneof![1usize..=8, 120usize..=200].prop_map(deep_array),
    ]
    .boxed()
}

/// Any value: a leaf, or small arrays and objects of them.
fn any_value() -> BoxedStrategy<Value> {
    let keys = select(vec![
        "bufferView",
        "byteOffset",
        "count",
        "componentType",
        "type",
        "indices",
        "values",
        "attributes",
        "POSITION",
        "mesh",
        "children",
        "uri",
        "byteLength",
        "light",
        "lights",
        "index",
        "extensions",
        "x",
    ]);
    leaf_value()
        .prop_recursive(3, 24, 6, move |inner| {
            prop_oneof![
                prop::collection::vec(inner.clone(), 0..6).prop_map(Value::Array),
                prop::collection::btree_map(keys.clone().prop_map(str::to_owned), inner, 0..4)
                    .prop_map(|m| Value::Object(m.into_iter().collect())),
            ]
        })
        .boxed()
}

/// What a field holds, to generate values of its own kind.
#[derive(Clone, Copy, Debug)]
enum Class {
    Index,
    IndexList,
    Size,
    Stride,
    Component,
    AccessorType,
    Mode,
    Bool,
    Number,
    Numbers(usize),
    Str,
    Uri,
    Sparse,
    SparseRef,
    Extensions,
    ExtensionNames,
    TextureInfo,
    Attributes,
    Array,
    Object,
}

fn index_value() -> BoxedStrategy<Value> {
    prop_oneof![6 => (0u64..=72).prop_map(Value::from), 3 => int_value(), 1 => leaf_value()].boxed()
}

fn index_list() -> BoxedStrategy<Value> {
    prop::collection::vec(
        prop_oneof![8 => (0u64..=40).prop_map(Value::from), 1 => int_value(), 1 => leaf_value()],
        0..8,
    )
    .prop_map(Value::Array)
    .boxed()
}

fn numbers(n: usize) -> BoxedStrategy<Value> {
    let num = prop_oneof![4 => (-4i32..=4).prop_map(Value::from), 4 => float_value(), 1 => int_value(), 1 => leaf_value()];
    prop::collection::vec(num, 0..=n + 2).prop_map(Value::Array).boxed()
}

fn sparse_ref(indices: bool) -> BoxedStrategy<Value> {
    let comp =
        prop_oneof![4 => select(vec![5121u64, 5123, 5125]).prop_map(Value::from), 1 => component_value()];
    (index_value(), prop_oneof![3 => Just(json!(0)), 1 => size_value()], comp, any::<bool>())
        .prop_map(move |(view, offset, comp, with_offset)| {
            let mut o = Map::new();
            o.insert("bufferView".into(), view);
            if with_offset {
                o.insert("byteOffset".into(), offset);
            }
            if indices {
                o.insert("componentType".into(), comp);
            }
            Value::Object(o)
        })
        .boxed()
}

fn sparse_value() -> BoxedStrategy<Value> {
    (
        prop_oneof![3 => (0u64..=64).prop_map(Value::from), 1 => size_value()],
        sparse_ref(true),
        sparse_ref(false),
    )
        .prop_map(|(count, indices, values)| json!({"count": count, "indices": indices, "values": values}))
        .boxed()
}

fn size_value() -> BoxedStrategy<Value> {
    prop_oneof![
        4 => adversarial_u64().prop_map(Value::from),
        2 => (0u64..=4096).prop_map(|x| Value::from(x * 4)),
        1 => int_value(),
        1 => leaf_value(),
    ]
    .boxed()
}

fn component_value() -> BoxedStrategy<Value> {
    prop_oneof![
        4 => select(vec![5120u64, 5121, 5122, 5123, 5124, 5125, 5126, 5130, 5119, 0, 5121 + (1 << 32)]).prop_map(Value::from),
        1 => leaf_value(),
    ]
    .boxed()
}

fn extension_names() -> BoxedStrategy<Value> {
    let name = prop_oneof![
        4 => select(vec![
            "KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_texture_transform",
            "KHR_mesh_quantization", "EXT_mesh_gpu_instancing", "KHR_draco_mesh_compression",
            "EXT_meshopt_compression", "KHR_materials_specular", "MSFT_texture_dds", "KHR_texture_basisu",
            "EXT_texture_webp", "VENDOR_unknown", "", "a\nb",
        ])
        .prop_map(Value::from),
        1 => leaf_value(),
    ];
    prop_oneof![5 => prop::collection::vec(name, 0..5).prop_map(Value::Array), 1 => leaf_value()].boxed()
}

fn extensions_value() -> BoxedStrategy<Value> {
    let light =
        (select(vec!["point", "spot", "directional", "area", ""]), numbers(3), float_value(), float_value())
            .prop_map(|(t, color, intensity, cone)| {
                json!({"type": t, "color": color, "intensity": intensity, "range": 1, "name": "l\nx",
                   "spot": {"innerConeAngle": cone, "outerConeAngle": 0.5}})
            });
    prop_oneof![
        2 => index_value().prop_map(|l| json!({"KHR_lights_punctual": {"light": l}})),
        2 => prop::collection::vec(light, 0..3).prop_map(|l| json!({"KHR_lights_punctual": {"lights": l}})),
        3 => (index_value(), index_value(), index_value(), 0u8..8).prop_map(|(t, r, s, mask)| {
            let mut a = Map::new();
            for (bit, (k, v)) in [("TRANSLATION", t), ("ROTATION", r), ("SCALE", s)].into_iter().enumerate() {
                if mask & (1 << bit) != 0 {
                    a.insert(k.into(), v);
                }
            }
            json!({"EXT_mesh_gpu_instancing": {"attributes": a}})
        }),
        2 => (numbers(2), float_value(), numbers(2), index_value()).prop_map(|(o, r, s, t)| {
            json!({"KHR_texture_transform": {"offset": o, "rotation": r, "scale": s, "texCoord": t}})
        }),
        1 => float_value().prop_map(|s| json!({"KHR_materials_emissive_strength": {"emissiveStrength": s}})),
        1 => (index_value(), index_value()).prop_map(|(v, a)| {
            json!({"KHR_draco_mesh_compression": {"bufferView": v, "attributes": {"POSITION": a}}})
        }),
        1 => any_value(),
    ]
    .boxed()
}

fn uri_value() -> BoxedStrategy<Value> {
    select(vec![
        "data:application/octet-stream;base64,",
        "data:application/octet-stream;base64,AAAA",
        "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA",
        "data:application/octet-stream;base64,!!!!",
        "data:application/octet-stream;base64,A",
        "data:application/octet-stream;base64,====",
        "data:application/octet-stream;base64,QUJD\nREVG",
        "data:application/octet-stream,%00%ff%zz%",
        "data:",
        "data:,",
        "data:;base64",
        "data:image/png;base64,iVBORw0KGgo=",
        "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAQAAAC1HAwCAAAAC0lEQVR42mNkYAAAA",
        TINY_PNG,
        "BreakfastRoom.bin",
        "marble.jpg",
        "tiles.png",
        "missing.bin",
        "",
        "%",
        "%2e%2e/%2e%2e/nope",
        ".",
        "..",
        "http://example.invalid/a.bin",
        "file:///dev/zero",
        "/dev/zero",
        "../../../../../../../../../../dev/zero",
        "/dev/null",
        "/proc/self/status",
    ])
    .prop_map(Value::from)
    .boxed()
}

fn texture_info() -> BoxedStrategy<Value> {
    (index_value(), prop::option::of(index_value()), prop::option::of(extensions_value()))
        .prop_map(|(index, tc, ext)| {
            let mut o = Map::new();
            o.insert("index".into(), index);
            if let Some(tc) = tc {
                o.insert("texCoord".into(), tc);
            }
            if let Some(ext) = ext {
                o.insert("extensions".into(), ext);
            }
            Value::Object(o)
        })
        .boxed()
}

fn attributes_value() -> BoxedStrategy<Value> {
    let name = select(vec![
        "POSITION",
        "NORMAL",
        "TANGENT",
        "TEXCOORD_0",
        "TEXCOORD_1",
        "TEXCOORD_7",
        "COLOR_0",
        "JOINTS_0",
    ]);
    prop::collection::btree_map(name.prop_map(str::to_owned), index_value(), 0..5)
        .prop_map(|m| Value::Object(m.into_iter().collect()))
        .boxed()
}

/// A value for a field of class `c`: mostly of its kind, sometimes anything at all.
fn value_of(c: Class) -> BoxedStrategy<Value> {
    let specific = match c {
        Class::Index => index_value(),
        Class::IndexList => index_list(),
        Class::Size => size_value(),
        Class::Stride => select(vec![
            0u64,
            1,
            2,
            3,
            4,
            5,
            8,
            11,
            12,
            16,
            20,
            24,
            31,
            32,
            33,
            64,
            252,
            255,
            256,
            1 << 20,
            u64::from(u32::MAX),
        ])
        .prop_map(Value::from)
        .boxed(),
        Class::Component => component_value(),
        Class::AccessorType => string_value(),
        Class::Mode => prop_oneof![(0u64..=8).prop_map(Value::from), int_value()].boxed(),
        Class::Bool => prop_oneof![any::<bool>().prop_map(Value::Bool), leaf_value()].boxed(),
        Class::Number => prop_oneof![float_value(), int_value()].boxed(),
        Class::Numbers(n) => numbers(n),
        Class::Str => string_value(),
        Class::Uri => uri_value(),
        Class::Sparse => sparse_value(),
        Class::SparseRef => sparse_ref(true),
        Class::Extensions => extensions_value(),
        Class::ExtensionNames => extension_names(),
        Class::TextureInfo => texture_info(),
        Class::Attributes => attributes_value(),
        Class::Array => prop_oneof![
            Just(json!([])),
            prop::collection::vec(leaf_value(), 1..4).prop_map(Value::Array),
            any_value()
        ]
        .boxed(),
        Class::Object => prop_oneof![Just(json!({})), any_value()].boxed(),
    };
    prop_oneof![5 => specific, 1 => any_value()].boxed()
}

// ---------------------------------------------------------------------------------------
// JSON paths and what lives at them.

#[derive(Clone, Debug, PartialEq, Eq)]
enum Seg {
    Key(String),
    At(usize),
}

type JsonPath = Vec<Seg>;

fn all_paths(v: &Value) -> Vec<JsonPath> {
    fn walk(v: &Value, prefix: &mut JsonPath, out: &mut Vec<JsonPath>) {
        out.push(prefix.clone());
        match v {
            Value::Object(m) => {
                for (k, c) in m {
                    prefix.push(Seg::Key(k.clone()));
                    walk(c, prefix, out);
                    prefix.pop();
                }
            }
            Value::Array(a) => {
                for (i, c) in a.iter().enumerate() {
                    prefix.push(Seg::At(i));
                    walk(c, prefix, out);
                    prefix.pop();
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(v, &mut Vec::new(), &mut out);
    out
}

fn get_mut<'a>(v: &'a mut Value, path: &[Seg]) -> Option<&'a mut Value> {
    path.iter().try_fold(v, |v, s| match s {
        Seg::Key(k) => v.get_mut(k.as_str()),
        Seg::At(i) => v.get_mut(*i),
    })
}

fn get<'a>(v: &'a Value, path: &[Seg]) -> Option<&'a Value> {
    path.iter().try_fold(v, |v, s| match s {
        Seg::Key(k) => v.get(k.as_str()),
        Seg::At(i) => v.get(*i),
    })
}

/// The glTF objects mutated field by field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Root,
    Asset,
    Accessor,
    Sparse,
    SparseIndices,
    SparseValues,
    BufferView,
    Buffer,
    Mesh,
    Primitive,
    Attributes,
    Node,
    Material,
    Pbr,
    TextureInfo,
    Texture,
    Image,
    Sampler,
    Camera,
    Perspective,
    Scene,
}

/// What the object at `path` is, from the path's shape (indices written `#`).
fn kind_of(path: &[Seg]) -> Option<Kind> {
    let shape: Vec<&str> = path.iter().map(|s| if let Seg::Key(k) = s { k.as_str() } else { "#" }).collect();
    Some(match shape.join("/").as_str() {
        "" => Kind::Root,
        "asset" => Kind::Asset,
        "accessors/#" => Kind::Accessor,
        "accessors/#/sparse" => Kind::Sparse,
        "accessors/#/sparse/indices" => Kind::SparseIndices,
        "accessors/#/sparse/values" => Kind::SparseValues,
        "bufferViews/#" => Kind::BufferView,
        "buffers/#" => Kind::Buffer,
        "meshes/#" => Kind::Mesh,
        "meshes/#/primitives/#" => Kind::Primitive,
        "meshes/#/primitives/#/attributes" => Kind::Attributes,
        "nodes/#" => Kind::Node,
        "materials/#" => Kind::Material,
        "materials/#/pbrMetallicRoughness" => Kind::Pbr,
        "materials/#/pbrMetallicRoughness/baseColorTexture" | "materials/#/emissiveTexture" => {
            Kind::TextureInfo
        }
        "textures/#" => Kind::Texture,
        "images/#" => Kind::Image,
        "samplers/#" => Kind::Sampler,
        "cameras/#" => Kind::Camera,
        "cameras/#/perspective" => Kind::Perspective,
        "scenes/#" => Kind::Scene,
        _ => return None,
    })
}

/// Every field the loader reads, the objects that have it, and what it holds.
const FIELDS: &[(&str, &[Kind], Class)] = {
    use Class as C;
    use Kind as K;
    &[
        ("bufferView", &[K::Accessor, K::SparseIndices, K::SparseValues, K::Image], C::Index),
        ("byteOffset", &[K::Accessor, K::BufferView, K::SparseIndices, K::SparseValues], C::Size),
        ("componentType", &[K::Accessor, K::SparseIndices], C::Component),
        ("normalized", &[K::Accessor], C::Bool),
        ("count", &[K::Accessor, K::Sparse], C::Size),
        ("type", &[K::Accessor], C::AccessorType),
        ("sparse", &[K::Accessor], C::Sparse),
        ("indices", &[K::Sparse], C::SparseRef),
        ("values", &[K::Sparse], C::SparseRef),
        ("min", &[K::Accessor], C::Numbers(3)),
        ("buffer", &[K::BufferView], C::Index),
        ("byteLength", &[K::BufferView, K::Buffer], C::Size),
        ("byteStride", &[K::BufferView], C::Stride),
        ("uri", &[K::Buffer, K::Image], C::Uri),
        ("primitives", &[K::Mesh], C::Array),
        ("attributes", &[K::Primitive], C::Attributes),
        ("indices", &[K::Primitive], C::Index),
        ("material", &[K::Primitive], C::Index),
        ("mode", &[K::Primitive], C::Mode),
        (
            "extensions",
            &[
                K::Primitive,
                K::Node,
                K::Material,
                K::TextureInfo,
                K::Texture,
                K::Root,
                K::Accessor,
                K::BufferView,
                K::Mesh,
            ],
            C::Extensions,
        ),
        ("POSITION", &[K::Attributes], C::Index),
        ("NORMAL", &[K::Attributes], C::Index),
        ("TANGENT", &[K::Attributes], C::Index),
        ("TEXCOORD_0", &[K::Attributes], C::Index),
        ("TEXCOORD_1", &[K::Attributes], C::Index),
        ("children", &[K::Node], C::IndexList),
        ("mesh", &[K::Node], C::Index),
        ("camera", &[K::Node], C::Index),
        ("skin", &[K::Node], C::Index),
        ("matrix", &[K::Node], C::Numbers(16)),
        ("translation", &[K::Node], C::Numbers(3)),
        ("rotation", &[K::Node], C::Numbers(4)),
        ("scale", &[K::Node], C::Numbers(3)),
        ("name", &[K::Node, K::Mesh, K::Material, K::Camera], C::Str),
        ("alphaMode", &[K::Material], C::Str),
        ("alphaCutoff", &[K::Material], C::Number),
        ("doubleSided", &[K::Material], C::Bool),
        ("emissiveFactor", &[K::Material], C::Numbers(3)),
        ("emissiveTexture", &[K::Material], C::TextureInfo),
        ("pbrMetallicRoughness", &[K::Material], C::Object),
        ("baseColorFactor", &[K::Pbr], C::Numbers(4)),
        ("baseColorTexture", &[K::Pbr], C::TextureInfo),
        ("index", &[K::TextureInfo], C::Index),
        ("texCoord", &[K::TextureInfo], C::Index),
        ("source", &[K::Texture], C::Index),
        ("sampler", &[K::Texture], C::Index),
        ("mimeType", &[K::Image], C::Str),
        ("wrapS", &[K::Sampler], C::Component),
        ("type", &[K::Camera], C::Str),
        ("perspective", &[K::Camera], C::Object),
        ("yfov", &[K::Perspective], C::Number),
        ("aspectRatio", &[K::Perspective], C::Number),
        ("nodes", &[K::Scene, K::Root], C::IndexList),
        ("scene", &[K::Root], C::Index),
        ("scenes", &[K::Root], C::Array),
        ("meshes", &[K::Root], C::Array),
        ("accessors", &[K::Root], C::Array),
        ("bufferViews", &[K::Root], C::Array),
        ("buffers", &[K::Root], C::Array),
        ("samplers", &[K::Root], C::Array),
        ("extensionsRequired", &[K::Root], C::ExtensionNames),
        ("extensionsUsed", &[K::Root], C::ExtensionNames),
        ("asset", &[K::Root], C::Object),
        ("version", &[K::Asset], C::Str),
    ]
};

// ---------------------------------------------------------------------------------------
// Mutations.

/// How a number is nudged.
#[derive(Clone, Copy, Debug)]
enum Nudge {
    Add(i64),
    Mul(i64),
    Negate,
    Stringify,
    PlusHalf,
}

/// How a `data:` URI is damaged.
#[derive(Clone, Debug)]
enum UriDamage {
    /// Cut the URI at this fraction of its length.
    Truncate(Index),
    /// Put this character at this position.
    Poke(Index, char),
    /// Drop the `,` between header and data.
    DropComma,
    /// Drop the `;base64` marker (the payload is then read as percent-encoded text).
    DropBase64,
    /// Append the payload again (more bytes than `byteLength`).
    Double,
}

/// One structural change to a glTF JSON document. Indices pick among the document's
/// current paths (or objects of the right kind) when the mutation is applied.
#[derive(Clone, Debug)]
enum JsonMutation {
    /// Set `FIELDS[field]` on an object of one of its kinds.
    SetField { field: usize, target: Index, value: Value },
    /// Replace the value at any path.
    Replace { at: Index, value: Value },
    /// Delete an object key or array element.
    Delete { at: Index },
    /// Nudge a number.
    Nudge { at: Index, how: Nudge },
    /// Copy the value at one path over another.
    Copy { from: Index, to: Index },
    /// Make `child` a child of `parent` (cycles, self-loops, shared children).
    Link { parent: Index, child: Index },
    /// Append `times` copies of an array's element (primitives and nodes that share data).
    Duplicate { array: Index, element: Index, times: usize },
    /// Remove an accessor's buffer view and give it `count` elements (zeros nobody stored).
    Viewless { accessor: Index, count: u64 },
    /// Damage a `data:` URI.
    DataUri { target: Index, how: UriDamage },
}

fn json_mutation() -> BoxedStrategy<JsonMutation> {
    let m = MAX_ACCESSOR_VALUES;
    let set_field = (0..FIELDS.len())
        .prop_flat_map(|f| (Just(f), any::<Index>(), value_of(FIELDS[f].2)))
        .prop_map(|(field, target, value)| JsonMutation::SetField { field, target, value });
    let nudge = prop_oneof![
        4 => select(vec![-2i64, -1, 1, 2, 3, 4, 7, 8, 12, 16, 32, 1 << 16, 1 << 31]).prop_map(Nudge::Add),
        2 => select(vec![2i64, 3, 4, 1000, 1 << 20, 1 << 32]).prop_map(Nudge::Mul),
        1 => Just(Nudge::Negate),
        1 => Just(Nudge::Stringify),
        1 => Just(Nudge::PlusHalf),
    ];
    let damage = prop_oneof![
        3 => any::<Index>().prop_map(UriDamage::Truncate),
        3 => (any::<Index>(), select(vec!['!', '*', '\n', ' ', '=', '-', '_', '%', 'é', '\u{0}', ','])).prop_map(|(i, c)| UriDamage::Poke(i, c)),
        1 => Just(UriDamage::DropComma),
        1 => Just(UriDamage::DropBase64),
        1 => Just(UriDamage::Double),
    ];
    prop_oneof![
        8 => set_field,
        3 => (any::<Index>(), any_value()).prop_map(|(at, value)| JsonMutation::Replace { at, value }),
        2 => any::<Index>().prop_map(|at| JsonMutation::Delete { at }),
        3 => (any::<Index>(), nudge).prop_map(|(at, how)| JsonMutation::Nudge { at, how }),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(from, to)| JsonMutation::Copy { from, to }),
        2 => (any::<Index>(), any::<Index>()).prop_map(|(parent, child)| JsonMutation::Link { parent, child }),
        1 => (any::<Index>(), any::<Index>(), prop_oneof![3 => Just(1usize), 1 => 2usize..=64])
            .prop_map(|(array, element, times)| JsonMutation::Duplicate { array, element, times }),
        1 => (any::<Index>(), select(vec![3, 1 << 16, 1 << 20, 1 << 24, m / 16, m / 4, m / 3, m / 3 + 1, m, u64::from(u32::MAX)]))
            .prop_map(|(accessor, count)| JsonMutation::Viewless { accessor, count }),
        2 => (any::<Index>(), damage).prop_map(|(target, how)| JsonMutation::DataUri { target, how }),
    ]
    .boxed()
}

fn pick<'a, T>(items: &'a [T], i: &Index) -> Option<&'a T> {
    (!items.is_empty()).then(|| &items[i.index(items.len())])
}

fn nudged(v: &Value, how: Nudge) -> Option<Value> {
    let x = v.as_f64()?;
    let int = v.as_i64().map(i128::from).or(v.as_u64().map(i128::from));
    let from_int = |n: i128| {
        u64::try_from(n)
            .map(Value::from)
            .or_else(|_| i64::try_from(n).map(Value::from))
            .unwrap_or_else(|_| Value::from(n as f64))
    };
    Some(match (how, int) {
        (Nudge::Add(d), Some(n)) => from_int(n + i128::from(d)),
        (Nudge::Add(d), None) => Value::from(x + d as f64),
        (Nudge::Mul(k), Some(n)) => from_int(n.saturating_mul(i128::from(k))),
        (Nudge::Mul(k), None) => Value::from(x * k as f64),
        (Nudge::Negate, Some(n)) => from_int(-n),
        (Nudge::Negate, None) => Value::from(-x),
        (Nudge::Stringify, _) => Value::from(v.to_string()),
        (Nudge::PlusHalf, _) => Value::from(x + 0.5),
    })
}

/// The `data:` URI of `bin`.
fn data_uri(bin: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", base64(bin))
}

fn base64(data: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for c in data.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            out.push(if k <= c.len() { A[(n >> (18 - 6 * k) & 63) as usize] as char } else { '=' });
        }
    }
    out
}

fn damaged(uri: &str, how: &UriDamage) -> String {
    let chars: Vec<char> = uri.chars().collect();
    match how {
        UriDamage::Truncate(i) => chars[..i.index(chars.len() + 1)].iter().collect(),
        UriDamage::Poke(i, c) => {
            let mut chars = chars;
            if !chars.is_empty() {
                let at = i.index(chars.len());
                chars[at] = *c;
            }
            chars.into_iter().collect()
        }
        UriDamage::DropComma => uri.replacen(',', "", 1),
        UriDamage::DropBase64 => uri.replacen(";base64", "", 1),
        UriDamage::Double => {
            let payload = uri.split_once(',').map_or("", |(_, p)| p);
            format!("{uri}{payload}")
        }
    }
}

fn apply(doc: &mut Value, bin: &[u8], m: &JsonMutation) {
    let paths = all_paths(doc);
    let objects_of = |kinds: &[Kind]| -> Vec<JsonPath> {
        paths
            .iter()
            .filter(|p| {
                kind_of(p).is_some_and(|k| kinds.contains(&k)) && get(doc, p).is_some_and(Value::is_object)
            })
            .cloned()
            .collect()
    };
    let set = |doc: &mut Value, path: &[Seg], value: Value| {
        if let Some(slot) = get_mut(doc, path) {
            *slot = value;
        }
    };
    match m {
        JsonMutation::SetField { field, target, value } => {
            let (name, kinds, _) = FIELDS[*field];
            let mut targets = objects_of(kinds);
            if targets.is_empty() {
                // No such object (a sampler, a sparse block): any object gets the field.
                targets =
                    paths.iter().filter(|p| get(doc, p).is_some_and(Value::is_object)).cloned().collect();
            }
            if let Some(p) = pick(&targets, target)
                && let Some(Value::Object(o)) = get_mut(doc, p)
            {
                o.insert(name.to_owned(), value.clone());
            }
        }
        JsonMutation::Replace { at, value } => {
            if let Some(p) = pick(&paths, at) {
                set(doc, &p.clone(), value.clone());
            }
        }
        JsonMutation::Delete { at } => {
            let Some((last, parent)) = pick(&paths[1..], at).and_then(|p| p.split_last()) else { return };
            match (get_mut(doc, parent), last.clone()) {
                (Some(Value::Object(o)), Seg::Key(k)) => {
                    o.remove(&k);
                }
                (Some(Value::Array(a)), Seg::At(i)) => {
                    a.remove(i);
                }
                _ => {}
            }
        }
        JsonMutation::Nudge { at, how } => {
            let numbers: Vec<&JsonPath> =
                paths.iter().filter(|p| get(doc, p).is_some_and(Value::is_number)).collect();
            if let Some(&p) = pick(&numbers, at)
                && let Some(v) = get(doc, p).and_then(|v| nudged(v, *how))
            {
                set(doc, &p.clone(), v);
            }
        }
        JsonMutation::Copy { from, to } => {
            if let (Some(f), Some(t)) = (pick(&paths, from), pick(&paths, to))
                && let Some(v) = get(doc, f).cloned()
            {
                set(doc, &t.clone(), v);
            }
        }
        JsonMutation::Link { parent, child } => {
            let n = doc.get("nodes").and_then(Value::as_array).map_or(0, Vec::len);
            if n == 0 {
                return;
            }
            let (p, c) = (parent.index(n), child.index(n));
            if let Some(node) = doc["nodes"][p].as_object_mut() {
                let children = node.entry("children").or_insert_with(|| json!([]));
                if let Some(a) = children.as_array_mut() {
                    a.push(json!(c));
                } else {
                    *children = json!([c]);
                }
            }
        }
        JsonMutation::Duplicate { array, element, times } => {
            let arrays: Vec<&JsonPath> = paths
                .iter()
                .filter(|p| get(doc, p).and_then(Value::as_array).is_some_and(|a| !a.is_empty()))
                .collect();
            if let Some(&p) = pick(&arrays, array)
                && let Some(Value::Array(a)) = get_mut(doc, p)
            {
                let e = a[element.index(a.len())].clone();
                a.extend(std::iter::repeat_n(e, *times));
            }
        }
        JsonMutation::Viewless { accessor, count } => {
            let accessors = objects_of(&[Kind::Accessor]);
            if let Some(p) = pick(&accessors, accessor)
                && let Some(Value::Object(o)) = get_mut(doc, p)
            {
                o.remove("bufferView");
                o.insert("count".into(), json!(count));
            }
        }
        JsonMutation::DataUri { target, how } => {
            let uris: Vec<&JsonPath> = paths
                .iter()
                .filter(|p| {
                    get(doc, p)
                        .and_then(Value::as_str)
                        .is_some_and(|s| s == BIN_PLACEHOLDER || s.starts_with("data:"))
                })
                .collect();
            if let Some(&p) = pick(&uris, target) {
                let uri = match get(doc, p).and_then(Value::as_str) {
                    Some(BIN_PLACEHOLDER) => data_uri(bin),
                    Some(s) => s.to_owned(),
                    None => return,
                };
                set(doc, &p.clone(), Value::from(damaged(&uri, how)));
            }
        }
    }
}

/// A u32 of the binary buffer overwritten, or bytes cut from its end.
#[derive(Clone, Debug)]
enum BinMutation {
    Word { at: Index, value: u32 },
    Flip { at: Index, xor: u8 },
    Truncate { at: Index },
}

fn bin_mutation() -> BoxedStrategy<BinMutation> {
    let word = prop_oneof![
        3 => select(vec![
            0x7FC0_0000u32, 0xFFC0_0000, 0x7F80_0000, 0xFF80_0000, 0x7F7F_FFFF, 0x0000_0001, 0,
            u32::MAX, 0x8000_0000, 0x0001_0000, 0xFFFF, 5000, 100_000,
        ]),
        1 => any::<u32>(),
    ];
    prop_oneof![
        6 => (any::<Index>(), word).prop_map(|(at, value)| BinMutation::Word { at, value }),
        3 => (any::<Index>(), 1u8..=255).prop_map(|(at, xor)| BinMutation::Flip { at, xor }),
        1 => any::<Index>().prop_map(|at| BinMutation::Truncate { at }),
    ]
    .boxed()
}

fn apply_bin(bin: &mut Vec<u8>, m: &BinMutation) {
    if bin.is_empty() {
        return;
    }
    match m {
        BinMutation::Word { at, value } => {
            let words = bin.len() / 4;
            if words > 0 {
                let o = 4 * at.index(words);
                bin[o..o + 4].copy_from_slice(&value.to_le_bytes());
            }
        }
        BinMutation::Flip { at, xor } => {
            let i = at.index(bin.len());
            bin[i] ^= xor;
        }
        BinMutation::Truncate { at } => bin.truncate(at.index(bin.len())),
    }
}

/// A change to the serialized JSON text.
#[derive(Clone, Debug)]
enum TextMutation {
    /// Replace a number token with this text.
    Number { which: Index, with: &'static str },
    /// Cut the text.
    Truncate { at: Index },
    /// Insert a byte.
    Insert { at: Index, byte: u8 },
}

fn text_mutation() -> BoxedStrategy<TextMutation> {
    let with = select(vec![
        "1e999",
        "-1e999",
        "NaN",
        "Infinity",
        "-Infinity",
        "1e-999",
        "00",
        "-",
        "0x10",
        "1.",
        ".5",
        "+1",
        "18446744073709551616",
        "-9223372036854775809",
        "1E400",
        "-0",
    ]);
    prop_oneof![
        6 => (any::<Index>(), with).prop_map(|(which, with)| TextMutation::Number { which, with }),
        1 => any::<Index>().prop_map(|at| TextMutation::Truncate { at }),
        1 => (any::<Index>(), any::<u8>()).prop_map(|(at, byte)| TextMutation::Insert { at, byte }),
    ]
    .boxed()
}

fn apply_text(text: &mut Vec<u8>, m: &TextMutation) {
    match m {
        TextMutation::Number { which, with } => {
            let mut spans = Vec::new();
            let mut i = 0;
            while i < text.len() {
                let starts = (text[i].is_ascii_digit() || text[i] == b'-')
                    && i > 0
                    && matches!(text[i - 1], b':' | b',' | b'[' | b' ');
                if starts {
                    let s = i;
                    while i < text.len() && matches!(text[i], b'0'..=b'9' | b'-' | b'+' | b'.' | b'e' | b'E')
                    {
                        i += 1;
                    }
                    spans.push(s..i);
                } else {
                    i += 1;
                }
            }
            if let Some(r) = pick(&spans, which).cloned() {
                text.splice(r, with.bytes());
            }
        }
        TextMutation::Truncate { at } => text.truncate(at.index(text.len() + 1)),
        TextMutation::Insert { at, byte } => text.insert(at.index(text.len() + 1), *byte),
    }
}

/// Replaces [`BIN_PLACEHOLDER`] strings by the buffer's `data:` URI.
fn fill_placeholder(v: &mut Value, bin: &[u8]) {
    match v {
        Value::String(s) if s == BIN_PLACEHOLDER => *s = data_uri(bin),
        Value::Array(a) => a.iter_mut().for_each(|c| fill_placeholder(c, bin)),
        Value::Object(o) => o.values_mut().for_each(|c| fill_placeholder(c, bin)),
        _ => {}
    }
}

/// The mutated JSON text and binary buffer of a document.
fn mutated(
    f: &Fixture,
    json: &[JsonMutation],
    bin: &[BinMutation],
    text: Option<&TextMutation>,
) -> (Vec<u8>, Vec<u8>) {
    let mut b = f.bin.clone();
    for m in bin {
        apply_bin(&mut b, m);
    }
    let mut doc = f.json.clone();
    for m in json {
        apply(&mut doc, &b, m);
    }
    fill_placeholder(&mut doc, &b);
    let mut t = serde_json::to_vec(&doc).expect("a Value serializes");
    if let Some(m) = text {
        apply_text(&mut t, m);
    }
    (t, b)
}

/// A `.gltf` case.
#[derive(Clone, Debug)]
struct JsonCase {
    json: Vec<JsonMutation>,
    bin: Vec<BinMutation>,
    text: Option<TextMutation>,
}

fn json_case() -> impl Strategy<Value = JsonCase> {
    (
        prop::collection::vec(json_mutation(), 1..=MAX_MUTATIONS),
        prop_oneof![3 => Just(Vec::new()), 1 => prop::collection::vec(bin_mutation(), 1..=2)],
        prop_oneof![7 => Just(None), 1 => text_mutation().prop_map(Some)],
    )
        .prop_map(|(json, bin, text)| JsonCase { json, bin, text })
}

// ---------------------------------------------------------------------------------------
// GLB containers.

/// How the chunks are laid out.
#[derive(Clone, Debug)]
enum Layout {
    Standard,
    NoBin,
    BinFirst,
    TwoJson,
    UnknownChunk { first: bool },
    EmptyBin,
    UnpaddedJson,
    Trailing(Vec<u8>),
}

/// A header word of the packed file.
#[derive(Clone, Copy, Debug)]
enum Field {
    Magic,
    Version,
    Length,
    FirstChunkLength,
    FirstChunkType,
    SecondChunkLength,
    SecondChunkType,
}

/// A value for a header word: absolute, or relative to what is there.
#[derive(Clone, Copy, Debug)]
enum Word {
    Abs(u32),
    Rel(i64),
}

/// A change to the packed GLB bytes.
#[derive(Clone, Debug)]
enum ByteMutation {
    Header {
        field: Field,
        value: Word,
    },
    /// Flip bits of a byte in the header (0), the JSON chunk (1), the BIN chunk (2) or anywhere (3).
    Flip {
        region: u8,
        at: Index,
        xor: u8,
    },
    Truncate {
        at: Index,
    },
}

/// A `.glb` case.
#[derive(Clone, Debug)]
struct GlbCase {
    json: Vec<JsonMutation>,
    bin: Vec<BinMutation>,
    text: Option<TextMutation>,
    layout: Layout,
    bytes: Vec<ByteMutation>,
}

fn byte_mutation() -> BoxedStrategy<ByteMutation> {
    let field = select(vec![
        Field::Magic,
        Field::Version,
        Field::Length,
        Field::FirstChunkLength,
        Field::FirstChunkType,
        Field::SecondChunkLength,
        Field::SecondChunkType,
    ]);
    let value = prop_oneof![
        2 => select(vec![0u32, 1, 2, 3, 4, 7, 8, 12, 20, 1 << 16, 0x7FFF_FFFF, 0x8000_0000, u32::MAX - 3, u32::MAX, CHUNK_JSON, CHUNK_BIN]).prop_map(Word::Abs),
        2 => select(vec![-9i64, -8, -4, -1, 1, 3, 4, 8, 1 << 20]).prop_map(Word::Rel),
        1 => any::<u32>().prop_map(Word::Abs),
    ];
    prop_oneof![
        3 => (field, value).prop_map(|(field, value)| ByteMutation::Header { field, value }),
        4 => (0u8..4, any::<Index>(), 1u8..=255).prop_map(|(region, at, xor)| ByteMutation::Flip { region, at, xor }),
        1 => any::<Index>().prop_map(|at| ByteMutation::Truncate { at }),
    ]
    .boxed()
}

fn glb_case() -> impl Strategy<Value = GlbCase> {
    let layout = prop_oneof![
        12 => Just(Layout::Standard),
        1 => Just(Layout::NoBin),
        1 => Just(Layout::BinFirst),
        1 => Just(Layout::TwoJson),
        1 => any::<bool>().prop_map(|first| Layout::UnknownChunk { first }),
        1 => Just(Layout::EmptyBin),
        1 => Just(Layout::UnpaddedJson),
        1 => prop::collection::vec(any::<u8>(), 1..40).prop_map(Layout::Trailing),
    ];
    (
        prop_oneof![1 => Just(Vec::new()), 3 => prop::collection::vec(json_mutation(), 1..=MAX_MUTATIONS)],
        prop_oneof![3 => Just(Vec::new()), 1 => prop::collection::vec(bin_mutation(), 1..=2)],
        prop_oneof![7 => Just(None), 1 => text_mutation().prop_map(Some)],
        layout,
        prop_oneof![1 => Just(Vec::new()), 1 => prop::collection::vec(byte_mutation(), 1..=3)],
    )
        .prop_map(|(json, bin, text, layout, bytes)| GlbCase { json, bin, text, layout, bytes })
}

/// Packs chunks into a GLB: `(type, data, pad)` each, padded to 4 bytes with `pad`.
fn pack(chunks: &[(u32, &[u8], Option<u8>)]) -> Vec<u8> {
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    for &(kind, data, pad) in chunks {
        let padded = if pad.is_some() { data.len().next_multiple_of(4) } else { data.len() };
        out.extend_from_slice(&(padded as u32).to_le_bytes());
        out.extend_from_slice(&kind.to_le_bytes());
        out.extend_from_slice(data);
        out.resize(out.len() + padded - data.len(), pad.unwrap_or(0));
    }
    let len = out.len() as u32;
    out[8..12].copy_from_slice(&len.to_le_bytes());
    out
}

fn glb_bytes(f: &Fixture, case: &GlbCase) -> Vec<u8> {
    let (json, bin) = mutated(f, &case.json, &case.bin, case.text.as_ref());
    let (j, b) = (Some(b' '), Some(0u8));
    let mut glb = match &case.layout {
        Layout::Standard => pack(&[(CHUNK_JSON, &json, j), (CHUNK_BIN, &bin, b)]),
        Layout::NoBin => pack(&[(CHUNK_JSON, &json, j)]),
        Layout::BinFirst => pack(&[(CHUNK_BIN, &bin, b), (CHUNK_JSON, &json, j)]),
        Layout::TwoJson => pack(&[
            (CHUNK_JSON, br#"{"asset":{"version":"2.0"}}"#, j),
            (CHUNK_JSON, &json, j),
            (CHUNK_BIN, &bin, b),
        ]),
        Layout::UnknownChunk { first: true } => {
            pack(&[(0x1234_5678, b"junk", b), (CHUNK_JSON, &json, j), (CHUNK_BIN, &bin, b)])
        }
        Layout::UnknownChunk { first: false } => {
            pack(&[(CHUNK_JSON, &json, j), (0x1234_5678, b"junk!", b), (CHUNK_BIN, &bin, b)])
        }
        Layout::EmptyBin => pack(&[(CHUNK_JSON, &json, j), (CHUNK_BIN, &[], b)]),
        Layout::UnpaddedJson => pack(&[(CHUNK_JSON, &json, None), (CHUNK_BIN, &bin, b)]),
        Layout::Trailing(t) => {
            let mut g = pack(&[(CHUNK_JSON, &json, j), (CHUNK_BIN, &bin, b)]);
            g.extend_from_slice(t);
            g
        }
    };
    let first_len = u32::from_le_bytes(glb[12..16].try_into().expect("4 bytes")) as usize;
    let second = 20 + first_len;
    let json_region = 20..second.min(glb.len());
    let bin_region = (second + 8).min(glb.len())..glb.len();
    for m in &case.bytes {
        match m {
            ByteMutation::Header { field, value } => {
                let at = match field {
                    Field::Magic => 0,
                    Field::Version => 4,
                    Field::Length => 8,
                    Field::FirstChunkLength => 12,
                    Field::FirstChunkType => 16,
                    Field::SecondChunkLength => second,
                    Field::SecondChunkType => second + 4,
                };
                if at + 4 <= glb.len() {
                    let old = u32::from_le_bytes(glb[at..at + 4].try_into().expect("4 bytes"));
                    let new = match value {
                        Word::Abs(v) => *v,
                        Word::Rel(d) => (i64::from(old) + d) as u32,
                    };
                    glb[at..at + 4].copy_from_slice(&new.to_le_bytes());
                }
            }
            ByteMutation::Flip { region, at, xor } => {
                let r = match region {
                    0 => 0..20.min(glb.len()),
                    1 => json_region.start.min(glb.len())..json_region.end.min(glb.len()),
                    2 => bin_region.start.min(glb.len())..glb.len(),
                    _ => 0..glb.len(),
                };
                if !r.is_empty() {
                    let i = r.start + at.index(r.len());
                    glb[i] ^= xor;
                }
            }
            ByteMutation::Truncate { at } => glb.truncate(at.index(glb.len() + 1)),
        }
    }
    glb
}

// ---------------------------------------------------------------------------------------
// Running.

/// What the cases ended in, for the summary and the coverage check.
#[derive(Default)]
struct Outcomes {
    ok: usize,
    /// Error messages with numbers and quoted names removed, and how often each came.
    errors: BTreeMap<String, usize>,
}

impl Outcomes {
    fn record(&mut self, r: &Result<usize, String>) {
        match r {
            Ok(_) => self.ok += 1,
            Err(e) => {
                let e = e.strip_prefix("glTF error in fuzz: ").unwrap_or(e);
                let words: Vec<&str> = e.split(' ').filter(|w| !w.starts_with('\'')).take(7).collect();
                let shape: String = words.join(" ").chars().filter(|c| !c.is_ascii_digit()).collect();
                *self.errors.entry(shape).or_default() += 1;
            }
        }
    }

    fn summary(&self, what: &str) -> String {
        let total = self.ok + self.errors.values().sum::<usize>();
        let mut top: Vec<(&String, &usize)> = self.errors.iter().collect();
        top.sort_by(|a, b| b.1.cmp(a.1));
        let lines: Vec<String> = top.iter().take(40).map(|(e, n)| format!("  {n:4} × …{e}…")).collect();
        format!(
            "{what}: {total} runs, {} Ok, {} kinds of error:\n{}",
            self.ok,
            self.errors.len(),
            lines.join("\n")
        )
    }
}

fn light_is_finite(l: &PunctualLight) -> bool {
    match l {
        PunctualLight::Point { position, intensity } => {
            position.is_finite() && intensity.iter().all(|x| x.is_finite())
        }
        PunctualLight::Spot { position, axis, intensity, inner, outer } => {
            position.is_finite()
                && axis.is_finite()
                && intensity.iter().all(|x| x.is_finite())
                && inner.is_finite()
                && outer.is_finite()
        }
        PunctualLight::Directional { to_light, irradiance } => {
            to_light.is_finite() && irradiance.iter().all(|x| x.is_finite())
        }
    }
}

/// Loads `bytes` and checks the outcome: a finite scene, or one non-empty line. Returns the
/// triangle count or the message.
fn check(bytes: &[u8], base: &Path, case: &dyn Debug) -> Result<Result<usize, String>, TestCaseError> {
    let running = Running::start(case);
    let before = status_bytes("VmRSS:");
    reset_peak();
    let result = load_gltf_slice(bytes, Some(base), "fuzz", &LoadOptions::default());
    drop(running);
    let peak = status_bytes("VmHWM:").saturating_sub(before);
    // A scene the file really describes (an instanced mesh, a duplicated primitive) may
    // cost what its triangles cost; anything beyond that is memory the input did not back.
    let triangles = result.as_ref().map_or(0, |s| s.triangles.len() + s.report.degenerate_skipped);
    let budget = CASE_MEMORY_BUDGET + triangles * BYTES_PER_TRIANGLE;
    prop_assert!(
        peak <= budget,
        "the load held {} MiB at once (budget {} MiB for {triangles} triangles)",
        peak >> 20,
        budget >> 20
    );
    Ok(match result {
        Ok(scene) => {
            prop_assert!(
                scene.triangles.iter().all(|t| t.v.iter().all(|p| p.is_finite())),
                "a loaded scene has a non-finite vertex"
            );
            prop_assert!(
                scene.punctual.iter().all(light_is_finite),
                "a loaded light is not finite: {:?}",
                scene.punctual
            );
            prop_assert!(
                scene.cameras.iter().all(|c| c.position.is_finite()
                    && c.forward.is_finite()
                    && c.up.is_finite()
                    && c.yfov.is_finite()),
                "a loaded camera is not finite: {:?}",
                scene.cameras
            );
            Ok(scene.triangles.len())
        }
        Err(e) => {
            let msg = e.to_string();
            prop_assert!(!msg.trim().is_empty(), "empty error message ({e:?})");
            prop_assert!(
                !msg.contains('\n') && !msg.contains('\r'),
                "error message is not one line: {msg:?}"
            );
            Err(msg)
        }
    })
}

fn runner(cases: u32) -> TestRunner {
    let config = Config { cases, failure_persistence: None, max_shrink_iters: 512, ..Config::default() };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, SEED))
}

fn run<S: Strategy>(
    name: &str,
    cases: u32,
    strategy: S,
    test: impl Fn(S::Value, &mut Outcomes) -> TestCaseResult,
) where
    S::Value: Debug,
{
    let outcomes = RefCell::new(Outcomes::default());
    let result = runner(cases).run(&strategy, |case| test(case, &mut outcomes.borrow_mut()));
    let o = outcomes.into_inner();
    eprintln!("{}", o.summary(name));
    if let Err(e) = result {
        panic!("{name}: {e}");
    }
    // The mutations must get past the parser: some loads succeed and the errors are many.
    assert!(o.ok > 0 && o.errors.len() >= 10, "{name}: the mutations exercise too little of the loader");
}

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
