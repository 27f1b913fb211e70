//! Helpers shared by the CLI integration tests: run `lightvol` in-process and get its one
//! error line.

use std::path::Path;
use std::process::ExitCode;

/// Runs `lightvol ARGS` in-process; an error becomes the line the binary would print.
pub fn run(args: &[&str]) -> Result<ExitCode, String> {
    lightvol::run_from_args(std::iter::once("lightvol").chain(args.iter().copied()))
        .map_err(|e| format!("{e:#}").replace('\n', " "))
}

/// Runs `lightvol ARGS` and panics with the command and its error line if it fails.
pub fn ok(args: &[&str]) {
    if let Err(e) = run(args) {
        panic!("lightvol {}: {e}", args.join(" "));
    }
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("test paths are UTF-8")
}
