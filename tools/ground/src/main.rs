use clap::Parser;
use skyframe_ground::cli::{Cli, run};

fn main() {
    let cli = Cli::parse();
    if let Err(exit) = run(cli) {
        eprintln!("skyframe-ground: {}", exit.message);
        std::process::exit(exit.code);
    }
}
