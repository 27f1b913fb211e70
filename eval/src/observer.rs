//! What an evaluation tells its caller while it runs: the stage it is in (each bake, the
//! reference), the progress of that stage, and each measured point of the sweeps. A
//! command line draws progress bars from it; a test or a batch job passes [`Silent`].

use crate::metrics::Metrics;
use crate::metrics::SweepPoint;
use lightvol_core::progress::Progress;

/// Receives an evaluation's progress. Every method has an empty default; the calls come
/// from the thread that called the evaluation (the bakes report from their calling thread,
/// see [`BakeControl`](lightvol_core::progress::BakeControl)), one stage at a time.
pub trait Observer: Sync {
    /// A stage starts: the bake labelled `label` (the entry's name, or `sweep x0.5`, ...)
    /// or the path-traced reference (`reference`).
    fn stage_started(&self, label: &str) {
        let _ = label;
    }

    /// Progress of the current stage: units (cells, nodes, plates) done of the total known
    /// so far.
    fn progress(&self, progress: Progress) {
        let _ = progress;
    }

    /// The current stage ended (successfully or not).
    fn stage_finished(&self) {}

    /// One point of the error-vs-memory study was measured; `octree_base` is the base
    /// grid's resolution for the octree series, `None` for the uniform ones.
    fn sweep_point(&self, point: &SweepPoint, octree_base: Option<[u32; 3]>) {
        let _ = (point, octree_base);
    }

    /// One point of the resolution study was measured: `method` on a grid of `nodes_x`
    /// nodes along x.
    fn resolution_point(&self, method: &str, nodes_x: u32, metrics: &Metrics) {
        let _ = (method, nodes_x, metrics);
    }
}

/// An [`Observer`] that ignores everything.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Observer for Silent {}
