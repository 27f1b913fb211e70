//! The crate's error type.
//!
//! Everything that touches user input (grid parameters, files, sidecars) returns
//! [`VolumeError`]; readers never panic on malformed or truncated input.

use std::path::PathBuf;

/// The file formats this crate reads and writes, for error messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileFormat {
    /// The native multi-part OpenEXR volume ([`crate::io::exr`]).
    Exr,
    /// The KTX2 RGBA16F 3D texture ([`crate::io::ktx2`]).
    Ktx2,
    /// The DDS volume texture ([`crate::io::dds`]).
    Dds,
    /// Bevy's ambient-cube irradiance volume ([`crate::io::bevy`]).
    Bevy,
    /// The JSON sidecar ([`crate::io::sidecar`]).
    Sidecar,
    /// An accumulator shard file ([`crate::io::accumulator`]).
    Shard,
}

impl std::fmt::Display for FileFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Exr => "OpenEXR",
            Self::Ktx2 => "KTX2",
            Self::Dds => "DDS",
            Self::Bevy => "Bevy KTX2",
            Self::Sidecar => "JSON sidecar",
            Self::Shard => "accumulator shard",
        })
    }
}

/// Every error this crate returns.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VolumeError {
    /// The grid parameters are unusable (resolution below 2, empty or non-finite box,
    /// singular placement transform, too many nodes).
    #[error("invalid grid: {0}")]
    InvalidGrid(String),
    /// The number of SH coefficients per channel is not one this crate supports.
    #[error("unsupported SH coefficient count {0} per channel (supported: 4, 9, 16)")]
    UnsupportedCoeffs(usize),
    /// Two objects that must agree (grids, SH orders, slice lengths) do not.
    #[error("mismatch: {0}")]
    Mismatch(String),
    /// In-memory data is unusable (wrong length, non-finite, unrepresentable in the
    /// requested encoding).
    #[error("invalid data: {0}")]
    InvalidData(String),
    /// A value that must be finite is NaN or infinite.
    #[error("non-finite value in {what} at element {index}")]
    NonFinite {
        /// Which array held it.
        what: &'static str,
        /// Flat element index.
        index: usize,
    },
    /// An operating-system I/O error on a file.
    #[error("I/O error on {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file is malformed: bad magic, truncated, inconsistent sizes, missing metadata.
    #[error("malformed {format} data: {reason}")]
    Malformed {
        /// Which format.
        format: FileFormat,
        /// What is wrong, in words.
        reason: String,
    },
    /// A file is well formed but uses something this crate does not support (another
    /// pixel format, a newer version, a different SH convention).
    #[error("unsupported {format} content: {reason}")]
    Unsupported {
        /// Which format.
        format: FileFormat,
        /// What is unsupported, in words.
        reason: String,
    },
}

impl VolumeError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io { path: path.into(), source }
    }

    pub(crate) fn malformed(format: FileFormat, reason: impl Into<String>) -> Self {
        Self::Malformed { format, reason: reason.into() }
    }

    pub(crate) fn unsupported(format: FileFormat, reason: impl Into<String>) -> Self {
        Self::Unsupported { format, reason: reason.into() }
    }
}

/// Returns the first non-finite element of `values` as an error.
pub(crate) fn check_finite(what: &'static str, values: &[f32]) -> Result<(), VolumeError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(VolumeError::NonFinite { what, index }),
        None => Ok(()),
    }
}
