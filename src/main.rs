//! The `wgslam` executable: parse arguments, run, print errors without a backtrace.

use clap::Parser;

fn main() -> std::process::ExitCode {
    restore_sigpipe();
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

/// A closed pipe ends the process quietly, as it does a C tool: Rust ignores SIGPIPE, so
/// `wgslam batch list M | head -1` made `println!` panic on the broken pipe.
#[cfg(unix)]
fn restore_sigpipe() {
    // SAFETY: setting a signal's disposition to the default before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn restore_sigpipe() {}
