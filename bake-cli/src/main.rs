//! `lightvol`: the command line of the lightvol toolkit. See `lightvol --help`.

fn main() -> std::process::ExitCode {
    lightvol::main_with_args(std::env::args_os())
}
