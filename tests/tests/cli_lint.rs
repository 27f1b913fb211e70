//! `lightvol lint` finds a flipped triangle in an otherwise closed mesh ([KL06] §7) and
//! passes the clean mesh and the Cornell box.

use std::process::ExitCode;

/// A closed cube (outward normals, 12 triangles) standing in open space on a ground quad;
/// with `flip`, one of its side triangles is reversed.
fn cube_obj(flip: bool) -> String {
    let mut s = String::from("v -20 -20 0\nv 20 -20 0\nv 20 20 0\nv -20 20 0\n");
    for z in [1.0, 3.0] {
        for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            s += &format!("v {x} {y} {z}\n");
        }
    }
    s += "f 1 2 3\nf 1 3 4\n"; // ground, facing up
    // Cube vertices 5..12: bottom 5-8, top 9-12 (counter-clockwise seen from above).
    let faces = [
        [5, 7, 6],
        [5, 8, 7], // bottom, facing down
        [9, 10, 11],
        [9, 11, 12], // top, facing up
        [5, 6, 10],
        [5, 10, 9], // -y side
        [6, 7, 11],
        [6, 11, 10], // +x side
        [7, 8, 12],
        [7, 12, 11], // +y side
        [8, 5, 9],
        [8, 9, 12], // -x side
    ];
    for (i, f) in faces.iter().enumerate() {
        let f = if flip && i == 6 { [f[0], f[2], f[1]] } else { *f };
        s += &format!("f {} {} {}\n", f[0], f[1], f[2]);
    }
    s
}

fn lint(path: &std::path::Path) -> ExitCode {
    let args = [
        "lightvol",
        "lint",
        path.to_str().unwrap(),
        "--up",
        "z",
        "--bounds",
        "-4,-4,0.2,4,4,4",
        "--res",
        "9,9,5",
    ];
    lightvol::run_from_args(args).unwrap_or_else(|e| panic!("{e:#}"))
}

#[test]
fn flipped_triangle_is_reported_and_clean_meshes_pass() {
    let dir = tempfile::tempdir().unwrap();
    let clean = dir.path().join("clean.obj");
    std::fs::write(&clean, cube_obj(false)).unwrap();
    let flipped = dir.path().join("flipped.obj");
    std::fs::write(&flipped, cube_obj(true)).unwrap();
    assert_eq!(lint(&clean), ExitCode::SUCCESS);
    assert_eq!(lint(&flipped), ExitCode::from(2));
    let cornell = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/cornell_box/cornell_box.obj");
    let code = lightvol::run_from_args(["lightvol", "lint", cornell, "--up", "y"]).unwrap();
    assert_eq!(code, ExitCode::SUCCESS);
}
