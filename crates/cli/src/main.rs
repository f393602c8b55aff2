//! `crowd`: the crowd-patches asset compiler's command line.

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = crowd::cli::Cli::parse();
    match crowd::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err}");
            for cause in err.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            // What the codes mean: `crowd::cli::EXIT_CODES`.
            if err.downcast_ref::<crowd::cli::Broken>().is_some() {
                ExitCode::from(3)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
