//! The `wgslam` executable: parse arguments, run, print errors without a backtrace.

use clap::Parser;

fn main() -> std::process::ExitCode {
    restore_sigpipe();
    quiet_display_probe();
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

/// Keeps a window-system probe from printing what reads as an error of ours.
///
/// Mesa's implicit Vulkan layer `VK_LAYER_MESA_device_select` connects to the Wayland and X
/// servers while adapters are enumerated, to learn which GPU drives the display. On a
/// headless machine (no valid `XDG_RUNTIME_DIR`) libwayland then prints "error:
/// XDG_RUNTIME_DIR is invalid or not set in the environment." twice before wgslam's first
/// line. wgslam draws on no display and picks its adapter itself (high performance first),
/// so there the layer is switched off through its own documented switch, `NODEVICE_SELECT=1`.
/// A user who sets `NODEVICE_SELECT` or `MESA_VK_DEVICE_SELECT` keeps the layer as they
/// set it. Runs before any thread starts, so setting the variable races with nothing.
#[cfg(all(unix, not(target_os = "macos")))]
fn quiet_display_probe() {
    let is_set = |key: &str| std::env::var_os(key).is_some();
    if is_set("NODEVICE_SELECT") || is_set("MESA_VK_DEVICE_SELECT") {
        return;
    }
    let runtime_dir_ok =
        std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|dir| std::path::Path::new(&dir).is_dir());
    if !runtime_dir_ok {
        std::env::set_var("NODEVICE_SELECT", "1");
    }
}

#[cfg(not(all(unix, not(target_os = "macos"))))]
fn quiet_display_probe() {}
