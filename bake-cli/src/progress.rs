//! Progress bars on standard error (indicatif), and bakes run under one.

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use lightvol_core::progress::{BakeControl, Progress};
use lightvol_sampler::{BakeOutput, BakeSettings};
use lightvol_scene::{Tracer, Transport, TransportSettings};
use lightvol_volume::GridSpec;

use crate::setup::LoadedScene;

/// A progress bar on stderr (hidden when quiet or not a terminal).
pub(crate) fn progress_bar(quiet: bool, len: u64, what: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_owned());
    pb
}

/// Shows the progress report `p` on `pb`: the units done of the total.
pub(crate) fn show(pb: &ProgressBar, p: Progress) {
    pb.set_length(p.total as u64);
    pb.set_position(p.done as u64);
}

/// Runs `f` with a [`BakeControl`] whose progress drives a bar labelled `label` (hidden when
/// `quiet`), cleared when `f` returns.
pub(crate) fn with_bar<T>(quiet: bool, label: &str, f: impl FnOnce(&BakeControl<'_>) -> T) -> T {
    with_report_bar(quiet, label, |report| f(&BakeControl { progress: Some(report), cancel: None }))
}

/// Runs `f` with a progress report that drives a bar labelled `label` (hidden when
/// `quiet`), cleared when `f` returns: bakes, and the path-traced views of `render`.
pub(crate) fn with_report_bar<T>(
    quiet: bool,
    label: &str,
    f: impl FnOnce(&(dyn Fn(Progress) + Sync)) -> T,
) -> T {
    let pb = progress_bar(quiet, 0, label);
    let out = f(&|p| show(&pb, p));
    pb.finish_and_clear();
    out
}

/// Runs `bake` with a transport over `loaded` and a progress bar labelled `label` (hidden
/// when `quiet`), cleared when the bake ends.
pub(crate) fn with_progress<T>(
    loaded: &LoadedScene,
    tracer: &Tracer,
    transport_settings: TransportSettings,
    quiet: bool,
    label: &str,
    bake: impl FnOnce(&Transport<'_>, &BakeControl<'_>) -> Result<T, lightvol_sampler::BakeError>,
) -> anyhow::Result<T> {
    let transport = Transport::new(&loaded.scene, tracer, transport_settings);
    with_bar(quiet, label, |c| bake(&transport, c)).context("baking")
}

/// Bakes `loaded` on `grid` with `settings`, showing progress.
pub(crate) fn run_bake(
    loaded: &LoadedScene,
    tracer: &Tracer,
    grid: &GridSpec,
    settings: &BakeSettings,
    transport_settings: TransportSettings,
    quiet: bool,
    label: &str,
) -> anyhow::Result<BakeOutput> {
    with_progress(loaded, tracer, transport_settings, quiet, label, |t, c| {
        lightvol_sampler::bake(t, grid, settings, c)
    })
}
