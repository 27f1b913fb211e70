//! The skip / require paths of the GPU test harness (no device: skip, or fail when a device
//! is required), checked by re-running this test binary with the Vulkan driver list pointed
//! at a file that does not exist, so the loader finds no device on any machine.

use std::process::Command;

use lightvol_gpu::gpu_or_skip;

/// Set in the child process; the probe test does nothing without it.
const CHILD_ENV: &str = "LIGHTVOL_GPU_HARNESS_CHILD";

/// Runs in the child: calls the harness once and reports what it got.
#[test]
fn harness_probe() {
    if std::env::var_os(CHILD_ENV).is_none() {
        return;
    }
    let ctx = gpu_or_skip();
    println!("probe: context = {}", ctx.is_some());
}

fn run_child(require: bool) -> (bool, String) {
    let exe = std::env::current_exe().expect("test binary path");
    let mut cmd = Command::new(exe);
    // Captured output (no --nocapture), as under a plain `cargo test`.
    cmd.args(["harness_probe", "--exact", "--show-output", "--test-threads=1"])
        .env(CHILD_ENV, "1")
        // Both spellings: VK_DRIVER_FILES (loader >= 1.3.207) and the older VK_ICD_FILENAMES.
        .env("VK_ICD_FILENAMES", "/nonexistent/lightvol_no_icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/lightvol_no_icd.json")
        .env_remove("VK_ADD_DRIVER_FILES")
        .env_remove("LIGHTVOL_VK_DEVICE")
        .env_remove("LIGHTVOL_VK_VALIDATION");
    if require {
        cmd.env("LIGHTVOL_REQUIRE_GPU", "1");
    } else {
        cmd.env_remove("LIGHTVOL_REQUIRE_GPU");
    }
    let out = cmd.output().expect("run the test binary");
    // stderr first: the skip line goes there, on a line of its own.
    let text = format!("{}\n{}", String::from_utf8_lossy(&out.stderr), String::from_utf8_lossy(&out.stdout));
    (out.status.success(), text)
}

#[test]
fn no_device_skips_with_one_line() {
    let (ok, text) = run_child(false);
    assert!(ok, "child failed:\n{text}");
    let skips: Vec<_> = text.lines().filter(|l| l.starts_with("skipped: no Vulkan device (")).collect();
    assert_eq!(skips.len(), 1, "want exactly one skip line:\n{text}");
    assert!(skips[0].ends_with(')'), "{}", skips[0]);
    assert!(text.contains("probe: context = false"), "{text}");
}

#[test]
fn no_device_fails_when_gpu_required() {
    let (ok, text) = run_child(true);
    assert!(!ok, "child passed although LIGHTVOL_REQUIRE_GPU=1 and no device:\n{text}");
    assert!(text.contains("LIGHTVOL_REQUIRE_GPU=1 but there is no Vulkan device"), "{text}");
    assert!(!text.contains("skipped: no Vulkan device"), "{text}");
}
