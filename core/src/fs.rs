//! Atomic and bounded file I/O.
//!
//! A writer never leaves a half-written file: the bytes go to a temporary file in the
//! target's directory (`.lightvol-*.tmp`), which is written, synced to disk and renamed
//! over the target (atomic on POSIX and NTFS); on Unix the directory is synced too, so the
//! rename itself survives a crash. On any error the temporary file is removed and the
//! target is untouched. A reader refuses a file larger than its caller's limit before
//! reading any of it.

use std::fs::File;
use std::io::{self, Write};
use std::path::Path;

/// The directory a new file at `path` is created in (`.` for a bare file name).
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Writes the file at `path` atomically (module docs): `write` fills a temporary file in
/// the same directory, which then replaces `path`.
///
/// # Errors
/// Any error of `write`, of creating, syncing or renaming the temporary file; the temporary
/// file is removed and `path` is left as it was.
pub fn write_atomic_with<E: From<io::Error>>(
    path: &Path,
    write: impl FnOnce(&mut File) -> Result<(), E>,
) -> Result<(), E> {
    let dir = parent_dir(path);
    // Dropping `tmp` on any early return deletes the temporary file.
    let mut tmp = tempfile::Builder::new().prefix(".lightvol-").suffix(".tmp").tempfile_in(dir)?;
    write(tmp.as_file_mut())?;
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    sync_dir(dir)?;
    Ok(())
}

/// [`write_atomic_with`] for bytes already in memory.
///
/// # Errors
/// As [`write_atomic_with`].
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_with(path, |f| f.write_all(bytes))
}

/// Syncs a directory's entries (Unix; elsewhere the rename is all there is).
fn sync_dir(dir: &Path) -> io::Result<()> {
    #[cfg(unix)]
    File::open(dir)?.sync_all()?;
    #[cfg(not(unix))]
    let _ = dir;
    Ok(())
}

/// Reads a whole file, refusing one larger than `max_bytes` before reading it.
///
/// # Errors
/// The file's metadata or contents cannot be read, or it is larger than `max_bytes`
/// ([`io::ErrorKind::InvalidData`], naming both sizes).
pub fn read_bounded(path: &Path, max_bytes: u64) -> io::Result<Vec<u8>> {
    let len = std::fs::metadata(path)?.len();
    if len > max_bytes {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("file of {len} bytes is too large (at most {max_bytes} are read)"),
        ));
    }
    std::fs::read(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn replaces_the_target_and_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two!").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two!");
        assert_eq!(entries(dir.path()), ["a.bin"]);
    }

    /// A writer that fails half-way leaves the old file and no temporary one.
    #[test]
    fn a_failed_write_leaves_the_target_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        write_atomic(&p, b"old").unwrap();
        let r = write_atomic_with(&p, |f| {
            f.write_all(b"half")?;
            Err(io::Error::other("disk on fire"))
        });
        assert_eq!(r.unwrap_err().to_string(), "disk on fire");
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(entries(dir.path()), ["a.bin"]);
        // A directory that does not exist is an error, not a panic, and creates nothing.
        assert!(write_atomic(&dir.path().join("no/such/dir/x"), b"x").is_err());
        assert_eq!(entries(dir.path()), ["a.bin"]);
    }

    #[test]
    fn bounded_reads_refuse_large_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        write_atomic(&p, &[7; 10]).unwrap();
        assert_eq!(read_bounded(&p, 10).unwrap(), [7; 10]);
        let e = read_bounded(&p, 9).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert!(e.to_string().contains("10 bytes"), "{e}");
        assert!(read_bounded(&dir.path().join("missing"), 10).is_err());
    }
}
