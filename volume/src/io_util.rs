//! Atomic file writing and bounded file reading shared by the format modules.
//!
//! Writers never leave a half-written file: bytes go to a temporary file in the target's
//! directory, which is flushed, synced and then renamed over the target (atomic on POSIX
//! and NTFS). On any error the temporary file is removed and the target is untouched.

use std::io::Write;
use std::path::Path;

use crate::error::VolumeError;

/// Largest file the readers accept (4 GiB): well above any volume within
/// [`crate::grid::MAX_NODES`] at f16, and a guard against reading arbitrary huge files.
pub const MAX_FILE_BYTES: u64 = 4 << 30;

/// Writes `bytes` to `path` through a temporary file and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), VolumeError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".lightvol-")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| VolumeError::io(path, e))?;
    tmp.write_all(bytes).map_err(|e| VolumeError::io(path, e))?;
    tmp.as_file().sync_all().map_err(|e| VolumeError::io(path, e))?;
    tmp.persist(path).map_err(|e| VolumeError::io(path, e.error))?;
    Ok(())
}

/// Reads a whole file, refusing files larger than [`MAX_FILE_BYTES`].
pub fn read_bounded(path: &Path) -> Result<Vec<u8>, VolumeError> {
    let meta = std::fs::metadata(path).map_err(|e| VolumeError::io(path, e))?;
    if meta.len() > MAX_FILE_BYTES {
        return Err(VolumeError::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("file of {} bytes is too large", meta.len()),
            ),
        ));
    }
    std::fs::read(path).map_err(|e| VolumeError::io(path, e))
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

/// Little-endian f16 bytes of an f32, erroring if it exceeds the f16 range.
pub(crate) fn f16_bytes(v: f32, what: &str) -> Result<[u8; 2], VolumeError> {
    let h = half::f16::from_f32(v);
    if h.is_finite() {
        Ok(h.to_le_bytes())
    } else {
        Err(VolumeError::InvalidData(format!("{what} value {v} exceeds the f16 range (65504)")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two!").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two!");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        // A directory that does not exist is an error, not a panic, and creates nothing.
        assert!(write_atomic(&dir.path().join("missing/x.bin"), b"x").is_err());
        assert!(read_bounded(&dir.path().join("nope")).is_err());
    }
}
