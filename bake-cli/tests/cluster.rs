//! The binary on a cluster: `--shard auto` from the scheduler's variables, `lightvol k8s`
//! manifests, and — on a real Slurm (`ci/slurm-up.sh`) — `lightvol slurm --submit --wait`
//! producing the whole bake's file byte for byte (plain, adaptive, and `--target
//! lightvol`, smoothed by the merge job), an `--array=1-8:2` job array with
//! `--shard auto`, and a failing shard that cancels the merge.
//!
//! The Slurm tests need `sbatch` and a configured cluster (`SLURM_CONF`). Without them
//! they say so in one loud line and pass, unless `LIGHTVOL_REQUIRE_SLURM=1` (set by
//! `.ci/run`), which turns the missing cluster into a failure.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_lightvol");

/// The bake every case shares: small and quick, 4 × 5 × 3 nodes of the city.
const BAKE: [&str; 7] = ["--res", "5,5,3", "--samples", "6", "--bounces", "1", "--quiet"];

fn lightvol(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(BIN);
    c.args(args);
    for v in ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX", "AWS_BATCH_JOB_ARRAY_INDEX", "LIGHTVOL_SHARD"] {
        c.env_remove(v);
    }
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("run lightvol")
}

fn ok(args: &[&str], env: &[(&str, &str)]) -> Output {
    let o = lightvol(args, env);
    assert!(o.status.success(), "lightvol {}: {}", args.join(" "), String::from_utf8_lossy(&o.stderr));
    o
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Byte-for-byte equality, reported without dumping the bytes.
fn same_file(a: &Path, b: &Path) {
    let (x, y) = (std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
    let first = x.iter().zip(&y).position(|(p, q)| p != q);
    assert!(
        x.len() == y.len() && first.is_none(),
        "{} and {} differ: {} vs {} bytes, first difference at {first:?}",
        a.display(),
        b.display(),
        x.len(),
        y.len()
    );
}

fn whole_bake(dir: &Path) -> PathBuf {
    let whole = dir.join("whole.exr");
    let mut a = vec!["bake", "builtin:city", "-o", s(&whole)];
    a.extend_from_slice(&BAKE);
    ok(&a, &[]);
    whole
}

/// `--shard auto` reads Slurm's array variables (`--array=1-7:2` task 5 is shard 2 of 4),
/// Kubernetes' and AWS's indices with `--shards`, and `LIGHTVOL_SHARD`; with none it is
/// one line naming what it looked for.
#[test]
fn shard_auto_reads_the_scheduler() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bake = |name: &str, extra: &[&str], env: &[(&str, &str)]| -> PathBuf {
        let out = d.join(name);
        let mut a = vec!["bake", "builtin:city", "-o", s(&out)];
        a.extend_from_slice(&BAKE);
        a.extend_from_slice(extra);
        ok(&a, env);
        std::fs::read(out.with_extension("lvacc")).unwrap();
        out.with_extension("lvacc")
    };
    let explicit = std::fs::read(bake("explicit.exr", &["--shard", "2/4"], &[])).unwrap();
    let slurm = [
        ("SLURM_ARRAY_TASK_ID", "5"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_MAX", "7"),
        ("SLURM_ARRAY_TASK_STEP", "2"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ];
    assert_eq!(std::fs::read(bake("slurm.exr", &["--shard", "auto"], &slurm)).unwrap(), explicit);
    let k8s = [("JOB_COMPLETION_INDEX", "2")];
    assert_eq!(
        std::fs::read(bake("k8s.exr", &["--shard", "auto", "--shards", "4"], &k8s)).unwrap(),
        explicit
    );
    let aws = [("AWS_BATCH_JOB_ARRAY_INDEX", "2")];
    assert_eq!(
        std::fs::read(bake("aws.exr", &["--shard", "auto", "--shards", "4"], &aws)).unwrap(),
        explicit
    );
    assert_eq!(
        std::fs::read(bake("env.exr", &["--shard", "auto"], &[("LIGHTVOL_SHARD", "2/4")])).unwrap(),
        explicit
    );
    let o = lightvol(&["bake", "builtin:city", "--shard", "auto", "-o", s(&d.join("none.exr"))], &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        err.lines().count() == 1 && err.contains("SLURM_ARRAY_TASK_ID") && err.contains("LIGHTVOL_SHARD"),
        "{err}"
    );
    let o = lightvol(&["bake", "builtin:city", "--shard", "auto", "-o", s(&d.join("k.exr"))], &k8s);
    assert!(String::from_utf8_lossy(&o.stderr).contains("--shards N"));
}

/// `lightvol k8s` writes an Indexed Job of N completions running `--shard auto --shards N`
/// and a merge Job, as YAML that is also JSON.
#[test]
fn k8s_writes_an_indexed_job_and_a_merge_job() {
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path().join("jobs");
    let mut a = vec![
        "k8s",
        "builtin:city",
        "--shards",
        "3",
        "--image",
        "registry.example/lightvol:1",
        "--workdir",
        s(&work),
        "-o",
        "/data/city.exr",
    ];
    a.extend_from_slice(&BAKE);
    ok(&a, &[]);
    let read = |f: &str| -> serde_json::Value {
        let t = std::fs::read_to_string(work.join(f)).unwrap();
        let body: String = t.lines().filter(|l| !l.starts_with('#')).collect::<Vec<_>>().join("\n");
        serde_json::from_str(&body).unwrap()
    };
    let bake = read("bake-job.yaml");
    assert_eq!(bake["kind"], "Job");
    assert_eq!(bake["spec"]["completionMode"], "Indexed");
    assert_eq!(bake["spec"]["completions"], 3);
    let cmd = bake["spec"]["template"]["spec"]["containers"][0]["command"][2].as_str().unwrap();
    assert!(
        cmd.contains("lightvol bake builtin:city")
            && cmd.contains("--shard auto --shards 3")
            && cmd.contains("$JOB_COMPLETION_INDEX")
            && cmd.contains("--samples 6"),
        "{cmd}"
    );
    assert!(!cmd.contains("--image") && !cmd.contains("/data/city.exr"), "{cmd}");
    let merge = read("merge-job.yaml");
    let mcmd = merge["spec"]["template"]["spec"]["containers"][0]["command"][2].as_str().unwrap();
    assert!(mcmd.contains("merge /data/shards/*.lvacc -o /data/city.exr"), "{mcmd}");

    // An adaptive bake: one Indexed Job per level, each reading the levels below, and an
    // assembling job.
    let work2 = dir.path().join("adaptive");
    let mut a2 = a.clone();
    let at = a2.iter().position(|x| *x == "--workdir").unwrap() + 1;
    a2[at] = s(&work2);
    a2.extend_from_slice(&["--adaptive", "--max-level", "1"]);
    ok(&a2, &[]);
    let cmd_of = |f: &str| -> String {
        let t = std::fs::read_to_string(work2.join(f)).unwrap();
        let body: String = t.lines().filter(|l| !l.starts_with('#')).collect::<Vec<_>>().join("\n");
        let v: serde_json::Value = serde_json::from_str(&body).unwrap();
        v["spec"]["template"]["spec"]["containers"][0]["command"][2].as_str().unwrap().to_owned()
    };
    let l0 = cmd_of("bake-level0-job.yaml");
    assert!(l0.contains("--shard auto --shards 3 -o /data/shards/level0-"), "{l0}");
    let l1 = cmd_of("bake-level1-job.yaml");
    assert!(
        l1.contains("--level 1 --from-shards /data/shards/level0-*.lvacc -o /data/shards/level1-"),
        "{l1}"
    );
    let m = cmd_of("merge-job.yaml");
    assert!(
        m.contains("--from-shards /data/shards/level0-*.lvacc /data/shards/level1-*.lvref -o /data/city.exr"),
        "{m}"
    );
    assert!(!work2.join("bake-level2-job.yaml").exists());
}

/// Whether a usable Slurm is here; otherwise one loud line, and a failure when
/// `LIGHTVOL_REQUIRE_SLURM=1`.
fn slurm_available(test: &str) -> bool {
    common::available_or_loud(
        Command::new("sinfo").arg("-h").output().is_ok_and(|o| o.status.success()),
        "LIGHTVOL_REQUIRE_SLURM",
        &format!(
            "SLURM TESTS NOT RUN ({test}): no working sinfo/sbatch (start one with ci/slurm-up.sh and source its env)"
        ),
    )
}

/// `lightvol slurm --shards 4 --submit --wait` gives the whole bake's file, byte for byte.
#[test]
fn slurm_submit_wait_equals_the_whole_bake() {
    if !slurm_available("slurm_submit_wait_equals_the_whole_bake") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = whole_bake(d);
    let merged = d.join("cluster.exr");
    let mut a = vec![
        "slurm",
        "builtin:city",
        "--shards",
        "4",
        "--submit",
        "--wait",
        "-o",
        s(&merged),
        "--lightvol",
        BIN,
    ];
    a.extend_from_slice(&BAKE);
    let o = ok(&a, &[]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("bake array"));
    same_file(&merged, &whole);
    assert_eq!(
        std::fs::read_dir(d.join("cluster.slurm/shards"))
            .unwrap()
            .filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == "lvacc"))
            .count(),
        4
    );
}

/// `doi --target lightvol` on the cluster: the shard tasks carry their nodes' error
/// estimates and the merge job smooths the merged set, giving the whole bake's file.
#[test]
fn slurm_targeted_bake_equals_the_whole_bake() {
    if !slurm_available("slurm_targeted_bake_equals_the_whole_bake") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let target = ["--target", "lightvol", "--samples", "16"];
    let whole = d.join("whole.exr");
    let mut a = vec!["bake", "builtin:maze", "-o", s(&whole), "--quiet"];
    a.extend_from_slice(&target);
    ok(&a, &[]);
    let plain = d.join("plain.exr");
    ok(&["bake", "builtin:maze", "--samples", "16", "--quiet", "-o", s(&plain)], &[]);
    assert_ne!(std::fs::read(&whole).unwrap(), std::fs::read(&plain).unwrap(), "the target smooths");
    let merged = d.join("cluster.exr");
    let mut a = vec![
        "slurm",
        "builtin:maze",
        "--shards",
        "3",
        "--submit",
        "--wait",
        "--quiet",
        "-o",
        s(&merged),
        "--lightvol",
        BIN,
    ];
    a.extend_from_slice(&target);
    ok(&a, &[]);
    same_file(&merged, &whole);
}

/// An adaptive bake on the cluster: one job array per octree level, each after the one
/// below, and an assembling job: the whole adaptive bake's file, byte for byte.
#[test]
fn slurm_adaptive_bake_equals_the_whole_bake() {
    if !slurm_available("slurm_adaptive_bake_equals_the_whole_bake") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let adaptive = ["--adaptive", "--max-level", "1", "--depth-rays", "8"];
    let whole = d.join("whole.exr");
    let mut a = vec!["bake", "builtin:city", "-o", s(&whole)];
    a.extend_from_slice(&BAKE);
    a.extend_from_slice(&adaptive);
    ok(&a, &[]);
    let merged = d.join("cluster.exr");
    let mut a = vec![
        "slurm",
        "builtin:city",
        "--shards",
        "3",
        "--submit",
        "--wait",
        "-o",
        s(&merged),
        "--lightvol",
        BIN,
    ];
    a.extend_from_slice(&BAKE);
    a.extend_from_slice(&adaptive);
    let o = ok(&a, &[]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("bake-level0 array") && out.contains("bake-level1 array"), "{out}");
    same_file(&merged, &whole);
    let count = |ext: &str| {
        std::fs::read_dir(d.join("cluster.slurm/shards"))
            .unwrap()
            .filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == ext))
            .count()
    };
    assert_eq!((count("lvacc"), count("lvref")), (3, 3));
}

/// A hand-written sparse array (`--array=1-8:2`: tasks 1, 3, 5, 7) with `--shard auto`,
/// merged, gives the whole bake too.
#[test]
fn slurm_sparse_array_with_shard_auto() {
    if !slurm_available("slurm_sparse_array_with_shard_auto") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = whole_bake(d);
    let wrap = format!(
        "{BIN} bake builtin:city {} --shard auto -o {}/s-$SLURM_ARRAY_TASK_ID.exr",
        BAKE.join(" "),
        s(d)
    );
    let o = Command::new("sbatch")
        .args([
            "--parsable",
            "--wait",
            "--array=1-8:2",
            "--output",
            &format!("{}/log-%a.txt", s(d)),
            "--wrap",
            &wrap,
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let shards: Vec<String> = [1, 3, 5, 7].iter().map(|t| format!("{}/s-{t}.lvacc", s(d))).collect();
    let merged = d.join("m.exr");
    let mut a: Vec<&str> = vec!["merge"];
    a.extend(shards.iter().map(String::as_str));
    a.extend(["-o", s(&merged)]);
    ok(&a, &[]);
    same_file(&merged, &whole);
}

/// A shard that exits non-zero cancels the merge; the CLI exits non-zero and names the
/// failed array task; no merged volume appears.
#[test]
fn slurm_failed_shard_cancels_the_merge() {
    if !slurm_available("slurm_failed_shard_cancels_the_merge") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A lightvol that fails as array task 2.
    let fake = d.join("flaky-lightvol");
    std::fs::write(&fake, format!("#!/bin/sh\nif [ \"${{SLURM_ARRAY_TASK_ID:-}}\" = 2 ]; then echo 'shard 2 broke' >&2; exit 3; fi\nexec {BIN} \"$@\"\n")).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let merged = d.join("never.exr");
    let mut a = vec![
        "slurm",
        "builtin:city",
        "--shards",
        "4",
        "--submit",
        "--wait",
        "-o",
        s(&merged),
        "--lightvol",
        s(&fake),
    ];
    a.extend_from_slice(&BAKE);
    let o = lightvol(&a, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("array task 2") && err.contains("FAILED") && err.contains("CANCELLED"), "{err}");
    assert!(!merged.exists());
}

/// Values that would break out of an `#SBATCH` line or a pod's shell command are refused
/// in one line, and nothing is written.
#[test]
fn job_files_refuse_unsafe_values() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("v.exr");
    for (extra, want) in
        [(&["--partition", "gpu\ntouch /tmp/x #"][..], "control character"), (&["--mem", "4G%"][..], "'%'")]
    {
        let mut a = vec!["slurm", "builtin:city", "--shards", "2", "-o", s(&out)];
        a.extend_from_slice(extra);
        let o = lightvol(&a, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(want), "{err}");
        assert!(!d.join("v.slurm").exists());
    }
    let o = lightvol(
        &[
            "k8s",
            "builtin:city",
            "--shards",
            "2",
            "--image",
            "x",
            "--mount",
            "/data; touch /tmp/x #",
            "-o",
            "/data/v.exr",
            "--workdir",
            s(&d.join("k")),
        ],
        &[],
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("--mount"), "{}", String::from_utf8_lossy(&o.stderr));
    let o = lightvol(
        &[
            "k8s",
            "builtin:city",
            "--shards",
            "2",
            "--image",
            "x",
            "-o",
            "v.exr",
            "--workdir",
            s(&d.join("k")),
        ],
        &[],
    );
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("under --mount"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!d.join("k").exists());
}

/// What a shard's bake refuses is refused before any job file is written (an engine's
/// `--target`, whose fit a merge cannot run); `--target lightvol`, which the merge finishes,
/// goes into the jobs' bake lines.
#[test]
fn job_files_refuse_what_a_shard_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("v.exr");
    let o = lightvol(&["slurm", "builtin:city", "--shards", "2", "--target", "three", "-o", s(&out)], &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("--target") && err.contains("a shard") && !err.trim_end().contains('\n'), "{err}");
    assert!(!d.join("v.slurm").exists());
    ok(&["slurm", "builtin:city", "--shards", "2", "--target", "lightvol", "-o", s(&out)], &[]);
    let job = std::fs::read_to_string(d.join("v.slurm/bake.sbatch")).unwrap();
    assert!(job.contains("--target lightvol"), "{job}");
}
