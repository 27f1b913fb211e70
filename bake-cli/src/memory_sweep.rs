//! The files of the error-vs-memory study (`compare --memory-sweep`, and `demo` on `city`
//! and `interior`; the study itself is lightvol-sampler's `eval::memory_sweep`):
//! `memory_sweep.json` (the sweep's report with the scene's label) and its plot, relative
//! RMSE against log2 of the memory, as `memory_sweep.svg` and `.png`.

use std::path::Path;

use lightvol_sampler::eval::SweepReport;
use serde::Serialize;

use crate::imaging::{Plot, write_atomic};

/// `memory_sweep.json`: the scene's label, then the report's fields.
#[derive(Serialize)]
struct SweepJson<'a> {
    /// Scene label.
    scene: &'a str,
    /// The study.
    #[serde(flatten)]
    report: &'a SweepReport,
}

/// rel_rmse against log2 of the memory in KiB, one line per series.
#[must_use]
pub(crate) fn plot(scene: &str, report: &SweepReport) -> Plot {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for p in &report.points {
        // Memories span two orders of magnitude: a log axis (the plot's axis is linear).
        let xy = ((p.memory_bytes as f64 / 1024.0).log2(), p.rel_rmse);
        match series.iter_mut().find(|s| s.0 == p.series) {
            Some(s) => s.1.push(xy),
            None => series.push((p.series.clone(), vec![xy])),
        }
    }
    Plot {
        title: format!("{}: relative RMSE vs run-time memory", scene.trim_start_matches("builtin:")),
        x_label: "log2 of memory in KiB (f32 SH [+ gradients] per node)".into(),
        y_label: "relative RMSE".into(),
        series,
    }
}

/// Writes `memory_sweep.json`, `memory_sweep.svg` and `memory_sweep.png` of the study on
/// the scene labelled `scene` into `dir`.
pub(crate) fn write(dir: &Path, scene: &str, report: &SweepReport) -> anyhow::Result<()> {
    let json = SweepJson { scene, report };
    write_atomic(&dir.join("memory_sweep.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    plot(scene, report).write(&dir.join("memory_sweep"))
}
