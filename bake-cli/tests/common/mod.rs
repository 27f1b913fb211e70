//! Shared by the binary's integration tests: running a test only where its system service
//! is, and saying so loudly where it is not.

/// `available`, or one loud line naming `what` is missing (`msg`) — and a failure instead
/// when the variable `require` is `1` (`.ci/run` sets it).
pub fn available_or_loud(available: bool, require: &str, msg: &str) -> bool {
    if !available {
        assert!(std::env::var(require).as_deref() != Ok("1"), "{msg}, and {require}=1");
        // Straight to the process's stderr, past the test harness's capture, so that a run
        // without the service says so.
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), "\n!!!!! {msg} !!!!!\n");
    }
    available
}
