//! What a user of three.js or Bevy sees of each bake: the real clients (`clients/three` in
//! Debian's Chromium, `clients/bevy` on lavapipe) draw the Breakfast Room from its main glTF
//! camera lit only by their export of a `doi --target ENGINE` bake, of a Unity APV bake
//! (`point+apv`) and of a DDGI relocation bake (`point+ddgi`), and each frame is measured
//! against the path-traced view of the same scene and light (relative RMSE over the lit
//! pixels away from edges, as the emulation test measures frames).
//!
//! The scene is the vendored Breakfast Room without its textures (the Bevy client is built
//! without image decoders), cameras or DDS extension; every frame and the reference see the
//! same untextured materials. The light is a uniform white sky and ground and its bounces.
//!
//! A missing browser, Node.js package or Bevy build skips a client loudly; with
//! `LIGHTVOL_REQUIRE_CHROMIUM=1` or `LIGHTVOL_REQUIRE_BEVY=1` (set by `.ci/run`) it fails.

mod clients;
mod common;

use std::path::Path;
use std::sync::OnceLock;

use clients::{Engine, Frame, Shot, edge_mask, frame_rmse, path_traced, root};
use common::{ok, s};
use serde_json::Value;

const WIDTH: u32 = 160;
const HEIGHT: u32 = 128;
/// The Breakfast Room's `CameraMain` (file frame, +Y up): its position and a point one
/// metre along its view direction; a wider vertical field than its 45° so that the frame
/// holds the floor under the table and the chairs.
const EYE: [f64; 3] = [1.1668, 0.9702, 0.6777];
const TARGET: [f64; 3] = [1.1668 - 0.4072, 0.9702 + 0.0157, 0.6777 - 0.9132];
const FOV: f64 = 60.0;
/// Samples per node of every bake: the method table's.
const SAMPLES: &str = "128";
/// The light of the bakes and the reference.
const LIGHT: [&str; 6] = ["--light", "sky+indirect", "--sky", "1,1,1", "--ground", "1,1,1"];

/// The folder with the untextured scene and every bake's exports.
struct Bakes {
    dir: tempfile::TempDir,
}

/// The Breakfast Room's glTF without images, textures, cameras and the DDS extension.
fn untextured(gltf: &Path) -> String {
    let mut g: Value = serde_json::from_str(&std::fs::read_to_string(gltf).unwrap()).unwrap();
    let o = g.as_object_mut().unwrap();
    for k in ["images", "textures", "samplers", "cameras"] {
        o.remove(k);
    }
    if let Some(used) = o.get_mut("extensionsUsed").and_then(Value::as_array_mut) {
        used.retain(|e| e != "MSFT_texture_dds");
    }
    for m in o.get_mut("materials").and_then(Value::as_array_mut).into_iter().flatten() {
        if let Some(pbr) = m.get_mut("pbrMetallicRoughness").and_then(Value::as_object_mut) {
            pbr.remove("baseColorTexture");
            pbr.remove("metallicRoughnessTexture");
        }
        let m = m.as_object_mut().unwrap();
        for k in ["normalTexture", "occlusionTexture", "emissiveTexture"] {
            m.remove(k);
        }
    }
    for n in o.get_mut("nodes").and_then(Value::as_array_mut).into_iter().flatten() {
        n.as_object_mut().unwrap().remove("camera");
    }
    g.to_string()
}

/// The bakes, each exported for the clients: `ENGINE-METHOD.ktx2`.
fn bakes() -> &'static Bakes {
    static BAKES: OnceLock<Bakes> = OnceLock::new();
    BAKES.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let src = root().join("data/scenes/breakfast_room");
        std::fs::copy(src.join("BreakfastRoom.bin"), dir.path().join("BreakfastRoom.bin")).unwrap();
        std::fs::write(dir.path().join("room.gltf"), untextured(&src.join("BreakfastRoom.gltf"))).unwrap();
        let scene = dir.path().join("room.gltf");
        let bake = |name: &str, method: &[&str]| {
            let out = dir.path().join(format!("{name}.exr"));
            let mut args =
                vec!["bake", s(&scene), "--samples", SAMPLES, "--seed", "1", "--quiet", "-o", s(&out)];
            args.extend(LIGHT);
            args.extend(method);
            ok(&args);
            out
        };
        let export = |volume: &Path, engine: Engine, name: &str| {
            let out = dir.path().join(format!("{}-{name}.ktx2", engine.name()));
            ok(&["export", s(volume), "--format", engine.name(), "-o", s(&out)]);
        };
        for engine in [Engine::Three, Engine::Bevy] {
            let v = bake(&format!("doi-{}", engine.name()), &["--target", engine.name()]);
            export(&v, engine, "doi");
        }
        for method in ["point+apv", "point+ddgi"] {
            let v = bake(method, &["--method", method]);
            for engine in [Engine::Three, Engine::Bevy] {
                export(&v, engine, method);
            }
        }
        Bakes { dir }
    })
}

fn shot() -> Shot<'static> {
    Shot {
        files: bakes().dir.path(),
        scene: "room.gltf",
        eye: EYE,
        target: TARGET,
        fov: FOV,
        width: WIDTH,
        height: HEIGHT,
    }
}

/// The path-traced view under the bakes' light, 256 samples a pixel.
fn reference() -> &'static Frame {
    static REFERENCE: OnceLock<Frame> = OnceLock::new();
    REFERENCE.get_or_init(|| path_traced(&shot(), &LIGHT))
}

// Measured (relative RMSE of each frame against the path-traced view), seed 1: three.js
// doi 0.1558, APV 0.1787, DDGI 0.1825; Bevy 0.1590, 0.1975, 0.3499. Seed 2: three.js
// 0.1545, 0.1657, 0.1680; Bevy 0.1608, 0.1896, 0.3247. The targeted doi leads the nearest
// fix by 12.8% at seed 1 (the seed of these bakes) and by 6.8% at seed 2, so the comparison
// is strict.

/// Each method's frame drawn by `engine` against the path-traced view; the targeted `doi`
/// must be closer than both engine fixes.
fn targeted_doi_beats_the_fixes(engine: Engine) {
    let truth = reference();
    let interior = edge_mask(&shot());
    let mut errors = Vec::new();
    for method in ["doi", "point+apv", "point+ddgi"] {
        let texture = format!("{}-{method}.ktx2", engine.name());
        let Some(frame) = engine.render(&shot(), &texture, "none", None) else { return };
        let (err, n) = frame_rmse(&frame, truth, &interior);
        assert!(n > (WIDTH * HEIGHT / 3) as usize, "{}: only {n} pixels compared", engine.name());
        eprintln!(
            "{}: {method}{} against the path-traced view: relative RMSE {err:.4} over {n} pixels",
            engine.name(),
            if method == "doi" { format!(" --target {}", engine.name()) } else { String::new() }
        );
        errors.push((method, err));
    }
    let doi = errors[0].1;
    for &(method, err) in &errors[1..] {
        assert!(doi < err, "{}: doi --target {} {doi} against {method} {err}", engine.name(), engine.name());
    }
}

#[test]
fn three_js_draws_targeted_doi_closer_to_path_tracing_than_the_fixes() {
    targeted_doi_beats_the_fixes(Engine::Three);
}

#[test]
fn bevy_draws_targeted_doi_closer_to_path_tracing_than_the_fixes() {
    targeted_doi_beats_the_fixes(Engine::Bevy);
}
