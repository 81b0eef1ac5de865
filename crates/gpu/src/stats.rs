//! The byte and submission counters a [`super::GpuContext`] and all its buffers share, which
//! `wgslam bench` reports (allocated, peak, uploaded and read-back bytes; submissions, those
//! the device got; waits).
//! Counting only: nothing here allocates, submits or waits.

use std::sync::atomic::{AtomicU64, Ordering};

/// Counters shared by a [`super::GpuContext`] and all its buffers.
#[derive(Debug, Default)]
pub struct GpuStats {
    allocated_bytes: AtomicU64,
    peak_allocated_bytes: AtomicU64,
    uploaded_bytes: AtomicU64,
    readback_bytes: AtomicU64,
    submissions: AtomicU64,
    device_submissions: AtomicU64,
    waits: AtomicU64,
    shared_waits: AtomicU64,
}

/// A copy of the counters at one moment (all byte counts are bytes, not elements).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct StatsSnapshot {
    /// Bytes in live [`super::GpuArray`] / [`super::ParamBuffer`] buffers (staging buffers excluded).
    pub allocated_bytes: u64,
    /// Largest `allocated_bytes` seen so far.
    pub peak_allocated_bytes: u64,
    /// Bytes written from the host with `write_buffer`.
    pub uploaded_bytes: u64,
    /// Bytes copied back to the host through staging buffers.
    pub readback_bytes: u64,
    /// Queue submissions made through [`super::GpuContext::submit`] and the buffer helpers.
    pub submissions: u64,
    /// `queue.submit` calls this context's thread made: its own submissions, and those of
    /// other contexts on the shared queue that it made with them in one call
    /// ([`super::GpuContext::share`]). Equal to `submissions` for a lone context; summed
    /// over every context sharing a queue, what the device got.
    pub device_submissions: u64,
    /// Times the host blocked until submitted work was done ([`super::GpuContext::wait_idle`]:
    /// every read-back waits through it) in a device wait of its own.
    pub waits: u64,
    /// Times the host's wait for submitted work was served by another context's device
    /// wait on the shared queue ([`super::GpuContext::share`]): no device wait of its own.
    pub shared_waits: u64,
}

impl GpuStats {
    pub(crate) fn alloc(&self, bytes: u64) {
        let now = self.allocated_bytes.fetch_add(bytes, Ordering::Relaxed) + bytes;
        self.peak_allocated_bytes.fetch_max(now, Ordering::Relaxed);
    }
    pub(crate) fn free(&self, bytes: u64) {
        self.allocated_bytes.fetch_sub(bytes, Ordering::Relaxed);
    }
    pub(crate) fn upload(&self, bytes: u64) {
        self.uploaded_bytes.fetch_add(bytes, Ordering::Relaxed);
    }
    pub(crate) fn readback(&self, bytes: u64) {
        self.readback_bytes.fetch_add(bytes, Ordering::Relaxed);
    }
    pub(crate) fn count_submission(&self) {
        self.submissions.fetch_add(1, Ordering::Relaxed);
    }
    pub(crate) fn count_device_submission(&self) {
        self.device_submissions.fetch_add(1, Ordering::Relaxed);
    }
    pub(crate) fn count_wait(&self) {
        self.waits.fetch_add(1, Ordering::Relaxed);
    }
    // A browser has one thread and never shares a wait.
    #[cfg_attr(target_arch = "wasm32", allow(dead_code))]
    pub(crate) fn count_shared_wait(&self) {
        self.shared_waits.fetch_add(1, Ordering::Relaxed);
    }
    pub(crate) fn snapshot(&self) -> StatsSnapshot {
        StatsSnapshot {
            allocated_bytes: self.allocated_bytes.load(Ordering::Relaxed),
            peak_allocated_bytes: self.peak_allocated_bytes.load(Ordering::Relaxed),
            uploaded_bytes: self.uploaded_bytes.load(Ordering::Relaxed),
            readback_bytes: self.readback_bytes.load(Ordering::Relaxed),
            submissions: self.submissions.load(Ordering::Relaxed),
            device_submissions: self.device_submissions.load(Ordering::Relaxed),
            waits: self.waits.load(Ordering::Relaxed),
            shared_waits: self.shared_waits.load(Ordering::Relaxed),
        }
    }
}
