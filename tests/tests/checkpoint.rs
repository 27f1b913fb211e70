//! `bake --checkpoint DIR` and `--resume`: a bake killed with SIGKILL part-way (in a child
//! process, this test binary started again) and resumed writes the uninterrupted bake's
//! bytes, and the resumed run traces only the pieces the checkpoint lacked.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{ok, run, s};

/// The child's `lightvol` arguments, one per line ([`child_runs_lightvol`]).
const CHILD_ARGS: &str = "LIGHTVOL_TEST_CHECKPOINT_ARGS";

/// Pieces of the bake: enough that the parent sees some finished long before the last.
const PIECES: usize = 24;

/// The bake, checkpointed into `dir` (plus `extra`): doi on the built-in interior, enough
/// samples that a piece takes a noticeable time on one thread, its report as JSON.
fn bake_args(out: &Path, dir: &Path, extra: &[&str]) -> Vec<String> {
    let mut a: Vec<String> = [
        "bake",
        "builtin:interior",
        "--samples",
        "1024",
        "--seed",
        "3",
        "--threads",
        "1",
        "--quiet",
        "--json",
        "--checkpoint-pieces",
        "24",
        "-o",
        s(out),
        "--checkpoint",
        s(dir),
    ]
    .iter()
    .map(|x| (*x).to_owned())
    .collect();
    a.extend(extra.iter().map(|x| (*x).to_owned()));
    a
}

/// This test binary, started again to run only [`child_runs_lightvol`] with `args`.
fn child(args: &[String]) -> Command {
    let mut c = Command::new(std::env::current_exe().unwrap());
    c.args(["child_runs_lightvol", "--exact", "--test-threads", "1", "--nocapture", "--quiet"])
        .env(CHILD_ARGS, args.join("\n"));
    c
}

/// The JSON report a child's `lightvol bake --json` prints (among the test harness's lines).
fn child_report(args: &[String]) -> serde_json::Value {
    let out = child(args).stderr(Stdio::inherit()).output().unwrap();
    assert!(out.status.success(), "lightvol {}", args.join(" "));
    let text = String::from_utf8(out.stdout).unwrap();
    let start = text.find("\n{").map_or(0, |i| i + 1);
    let end = text.rfind("\n}").expect("a JSON report") + 2;
    serde_json::from_str(&text[start..end]).unwrap_or_else(|e| panic!("{e}: {text}"))
}

fn pieces_done(dir: &Path) -> usize {
    lightvol_sampler::checkpoint::read_state(dir).ok().flatten().map_or(0, |s| s.done.len())
}

#[test]
fn a_killed_bake_resumes_to_the_same_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let p = |name: &str| tmp.path().join(name);
    // The uninterrupted bake without a checkpoint, and checkpointed without interruption.
    ok(&[
        "bake",
        "builtin:interior",
        "--samples",
        "1024",
        "--seed",
        "3",
        "--quiet",
        "-o",
        s(&p("whole.exr")),
    ]);
    let straight = child_report(&bake_args(&p("straight.exr"), &p("ck-straight"), &[]));
    assert_eq!(std::fs::read(p("straight.exr")).unwrap(), std::fs::read(p("whole.exr")).unwrap());
    assert!(!p("ck-straight").join("checkpoint.json").exists(), "a finished bake removes its checkpoint");
    let all_rays = straight["rays_total"].as_u64().unwrap();
    assert_eq!(straight["rays_this_run"].as_u64(), Some(all_rays));

    // A child bakes until the parent kills it (SIGKILL) with some pieces done.
    let (dir, out) = (p("ck"), p("resumed.exr"));
    let mut killed = child(&bake_args(&out, &dir, &[])).stdout(Stdio::null()).spawn().unwrap();
    let t0 = Instant::now();
    while pieces_done(&dir) < 3 {
        assert!(killed.try_wait().unwrap().is_none(), "the bake ended before it was killed");
        assert!(t0.elapsed() < Duration::from_secs(600), "no piece finished in 10 minutes");
        std::thread::sleep(Duration::from_millis(5));
    }
    killed.kill().unwrap();
    killed.wait().unwrap();
    let state = lightvol_sampler::checkpoint::read_state(&dir).unwrap().expect("a checkpoint");
    assert!(
        (3..PIECES).contains(&state.done.len()),
        "killed with {} of {PIECES} pieces done",
        state.done.len()
    );
    assert!(state.rays > 0 && state.rays < all_rays, "{} of {all_rays} rays", state.rays);
    assert!(!out.exists(), "the killed bake wrote no volume");

    // Without --resume the checkpoint is refused in one line, and so is another bake's.
    let args = |extra: &[&str]| bake_args(&out, &dir, extra);
    let as_str = |a: &[String]| a.iter().map(String::as_str).collect::<Vec<_>>().join(" ");
    let e = run(&args(&[]).iter().map(String::as_str).collect::<Vec<_>>()).unwrap_err();
    assert!(e.contains("--resume"), "{}: {e}", as_str(&args(&[])));
    let mut other = args(&["--resume"]);
    let seed = other.iter().position(|a| a == "--seed").unwrap() + 1;
    other[seed] = "4".into();
    let e = run(&other.iter().map(String::as_str).collect::<Vec<_>>()).unwrap_err();
    assert!(e.contains("another bake"), "{e}");
    assert!(!out.exists());

    // Resumed: the uninterrupted bake's bytes, tracing only the pieces not yet done.
    let resumed = child_report(&args(&["--resume"]));
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(p("whole.exr")).unwrap(), "resumed bytes");
    assert!(!dir.join("checkpoint.json").exists());
    assert_eq!(resumed["resumed_pieces"].as_array().unwrap().len(), state.done.len());
    let this_run = resumed["rays_this_run"].as_u64().unwrap();
    assert_eq!(
        this_run + state.rays,
        all_rays,
        "rays traced again: {this_run} + {} checkpointed",
        state.rays
    );
    assert_eq!(resumed["rays_total"].as_u64(), Some(all_rays));
}

/// The child process of [`a_killed_bake_resumes_to_the_same_bytes`]: runs `lightvol` with
/// the arguments in [`CHILD_ARGS`]. Without that variable (a normal test run) it does
/// nothing.
#[test]
fn child_runs_lightvol() {
    let Some(args) = std::env::var_os(CHILD_ARGS) else { return };
    let args = args.into_string().unwrap();
    let args: Vec<&str> = args.lines().collect();
    ok(&args);
}
