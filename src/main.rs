//! The `wgslam` executable: parse arguments, run, print errors without a backtrace.

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = wgslam::cli::Cli::parse();
    match wgslam::cli::execute(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
