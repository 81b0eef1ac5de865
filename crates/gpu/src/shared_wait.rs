//! One device wait for every stream sharing a queue (issue 48 item 2): the contexts that
//! [`super::GpuContext::share`] makes from one device submit through one [`QueueWaits`],
//! which numbers their submissions in queue order and lets a single thread at a time block
//! in the device; a context whose work that wait covers sleeps until it ends instead of
//! waiting itself (group commit). Nothing here records commands or owns buffers.
//!
//! Why a thread waits for the *newest* submission rather than its own: every stream whose
//! work was submitted before the wait began is then served by that one wait, and lavapipe
//! (like most drivers) runs one queue's submissions in order anyway, so waiting for its
//! own older work would end barely sooner. A stream that submits while the wait is under
//! way sleeps until it ends, then becomes the next waiter, covering every stream that
//! submitted meanwhile.
//!
//! Streams are counted by the thread that drives them (the thread of each stream's last
//! submission): a waiter gathers the other *threads*, since the streams of its own thread
//! cannot submit while it waits (Python driving several trackers in one loop).

// A browser has one thread: it waits through `super::wait` and never shares a wait.
#![cfg_attr(target_arch = "wasm32", allow(dead_code))]

use std::collections::HashMap;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::ThreadId;
use std::time::Duration;

/// Longest a thread about to wait for the device first waits for the other threads that
/// drive streams to submit their next step and sleep (so that its one wait covers them
/// too). Bounded, since a stream may be busy on the host (decoding a frame, say): while the
/// host delays, the device runs the submitted work anyway, so a short delay rarely delays
/// the result. A lone thread never delays, however many streams it drives.
const GATHER: Duration = Duration::from_millis(1);

/// The submissions and the device wait of every context sharing one queue.
#[derive(Debug, Default)]
pub(crate) struct QueueWaits {
    state: Mutex<State>,
    /// Notified when a device wait ends (done or failed).
    wait_ended: Condvar,
}

#[derive(Debug, Default)]
struct State {
    /// Sequence number (from 1, in queue order) and wgpu index of the newest submission.
    newest: Option<(u64, wgpu::SubmissionIndex)>,
    /// Every submission numbered up to this one is done.
    completed: u64,
    /// The submission number the device wait under way waits for, if one is.
    waiting_for: Option<u64>,
    /// The last device wait that failed: the number it waited for and wgpu's message.
    failed: Option<(u64, String)>,
    /// Streams (contexts) that have submitted work and are not dropped, counted by the
    /// thread of their last submission (a thread without streams has no entry).
    threads: HashMap<ThreadId, usize>,
    /// Threads sleeping until the device wait under way (or being gathered) ends.
    sleeping: usize,
    /// Gathers that ended at their deadline, the other threads not all asleep
    /// ([`Stream::gathers_timed_out`]).
    gathers_timed_out: u64,
}

impl State {
    /// Counts a stream under `to` instead of `from` (`None`: not counted).
    fn move_stream(&mut self, from: Option<ThreadId>, to: Option<ThreadId>) {
        if let Some(from) = from {
            if let Some(n) = self.threads.get_mut(&from) {
                *n -= 1;
                if *n == 0 {
                    self.threads.remove(&from);
                }
            }
        }
        if let Some(to) = to {
            *self.threads.entry(to).or_default() += 1;
        }
    }
}

/// One context's handle on the [`QueueWaits`] of its queue: counted among the streams from
/// its first submission until it is dropped, under the thread of its last submission.
#[derive(Debug, Default)]
pub(crate) struct Stream {
    waits: Arc<QueueWaits>,
    /// The thread this stream is counted under; `None` before its first submission.
    thread: Mutex<Option<ThreadId>>,
}

impl Stream {
    /// Another stream on the same queue.
    pub(crate) fn share(&self) -> Stream {
        Stream {
            waits: Arc::clone(&self.waits),
            thread: Mutex::new(None),
        }
    }

    /// [`QueueWaits::submit`], counting this stream under the submitting thread.
    pub(crate) fn submit(&self, queue: &wgpu::Queue, buffers: Vec<wgpu::CommandBuffer>) -> u64 {
        let me = std::thread::current().id();
        let mut thread = self.thread.lock().unwrap_or_else(|p| p.into_inner());
        if *thread != Some(me) {
            self.waits.lock().move_stream(*thread, Some(me));
            *thread = Some(me);
        }
        drop(thread);
        self.waits.submit(queue, buffers)
    }

    /// How many device waits on this queue first waited the whole [`GATHER`] for other
    /// threads that did not come (a diagnostic: a thread's own streams never count).
    pub(crate) fn gathers_timed_out(&self) -> u64 {
        self.waits.lock().gathers_timed_out
    }

    /// [`QueueWaits::wait_for`].
    #[cfg(not(target_arch = "wasm32"))]
    pub(crate) fn wait_for(&self, device: &wgpu::Device, number: u64) -> Result<Waited, String> {
        self.waits.wait_for(device, number)
    }
}

impl Drop for Stream {
    fn drop(&mut self) {
        let thread = *self.thread.get_mut().unwrap_or_else(|p| p.into_inner());
        if thread.is_some() {
            self.waits.lock().move_stream(thread, None);
            self.waits.wait_ended.notify_all();
        }
    }
}

/// Who waited for a context's submission.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Waited {
    /// This thread blocked in the device (one wait, counted as the context's).
    Own,
    /// Another context's wait covered it (or had already): no device wait of its own.
    Shared,
}

impl QueueWaits {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Submits `buffers` on `queue` and returns the submission's number. Under the lock, so
    /// that numbers follow the queue's order (wgpu's indices cannot be compared).
    pub(crate) fn submit(&self, queue: &wgpu::Queue, buffers: Vec<wgpu::CommandBuffer>) -> u64 {
        let mut s = self.lock();
        let index = queue.submit(buffers);
        let number = s.newest.as_ref().map_or(0, |(n, _)| *n) + 1;
        s.newest = Some((number, index));
        number
    }

    /// Blocks until submission `number` is done: natively by the device wait under way if
    /// it covers `number`, else (once any wait under way has ended) by a device wait of
    /// this thread's for the newest submission. wgpu's error, as text, when the wait that
    /// covered `number` failed (every context it served gets it).
    #[cfg(not(target_arch = "wasm32"))]
    pub(crate) fn wait_for(&self, device: &wgpu::Device, number: u64) -> Result<Waited, String> {
        let mut s = self.lock();
        loop {
            if s.completed >= number {
                return Ok(Waited::Shared);
            }
            if let Some((target, msg)) = &s.failed {
                if *target >= number {
                    return Err(msg.clone());
                }
            }
            if s.waiting_for.is_some() {
                s.sleeping += 1;
                // Wakes a thread gathering sleepers (below) as well.
                self.wait_ended.notify_all();
                s = self.wait_ended.wait(s).unwrap_or_else(|p| p.into_inner());
                s.sleeping -= 1;
                continue;
            }
            // This thread waits. First, for a little while, for every other thread that
            // drives a stream to submit and sleep: the placeholder target makes arriving
            // threads sleep (nothing here can panic while it stands).
            s.waiting_for = Some(0);
            let deadline = std::time::Instant::now() + GATHER;
            while s.sleeping + 1 < s.threads.len() {
                let left = deadline.saturating_duration_since(std::time::Instant::now());
                if left.is_zero() {
                    s.gathers_timed_out += 1;
                    break;
                }
                s = self
                    .wait_ended
                    .wait_timeout(s, left)
                    .unwrap_or_else(|p| p.into_inner())
                    .0;
            }
            let Some((target, index)) = s.newest.clone() else {
                // Numbers come from `submit`: none can be waited for before it.
                s.waiting_for = None;
                drop(s);
                self.wait_ended.notify_all();
                return Err(format!("submission {number} was never made"));
            };
            s.waiting_for = Some(target);
            drop(s);
            // Ends the wait under way whatever happens, a panic included, so that no
            // sleeping context is left waiting for a wait that will never end.
            let ended = EndWait {
                waits: self,
                target,
            };
            let polled = device.poll(wgpu::PollType::Wait {
                submission_index: Some(index),
                timeout: None,
            });
            let outcome = polled.map(|_| Waited::Own).map_err(|e| e.to_string());
            ended.end(outcome.as_ref().err().cloned());
            return outcome;
        }
    }
}

/// Ends a device wait: records its outcome and wakes every context sleeping on it. Dropped
/// without [`EndWait::end`] (the waiting thread panicked), it records a failure.
struct EndWait<'a> {
    waits: &'a QueueWaits,
    target: u64,
}

impl EndWait<'_> {
    fn end(self, error: Option<String>) {
        self.finish(error);
        std::mem::forget(self);
    }

    fn finish(&self, error: Option<String>) {
        let mut s = self.waits.lock();
        s.waiting_for = None;
        match error {
            None => s.completed = s.completed.max(self.target),
            Some(msg) => s.failed = Some((self.target, msg)),
        }
        drop(s);
        self.waits.wait_ended.notify_all();
    }
}

impl Drop for EndWait<'_> {
    fn drop(&mut self) {
        self.finish(Some("the thread waiting for the GPU panicked".into()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_ended_wait_completes_its_target_or_fails_every_waiter_it_covered() {
        let waits = QueueWaits::default();
        waits.lock().waiting_for = Some(3);
        EndWait {
            waits: &waits,
            target: 3,
        }
        .end(None);
        assert_eq!(waits.lock().completed, 3);
        assert_eq!(waits.lock().waiting_for, None);
        // A panicking waiter (dropped guard) records a failure for what it covered.
        drop(EndWait {
            waits: &waits,
            target: 5,
        });
        let s = waits.lock();
        assert_eq!(s.completed, 3);
        assert_eq!(s.failed.as_ref().map(|f| f.0), Some(5));
    }
}
