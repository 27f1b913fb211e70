#![doc = include_str!("../README.md")]
// A thin shell over the library crates: the entry points below are its only public items
// (every other item is `pub(crate)`, checked by `tests/thin_shell.rs`), and a `pub` item in
// one of its private modules is an error.
#![deny(unreachable_pub)]

mod adaptive_bake;
mod bake_args;
mod bench_scale;
mod cli;
mod cmd_bake;
mod cmd_bake_surface;
mod cmd_bench;
mod cmd_cluster;
mod cmd_compare;
mod cmd_demo;
mod cmd_export;
mod cmd_gpu;
mod cmd_imse;
mod cmd_info;
mod cmd_inspect;
mod cmd_layout;
mod cmd_lint;
mod cmd_merge;
mod cmd_proxies;
mod cmd_relight;
mod cmd_render;
mod cmd_render_surface;
mod cmd_shader;
mod cmd_table;
mod compare_views;
mod embree_baseline;
mod gradient_args;
mod imaging;
mod progress;
mod render_args;
mod setup;

use std::ffi::OsString;
use std::process::ExitCode;

use clap::Parser;

/// Parses `args` (including the program name) and runs the command. `--help` and
/// `--version` print and return success; parse errors return an error.
pub fn run_from_args<I, T>(args: I) -> anyhow::Result<ExitCode>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let args: Vec<OsString> = args.into_iter().map(Into::into).collect();
    let argv: Vec<String> = args.iter().skip(2).map(|a| a.to_string_lossy().into_owned()).collect();
    let cli = match cli::Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e)
            if matches!(
                e.kind(),
                clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion
            ) =>
        {
            print!("{e}");
            return Ok(ExitCode::SUCCESS);
        }
        Err(e) => return Err(anyhow::anyhow!("{}", clap_message(&e.to_string()))),
    };
    // A kernel named in the environment that this machine cannot run is refused here, in
    // one line, rather than silently replaced (results are the same on every kernel).
    lightvol_scene::Isa::from_env().map_err(anyhow::Error::msg)?;
    match cli.command {
        cli::Command::Slurm(a) => cmd_cluster::run_slurm(&a, &argv),
        cli::Command::K8s(a) => cmd_cluster::run_k8s(&a, &argv),
        _ => run(cli),
    }
}

/// Runs a parsed command. (`slurm` and `k8s` need the raw command line: they go through
/// [`run_from_args`].)
fn run(args: cli::Cli) -> anyhow::Result<ExitCode> {
    match args.command {
        cli::Command::Bake(a) => cmd_bake::run(&a),
        cli::Command::BakeSurface(a) => cmd_bake_surface::run(&a),
        cli::Command::Bench(a) => cmd_bench::run(&a),
        cli::Command::Compare(a) => cmd_compare::run(&a),
        cli::Command::Demo(a) => cmd_demo::run(&a),
        cli::Command::GpuInfo(a) => cmd_gpu::run_info(&a),
        cli::Command::Imse(a) => cmd_imse::run(&a),
        cli::Command::Info(a) => cmd_info::run(&a),
        cli::Command::Relight(a) => cmd_relight::run(&a),
        cli::Command::Table(a) => cmd_table::run(&a),
        cli::Command::Inspect(a) => cmd_inspect::run(&a),
        cli::Command::Layout(a) => cmd_layout::run(&a),
        cli::Command::Lint(a) => cmd_lint::run(&a),
        cli::Command::Merge(a) => cmd_merge::run(&a),
        cli::Command::Proxies(a) => cmd_proxies::run(&a),
        cli::Command::Render(a) => cmd_render::run(&a),
        cli::Command::Export(a) => cmd_export::run(&a),
        cli::Command::Shader(a) => cmd_shader::run(&a),
        cli::Command::Slurm(_) | cli::Command::K8s(_) => {
            anyhow::bail!("the slurm and k8s verbs need the command line: call run_from_args")
        }
    }
}

/// The binary's entry: runs and turns an error into one line on stderr and exit code 1.
///
/// Standard output closed early by a reader (`lightvol inspect --json | head`) ends the
/// command quietly with exit code 141 (the shell's code for SIGPIPE), where `println!`
/// would otherwise panic.
pub fn main_with_args<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !is_broken_pipe(info.payload()) {
            default_hook(info);
        }
    }));
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run_from_args(args))) {
        Ok(Ok(code)) => code,
        Ok(Err(err)) => {
            eprintln!("error: {}", one_line(&err));
            ExitCode::FAILURE
        }
        Err(payload) if is_broken_pipe(payload.as_ref()) => ExitCode::from(141),
        Err(payload) => std::panic::resume_unwind(payload),
    }
}

/// The panic `println!` raises when standard output is a closed pipe.
fn is_broken_pipe(payload: &(dyn std::any::Any + Send)) -> bool {
    let text = payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("");
    text.starts_with("failed printing to stdout") && text.contains("Broken pipe")
}

/// A clap error's message on one line: its first paragraph (the usage and the hints that
/// follow are left out), whose lines, such as the names of missing arguments under "the
/// following required arguments were not provided:", are joined.
fn clap_message(text: &str) -> String {
    let first: Vec<&str> = text.lines().map(str::trim).take_while(|l| !l.is_empty()).collect();
    let joined = first.join(" ");
    let message = joined.trim_start_matches("error: ");
    if message.is_empty() { "invalid arguments".to_owned() } else { message.to_owned() }
}

/// The error and its context chain on one line.
#[must_use]
fn one_line(err: &anyhow::Error) -> String {
    format!("{err:#}").replace('\n', " ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A clap error keeps what its first paragraph lists (the missing arguments) and drops
    /// the usage and the hints.
    #[test]
    fn clap_errors_keep_their_first_paragraph() {
        let missing = "error: the following required arguments were not provided:\n  --target <ENGINE>\n\nUsage: lightvol bake --target <ENGINE> <SCENE>\n\nFor more information, try '--help'.\n";
        assert_eq!(
            clap_message(missing),
            "the following required arguments were not provided: --target <ENGINE>"
        );
        let unknown =
            "error: unexpected argument '--foo' found\n\n  tip: to pass '--foo' as a value, use '-- --foo'\n";
        assert_eq!(clap_message(unknown), "unexpected argument '--foo' found");
        assert_eq!(clap_message(""), "invalid arguments");
        // Through the binary's parser: the missing argument is named on the one line.
        let e = run_from_args(["lightvol", "bake", "builtin:maze", "--target-lambda", "0.3"]).unwrap_err();
        let line = one_line(&e);
        assert!(line.contains("--target <ENGINE>") && !line.contains('\n'), "{line}");
    }
}
