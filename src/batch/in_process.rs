//! `wgslam batch --concurrent N`: up to N jobs at once on threads of the batch's own
//! process, so that one job's waits for the GPU overlap the other jobs' kernels on the one
//! shared device (each job its own [`crate::gpu::GpuContext::share`] of it and its own
//! buffers), and CPU jobs share the cores.
//!
//! What runs where: [`run_queue`] hands the jobs to the threads in index order; each runs
//! [`super::job::Runner::run`], whose backend runs are `wgslam run` in this process through
//! [`InProcessRun`] with [`RunHooks`] (its lines into the backend's log, its progress to the
//! batch's bar, the interrupt flag polled after each frame). Not here: the runs' own work
//! (`crate::cli::run::execute_in`), or child processes (`--concurrent 1`).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use crate::slam::any_backend::AnyBackend;
use crate::Result;

/// What a run embedded in a batch reports through, instead of printing.
pub struct RunHooks<'a> {
    /// Each line `wgslam run` would print (its events and its summary), in order: the
    /// batch writes them into the run's `<backend>.log`.
    pub say: &'a dyn Fn(&str),
    /// Frames done and frames in all, after each frame.
    pub progress: &'a dyn Fn(u64, u64),
    /// Polled after each frame: `true` stops the run with [`crate::Error::Interrupted`]
    /// before it writes anything.
    pub stop: &'a dyn Fn() -> bool,
}

/// A run started inside the batch's process: the backend it runs on (a GPU backend on the
/// batch's shared device) and its hooks.
pub struct Embedded<'a> {
    pub backend: AnyBackend,
    pub hooks: RunHooks<'a>,
}

/// Runs one backend of a job in this process: the `wgslam run` arguments (as
/// [`super::job::Runner::run_args`] makes them, `run` first) and the hooks. An error is
/// the run's failure, as a child's exit status would be.
pub type InProcessRun = dyn Fn(&[String], &RunHooks) -> Result<()> + Send + Sync;

/// Calls `work(slot, k, &items[k])` for every item, on `threads` threads (at least one, at
/// most one per item), taking the items in order as threads come free; `slot` (below
/// `threads`) names the thread, for its progress bar. `work` returning `false` stops the
/// queue: the items in flight finish, none starts after.
pub fn run_queue<T: Sync>(
    items: &[T],
    threads: usize,
    work: impl Fn(usize, usize, &T) -> bool + Sync,
) {
    let next = AtomicUsize::new(0);
    let stopped = AtomicBool::new(false);
    let work = &work;
    std::thread::scope(|s| {
        for slot in 0..threads.clamp(1, items.len().max(1)) {
            let (next, stopped) = (&next, &stopped);
            s.spawn(move || {
                while !stopped.load(Ordering::SeqCst) {
                    let k = next.fetch_add(1, Ordering::SeqCst);
                    let Some(item) = items.get(k) else { break };
                    if !work(slot, k, item) {
                        stopped.store(true, Ordering::SeqCst);
                    }
                }
            });
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    #[test]
    fn every_item_once_on_at_most_the_threads_asked_for() {
        let items: Vec<usize> = (0..20).collect();
        let seen = Mutex::new(Vec::new());
        let slots = Mutex::new(std::collections::BTreeSet::new());
        run_queue(&items, 3, |slot, k, &item| {
            assert_eq!(k, item);
            seen.lock().unwrap().push(item);
            slots.lock().unwrap().insert(slot);
            true
        });
        let mut seen = seen.into_inner().unwrap();
        seen.sort();
        assert_eq!(seen, items);
        assert!(slots.into_inner().unwrap().iter().all(|&s| s < 3));
    }

    #[test]
    fn false_stops_the_queue() {
        let items: Vec<usize> = (0..50).collect();
        let ran = AtomicUsize::new(0);
        run_queue(&items, 1, |_, k, _| {
            ran.fetch_add(1, Ordering::SeqCst);
            k < 4
        });
        assert_eq!(
            ran.load(Ordering::SeqCst),
            5,
            "items 0..=4, the last said stop"
        );
    }
}
