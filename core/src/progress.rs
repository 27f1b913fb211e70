//! Progress reports and cancellation of long work (bakes of volumes, of octree levels and of
//! lightmaps, path-traced views): the caller passes a [`BakeControl`] with an optional
//! callback, which receives [`Progress`] reports from the calling thread, and an optional
//! flag; raising the flag stops the work at its next unit.

use std::sync::atomic::{AtomicBool, Ordering};

/// Progress report: units done of the shard's total.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// Units finished.
    pub done: usize,
    /// Units in this shard.
    pub total: usize,
}

/// Progress callback and cancellation flag (both optional).
#[derive(Clone, Copy, Default)]
pub struct BakeControl<'a> {
    /// Called after every chunk, from the calling thread.
    pub progress: Option<&'a (dyn Fn(Progress) + Sync)>,
    /// When it becomes true the work stops at its next unit and returns its "cancelled"
    /// error (lightvol-sampler's `BakeError::Cancelled`, for example).
    pub cancel: Option<&'a AtomicBool>,
}

impl std::fmt::Debug for BakeControl<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BakeControl")
            .field("progress", &self.progress.is_some())
            .field("cancel", &self.cancel)
            .finish()
    }
}

impl BakeControl<'_> {
    /// True when the caller has raised the cancel flag.
    #[must_use]
    #[inline]
    pub fn cancelled(&self) -> bool {
        self.cancel.is_some_and(|c| c.load(Ordering::Relaxed))
    }

    /// Reports `p` to the callback, if there is one.
    #[inline]
    pub fn report(&self, p: Progress) {
        if let Some(f) = self.progress {
            f(p);
        }
    }
}
