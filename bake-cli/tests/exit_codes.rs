//! The binary itself: errors are one line on stderr and exit status 1; help exits 0.

use std::process::Command;

fn lightvol(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lightvol")).args(args).output().expect("run lightvol")
}

#[test]
fn errors_are_one_line_and_exit_1() {
    for args in
        [&["info", "/nonexistent/v.exr"][..], &["bake", "builtin:city", "--res", "0,0,0"], &["nonsense-verb"]]
    {
        let out = lightvol(args);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
        assert!(lines[0].starts_with("error: "), "{stderr}");
        assert!(!stderr.contains("panicked"));
    }
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
