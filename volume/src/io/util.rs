//! The format modules' file edges: lightvol-core's atomic writes and bounded reads
//! (`lightvol_core::fs`, whose docs say what "atomic" guarantees) with the path in the
//! error, and a panic guard for third-party parsers.

use std::path::Path;

use crate::error::VolumeError;

/// Largest file the readers accept (4 GiB): well above any volume within
/// [`crate::grid::MAX_NODES`] at f16, and a guard against reading arbitrary huge files.
pub const MAX_FILE_BYTES: u64 = 4 << 30;

/// Writes `bytes` to `path` atomically (`lightvol_core::fs::write_atomic`).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), VolumeError> {
    lightvol_core::fs::write_atomic(path, bytes).map_err(|e| VolumeError::io(path, e))
}

/// Reads a whole file, refusing files larger than [`MAX_FILE_BYTES`].
pub fn read_bounded(path: &Path) -> Result<Vec<u8>, VolumeError> {
    lightvol_core::fs::read_bounded(path, MAX_FILE_BYTES).map_err(|e| VolumeError::io(path, e))
}

/// Runs a third-party parser and turns a panic inside it into an error. Our own code never
/// panics on bad input; this is a second line of defence for dependencies (exr, ddsfile)
/// whose parsers we cannot audit, so that malformed files are always an `Err`.
pub(crate) fn guard<T>(
    format: crate::error::FileFormat,
    f: impl FnOnce() -> Result<T, VolumeError> + std::panic::UnwindSafe,
) -> Result<T, VolumeError> {
    match std::panic::catch_unwind(f) {
        Ok(r) => r,
        Err(_) => {
            Err(VolumeError::malformed(format, "the decoder rejected the data (internal panic caught)"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The wrappers' own job: the path is in the error.
    #[test]
    fn errors_name_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing/x.bin");
        let e = write_atomic(&missing, b"x").unwrap_err().to_string();
        assert!(e.contains("x.bin"), "{e}");
        let e = read_bounded(&dir.path().join("nope.bin")).unwrap_err().to_string();
        assert!(e.contains("nope.bin"), "{e}");
    }
}
