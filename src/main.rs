//! The `snell` command-line tool (the code is [`snell::cli`]).

fn main() -> std::process::ExitCode {
    snell::cli::main_with_args(std::env::args_os())
}
