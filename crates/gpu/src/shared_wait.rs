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
//!
//! With combined submissions ([`super::context::GpuSubmissions::Combined`]) submissions
//! combine the same way: while more than one stream shares the queue and the device has
//! work in flight (made, not yet known to be done), a stream's submission is *held*
//! (numbered, not yet given to the device), unless a thread is already blocked in the
//! device (nothing would make it before that wait ends). The thread about to block in the
//! device gives every held submission to the device in one `queue.submit`, in number
//! order, then waits; when its wait ends, it gives what was held meanwhile in one call too,
//! so held work never waits on an idle device for long. A stream that writes through the
//! queue (`write_buffer`, `write_texture`) first has its held work made, since the write
//! would otherwise land before it ([`Stream::make_held`]); a read-back's `map_async`, which
//! wgpu refuses before the submission that writes the buffer is made, is held with it
//! ([`Stream::after_made`]). A lone stream's submissions go to the device at once.
//!
//! Errors stay with the stream that made them. wgpu reports a command buffer's recording
//! errors to the error scope of the thread that finishes it (the stream's own), and its
//! submission's to the thread that calls `queue.submit`, which for held work may be
//! another stream's. So when a stream's error scope catches an error, the submissions it
//! held within that scope are dropped, never made ([`Stream::discard_held_since`]), and
//! their read-backs' maps are requested at once, so that nothing waits for them for ever.

// A browser has one thread: it waits through `super::wait` and never shares a wait.
#![cfg_attr(target_arch = "wasm32", allow(dead_code))]

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::ThreadId;
use std::time::Duration;

use super::stats::GpuStats;

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
    /// Whether streams hold submissions to combine them (`GpuSubmissions::Combined`).
    combine: bool,
    /// The last stream id handed out ([`Stream::share`]).
    streams_made: AtomicU64,
}

/// A read-back's `map_async` call, kept until the submission that writes its buffer is
/// made (wgpu refuses a submission that uses a buffer with a map pending).
pub(crate) type MapRequest = Box<dyn FnOnce() + Send>;

/// A submission held to be made with others: its stream, number and command buffers.
struct Held {
    stream: u64,
    number: u64,
    buffers: Vec<wgpu::CommandBuffer>,
}

#[derive(Default)]
struct State {
    /// The newest submission number handed out (from 1, in queue order).
    handed: u64,
    /// Number and wgpu index of the newest submission made on the device: every number up
    /// to it is made (or was dropped, [`Stream::discard_held_since`]), every held one is
    /// after it.
    newest: Option<(u64, wgpu::SubmissionIndex)>,
    /// The held submissions, in number order.
    held: Vec<Held>,
    /// Map requests of read-backs that held submissions write, by submission number,
    /// issued once those are made.
    maps: Vec<(u64, MapRequest)>,
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

impl std::fmt::Debug for State {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("State")
            .field("handed", &self.handed)
            .field("newest", &self.newest.as_ref().map(|n| n.0))
            .field("held", &self.held.len())
            .field("maps", &self.maps.len())
            .field("completed", &self.completed)
            .field("waiting_for", &self.waiting_for)
            .finish_non_exhaustive()
    }
}

impl State {
    /// Whether submission `number` is made (given to the device, or dropped).
    fn made(&self, number: u64) -> bool {
        self.newest.as_ref().is_some_and(|(n, _)| *n >= number)
    }

    /// Streams counted, over every thread.
    fn streams(&self) -> usize {
        self.threads.values().sum()
    }

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
    /// This stream's id among those sharing the queue.
    id: u64,
    /// The thread this stream is counted under; `None` before its first submission.
    thread: Mutex<Option<ThreadId>>,
    /// The number of this stream's latest held submission, 0 once it is known to be made.
    held: AtomicU64,
}

impl Stream {
    /// The first stream on a new queue; `combine`: whether streams sharing it combine
    /// their submissions.
    // In a browser wgpu's command buffers are not `Send`, and there is one thread.
    #[cfg_attr(target_arch = "wasm32", allow(clippy::arc_with_non_send_sync))]
    pub(crate) fn new(combine: bool) -> Stream {
        Stream {
            waits: Arc::new(QueueWaits {
                combine,
                ..QueueWaits::default()
            }),
            id: 0,
            thread: Mutex::new(None),
            held: AtomicU64::new(0),
        }
    }

    /// Another stream on the same queue.
    pub(crate) fn share(&self) -> Stream {
        Stream {
            waits: Arc::clone(&self.waits),
            id: self.waits.streams_made.fetch_add(1, Ordering::SeqCst) + 1,
            thread: Mutex::new(None),
            held: AtomicU64::new(0),
        }
    }

    /// [`QueueWaits::submit`], counting this stream under the submitting thread.
    pub(crate) fn submit(
        &self,
        queue: &wgpu::Queue,
        buffers: Vec<wgpu::CommandBuffer>,
        stats: &GpuStats,
    ) -> u64 {
        let me = std::thread::current().id();
        let mut thread = self.thread.lock().unwrap_or_else(|p| p.into_inner());
        if *thread != Some(me) {
            self.waits.lock().move_stream(*thread, Some(me));
            *thread = Some(me);
        }
        drop(thread);
        let (number, held) = self.waits.submit(self.id, queue, buffers, stats);
        if held {
            self.held.store(number, Ordering::SeqCst);
        }
        number
    }

    /// Makes every held submission if one of this stream's still is (before a write
    /// through the queue, which would land before it). Nothing for a lone stream, nor
    /// once a waiter has made this stream's submissions.
    pub(crate) fn make_held(&self, queue: &wgpu::Queue, stats: &GpuStats) {
        let number = self.held.load(Ordering::SeqCst);
        if number == 0 {
            return;
        }
        let mut s = self.waits.lock();
        if !s.made(number) {
            self.waits.make(&mut s, queue, Vec::new(), stats);
        }
        drop(s);
        // Unless a later submission of this stream's was held meanwhile (another thread).
        let _ = self
            .held
            .compare_exchange(number, 0, Ordering::SeqCst, Ordering::SeqCst);
    }

    /// Calls `map` once submission `number` is made: now, unless this stream's
    /// submissions were held and it still is.
    pub(crate) fn after_made(&self, number: u64, map: MapRequest) {
        let map = match self.held.load(Ordering::SeqCst) {
            0 => Some(map),
            _ => self.waits.after_made(number, map),
        };
        if let Some(map) = map {
            map();
        }
    }

    /// The newest submission number handed out on the queue (a mark for
    /// [`Stream::discard_held_since`]).
    pub(crate) fn handed(&self) -> u64 {
        self.waits.lock().handed
    }

    /// Drops this stream's held submissions numbered after `mark` (recorded within an
    /// error scope that caught an error: they may be invalid), and requests their
    /// read-backs' maps now (their buffers hold nothing new, but no wait hangs on them).
    pub(crate) fn discard_held_since(&self, mark: u64) {
        if self.held.load(Ordering::SeqCst) == 0 {
            return;
        }
        let mut s = self.waits.lock();
        let dropped: Vec<u64> = s
            .held
            .iter()
            .filter(|h| h.stream == self.id && h.number > mark)
            .map(|h| h.number)
            .collect();
        s.held.retain(|h| !(h.stream == self.id && h.number > mark));
        let (maps, kept): (Vec<_>, Vec<_>) = std::mem::take(&mut s.maps)
            .into_iter()
            .partition(|(n, _)| dropped.contains(n));
        s.maps = kept;
        let still = s
            .held
            .iter()
            .filter(|h| h.stream == self.id)
            .map(|h| h.number)
            .max();
        self.held.store(still.unwrap_or(0), Ordering::SeqCst);
        drop(s);
        for (_, map) in maps {
            map();
        }
    }

    /// How many device waits on this queue first waited the whole [`GATHER`] for other
    /// threads that did not come (a diagnostic: a thread's own streams never count).
    pub(crate) fn gathers_timed_out(&self) -> u64 {
        self.waits.lock().gathers_timed_out
    }

    /// The submissions and waits of every stream on the queue ([`QueueWaits::wait_for`]).
    pub(crate) fn queue(&self) -> &QueueWaits {
        &self.waits
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

    /// Numbers a submission of `buffers` by stream `stream` and returns its number, and
    /// whether it is held: with combined submissions, while more than one stream shares
    /// the queue (natively) and work already made is not known to be done; else it is made
    /// now, after any held ones. Under the lock, so that numbers follow the queue's order
    /// (wgpu's indices cannot be compared).
    pub(crate) fn submit(
        &self,
        stream: u64,
        queue: &wgpu::Queue,
        buffers: Vec<wgpu::CommandBuffer>,
        stats: &GpuStats,
    ) -> (u64, bool) {
        let mut s = self.lock();
        s.handed += 1;
        let number = s.handed;
        // Held only while made work is not known to be done: given at once to a device
        // that is (as far as the host knows) idle, it starts sooner than held for the
        // next waiter. Held work never outlasts the work in flight: the wait that ends it
        // makes what was held meanwhile (`wait_for`).
        let busy = s.newest.as_ref().is_some_and(|(n, _)| *n > s.completed);
        // A thread already blocked in the device makes nothing until its wait ends: work
        // held now would wait out that whole wait, so it goes to the device at once.
        let blocked = s.waiting_for.is_some_and(|t| t > 0);
        let hold = self.combine
            && cfg!(not(target_arch = "wasm32"))
            && s.streams() > 1
            && busy
            && !blocked;
        if hold {
            s.held.push(Held {
                stream,
                number,
                buffers,
            });
        } else {
            self.make(&mut s, queue, buffers, stats);
        }
        (number, hold)
    }

    /// Gives the held command buffers, then `more` (numbered already), to the device in
    /// one `queue.submit` (counted in `stats`), then issues the held map requests. Nothing
    /// when both are empty.
    fn make(
        &self,
        s: &mut State,
        queue: &wgpu::Queue,
        more: Vec<wgpu::CommandBuffer>,
        stats: &GpuStats,
    ) {
        if s.held.is_empty() && more.is_empty() {
            return;
        }
        let mut buffers: Vec<wgpu::CommandBuffer> = std::mem::take(&mut s.held)
            .into_iter()
            .flat_map(|h| h.buffers)
            .collect();
        buffers.extend(more);
        let index = queue.submit(buffers);
        stats.count_device_submission();
        s.newest = Some((s.handed, index));
        for (_, map) in std::mem::take(&mut s.maps) {
            map();
        }
    }

    /// `map` back when submission `number` is made already (the caller calls it), else
    /// kept until [`QueueWaits::make`] makes it.
    fn after_made(&self, number: u64, map: MapRequest) -> Option<MapRequest> {
        let mut s = self.lock();
        if s.made(number) {
            return Some(map);
        }
        s.maps.push((number, map));
        None
    }

    /// Blocks until submission `number` is done: natively by the device wait under way if
    /// it covers `number`, else (once any wait under way has ended) by a device wait of
    /// this thread's for the newest submission, after making every held one. wgpu's
    /// error, as text, when the wait that covered `number` failed (every context it served
    /// gets it).
    #[cfg(not(target_arch = "wasm32"))]
    pub(crate) fn wait_for(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        number: u64,
        stats: &GpuStats,
    ) -> Result<Waited, String> {
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
            self.make(&mut s, queue, Vec::new(), stats);
            let Some((target, index)) = s.newest.clone().filter(|(n, _)| *n >= number) else {
                // Every held submission is made above: `number` was dropped with its
                // stream's failed scope, or never handed out. Nothing to wait for.
                s.waiting_for = None;
                drop(s);
                self.wait_ended.notify_all();
                return Ok(Waited::Shared);
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
            // What was held while the device worked goes to it now, in one call, rather
            // than wait for the next waiter.
            let mut s = self.lock();
            self.make(&mut s, queue, Vec::new(), stats);
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
