//! The vendored real scenes (`data/scenes`, made by other people) end to end through the
//! CLI: each loads, `inspect` describes it as its SOURCE.txt does, a small bake runs, and
//! the Breakfast Room renders through its own glTF camera.

mod common;

use common::{ok, run, s};
use std::path::PathBuf;

fn scene(rel: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes")).join(rel)
}

/// (file, instanced triangles, unique triangles, cameras, node spacing for a small bake).
const SCENES: [(&str, usize, usize, usize, &str); 5] = [
    ("breakfast_room/BreakfastRoom.gltf", 262_687, 82_291, 3, "0.6"),
    ("occlusion_room/room.glb", 63_720, 63_720, 0, "1.5"),
    ("living_room/living_room.glb", 5_088, 5_088, 0, "2"),
    ("zdm2/zdm2.glb", 58_772, 58_772, 0, "8"),
    ("cornell_original/CornellBox-Original.obj", 36, 36, 0, "0.5"),
];

#[test]
fn every_vendored_scene_is_inspected_and_bakes() {
    let dir = tempfile::tempdir().unwrap();
    for (file, instanced, unique, cameras, spacing) in SCENES {
        let path = scene(file);
        let json = dir.path().join("inspect.json");
        ok(&["inspect", s(&path), "--json", "-o", s(&json)]);
        let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        let n = |k: &str| j[k].as_u64().unwrap() as usize;
        assert_eq!(n("instanced_triangles") + n("degenerate_skipped"), instanced, "{file}");
        assert_eq!(n("unique_triangles"), unique, "{file}");
        assert_eq!(j["cameras"].as_array().unwrap().len(), cameras, "{file}");
        assert_eq!(j["up"], "y-up");
        // The file frame is +Y up: its y extent is the internal z extent.
        let (fmin, fmax) = (&j["bounds_file"]["min"], &j["bounds_file"]["max"]);
        let (imin, imax) = (&j["bounds_internal"]["min"], &j["bounds_internal"]["max"]);
        assert_eq!(fmin[1], imin[2], "{file}");
        assert_eq!(fmax[1], imax[2], "{file}");
        assert!(!j["materials"].as_array().unwrap().is_empty());
        // The memory estimate, made before loading, counted exactly the triangles the load
        // made, and its bytes follow the model.
        let m = &j["memory"];
        assert_eq!(m["triangles"].as_u64().unwrap() as usize, instanced, "{file}: estimated triangles");
        let tri = m["triangles"].as_u64().unwrap();
        // Traced through one level (all of them place under a million triangles), with the
        // instanced ones' placed triangles (128 bytes each) written out for the build.
        let copy = if m["instances"].as_u64().unwrap() > 0 { 128 } else { 0 };
        let per = lightvol_scene::estimate::tracer_bytes_per_triangle()
            + lightvol_scene::estimate::BVH_BUILD_BYTES_PER_TRIANGLE
            + copy;
        assert_eq!(m["tracer_bytes"].as_u64().unwrap(), tri * per, "{file}");
        let parts: u64 =
            ["geometry_bytes", "tracer_bytes", "texture_bytes"].iter().map(|k| m[*k].as_u64().unwrap()).sum();
        assert_eq!(m["total_bytes"].as_u64().unwrap(), parts);
        if file.starts_with("breakfast_room") {
            // Its textures: marble.jpg, picture3.jpg and tiles.png, 4 bytes a texel.
            assert!(m["texture_bytes"].as_u64().unwrap() > 0, "{file}: textures counted");
        }
        // The text form names the same counts.
        let txt = dir.path().join("inspect.txt");
        ok(&["inspect", s(&path), "-o", s(&txt)]);
        let t = std::fs::read_to_string(&txt).unwrap();
        assert!(t.contains(&format!("{unique} in the file's unique meshes")), "{file}: {t}");
        let vol = dir.path().join("v.exr");
        ok(&[
            "bake",
            s(&path),
            "--spacing",
            spacing,
            "--samples",
            "4",
            "--bounces",
            "1",
            "--sky",
            "1,1,1",
            "--quiet",
            "-o",
            s(&vol),
        ]);
        assert!(std::fs::metadata(&vol).unwrap().len() > 0);
        std::fs::remove_file(&vol).unwrap();
    }
}

/// `render --reference --camera gltf:N|NAME` uses the file's camera: its aspect ratio sets
/// the image height (1.7778 at width 64 → 36), and a missing camera is one clear line.
#[test]
fn breakfast_room_renders_through_its_glb_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("breakfast_room/BreakfastRoom.gltf");
    let out = dir.path().join("view.png");
    ok(&[
        "render",
        s(&path),
        "--reference",
        "--camera",
        "gltf:0",
        "--width",
        "64",
        "--reference-samples",
        "2",
        "--sky",
        "1,1,1",
        "-o",
        s(&out),
    ]);
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (64, 36));
    // Not a black image: the camera looks into the lit room.
    assert!(img.to_rgb8().pixels().any(|p| p.0.iter().any(|&c| c > 0)));
    ok(&[
        "render",
        s(&path),
        "--reference",
        "--camera",
        "gltf:CameraTopDown",
        "--width",
        "32",
        "--height",
        "20",
        "--reference-samples",
        "1",
        "-o",
        s(&out),
    ]);
    assert_eq!(image::open(&out).unwrap().height(), 20);
    let e = run(&["render", s(&path), "--reference", "--camera", "gltf:7", "-o", s(&out)]).unwrap_err();
    assert!(e.contains("no such camera") && e.contains("0 'CameraMain'"), "{e}");
    let cornell = scene("cornell_original/CornellBox-Original.obj");
    let e = run(&["render", s(&cornell), "--reference", "--camera", "gltf:0", "-o", s(&out)]).unwrap_err();
    assert!(e.contains("no perspective camera"), "{e}");
}

/// A scene over `--max-memory-mib` is refused before its geometry is loaded: one line that
/// names the estimate and its biggest consumer, and no output file.
#[test]
fn a_scene_over_the_memory_limit_is_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("never.exr");
    let room = scene("breakfast_room/BreakfastRoom.gltf");
    let e = run(&["bake", s(&room), "--max-memory-mib", "64", "--quiet", "-o", s(&out)]).unwrap_err();
    assert!(
        e.contains("needs about") && e.contains("262687 triangles") && e.contains("--max-memory-mib"),
        "{e}"
    );
    assert!(!e.contains('\n'), "{e}");
    assert!(!out.exists());
    // The grid counts too: a scene that fits, with a grid that does not.
    let e =
        run(&["bake", s(&room), "--max-memory-mib", "400", "--res", "90,90,90", "--quiet", "-o", s(&out)])
            .unwrap_err();
    assert!(e.contains("the bake needs about") && e.contains("grid 90x90x90"), "{e}");
    assert!(!out.exists());
}

/// The 32 × 32 layout of the occlusion room places 65 M triangles and stores 63,720: the
/// estimate (about 53 MiB with its grid) is refused under 32 MiB, in one line naming both
/// counts, without an output file, and the bake goes through under 256 MiB.
#[test]
fn a_1024_room_layout_bakes_within_its_instanced_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let layout = lightvol_scene::layout::write_grid_layout(
        &scene("occlusion_room/room.glb"),
        dir.path(),
        [32, 32],
        10.0,
    )
    .unwrap();
    let out = dir.path().join("layout.exr");
    let grid = ["--bounds", "-5,0.25,-5,315,4.75,315", "--res", "33,2,33", "--samples", "2", "--quiet"];
    let mut args = vec!["bake", s(&layout), "--max-memory-mib", "32", "-o", s(&out)];
    args.extend(grid);
    let e = run(&args).unwrap_err();
    assert!(e.contains("65249280 triangles placed, 63720 stored") && e.contains("--max-memory-mib"), "{e}");
    assert!(!e.contains('\n'), "{e}");
    assert!(!out.exists());
    args[3] = "256";
    ok(&args);
    assert!(out.is_file());
}
