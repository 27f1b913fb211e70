//! Error against the sample count: the relative RMSE of each method on each plate and view
//! of several `compare` runs of one scene that differ only in `--samples`, as a Markdown
//! table and a plot. A bake's error falls with the samples toward its own bias (the error
//! left at infinite samples); a method whose error rises again, or jumps, changes what it
//! computes with the sample count.

use std::fmt::Write as _;

use lightvol_view::picture::Plot;

/// One method's relative RMSE on one plate or view at one sample count.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorAtSamples {
    /// The series: the method and the plate or view (`doi, plate`, `doi, CameraMain`).
    pub series: String,
    /// Samples per node or cell of the bake.
    pub samples: u32,
    /// Relative RMSE against the path-traced reference.
    pub rel_rmse: f64,
}

/// Each series' points in first-seen order, each sorted by sample count.
fn series(points: &[ErrorAtSamples]) -> Vec<(String, Vec<(u32, f64)>)> {
    let mut out: Vec<(String, Vec<(u32, f64)>)> = Vec::new();
    for p in points {
        match out.iter_mut().find(|s| s.0 == p.series) {
            Some(s) => s.1.push((p.samples, p.rel_rmse)),
            None => out.push((p.series.clone(), vec![(p.samples, p.rel_rmse)])),
        }
    }
    for s in &mut out {
        s.1.sort_by_key(|&(n, _)| n);
    }
    out
}

/// Whether `errors`, in order of growing samples, never rise by more than `slack` (a share
/// of the previous error: the reference's own noise, which every count shares).
#[must_use]
pub fn falls_monotonically(errors: &[f64], slack: f64) -> bool {
    errors.windows(2).all(|w| w[1] <= w[0] * (1.0 + slack))
}

/// The table: one row per series, one column per sample count, and whether the series
/// falls monotonically within `slack` ([`falls_monotonically`]).
#[must_use]
pub fn convergence_table(points: &[ErrorAtSamples], slack: f64) -> String {
    let mut counts: Vec<u32> = points.iter().map(|p| p.samples).collect();
    counts.sort_unstable();
    counts.dedup();
    let mut s = String::from("| method, plate or view |");
    for n in &counts {
        let _ = write!(s, " {n} |");
    }
    s.push_str(" falls |\n| --- |");
    s.push_str(&" ---: |".repeat(counts.len()));
    s.push_str(" --- |\n");
    for (name, pts) in series(points) {
        let _ = write!(s, "| {name} |");
        for n in &counts {
            match pts.iter().find(|p| p.0 == *n) {
                Some((_, e)) => {
                    let _ = write!(s, " {e:.4} |");
                }
                None => s.push_str(" - |"),
            }
        }
        let errors: Vec<f64> = pts.iter().map(|p| p.1).collect();
        let _ = writeln!(s, " {} |", if falls_monotonically(&errors, slack) { "yes" } else { "no" });
    }
    s
}

/// Relative RMSE against log2 of the samples, one line per series.
#[must_use]
pub fn convergence_plot(scene: &str, points: &[ErrorAtSamples]) -> Plot {
    Plot {
        title: format!("{scene}: relative RMSE vs samples"),
        x_label: "log2 of samples per node or cell".into(),
        y_label: "relative RMSE".into(),
        series: series(points)
            .into_iter()
            .map(|(name, pts)| (name, pts.into_iter().map(|(n, e)| (f64::from(n).log2(), e)).collect()))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(series: &str, samples: u32, rel_rmse: f64) -> ErrorAtSamples {
        ErrorAtSamples { series: series.into(), samples, rel_rmse }
    }

    #[test]
    fn a_rise_beyond_the_slack_is_not_monotone() {
        assert!(falls_monotonically(&[0.3, 0.25, 0.25, 0.2], 0.0));
        assert!(falls_monotonically(&[0.3, 0.301], 0.01));
        assert!(!falls_monotonically(&[0.3, 0.31], 0.01));
        assert!(falls_monotonically(&[], 0.0));
    }

    #[test]
    fn the_table_has_a_column_per_count_and_a_row_per_series() {
        let pts = [
            p("doi, plate", 1024, 0.2),
            p("doi, plate", 256, 0.3),
            p("point, plate", 256, 0.4),
            p("point, plate", 1024, 0.45),
        ];
        let t = convergence_table(&pts, 0.01);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines[0], "| method, plate or view | 256 | 1024 | falls |");
        assert_eq!(lines[2], "| doi, plate | 0.3000 | 0.2000 | yes |");
        assert_eq!(lines[3], "| point, plate | 0.4000 | 0.4500 | no |");
        let plot = convergence_plot("room", &pts);
        assert_eq!(plot.series[0].1, vec![(8.0, 0.3), (10.0, 0.2)]);
    }
}
