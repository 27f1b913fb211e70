//! `lightvol bench --whole-bake --vs BIN`: a whole Breakfast Room bake timed against
//! another lightvol executable, here this same one, so both must write the same bytes.
//! Wall times are measured, not asserted.

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_lightvol");

#[test]
fn whole_bake_times_two_executables_on_the_same_bake() {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes");
    let o = Command::new(BIN)
        .args(["bench", "--whole-bake", "--bake-runs", "1", "--data", data, "--vs", BIN])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["samples"], 256);
    assert_eq!(r["spacing"], 0.2);
    assert_eq!(r["wall_seconds"].as_array().unwrap().len(), 1);
    let ours = r["median_wall_seconds"].as_f64().unwrap();
    let theirs = r["vs"]["median_wall_seconds"].as_f64().unwrap();
    assert!(ours > 0.0 && theirs > 0.0, "{r}");
    assert!((r["vs"]["speedup"].as_f64().unwrap() - theirs / ours).abs() < 1e-12, "{r}");
    assert_eq!(r["vs"]["same_bytes"], true, "{r}");
}

#[test]
fn whole_bake_refuses_bad_requests_in_one_line() {
    for (args, want) in
        [(vec!["--data", "/nonexistent"], "not found"), (vec!["--bake-runs", "0"], "at least 1")]
    {
        let o = Command::new(BIN).args(["bench", "--whole-bake"]).args(&args).output().unwrap();
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(want) && e.trim().lines().count() == 1, "{args:?}: {e}");
    }
    let o = Command::new(BIN).args(["bench", "--vs", BIN]).output().unwrap();
    assert!(!o.status.success(), "--vs needs --whole-bake");
}
