//! `lightvol imse`: the IMSE comparison of hemispherical bases (\[Ish11\] §3.1,
//! Table 3.1 and Fig. 3.1), reproduced with exact quadrature.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_hemibasis::imse;

use crate::imaging::{Plot, write_atomic};

/// `lightvol imse`.
#[derive(Debug, Args)]
pub(crate) struct ImseArgs {
    /// Random radiance signals (9 SH coefficients each, uniform in [-1, 1]).
    #[arg(long, default_value_t = 10_000)]
    signals: usize,
    /// Seed of the signals.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub(crate) json: bool,
    /// Also write `imse.svg` (Fig. 3.1-style), `imse.png` and `imse.json` into this directory.
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
}

/// Runs `lightvol imse`.
pub(crate) fn run(args: &ImseArgs) -> anyhow::Result<ExitCode> {
    if args.signals == 0 {
        bail!("--signals must be at least 1");
    }
    let report = imse::run(args.signals, args.seed);
    if args.json {
        println!("{}", report.to_json());
    } else {
        println!("{}", report.table().trim_end());
    }
    if let Some(dir) = &args.output {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        write_atomic(&dir.join("imse.svg"), report.svg().as_bytes())?;
        write_atomic(&dir.join("imse.json"), report.to_json().as_bytes())?;
        let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for row in &report.rows {
            match series.iter_mut().find(|s| s.0 == row.basis) {
                Some(s) => s.1.push((row.coefficients as f64, row.imse)),
                None => series.push((row.basis.to_owned(), vec![(row.coefficients as f64, row.imse)])),
            }
        }
        let plot = Plot {
            title: "mean IMSE vs coefficients".into(),
            x_label: "coefficients".into(),
            y_label: "IMSE".into(),
            series,
        };
        let (w, h, px) = plot.to_png_rgb8();
        crate::imaging::write_png_rgb8(&dir.join("imse.png"), w, h, &px)?;
        eprintln!("wrote {}", dir.join("imse.svg").display());
    }
    Ok(ExitCode::SUCCESS)
}
