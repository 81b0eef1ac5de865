//! The `wgslam` executable: parse arguments, run, print errors without a backtrace. The
//! body is the library's [`wgslam::cli::embed::main`], which the Python package's `wgslam`
//! command calls too.

fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(wgslam::cli::embed::main(std::env::args_os()))
}
