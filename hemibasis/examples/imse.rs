//! Reproduces [Ish11] Table 3.1 / Fig. 3.1 (mean IMSE of each hemispherical basis).
//!
//! ```text
//! cargo run --release -p lightvol-hemibasis --example imse -- [--signals N] [--seed S] [--json] [--svg PATH] [--investigate]
//! ```
//!
//! Without `--json` it prints a table beside the thesis values; `--svg PATH` also writes a
//! plot like Fig. 3.1; `--investigate` prints the candidate explanations of the thesis's
//! 9-coefficient SH entry (see the crate README).

use std::process::ExitCode;

use lightvol_hemibasis::imse;

struct Args {
    signals: usize,
    seed: u64,
    json: bool,
    svg: Option<std::path::PathBuf>,
    investigate: bool,
}

fn parse() -> Result<Args, String> {
    let mut a = Args { signals: 10_000, seed: 0, json: false, svg: None, investigate: false };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match arg.as_str() {
            "--signals" => {
                a.signals = value("--signals")?.parse().map_err(|e| format!("--signals: {e}"))?;
            }
            "--seed" => a.seed = value("--seed")?.parse().map_err(|e| format!("--seed: {e}"))?,
            "--json" => a.json = true,
            "--svg" => a.svg = Some(value("--svg")?.into()),
            "--investigate" => a.investigate = true,
            "-h" | "--help" => {
                return Err(
                    "usage: imse [--signals N] [--seed S] [--json] [--svg PATH] [--investigate]".into()
                );
            }
            other => return Err(format!("unknown argument {other:?} (try --help)")),
        }
    }
    if a.signals == 0 {
        return Err("--signals must be at least 1".into());
    }
    Ok(a)
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let report = imse::run(args.signals, args.seed);
    if args.json {
        println!("{}", report.to_json());
    } else {
        print!("{}", report.table());
    }
    if let Some(path) = &args.svg
        && let Err(e) = lightvol_core::fs::write_atomic(path, report.svg().as_bytes())
    {
        eprintln!("error: writing {}: {e}", path.display());
        return ExitCode::FAILURE;
    }
    if args.investigate {
        eprintln!("Candidate explanations of the thesis's SH-9 entry 0.00231 (closed-form expectations):");
        eprintln!(
            "  truncating the irradiance of a 5-band (25-coefficient) radiance to 3 bands: {:.5}",
            imse::expected_truncation_imse(5)
        );
        eprintln!(
            "  same with a 7-band (49-coefficient) radiance:                              {:.5}",
            imse::expected_truncation_imse(7)
        );
        for b in imse::table_bases() {
            eprintln!(
                "  LS fit of {:>10}{:<2}: 9-coefficient radiance {:.5}, 25-coefficient radiance {:.5}",
                b.name(),
                b.len(),
                imse::expected_imse_bands(b.as_ref(), 3),
                imse::expected_imse_bands(b.as_ref(), 5)
            );
        }
    }
    ExitCode::SUCCESS
}
