//! `skyframe-qnx`: the `skyframe` command line on QNX Neutrino.

fn main() -> std::process::ExitCode {
    let code = skyframe_shell::cli::main(skyframe_qnx::Qnx);
    // The clock period is system-wide: give the system back the tick it had.
    skyframe_qnx::clock_period::restore();
    code
}
