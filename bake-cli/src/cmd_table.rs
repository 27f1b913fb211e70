//! `lightvol table`: the scene × method Markdown table of `compare` reports
//! ([`lightvol_eval::table`]).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_eval::table::{TableRow, markdown_table};
use serde_json::Value;

/// `lightvol table`.
#[derive(Debug, Args)]
pub(crate) struct TableArgs {
    /// `compare` output directories (each holding a `report.json`), or report files.
    #[arg(required = true)]
    pub(crate) reports: Vec<PathBuf>,
}

/// The label of a report's scene: `builtin:NAME` as given, a file by its name without
/// the extension.
fn scene_label(scene: &str) -> String {
    if scene.starts_with("builtin:") {
        return scene.to_owned();
    }
    Path::new(scene).file_stem().map_or_else(|| scene.to_owned(), |s| s.to_string_lossy().into_owned())
}

/// The rows of one `report.json`.
fn rows_of(path: &Path) -> anyhow::Result<Vec<TableRow>> {
    let file = if path.is_dir() { path.join("report.json") } else { path.to_path_buf() };
    let text = std::fs::read_to_string(&file).with_context(|| format!("reading {}", file.display()))?;
    let v: Value = serde_json::from_str(&text).with_context(|| format!("{}: not JSON", file.display()))?;
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
    // The ways in the order the comparison read them (the methods map is sorted by name).
    if let Some(ways) = v["lookups"].as_array() {
        let rank = |w: &str| ways.iter().position(|x| x.as_str() == Some(w)).unwrap_or(usize::MAX);
        rows.sort_by_key(|r| rank(&r.lookup));
    }
    Ok(rows)
}

/// Runs `lightvol table`.
pub(crate) fn run(args: &TableArgs) -> anyhow::Result<ExitCode> {
    let mut rows = Vec::new();
    for p in &args.reports {
        rows.extend(rows_of(p)?);
    }
    print!("{}", markdown_table(&rows));
    Ok(ExitCode::SUCCESS)
}
