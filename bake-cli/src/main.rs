//! `lightvol`: the command line of the lightvol toolkit. See `lightvol --help` and the
//! crate README.

mod cli;
mod cmd_export;
mod cmd_info;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match run(args) {
        Ok(code) => code,
        Err(err) => {
            // One clear line: the context chain joined by ": ".
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: cli::Cli) -> anyhow::Result<ExitCode> {
    match args.command {
        cli::Command::Info(a) => cmd_info::run(&a),
        cli::Command::Export(a) => cmd_export::run(&a),
    }
}
