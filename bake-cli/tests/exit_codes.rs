//! The binary itself: errors are one line on stderr and exit status 1; help exits 0.

use std::process::Command;

fn lightvol(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lightvol")).args(args).output().expect("run lightvol")
}

#[test]
fn errors_are_one_line_and_exit_1() {
    for args in [
        &["info", "/nonexistent/v.exr"][..],
        &["bake", "builtin:city", "--res", "0,0,0"],
        &["nonsense-verb"],
        &["render", "builtin:city", "--reference", "--exposure", "nan", "-o", "/nonexistent/r.png"],
    ] {
        let out = lightvol(args);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
        assert!(lines[0].starts_with("error: "), "{stderr}");
        assert!(!stderr.contains("panicked"));
    }
}

/// Requests too large for memory are refused in one line before anything is allocated
/// (each of these used to be killed for memory or abort on a failed allocation).
#[test]
fn requests_too_large_for_memory_are_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let (bake, compare) = (out("b.exr"), out("c"));
    for (args, want) in [
        (vec!["bake", "builtin:city", "--samples", "4000000000", "-o", &bake], "samples per unit on"),
        (
            vec!["bake", "builtin:city", "--noise", "0.01", "--max-samples", "4000000000", "-o", &bake],
            "samples per unit on",
        ),
        (
            vec!["compare", "builtin:city", "--plate-res", "100000", "-o", &compare],
            "--plate-res must be between",
        ),
        (vec!["bench", "--rays", "10000000000"], "--rays must be between"),
        (
            vec!["bake-surface", "builtin:city", "--samples", "4000000000", "-o", &compare],
            "samples per unit on",
        ),
    ] {
        let o = lightvol(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(want), "{args:?}: {stderr}");
    }
    assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none(), "nothing written");
}

#[test]
fn help_explains_and_exits_0() {
    let out = lightvol(&["bake", "--help"]);
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8_lossy(&out.stdout);
    for opt in ["--method", "--samples", "--res", "--bounds", "--sun", "--shard", "--sky", "--env", "--up"] {
        assert!(text.contains(opt), "bake --help must explain {opt}");
    }
}

/// Standard output closed by its reader before the command writes (as `| head` does) ends
/// the command quietly with 141, not with a panic: `inspect` loads the Breakfast Room
/// (a few tenths of a second) before it prints, and the pipe is closed at once.
#[test]
fn a_closed_stdout_ends_quietly() {
    use std::process::Stdio;
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/breakfast_room/BreakfastRoom.gltf");
    let mut child = Command::new(env!("CARGO_BIN_EXE_lightvol"))
        .args(["inspect", scene])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run lightvol");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait for lightvol");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), Some(141), "{stderr}");
}
