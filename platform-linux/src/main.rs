//! `skyframe` on Linux.

fn main() -> std::process::ExitCode {
    skyframe_shell::cli::main(skyframe_linux::Linux)
}
