//! `compare bound+LOOKUP`, end to end: the node values fitted to the plate's reference
//! through a lookup are a floor under every bake read through the same lookup.

use serde_json::Value;

mod common;

/// Runs `lightvol compare` with `args` quietly into a temporary folder and returns the
/// parsed `report.json`.
fn report(args: &[&str]) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let mut all = args.to_vec();
    all.extend(["--quiet", "-o", common::s(dir.path())]);
    common::ok(&all);
    let text = std::fs::read_to_string(dir.path().join("report.json")).expect("report.json");
    serde_json::from_str(&text).expect("report.json parses")
}

fn rmse(r: &Value, m: &str) -> f64 {
    r["methods"][m]["rel_rmse"].as_f64().unwrap_or_else(|| panic!("{m}.rel_rmse"))
}

/// On the maze and the occlusion room (a wall thinner than a cell): each bound is at or
/// below every method read through its lookup (lightvol's, three.js's), and on a
/// horizontal plate three.js's, Bevy's and plain trilinear lookups share one bound (each
/// reads a bilinear function across the plate's cells, with each column's two node
/// layers free), equal up to the solver's tolerance and f32 node values.
#[test]
fn the_bound_is_a_floor_under_every_method_read_the_same_way() {
    let room = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/occlusion_room/room.glb");
    for scene in ["builtin:maze", room] {
        let r = report(&[
            "compare",
            scene,
            "--light",
            "sky+indirect",
            "--samples",
            "32",
            "--plate-res",
            "48",
            "--reference-samples",
            "128",
            "--methods",
            "doi,doi+three,point+apv,point+ddgi,bound+lightvol,bound+three,bound+trilinear,bound+bevy",
            "--lookup",
            "lightvol,three",
        ]);
        let (own, three) = (rmse(&r, "bound+lightvol"), rmse(&r, "bound+three@three"));
        println!("{scene}: bound lightvol {own:.4}, three {three:.4}");
        for m in ["doi", "doi+three", "point+apv", "point+ddgi"] {
            assert!(own <= rmse(&r, m), "{scene}: bound+lightvol {own} above {m} {}", rmse(&r, m));
            let read = rmse(&r, &format!("{m}@three"));
            assert!(three <= read, "{scene}: bound+three {three} above {m}@three {read}");
        }
        // The solver stops at 1e-7 relative and node values are f32 (6e-8): 1e-5 is far
        // above both and far below any difference between methods.
        for other in ["bound+trilinear@three", "bound+bevy@three"] {
            let b = rmse(&r, other);
            assert!((b - three).abs() <= 1e-5 * three, "{scene}: {other} {b} against bound+three {three}");
        }
    }
}
