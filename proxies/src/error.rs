//! Errors of the crate's fallible edges (scene files, mesh fitting).

/// What can go wrong.
#[derive(Debug, thiserror::Error)]
pub enum ProxyError {
    /// A scene description that does not parse or is degenerate.
    #[error("scene: {0}")]
    Scene(String),
    /// A mesh fit with bad input.
    #[error("sphere fit: {0}")]
    Fit(String),
}
