//! Ctrl-C and SIGTERM during a batch: a flag the job loop polls.
//!
//! The handler only sets the flag; the loop kills the child run in flight, writes no
//! record for it (so it does not look complete) and returns. A child started from a
//! terminal gets the terminal's Ctrl-C itself as well, and dies on it: the loop treats a
//! child killed by a signal while the flag is set, or by SIGINT/SIGTERM, as an interruption,
//! not as a failed job.

use std::sync::atomic::{AtomicBool, Ordering};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Installs the handler (once per process; later calls and a handler installed by someone
/// else are left as they are, the flag then staying unset).
pub fn install() {
    let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::SeqCst));
}

/// True once Ctrl-C or SIGTERM arrived.
pub fn requested() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}
