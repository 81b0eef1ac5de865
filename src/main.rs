//! The `wgslam` executable: parse arguments, run, print errors without a backtrace.

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = wgslam::cli::Cli::parse();
    match wgslam::cli::execute(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            match e {
                // 128 + SIGINT, as a shell reports a process Ctrl-C stopped.
                wgslam::Error::Interrupted(_) => std::process::ExitCode::from(130),
                _ => std::process::ExitCode::FAILURE,
            }
        }
    }
}
