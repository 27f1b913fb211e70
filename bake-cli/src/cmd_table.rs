//! `lightvol table`: the scene × method Markdown table of `compare` reports
//! ([`lightvol_eval::table`]).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_eval::convergence::{ErrorAtSamples, convergence_plot, convergence_table};
use lightvol_eval::table::{TableRow, markdown_table};
use serde_json::Value;

/// `lightvol table`.
#[derive(Debug, Args)]
pub(crate) struct TableArgs {
    /// `compare` output directories (each holding a `report.json`), or report files.
    #[arg(required = true)]
    pub(crate) reports: Vec<PathBuf>,
    /// Instead of the method table, the error against the sample count of reports that
    /// differ in `--samples`: each method's relative RMSE on the plate and in each view, a
    /// column per sample count, written as STEM.svg and STEM.png too
    #[arg(long, value_name = "STEM")]
    pub(crate) samples_plot: Option<PathBuf>,
}

/// How much a series may rise from one sample count to the next and still count as
/// falling: the reference's noise, shared by every count, is about 1% of the error at
/// the reference samples `compare` uses by default.
const MONOTONE_SLACK: f64 = 0.01;

/// The label of a report's scene: `builtin:NAME` as given, a file by its name without
/// the extension.
fn scene_label(scene: &str) -> String {
    if scene.starts_with("builtin:") {
        return scene.to_owned();
    }
    Path::new(scene).file_stem().map_or_else(|| scene.to_owned(), |s| s.to_string_lossy().into_owned())
}

/// The rows of one `report.json`: its plate's, then each view's (`SCENE (CAMERA view)`,
/// whose `too_dark_near` column holds the share of the view's pixels that are too dark).
fn rows_of(path: &Path) -> anyhow::Result<Vec<TableRow>> {
    let (file, v) = read_report(path)?;
    let scene = v["scene"].as_str().with_context(|| format!("{}: no \"scene\"", file.display()))?;
    let methods =
        v["methods"].as_object().with_context(|| format!("{}: no \"methods\" object", file.display()))?;
    // The first way of reading keeps the methods' names; further ways are `NAME@WAY`.
    let first = v["lookup"].as_str().unwrap_or("lightvol");
    let mut rows = Vec::new();
    for (name, m) in methods {
        let (method, lookup) = name.rsplit_once('@').unwrap_or((name.as_str(), first));
        let num = |k: &str| {
            m[k].as_f64().with_context(|| format!("{}: method {name} has no number \"{k}\"", file.display()))
        };
        rows.push(TableRow {
            scene: scene_label(scene),
            method: method.to_owned(),
            lookup: lookup.to_owned(),
            rel_rmse: num("rel_rmse")?,
            too_dark_near: num("too_dark_near")?,
            too_bright: num("too_bright")?,
            rays: m["rays"]["total"]
                .as_u64()
                .with_context(|| format!("{}: method {name} has no ray total", file.display()))?,
            seconds: num("seconds")?,
        });
    }
    if rows.is_empty() {
        bail!("{}: no methods", file.display());
    }
    // Each view through a camera: one more entry per method, its error over the view's
    // pixels, from the same bake (its rays and seconds).
    let plates = rows.len();
    for view in v["views"].as_array().into_iter().flatten() {
        let camera = view["camera"]
            .as_str()
            .with_context(|| format!("{}: a view without \"camera\"", file.display()))?;
        let of = view["methods"]
            .as_object()
            .with_context(|| format!("{}: view {camera} has no \"methods\" object", file.display()))?;
        for (name, m) in of {
            let (method, lookup) = name.rsplit_once('@').unwrap_or((name.as_str(), first));
            let plate = rows[..plates]
                .iter()
                .find(|r| r.method == method && r.lookup == lookup)
                .cloned()
                .with_context(|| {
                    format!("{}: view {camera} has {name}, the plate does not", file.display())
                })?;
            let num = |k: &str| {
                m[k].as_f64().with_context(|| {
                    format!("{}: {name} in view {camera} has no number \"{k}\"", file.display())
                })
            };
            rows.push(TableRow {
                scene: format!("{} ({camera} view)", scene_label(scene)),
                rel_rmse: num("rel_rmse")?,
                too_dark_near: num("too_dark")?,
                too_bright: num("too_bright")?,
                ..plate
            });
        }
    }
    // The ways in the order the comparison read them (the methods map is sorted by name).
    if let Some(ways) = v["lookups"].as_array() {
        let rank = |w: &str| ways.iter().position(|x| x.as_str() == Some(w)).unwrap_or(usize::MAX);
        rows.sort_by_key(|r| rank(&r.lookup));
    }
    Ok(rows)
}

/// The report in `path` (a `compare` output directory or its `report.json`).
fn read_report(path: &Path) -> anyhow::Result<(PathBuf, Value)> {
    let file = if path.is_dir() { path.join("report.json") } else { path.to_path_buf() };
    let text = std::fs::read_to_string(&file).with_context(|| format!("reading {}", file.display()))?;
    let v = serde_json::from_str(&text).with_context(|| format!("{}: not JSON", file.display()))?;
    Ok((file, v))
}

/// Each method's error on the plate and in each view of one report, at its sample count
/// (the first way of reading only).
fn errors_at_samples(path: &Path) -> anyhow::Result<(String, Vec<ErrorAtSamples>)> {
    let (file, v) = read_report(path)?;
    let scene = v["scene"].as_str().with_context(|| format!("{}: no \"scene\"", file.display()))?;
    let methods =
        v["methods"].as_object().with_context(|| format!("{}: no \"methods\" object", file.display()))?;
    let mut out = Vec::new();
    for (name, m) in methods.iter().filter(|(n, _)| !n.contains('@')) {
        let samples = m["samples"]
            .as_u64()
            .and_then(|n| u32::try_from(n).ok())
            .with_context(|| format!("{}: method {name} has no sample count", file.display()))?;
        let at = |series: String, e: &Value| {
            e.as_f64()
                .map(|rel_rmse| ErrorAtSamples { series, samples, rel_rmse })
                .with_context(|| format!("{}: method {name} has no relative RMSE", file.display()))
        };
        out.push(at(format!("{name}, plate"), &m["rel_rmse"])?);
        for view in v["views"].as_array().into_iter().flatten() {
            let camera = view["camera"].as_str().unwrap_or("view");
            out.push(at(format!("{name}, {camera}"), &view["methods"][name]["rel_rmse"])?);
        }
    }
    Ok((scene_label(scene), out))
}

/// `lightvol table --samples-plot`: the table on stdout, the plot beside `stem`.
fn samples_plot(reports: &[PathBuf], stem: &Path) -> anyhow::Result<ExitCode> {
    let mut points = Vec::new();
    let mut scenes: Vec<String> = Vec::new();
    for p in reports {
        let (scene, pts) = errors_at_samples(p)?;
        if !scenes.contains(&scene) {
            scenes.push(scene);
        }
        points.extend(pts);
    }
    if scenes.len() > 1 {
        bail!(
            "--samples-plot compares one scene at several sample counts; the reports hold {}",
            scenes.join(", ")
        );
    }
    for (path, bytes) in convergence_plot(&scenes[0], &points).files(stem)? {
        lightvol_core::fs::write_atomic(&path, &bytes)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    print!("{}", convergence_table(&points, MONOTONE_SLACK));
    Ok(ExitCode::SUCCESS)
}

/// Runs `lightvol table`.
pub(crate) fn run(args: &TableArgs) -> anyhow::Result<ExitCode> {
    if let Some(stem) = &args.samples_plot {
        return samples_plot(&args.reports, stem);
    }
    let mut rows = Vec::new();
    for p in &args.reports {
        rows.extend(rows_of(p)?);
    }
    print!("{}", markdown_table(&rows));
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `compare` report of `scene` with `doi` at `samples`, its plate error `plate` and
    /// one view's error `view`.
    fn report(dir: &Path, name: &str, scene: &str, samples: u32, plate: f64, view: f64) -> PathBuf {
        let v = serde_json::json!({
            "scene": scene,
            "methods": {
                "doi": {"samples": samples, "rel_rmse": plate},
                "doi@three": {"samples": samples, "rel_rmse": 1.0}
            },
            "views": [{"camera": "Main", "methods": {"doi": {"rel_rmse": view}}}]
        });
        let p = dir.join(name);
        std::fs::write(&p, v.to_string()).unwrap();
        p
    }

    #[test]
    fn the_samples_plot_reads_plates_and_views_and_refuses_two_scenes() {
        let dir = tempfile::tempdir().unwrap();
        let a = report(dir.path(), "a.json", "room.glb", 1024, 0.2, 0.3);
        let b = report(dir.path(), "b.json", "room.glb", 256, 0.25, 0.35);
        let (scene, pts) = errors_at_samples(&a).unwrap();
        assert_eq!(scene, "room");
        assert_eq!(
            pts,
            vec![
                ErrorAtSamples { series: "doi, plate".into(), samples: 1024, rel_rmse: 0.2 },
                ErrorAtSamples { series: "doi, Main".into(), samples: 1024, rel_rmse: 0.3 },
            ]
        );
        let stem = dir.path().join("conv");
        samples_plot(&[a.clone(), b], &stem).unwrap();
        assert!(std::fs::read_to_string(stem.with_extension("svg")).unwrap().contains("<svg"));
        assert!(stem.with_extension("png").exists());
        let c = report(dir.path(), "c.json", "hall.glb", 256, 0.25, 0.35);
        let e = samples_plot(&[a, c], &stem).unwrap_err().to_string();
        assert!(e.contains("room, hall"), "{e}");
    }

    /// A view of a report becomes one more entry per method, after the plate's, with the
    /// view's error and the bake's rays and seconds; a view naming a method the plate lacks
    /// is refused.
    #[test]
    fn views_are_entries_of_their_own() {
        let dir = tempfile::tempdir().unwrap();
        let entry = |e: f64| serde_json::json!({"rel_rmse": e, "too_dark_near": 0.1, "too_bright": 0.2, "rays": {"total": 7}, "seconds": 1.5});
        let view = |e: f64| serde_json::json!({"rel_rmse": e, "too_dark": 0.3, "too_bright": 0.4});
        let write = |name: &str, view_method: &str| {
            let v = serde_json::json!({
                "scene": "data/room.glb",
                "methods": {"doi": entry(0.2), "point+apv": entry(0.4)},
                "views": [{"camera": "Main", "methods": {"doi": view(0.25), view_method: view(0.5)}}]
            });
            let p = dir.path().join(name);
            std::fs::write(&p, v.to_string()).unwrap();
            p
        };
        let rows = rows_of(&write("a.json", "point+apv")).unwrap();
        let got: Vec<(&str, &str, f64, f64, u64)> = rows
            .iter()
            .map(|r| (r.scene.as_str(), r.method.as_str(), r.rel_rmse, r.too_dark_near, r.rays))
            .collect();
        assert_eq!(
            got,
            vec![
                ("room", "doi", 0.2, 0.1, 7),
                ("room", "point+apv", 0.4, 0.1, 7),
                ("room (Main view)", "doi", 0.25, 0.3, 7),
                ("room (Main view)", "point+apv", 0.5, 0.3, 7),
            ]
        );
        // The means run over plates and views: doi (0.2 + 0.25) / 2 against 0.45.
        let table = markdown_table(&rows);
        assert!(table.contains("| doi | 0.225 | 2 | 0.50 |"), "{table}");
        let e = rows_of(&write("b.json", "point+vlm")).unwrap_err().to_string();
        assert!(e.contains("point+vlm"), "{e}");
    }
}
