//! Errors of a bake.

/// Errors of a bake ([`bake`](crate::bake())).
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// The caller's cancel flag was raised; nothing is returned.
    #[error("bake cancelled")]
    Cancelled,
    /// Invalid settings (a shard index out of range, an unsupported coefficient count, ...).
    #[error("invalid bake settings: {0}")]
    Settings(String),
    /// The volume crate rejected the grid or the accumulation.
    #[error("volume error: {0}")]
    Volume(String),
}
