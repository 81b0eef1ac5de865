//! Typed GPU buffers: [`GpuArray`] (a storage array of `Pod` elements with upload,
//! read-back through a staging buffer, and grow-by-copy on the GPU) and [`ParamBuffer`] (one
//! `Pod` params struct); both account their bytes in [`super::stats`].
//!
//! Not a memory allocator: every array is one wgpu buffer sized `capacity` elements, and
//! its capacity is checked against the device limits before anything is allocated.

use std::marker::PhantomData;
use std::ops::Range;
use std::sync::Arc;

use bytemuck::Pod;

use super::context::GpuContext;
use super::stats::GpuStats;
use crate::{Error, Result};

/// The deferred step of [`GpuArray::grow`]'s copy.
const GROW_COPY: &str = "grow copy";

/// wgpu copies and `write_buffer` need sizes in multiples of this many bytes.
const COPY_ALIGN: u64 = wgpu::COPY_BUFFER_ALIGNMENT;

/// Rounds a byte count up to the copy alignment (and to at least one aligned word, since
/// zero-sized bindings are invalid).
fn padded_bytes(bytes: u64) -> u64 {
    bytes.max(1).div_ceil(COPY_ALIGN) * COPY_ALIGN
}

/// A storage buffer holding up to `capacity` elements of `T`, of which the first `len` are
/// meaningful. Usage: STORAGE | COPY_SRC | COPY_DST. Element layout is `T`'s `#[repr(C)]`
/// layout, which must match the WGSL element type (see `crates/core/src/layout/mod.rs`).
pub struct GpuArray<T: Pod> {
    buffer: wgpu::Buffer,
    len: usize,
    capacity: usize,
    label: String,
    stats: Arc<GpuStats>,
    _element: PhantomData<T>,
}

impl<T: Pod> std::fmt::Debug for GpuArray<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuArray")
            .field("label", &self.label)
            .field("len", &self.len)
            .field("capacity", &self.capacity)
            .finish()
    }
}

impl<T: Pod> Drop for GpuArray<T> {
    fn drop(&mut self) {
        self.stats.free(self.buffer.size());
    }
}

impl<T: Pod> GpuArray<T> {
    /// Bytes `capacity` elements take, or [`Error::Capacity`] (naming the array, the element
    /// count, the bytes and the limit) when one storage binding cannot hold them.
    pub fn check_capacity(ctx: &GpuContext, label: &str, capacity: usize) -> Result<u64> {
        let elem = std::mem::size_of::<T>() as u64;
        let bytes = (capacity as u64)
            .checked_mul(elem)
            .ok_or_else(|| Error::Capacity(format!("{label}: {capacity} elements overflow")))?;
        let limit = ctx.max_storage_bytes();
        if padded_bytes(bytes) > limit {
            return Err(Error::Capacity(format!(
                "{label}: {capacity} elements x {elem} bytes = {bytes} bytes exceeds the \
                 device limit of {limit} bytes per storage buffer (at most {} elements)",
                limit / elem.max(1)
            )));
        }
        Ok(padded_bytes(bytes))
    }

    /// A zero-filled array with room for `capacity` elements and `len = 0`.
    pub fn new(ctx: &GpuContext, label: &str, capacity: usize) -> Result<Self> {
        let bytes = Self::check_capacity(ctx, label, capacity)?;
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        ctx.stats_handle().alloc(bytes);
        Ok(GpuArray {
            buffer,
            len: 0,
            capacity,
            label: label.to_string(),
            stats: Arc::clone(ctx.stats_handle()),
            _element: PhantomData,
        })
    }

    /// An array holding a copy of `data` (`len = capacity = data.len()`).
    pub fn from_slice(ctx: &GpuContext, label: &str, data: &[T]) -> Result<Self> {
        let mut a = Self::new(ctx, label, data.len())?;
        a.upload(ctx, data)?;
        Ok(a)
    }

    /// Meaningful elements.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when `len == 0`.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Allocated elements.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Sets the meaningful length (e.g. after a kernel appended elements and the host read
    /// the counter). Panics if `len > capacity`: an internal contract.
    pub fn set_len(&mut self, len: usize) {
        assert!(
            len <= self.capacity,
            "{}: len {len} > capacity {}",
            self.label,
            self.capacity
        );
        self.len = len;
    }

    /// The underlying wgpu buffer.
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// The whole buffer as a binding resource.
    pub fn binding(&self) -> wgpu::BindingResource<'_> {
        self.buffer.as_entire_binding()
    }

    /// Replaces the contents with `data` (`len = data.len()`), growing without keeping the
    /// old contents when `data` does not fit. Queued: visible to the next submission.
    pub fn upload(&mut self, ctx: &GpuContext, data: &[T]) -> Result<()> {
        if data.len() > self.capacity {
            *self = Self::new(ctx, &self.label.clone(), data.len())?;
        }
        self.write_at(ctx, 0, data)?;
        self.len = data.len();
        Ok(())
    }

    /// Writes `data` at element `offset` without changing `len`; the range must fit.
    pub fn write_at(&mut self, ctx: &GpuContext, offset: usize, data: &[T]) -> Result<()> {
        if offset + data.len() > self.capacity {
            return Err(Error::Capacity(format!(
                "{}: writing {} elements at {offset} past capacity {}",
                self.label,
                data.len(),
                self.capacity
            )));
        }
        let bytes: &[u8] = bytemuck::cast_slice(data);
        if bytes.is_empty() {
            return Ok(());
        }
        if ctx.has_deferred(GROW_COPY) {
            // This write would land before a deferred grow copy into the buffer.
            ctx.flush();
        }
        let byte_offset = (offset * std::mem::size_of::<T>()) as u64;
        assert!(
            byte_offset % COPY_ALIGN == 0,
            "{}: element offset {offset} is not 4-byte aligned",
            self.label
        );
        if bytes.len() as u64 % COPY_ALIGN == 0 {
            ctx.write_buffer(&self.buffer, byte_offset, bytes);
        } else {
            // Odd tails (e.g. u16 elements): pad with zeros; the pad lies inside the buffer
            // because the buffer size is padded the same way.
            let mut padded = bytes.to_vec();
            padded.resize(padded_bytes(bytes.len() as u64) as usize, 0);
            ctx.write_buffer(&self.buffer, byte_offset, &padded);
        }
        ctx.stats_handle().upload(bytes.len() as u64);
        Ok(())
    }

    /// Records a clear of the whole buffer to zero bytes.
    pub fn clear(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.clear_buffer(&self.buffer, 0, None);
    }

    /// Copies the first `len` elements back to the host (submits, waits).
    pub fn read_back(&self, ctx: &GpuContext) -> Result<Vec<T>> {
        self.read_back_range(ctx, 0..self.len)
    }

    /// Copies elements `range` back to the host through a staging buffer: one submission,
    /// a map and a blocking poll. The range may extend past `len` but not `capacity`.
    pub fn read_back_range(&self, ctx: &GpuContext, range: Range<usize>) -> Result<Vec<T>> {
        if range.end > self.capacity || range.start > range.end {
            return Err(Error::Capacity(format!(
                "{}: read-back range {range:?} outside capacity {}",
                self.label, self.capacity
            )));
        }
        if range.is_empty() {
            return Ok(Vec::new());
        }
        let elem = std::mem::size_of::<T>() as u64;
        let start = range.start as u64 * elem;
        let bytes = range.len() as u64 * elem;
        // Copies must start and end on 4-byte boundaries: widen, then cut on the host.
        let aligned_start = start / COPY_ALIGN * COPY_ALIGN;
        let aligned_len = padded_bytes(start + bytes - aligned_start);
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wgslam read-back staging"),
            size: aligned_len,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = ctx.encoder("read back");
        enc.copy_buffer_to_buffer(&self.buffer, aligned_start, &staging, 0, aligned_len);
        ctx.submit(enc);
        let out = map_read(ctx, &staging, |view| {
            let skip = (start - aligned_start) as usize;
            bytemuck::pod_collect_to_vec::<u8, T>(&view[skip..skip + bytes as usize])
        })?;
        ctx.stats_handle().readback(bytes);
        Ok(out)
    }

    /// Grows to at least `new_capacity` elements keeping the first `len` elements: a new
    /// buffer and a GPU-side copy, deferred to the next submission (see
    /// [`GpuContext::defer`]; a write through [`GpuArray::write_at`] submits it first). No-op
    /// when already large enough.
    pub fn grow(&mut self, ctx: &GpuContext, new_capacity: usize) -> Result<()> {
        if new_capacity <= self.capacity {
            return Ok(());
        }
        let mut bigger = Self::new(ctx, &self.label, new_capacity)?;
        let keep =
            padded_bytes(self.len as u64 * std::mem::size_of::<T>() as u64).min(self.buffer.size());
        if self.len > 0 {
            let mut enc = ctx.encoder(GROW_COPY);
            enc.copy_buffer_to_buffer(&self.buffer, 0, &bigger.buffer, 0, keep);
            ctx.defer(GROW_COPY, enc);
        }
        bigger.len = self.len;
        *self = bigger;
        Ok(())
    }
}

/// Maps a `MAP_READ` buffer, waits for it, hands the bytes to `f`, and unmaps.
pub(crate) fn map_read<R>(
    ctx: &GpuContext,
    staging: &wgpu::Buffer,
    f: impl FnOnce(&[u8]) -> R,
) -> Result<R> {
    MapRequest::new(ctx, staging).finish(ctx, staging, false, f)
}

/// The result of a `map_async` as [`super::wait::block_on`] waits for it.
type MapResult = std::pin::Pin<
    Box<dyn std::future::Future<Output = std::result::Result<(), wgpu::BufferAsyncError>> + Send>,
>;

/// A `map_async` of a `MAP_READ` buffer, requested after the submission that fills it and
/// not yet waited for: a later wait or poll that finds that submission done runs its
/// callback, and [`MapRequest::finish`] then reads the bytes without a wait of its own.
pub(crate) struct MapRequest {
    /// Set by the map's callback.
    fired: Arc<std::sync::atomic::AtomicBool>,
    result: MapResult,
}

impl MapRequest {
    /// Requests the map of `staging` (valid once every submission using it is done), as
    /// soon as `ctx`'s latest submission, which fills it, is made (it may be held with
    /// other streams', `shared_wait.rs`).
    pub fn new(ctx: &GpuContext, staging: &wgpu::Buffer) -> Self {
        let (mapped, when_mapped) = super::wait::callback();
        let fired = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let seen = fired.clone();
        ctx.map_after_submission(staging, move |result| {
            seen.store(true, std::sync::atomic::Ordering::SeqCst);
            mapped(result)
        });
        MapRequest {
            fired,
            result: Box::pin(when_mapped),
        }
    }

    fn fired(&self) -> bool {
        self.fired.load(std::sync::atomic::Ordering::SeqCst)
    }

    /// Waits for the map unless its callback has run, hands the bytes of `staging` (the
    /// buffer it was requested on) to `f`, and unmaps. With `poll_first`, first polls the
    /// device without blocking, which runs the callback when the work that fills the buffer
    /// is done though not yet waited for; no wait is counted then.
    pub fn finish<R>(
        self,
        ctx: &GpuContext,
        staging: &wgpu::Buffer,
        poll_first: bool,
        f: impl FnOnce(&[u8]) -> R,
    ) -> Result<R> {
        if poll_first && !self.fired() {
            ctx.poll_ready()?;
        }
        if !self.fired() {
            ctx.wait_idle()?;
        }
        // Natively the map is settled now: `wait_idle` waited for this context's submission
        // or, with nothing submitted since its last wait, polled once. Should that poll not
        // have run the callback, wait for the whole queue rather than block on it for ever.
        #[cfg(not(target_arch = "wasm32"))]
        if !self.fired() {
            ctx.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| Error::Gpu(format!("waiting for a read-back: {e}")))?;
        }
        // Natively the wait above ran the callback; in a browser it may still be queued.
        if let Err(e) = super::wait::block_on(self.result) {
            return Err(Error::Gpu(format!("mapping a read-back buffer: {e}")));
        }
        let out = {
            let view = staging
                .get_mapped_range(..)
                .map_err(|e| Error::Gpu(format!("reading a mapped buffer: {e}")))?;
            f(&view)
        };
        staging.unmap();
        Ok(out)
    }
}

/// A read-only storage buffer holding one `T` (a params struct from `crates/core/src/layout/mod.rs`),
/// bound as `var<storage, read> params`; not a uniform buffer, see
/// [`super::kernel::ReflectedBinding`] (why params are storage buffers).
pub struct ParamBuffer<T: Pod> {
    buffer: wgpu::Buffer,
    stats: Arc<GpuStats>,
    _element: PhantomData<T>,
}

impl<T: Pod> Drop for ParamBuffer<T> {
    fn drop(&mut self) {
        self.stats.free(self.buffer.size());
    }
}

impl<T: Pod> ParamBuffer<T> {
    /// A params buffer initialised to `value`.
    pub fn new(ctx: &GpuContext, label: &str, value: &T) -> Self {
        let size = padded_bytes(std::mem::size_of::<T>() as u64);
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::UNIFORM
                | wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        ctx.stats_handle().alloc(size);
        let u = ParamBuffer {
            buffer,
            stats: Arc::clone(ctx.stats_handle()),
            _element: PhantomData,
        };
        u.write(ctx, value);
        u
    }

    /// Queues a new value (visible to the next submission).
    pub fn write(&self, ctx: &GpuContext, value: &T) {
        let bytes = bytemuck::bytes_of(value);
        ctx.write_buffer(&self.buffer, 0, bytes);
        ctx.stats_handle().upload(bytes.len() as u64);
    }

    /// The whole buffer as a binding resource.
    pub fn binding(&self) -> wgpu::BindingResource<'_> {
        self.buffer.as_entire_binding()
    }
}

/// A persistent `MAP_READ` staging buffer for small per-frame read-backs (ICP partials,
/// the surfel counter), so the frame loop allocates nothing.
pub struct Readback<T: Pod> {
    staging: wgpu::Buffer,
    capacity: usize,
    /// Elements copied by the last [`Readback::copy_from`].
    pending: usize,
    /// The map [`Readback::request`] asked for, until [`Readback::take`] reads it.
    requested: Option<MapRequest>,
    _element: PhantomData<T>,
}

impl<T: Pod> Readback<T> {
    /// Room for `capacity` elements (at least one).
    pub fn new(ctx: &GpuContext, label: &str, capacity: usize) -> Self {
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: padded_bytes((capacity.max(1) * std::mem::size_of::<T>()) as u64),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Readback {
            staging,
            capacity: capacity.max(1),
            pending: 0,
            requested: None,
            _element: PhantomData,
        }
    }

    /// Records a copy of the first `n` elements of `src` into the staging buffer.
    /// Panics when `n` exceeds either capacity, or while a requested map is not yet taken
    /// (internal contracts: wgpu refuses a copy into a buffer with a map pending).
    pub fn copy_from(&mut self, encoder: &mut wgpu::CommandEncoder, src: &GpuArray<T>, n: usize) {
        assert!(
            self.requested.is_none(),
            "a copy into `{}`'s read-back while its map is pending",
            src.label
        );
        assert!(
            n <= self.capacity && n <= src.capacity(),
            "read-back of {n} elements from `{}` exceeds a capacity",
            src.label
        );
        let bytes = padded_bytes((n * std::mem::size_of::<T>()) as u64).min(src.buffer.size());
        encoder.copy_buffer_to_buffer(&src.buffer, 0, &self.staging, 0, bytes);
        self.pending = n;
    }

    /// Records copies of the first `n` elements of each of `srcs`, one after the other,
    /// into the staging buffer (one read-back for several small results). Panics when they
    /// exceed a capacity (an internal contract).
    pub fn copy_from_each(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        srcs: &[&GpuArray<T>],
        n: usize,
    ) {
        let size = std::mem::size_of::<T>();
        assert!(
            self.requested.is_none(),
            "a copy into a read-back while its map is pending"
        );
        assert!(
            n * srcs.len() <= self.capacity && srcs.iter().all(|s| n <= s.capacity()),
            "read-back of {n} elements from each of {} buffers exceeds a capacity",
            srcs.len()
        );
        assert_eq!(
            (n * size) as u64 % COPY_ALIGN,
            0,
            "copies at aligned offsets"
        );
        for (i, src) in srcs.iter().enumerate() {
            let at = (i * n * size) as u64;
            encoder.copy_buffer_to_buffer(&src.buffer, 0, &self.staging, at, (n * size) as u64);
        }
        self.pending = n * srcs.len();
    }

    /// Waits for the submitted copy and returns its elements (counted as read-back bytes).
    pub fn read(&mut self, ctx: &GpuContext) -> Result<Vec<T>> {
        let request = self.requested.take();
        let request = request.unwrap_or_else(|| MapRequest::new(ctx, &self.staging));
        self.finish(ctx, request, false)
    }

    /// Requests the map of the submitted copy without waiting (call it after the
    /// submission that holds the copy): a later wait that covers that submission completes
    /// it, and [`Readback::take`] reads it then at no wait of its own.
    pub fn request(&mut self, ctx: &GpuContext) {
        if self.requested.is_none() {
            self.requested = Some(MapRequest::new(ctx, &self.staging));
        }
    }

    /// Whether a map was requested and not yet taken.
    pub fn is_requested(&self) -> bool {
        self.requested.is_some()
    }

    /// The submitted copy's elements as [`Readback::read`] returns them, but without a
    /// wait when the work that made them is done already (a later wait covered it, or the
    /// device finished it since): the map is requested if it was not, the device polled
    /// without blocking, and waited for only if the copy is still in flight.
    pub fn take(&mut self, ctx: &GpuContext) -> Result<Vec<T>> {
        self.request(ctx);
        let request = self.requested.take().expect("just requested");
        self.finish(ctx, request, true)
    }

    fn finish(
        &mut self,
        ctx: &GpuContext,
        request: MapRequest,
        poll_first: bool,
    ) -> Result<Vec<T>> {
        let n = std::mem::take(&mut self.pending);
        let bytes = n * std::mem::size_of::<T>();
        let out = request.finish(ctx, &self.staging, poll_first, |view| {
            bytemuck::pod_collect_to_vec::<u8, T>(&view[..bytes])
        })?;
        ctx.stats_handle().readback(bytes as u64);
        Ok(out)
    }
}
