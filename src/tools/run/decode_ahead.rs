//! The one place a frame loop gets its frames: [`for_each_frame`] loads and decodes them
//! (PNG/JPEG, colour mapped onto depth: `Sequence::load`) on a pool of worker threads ahead
//! of the loop, and hands them over strictly in sequence order, so a run's outputs do not
//! depend on the pool. Not a reader of any file format, and not a cache: each frame is
//! decoded once and dropped when the loop is done with it.
//!
//! Worker `w` of `n` decodes frames `first + w`, `first + w + n`, ...; each hands its frames
//! over through its own bounded channel and the loop takes them round robin, so the order
//! needs no sorting. Decoded frames in memory at once: at most `n x (depth + 1)` beside the
//! loop's own and the next one it took early, with `n` and `depth` cut down for large frames ([`AHEAD_BUDGET_BYTES`]).
//! With the frame it hands over, the loop gets the next one when a worker has finished it
//! already (it never waits for it), so the pipeline can upload the next frame's images
//! while the GPU fuses this one (`Slam::process_before`).
//! A decode error on frame k reaches the loop at frame k, as the same error. A loop that
//! stops early drops the channels, and each worker stops at its next hand-over (after at
//! most the one decode it is in), so the scope's join never hangs.

use std::num::NonZeroUsize;
use std::ops::RangeInclusive;
use std::sync::mpsc;
use web_time::Instant;

use crate::dataset::{RawFrame, Sequence};
use crate::slam::backend::NextFrame;
use crate::Result;

/// Most bytes of decoded frames the pool holds ahead of the loop (depth, colour and packed
/// colour, at the frames' own size): 256 MiB is 97 frames at 640x480 but only 3 at
/// 4096x2160, where it
/// takes fewer workers and shallower queues instead.
pub const AHEAD_BUDGET_BYTES: usize = 256 << 20;
/// Decoded frames each worker may hold beyond the one in its hand (the channel's bound):
/// two keep a worker busy through one slow frame of the loop without hoarding memory.
const AHEAD_PER_WORKER: usize = 2;

/// Where frames are decoded relative to the frame loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decode {
    /// On this many worker threads ahead of the loop, overlapping it (shortest wall time).
    Ahead(NonZeroUsize),
    /// On the loop's thread before each frame, so decoding never competes with the
    /// pipeline for a core (the per-stage benchmark passes; a browser tab, which has no
    /// threads).
    BeforeEachFrame,
}

impl Decode {
    /// Ahead on one worker per core the process may use (`available_parallelism`; one
    /// where it is unknown): the default of `run`, `bench`, `batch` and Python's `run`.
    pub fn ahead_on_every_core() -> Decode {
        Decode::Ahead(std::thread::available_parallelism().unwrap_or(NonZeroUsize::MIN))
    }

    /// `--decode-threads N`: ahead on `threads` workers, before each frame for 0.
    pub fn with_threads(threads: usize) -> Decode {
        NonZeroUsize::new(threads).map_or(Decode::BeforeEachFrame, Decode::Ahead)
    }

    /// The worker threads (0 before each frame).
    pub fn threads(self) -> usize {
        match self {
            Decode::Ahead(n) => n.get(),
            Decode::BeforeEachFrame => 0,
        }
    }
}

/// One frame as the loop gets it.
pub struct Decoded {
    /// Position in the sequence.
    pub index: usize,
    /// Its images, full resolution, as decoded.
    pub frame: RawFrame,
    /// Its colour packed as the pipeline takes it ([`super::packed_rgba`]), on the worker.
    pub rgba: Vec<u32>,
    /// Time spent loading, decoding and packing it, seconds (on a worker with
    /// [`Decode::Ahead`]).
    pub decode_seconds: f64,
    /// Time the loop waited for it, seconds: its whole decode before each frame, only what
    /// the workers had not finished ahead otherwise.
    pub wait_seconds: f64,
}

impl Decoded {
    /// This frame as the one after the frame in hand (`Slam::process_before`).
    pub fn as_next(&self) -> NextFrame<'_> {
        NextFrame {
            frame_id: self.index as u32,
            depth: &self.frame.depth,
            rgba: &self.rgba,
        }
    }
}

/// Calls `body` on frames `frames` of `seq` in order, decoded where `decode` says, each with
/// the next frame when it is decoded already (never with [`Decode::BeforeEachFrame`]);
/// stops at the first error, a frame's own decode error (at that frame) or `body`'s.
pub fn for_each_frame(
    seq: &Sequence,
    frames: RangeInclusive<usize>,
    decode: Decode,
    mut body: impl FnMut(Decoded, Option<&Decoded>) -> Result<()>,
) -> Result<()> {
    // A browser tab (wasm32) has no threads to decode on: decode before each frame.
    #[cfg(target_arch = "wasm32")]
    let decode = {
        let _ = decode;
        Decode::BeforeEachFrame
    };
    match decode {
        Decode::BeforeEachFrame => {
            for index in frames {
                let loaded = timed_load(seq, index);
                let wait = loaded.1;
                body(decoded(index, loaded, wait)?, None)?;
            }
            Ok(())
        }
        Decode::Ahead(threads) => ahead(seq, frames, threads.get(), body),
    }
}

/// Frame `i` of `seq` with its packed colour, and the seconds its load and packing took.
type Loaded = (Result<(RawFrame, Vec<u32>)>, f64);

/// Loads frame `i` of `seq` (see [`Loaded`]).
fn timed_load(seq: &Sequence, i: usize) -> Loaded {
    let t = Instant::now();
    let frame = seq.load(i).map(|f| {
        let rgba = super::packed_rgba(&f);
        (f, rgba)
    });
    (frame, t.elapsed().as_secs_f64())
}

/// Frame `index` as the loop gets it, after waiting `wait_seconds` for it; its load error.
fn decoded(index: usize, (frame, secs): Loaded, wait_seconds: f64) -> Result<Decoded> {
    let (frame, rgba) = frame?;
    Ok(Decoded {
        index,
        frame,
        rgba,
        decode_seconds: secs,
        wait_seconds,
    })
}

/// Workers and channel depth for `threads` asked over `count` frames of `frame_bytes`
/// each: no more workers than frames, and both cut so that the frames held ahead stay
/// within [`AHEAD_BUDGET_BYTES`] (at least one worker with a bare hand-over).
fn pool_shape(threads: usize, count: usize, frame_bytes: usize) -> (usize, usize) {
    let fit = (AHEAD_BUDGET_BYTES / frame_bytes.max(1)).max(1);
    let workers = threads.min(count).min(fit).max(1);
    let depth = (fit / workers).saturating_sub(1).min(AHEAD_PER_WORKER);
    (workers, depth)
}

/// [`for_each_frame`] with `threads` workers decoding ahead.
fn ahead(
    seq: &Sequence,
    frames: RangeInclusive<usize>,
    threads: usize,
    mut body: impl FnMut(Decoded, Option<&Decoded>) -> Result<()>,
) -> Result<()> {
    let k = seq.intrinsics;
    // Depth (u16), colour (3 x u8) and packed colour (u32) per pixel, at the intrinsics'
    // size (which `load` checks the frames against).
    let frame_bytes = (k.width as usize * k.height as usize) * 9;
    let count = frames.clone().count();
    let (workers, depth) = pool_shape(threads, count, frame_bytes);
    std::thread::scope(|s| {
        // Dropped when this closure returns (also on an error), before the scope joins:
        // a worker's next send fails and it stops.
        let mut handovers = Vec::with_capacity(workers);
        for w in 0..workers {
            let (tx, rx) = mpsc::sync_channel(depth);
            handovers.push(rx);
            let mine = frames.clone().skip(w).step_by(workers);
            s.spawn(move || {
                for i in mine {
                    if tx.send(timed_load(seq, i)).is_err() {
                        break; // the loop stopped early
                    }
                }
            });
        }
        // Frame `n + 1`, taken from its worker early because it was ready (or its error).
        let mut early: Option<Result<Decoded>> = None;
        for (n, index) in frames.enumerate() {
            let this = match early.take() {
                Some(d) => d?,
                None => {
                    let t = Instant::now();
                    // A worker ends before handing over all its frames only by panicking;
                    // the scope then passes its panic on.
                    let Ok(loaded) = handovers[n % workers].recv() else {
                        break;
                    };
                    decoded(index, loaded, t.elapsed().as_secs_f64())?
                }
            };
            if n + 1 < count {
                let ready = handovers[(n + 1) % workers].try_recv().ok();
                early = ready.map(|loaded| decoded(index + 1, loaded, 0.0));
            }
            body(this, early.as_ref().and_then(|d| d.as_ref().ok()))?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pool_has_no_more_workers_than_frames_and_stays_within_its_budget() {
        let vga = 640 * 480 * 9;
        assert_eq!(pool_shape(8, 100, vga), (8, AHEAD_PER_WORKER));
        assert_eq!(pool_shape(8, 3, vga), (3, AHEAD_PER_WORKER));
        assert_eq!(pool_shape(8, 0, vga), (1, AHEAD_PER_WORKER));
        // Frames of a third of the budget: three workers, each with a bare hand-over.
        assert_eq!(pool_shape(8, 100, AHEAD_BUDGET_BYTES / 3), (3, 0));
        // A frame larger than the budget still gets one worker.
        assert_eq!(pool_shape(8, 100, AHEAD_BUDGET_BYTES * 2), (1, 0));
        for (threads, bytes) in [
            (16, vga),
            (16, 4096 * 2160 * 9),
            (2, AHEAD_BUDGET_BYTES / 5),
        ] {
            let (w, d) = pool_shape(threads, 1000, bytes);
            assert!(
                w * (d + 1) * bytes <= AHEAD_BUDGET_BYTES,
                "{threads} threads, {bytes} B"
            );
        }
    }

    #[test]
    fn decode_threads_zero_decodes_before_each_frame() {
        assert_eq!(Decode::with_threads(0), Decode::BeforeEachFrame);
        assert_eq!(Decode::with_threads(3).threads(), 3);
        assert!(Decode::ahead_on_every_core().threads() >= 1);
    }
}
