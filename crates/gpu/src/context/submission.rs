//! Submitting a context's commands and waiting for them: deferred steps, submissions (held
//! and combined with other streams' under [`super::GpuSubmissions::Combined`], see
//! `shared_wait.rs`), writes through the queue, read-back maps and the host's wait. Not the
//! device's creation ([`super`]).

use super::GpuContext;
use crate::{Error, Result};

impl GpuContext {
    /// A new command encoder.
    pub fn encoder(&self, label: &str) -> wgpu::CommandEncoder {
        self.device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) })
    }

    /// Submits one encoder's commands, after every deferred step's in recording order, as
    /// one submission, and counts it. With combined submissions, while other contexts
    /// share the queue and the device has work in flight, the device gets it with theirs,
    /// in one `queue.submit`, when a context next waits for the device or this one writes
    /// through the queue (`shared_wait.rs`).
    pub fn submit(&self, encoder: wgpu::CommandEncoder) {
        let mut buffers = self.take_deferred();
        buffers.push(encoder.finish());
        self.submit_buffers(buffers);
    }

    /// Submits `buffers` as one counted submission and remembers its number, which
    /// [`GpuContext::wait_idle`] waits for.
    fn submit_buffers(&self, buffers: Vec<wgpu::CommandBuffer>) {
        self.stats.count_submission();
        let number = self.queue_waits.submit(&self.queue, buffers, &self.stats);
        *self
            .last_submission
            .lock()
            .unwrap_or_else(|p| p.into_inner()) = Some(number);
    }

    /// `queue.write_buffer`, after this context's held submissions are made (the write
    /// would land before them otherwise). Visible to the next submission.
    pub fn write_buffer(&self, buffer: &wgpu::Buffer, offset: u64, bytes: &[u8]) {
        self.queue_waits.make_held(&self.queue, &self.stats);
        self.queue.write_buffer(buffer, offset, bytes);
    }

    /// `queue.write_texture`, after this context's held submissions are made (see
    /// [`GpuContext::write_buffer`]).
    pub fn write_texture(
        &self,
        texture: wgpu::TexelCopyTextureInfo<'_>,
        bytes: &[u8],
        layout: wgpu::TexelCopyBufferLayout,
        size: wgpu::Extent3d,
    ) {
        self.queue_waits.make_held(&self.queue, &self.stats);
        self.queue.write_texture(texture, bytes, layout, size);
    }

    /// Asks for `staging` to be mapped for reading, calling `done` with the outcome, once
    /// this context's latest submission (which copies into it) is made: wgpu refuses a
    /// submission that uses a buffer with a map pending. At once unless that submission is
    /// held.
    pub(crate) fn map_after_submission(
        &self,
        staging: &wgpu::Buffer,
        done: impl FnOnce(std::result::Result<(), wgpu::BufferAsyncError>) + Send + 'static,
    ) {
        let last = *self
            .last_submission
            .lock()
            .unwrap_or_else(|p| p.into_inner());
        // A browser has one thread, never holds a submission, and its buffers cannot be
        // sent to another thread.
        #[cfg(not(target_arch = "wasm32"))]
        if let Some(number) = last {
            let staging = staging.clone();
            let map = move || staging.map_async(wgpu::MapMode::Read, .., done);
            self.queue_waits.after_made(number, Box::new(map));
            return;
        }
        let _ = last;
        staging.map_async(wgpu::MapMode::Read, .., done);
    }

    /// Keeps step `step`'s commands for the next submission instead of submitting them now
    /// (one round trip less when nothing waits for them). Safe only while no buffer that
    /// they read or write is written through the queue (`write_buffer`, `write_texture`)
    /// before that submission: such a write would land before them. The GPU backend
    /// defers only `preprocess` and `predict` (and flushes before any other step) and the
    /// copies of growing arrays (whose writes flush first).
    pub fn defer(&self, step: &'static str, encoder: wgpu::CommandEncoder) {
        let commands = encoder.finish();
        let mut d = self.deferred.lock().unwrap_or_else(|p| p.into_inner());
        d.push((step, commands));
    }

    /// Whether step `step`'s commands are deferred and not yet submitted.
    pub fn has_deferred(&self, step: &str) -> bool {
        let d = self.deferred.lock().unwrap_or_else(|p| p.into_inner());
        d.iter().any(|(s, _)| *s == step)
    }

    /// Submits the deferred steps, if any, as one submission.
    pub fn flush(&self) {
        let buffers = self.take_deferred();
        if !buffers.is_empty() {
            self.submit_buffers(buffers);
        }
    }

    fn take_deferred(&self) -> Vec<wgpu::CommandBuffer> {
        let mut d = self.deferred.lock().unwrap_or_else(|p| p.into_inner());
        d.drain(..).map(|(_, c)| c).collect()
    }

    /// Runs the map callbacks of work the device has finished, without blocking and
    /// without counting a wait (a read-back whose work a later wait may already have
    /// covered; see `Readback::take`). In a browser nothing runs them but the event loop.
    pub fn poll_ready(&self) -> Result<()> {
        #[cfg(not(target_arch = "wasm32"))]
        self.device
            .poll(wgpu::PollType::Poll)
            .map_err(|e| Error::Gpu(format!("polling the GPU: {e}")))?;
        Ok(())
    }

    /// Blocks until the work this context submitted is done, deferred steps submitted
    /// first; device loss or a timeout is [`Error::Gpu`]. Natively, when another context
    /// sharing the queue is already blocked in a device wait that covers this context's
    /// work, it sleeps until that wait ends (counted as a shared wait, not its own);
    /// otherwise it waits for the newest submission on the queue, covering every context's
    /// work submitted so far, and first making every held submission (`shared_wait.rs`).
    /// When nothing was submitted since the last wait (a second read-back of the same
    /// finished work, as the fern codes fusion recorded), or another context's wait served
    /// it, it only polls without blocking, which runs the map callbacks of that finished
    /// work.
    pub fn wait_idle(&self) -> Result<()> {
        self.flush();
        #[cfg(not(target_arch = "wasm32"))]
        {
            use crate::shared_wait::Waited;
            let last = self
                .last_submission
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .take();
            let waited = match last {
                Some(number) => self
                    .queue_waits
                    .queue()
                    .wait_for(&self.device, &self.queue, number, &self.stats)
                    .map_err(|e| Error::Gpu(format!("waiting for the GPU: {e}")))?,
                None => Waited::Shared,
            };
            match waited {
                Waited::Own => self.stats.count_wait(),
                Waited::Shared => {
                    if last.is_some() {
                        self.stats.count_shared_wait();
                    }
                    self.device
                        .poll(wgpu::PollType::Poll)
                        .map_err(|e| Error::Gpu(format!("polling the GPU: {e}")))?;
                }
            }
            self.check_device()
        }
        #[cfg(target_arch = "wasm32")]
        {
            // One thread in a browser: nothing to share a wait with.
            self.last_submission
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .take();
            self.stats.count_wait();
            crate::wait::wait_for_submitted(&self.device, &self.queue)
                .map_err(|e| Error::Gpu(format!("waiting for the GPU: {e}")))?;
            // The steps' error scopes, answered during that wait (`GpuContext::scoped`).
            self.read_popped_scopes()?;
            self.check_device()
        }
    }

    /// Device waits on this context's queue (every context [`GpuContext::share`] made from
    /// the same device counts here) that first waited the whole gathering time for other
    /// threads' streams that did not come (`shared_wait.rs`). A diagnostic: one thread
    /// driving several contexts never gathers for its own.
    pub fn gathers_timed_out(&self) -> u64 {
        self.queue_waits.gathers_timed_out()
    }
}
