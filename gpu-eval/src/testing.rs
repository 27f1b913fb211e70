//! The one entry point of every GPU test: a context, or a clear skip.
//!
//! Tests call [`gpu_or_skip`]: with a usable Vulkan device it returns the context; without
//! one it prints exactly one line to stderr, `skipped: no Vulkan device (<reason>)` (also
//! under `cargo test`'s output capture), and returns `None`, so machines without Vulkan
//! still pass. With `LIGHTVOL_REQUIRE_GPU=1` (CI, which
//! installs lavapipe) a missing device panics instead, so it cannot pass by skipping.

use std::io::Write;

use crate::context::{ContextOptions, GpuContext};
use crate::error::GpuError;

/// Environment variable: `1` turns "no Vulkan device" from a skip into a test failure.
pub const REQUIRE_GPU_ENV: &str = "LIGHTVOL_REQUIRE_GPU";

/// Whether `LIGHTVOL_REQUIRE_GPU=1` is set.
#[must_use]
pub fn gpu_required() -> bool {
    std::env::var(REQUIRE_GPU_ENV).is_ok_and(|v| v.trim() == "1")
}

/// A context from the environment ([`ContextOptions::from_env`]), or `None` after printing
/// the skip line (see the module docs).
///
/// # Panics
/// If there is no device and `LIGHTVOL_REQUIRE_GPU=1`, or if context creation fails for a
/// reason other than a missing loader or device (a real bug).
#[must_use]
pub fn gpu_or_skip() -> Option<GpuContext> {
    context_or_skip(&ContextOptions::from_env())
}

/// [`gpu_or_skip`] with explicit options.
///
/// # Panics
/// As [`gpu_or_skip`].
#[must_use]
pub fn context_or_skip(opts: &ContextOptions) -> Option<GpuContext> {
    match GpuContext::with_options(opts) {
        Ok(ctx) => Some(ctx),
        Err(e @ (GpuError::NoLoader(_) | GpuError::NoDevice(_))) => {
            let reason = skip_reason(&e);
            assert!(!gpu_required(), "{REQUIRE_GPU_ENV}=1 but there is no Vulkan device ({reason})");
            // Straight to the stderr handle, not `eprintln!`: the test harness captures the
            // print macros of passing tests, and this line must be seen.
            let _ = writeln!(std::io::stderr(), "skipped: no Vulkan device ({reason})");
            None
        }
        Err(e) => panic!("Vulkan context creation failed: {e}"),
    }
}

/// A context with the Khronos validation layer on (for the validation tests), or `None`
/// after a skip line: no device (as [`gpu_or_skip`]), or no validation layer, which prints
/// `!!! VALIDATION NOT CHECKED: <reason> !!!` unless `LIGHTVOL_REQUIRE_GPU=1`, where it panics.
///
/// # Panics
/// As [`gpu_or_skip`], and when the layer is missing under `LIGHTVOL_REQUIRE_GPU=1`.
#[must_use]
pub fn validated_context_or_skip() -> Option<GpuContext> {
    // Probe for a device first so that "no device" takes the ordinary skip path.
    drop(gpu_or_skip()?);
    let opts = ContextOptions { validation: true, ..ContextOptions::from_env() };
    match GpuContext::with_options(&opts) {
        Ok(ctx) => Some(ctx),
        Err(GpuError::ValidationUnavailable(why)) => {
            assert!(!gpu_required(), "{REQUIRE_GPU_ENV}=1 but validation is unavailable: {why}");
            let _ = writeln!(std::io::stderr(), "!!! VALIDATION NOT CHECKED: {why} !!!");
            None
        }
        Err(e) => panic!("Vulkan context creation with validation failed: {e}"),
    }
}

/// The reason text of a skip: the error without its "no Vulkan ..." prefix.
fn skip_reason(e: &GpuError) -> String {
    match e {
        GpuError::NoLoader(r) => format!("loader: {r}"),
        GpuError::NoDevice(r) => r.clone(),
        other => other.to_string(),
    }
}
