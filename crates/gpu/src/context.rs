//! The GPU context: one wgpu instance, adapter, device and queue, with the limits and
//! features the dense-SLAM kernels need, and the error-scope helper that turns wgpu
//! validation / out-of-memory errors and device loss into [`crate::Error::Gpu`].
//!
//! This is not a kernel runner: pipelines live in [`super::kernel`], buffers in
//! [`super::buffers`]. Only the Vulkan, Metal and DX12 backends are ever requested: the
//! OpenGL fallback on llvmpipe compiles one shader in minutes (see STYLE.md).

use std::sync::{Arc, Mutex};

mod submission;

use super::pipeline_cache::{self, DiskCache};
use super::shared_wait::Stream;
use super::stats::{GpuStats, StatsSnapshot};
use crate::{Error, Result};

/// Backends wgslam asks for. Never `GL`: on CPU-only machines it falls back to llvmpipe's
/// OpenGL, where a single compute shader took 235 s to compile.
#[cfg(not(target_arch = "wasm32"))]
pub const BACKENDS: wgpu::Backends = wgpu::Backends::VULKAN
    .union(wgpu::Backends::METAL)
    .union(wgpu::Backends::DX12);
/// Backends wgslam asks for in a browser: WebGPU only (never WebGL, which has no compute).
#[cfg(target_arch = "wasm32")]
pub const BACKENDS: wgpu::Backends = wgpu::Backends::BROWSER_WEBGPU;

/// Features the kernels use when the adapter offers them: 64-bit integers and 64-bit
/// `atomicMax` (the packed depth + surfel index map of `project_model`) and timestamp
/// queries (per-stage timing in [`super::timing`]), and the pipeline cache across
/// processes ([`super::pipeline_cache`]; unless [`super::pipeline_cache::CACHE_ENV`]
/// switches it off).
pub const WANTED_FEATURES: wgpu::Features = wgpu::Features::SHADER_INT64
    .union(wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX)
    .union(wgpu::Features::TIMESTAMP_QUERY)
    .union(wgpu::Features::PIPELINE_CACHE);

/// Environment variable choosing the kernels' integer width: `portable` creates the device
/// without 64-bit integers, so the two-pass 32-bit key kernels (`*_portable`) run even where
/// the adapter has 64-bit atomics; `auto` (or unset) takes them where offered. The
/// command line's `--gpu-features` sets it for the process and its children.
pub const FEATURES_ENV: &str = "WGSLAM_GPU_FEATURES";
/// Environment variable choosing the device's limits: `webgpu` asks for exactly
/// `wgpu::Limits::default()` (WebGPU's defaults: 8 storage buffers per stage, 128 MiB per
/// binding, ...) and no optional feature at all (so also the portable kernels and no
/// timestamp queries), as a browser tab gets; `adapter` (or unset) asks for the adapter's
/// own limits. The command line's `--gpu-limits` sets it.
pub const LIMITS_ENV: &str = "WGSLAM_GPU_LIMITS";
/// Environment variable choosing how contexts sharing a queue ([`GpuContext::share`]:
/// `batch --concurrent`, `bench --streams`, Python's trackers) submit: `own` (or unset)
/// gives each submission to the device when it is made; `combined` holds a stream's
/// submission while other streams share the queue and the device has work in flight, and
/// gives every held one to the device in one `queue.submit` (`shared_wait.rs`). The
/// command line's `--gpu-submissions` sets it.
pub const SUBMISSIONS_ENV: &str = "WGSLAM_GPU_SUBMISSIONS";

/// Which optional features the device is created with (see [`FEATURES_ENV`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum GpuFeatures {
    /// Every optional feature wgslam can use that the adapter offers: the 64-bit key
    /// kernels where the adapter has 64-bit atomics, the portable ones where it does not.
    #[default]
    Auto,
    /// No 64-bit integers whatever the adapter offers: the portable key kernels.
    Portable,
}

/// Which limits the device is created with (see [`LIMITS_ENV`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum GpuLimits {
    /// The adapter's own limits, as large as the hardware allows.
    #[default]
    Adapter,
    /// Exactly `wgpu::Limits::default()` and no optional feature: what WebGPU guarantees.
    Webgpu,
}

/// How contexts sharing one queue give their submissions to the device (see
/// [`SUBMISSIONS_ENV`]). Results are the same either way; only the number of
/// `queue.submit` calls and when the device gets the work differ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum GpuSubmissions {
    /// Every submission goes to the device at once, as one `queue.submit` of its own.
    #[default]
    Own,
    /// Streams sharing the queue combine their submissions into one `queue.submit` while
    /// the device is busy. Not the default: on lavapipe it was not faster (four streams
    /// about a tenth slower, docs/performance.md), and a real GPU has not measured it yet
    /// (`deploy/gpu-check.sh` runs both).
    Combined,
}

/// How the device is created: features, limits and submissions, read from
/// [`FEATURES_ENV`], [`LIMITS_ENV`] and [`SUBMISSIONS_ENV`] by [`DeviceOptions::from_env`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DeviceOptions {
    /// 64-bit key kernels where offered, or the portable ones.
    pub features: GpuFeatures,
    /// The adapter's limits or WebGPU's defaults.
    pub limits: GpuLimits,
    /// How streams sharing the queue submit.
    pub submissions: GpuSubmissions,
}

impl DeviceOptions {
    /// The options the environment asks for; unset variables take the defaults.
    ///
    /// [`Error::Argument`] naming the variable for a value that is not one of the choices.
    pub fn from_env() -> Result<DeviceOptions> {
        use clap::ValueEnum;
        fn read<T: ValueEnum + Default>(var: &str) -> Result<T> {
            match std::env::var(var) {
                Err(_) => Ok(T::default()),
                Ok(v) if v.is_empty() => Ok(T::default()),
                Ok(v) => T::from_str(&v, true).map_err(|_| {
                    let names: Vec<String> = T::value_variants()
                        .iter()
                        .filter_map(|c| c.to_possible_value().map(|p| p.get_name().to_string()))
                        .collect();
                    Error::Argument(format!("{var}={v}: want one of {}", names.join(", ")))
                }),
            }
        }
        Ok(DeviceOptions {
            features: read(FEATURES_ENV)?,
            limits: read(LIMITS_ENV)?,
            submissions: read(SUBMISSIONS_ENV)?,
        })
    }

    /// The features to ask of an adapter that offers `offered`: the [`WANTED_FEATURES`] it
    /// has, less the 64-bit integers under [`GpuFeatures::Portable`], and none at all under
    /// [`GpuLimits::Webgpu`].
    pub fn features_from(&self, offered: wgpu::Features) -> wgpu::Features {
        let mut features = offered & WANTED_FEATURES;
        if self.features == GpuFeatures::Portable {
            features
                .remove(wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX);
        }
        if self.limits == GpuLimits::Webgpu {
            features = wgpu::Features::empty();
        }
        features
    }

    /// The limits to ask of an adapter whose own are `offered`.
    pub fn limits_from(&self, offered: wgpu::Limits) -> wgpu::Limits {
        match self.limits {
            GpuLimits::Adapter => offered,
            GpuLimits::Webgpu => wgpu::Limits::default(),
        }
    }
}

/// Reduction workgroups on a CPU adapter (lavapipe): few workgroups with grid-stride
/// loops, each thread summing many pixels in registers; measured best around 16 at 640x480.
pub const CPU_REDUCTION_WORKGROUPS: u32 = 16;
/// Workgroups of 64 for grid-stride loops over pixels or surfels on a CPU adapter:
/// lavapipe pays per workgroup: a trivial kernel over a 320x240 map took ~8 ms in 1200
/// workgroups and ~2-3.5 ms in 256 (2 cores shared with other jobs; the whole pipeline
/// showed no clear change under that load).
pub const CPU_GRID_WORKGROUPS: u32 = 256;
/// Workgroups of a block-walking kernel (`project_model`, `fuse_select`, `fuse_merge`,
/// `fuse_prune`: a workgroup per culling block, striding over the blocks) on a CPU
/// adapter. Fewer than [`CPU_GRID_WORKGROUPS`]: with about 500 blocks, noisy frames 1..200
/// at 640x480 (`wgslam bench ... --downsample 1 --backends gpu --kernels`, one run each,
/// 2 cores): `fuse_select` 17.0 ms per pass in 256 workgroups, 15.5 in 64, 15.0 in 32,
/// 14.5 in 16; `fuse_prune` 13.8, 12.3, 12.0 and 11.1 ms.
pub const CPU_BLOCK_WORKGROUPS: u32 = 16;
/// Reduction workgroups on a real GPU, which needs thousands of threads in flight.
pub const GPU_REDUCTION_WORKGROUPS: u32 = 1024;

/// An open GPU device with its queue, limits and feature set, and byte/submission
/// accounting shared by every buffer created from it.
///
/// [`GpuContext::share`] gives another handle on the same device and queue with its own
/// accounting (`wgslam batch --concurrent`: one context per job, one device for all; wgpu's
/// error scopes are per thread, so each job's thread scopes its own work). Their waits
/// combine: one thread's device wait serves every context whose work it covers
/// (`shared_wait.rs`).
pub struct GpuContext {
    /// Kept alive for the lifetime of the adapter and device.
    _instance: wgpu::Instance,
    adapter: wgpu::Adapter,
    /// The logical device; create pipelines and buffers from it.
    pub device: wgpu::Device,
    /// The device's only queue; submit through [`GpuContext::submit`] so it is counted.
    pub queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    limits: wgpu::Limits,
    features: wgpu::Features,
    stats: Arc<GpuStats>,
    /// Set by the device-lost callback; reported by [`GpuContext::check_device`].
    lost: Arc<Mutex<Option<String>>>,
    /// Errors raised outside any error scope (wgpu's default handler would panic).
    uncaptured: Arc<Mutex<Vec<String>>>,
    /// The number of this context's latest submission not yet waited for
    /// ([`super::shared_wait::QueueWaits::submit`]): [`GpuContext::wait_idle`] waits until it is done.
    last_submission: Mutex<Option<u64>>,
    /// Submissions and device waits of every context sharing the queue.
    queue_waits: Stream,
    /// Objects built once per device, by key ([`GpuContext::cached`]: the kernels); one map
    /// for every context sharing the device.
    cache: Arc<Mutex<DeviceCache>>,
    /// Steps recorded but not yet submitted ([`GpuContext::defer`]), `(step, commands)` in
    /// recording order; the next submission carries them first.
    deferred: Mutex<Vec<(&'static str, wgpu::CommandBuffer)>>,
    /// The pipelines' cache across processes, one for every context sharing the device
    /// (written back when the last is dropped); `None` where the adapter has none or it is
    /// switched off.
    pipeline_cache: Option<Arc<DiskCache>>,
    /// Browser only: error scopes popped and not yet read ([`GpuContext::scoped`]).
    #[cfg(target_arch = "wasm32")]
    popped_scopes: Mutex<Vec<PoppedScope>>,
}

/// A step's error scopes, popped and not yet read (browser only): the step's name and the
/// pops' results, validation first.
#[cfg(target_arch = "wasm32")]
type PoppedScope = (String, [ScopeResult; 2]);

/// The result of an error scope's pop.
#[cfg(target_arch = "wasm32")]
type ScopeResult = std::pin::Pin<Box<dyn std::future::Future<Output = Option<wgpu::Error>>>>;

/// Objects built once per device by key (a kernel's name, or its name and its passes),
/// each of the type its key's callers ask for, in a slot of its own (empty while its first
/// build runs, or after that build failed).
type DeviceCache = std::collections::HashMap<String, CacheSlot>;

/// One key's entry of [`DeviceCache`]: locked while its object is built, so threads asking
/// for the same key wait for that one build, and threads asking for other keys do not.
type CacheSlot = Arc<Mutex<Option<Box<dyn std::any::Any + Send>>>>;

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext")
            .field("adapter", &self.info.name)
            .field("backend", &self.info.backend)
            .field("device_type", &self.info.device_type)
            .field("features", &self.features)
            .finish()
    }
}

/// Devices opened in this process ([`GpuContext::devices_opened`]).
static DEVICES_OPENED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

impl Drop for GpuContext {
    /// Gives held submissions to the device: a stream that ends with work held might
    /// otherwise leave it to a wait that never comes.
    fn drop(&mut self) {
        self.queue_waits.make_held(&self.queue, &self.stats);
    }
}

impl GpuContext {
    /// Opens the high-performance adapter among Vulkan / Metal / DX12, logs it to stderr and
    /// creates a device with every [`WANTED_FEATURES`] flag the adapter has and the
    /// adapter's own limits (so `max_storage_buffer_binding_size`, `max_buffer_size` and
    /// storage buffers per stage are as large as the hardware allows).
    ///
    /// The features and limits are those [`DeviceOptions::from_env`] asks for (by default
    /// all of the above).
    ///
    /// Errors: [`Error::NoAdapter`] naming the backends tried and the adapters seen;
    /// [`Error::Gpu`] when the device cannot be created; [`Error::Argument`] for a bad
    /// [`FEATURES_ENV`] or [`LIMITS_ENV`].
    pub fn new() -> Result<GpuContext> {
        Self::with_options(DeviceOptions::from_env()?)
    }

    /// Devices this process has opened ([`GpuContext::new`], [`GpuContext::with_options`];
    /// not [`GpuContext::share`], which opens none): a diagnostic for the tests that check
    /// that streams share one device.
    pub fn devices_opened() -> u64 {
        DEVICES_OPENED.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// [`GpuContext::new`] with the device's features and limits chosen by `options`
    /// rather than the environment.
    pub fn with_options(options: DeviceOptions) -> Result<GpuContext> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: BACKENDS,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapter =
            match super::wait::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: false,
                compatible_surface: None,
                // Trusted native tool: we want the real limits, not fingerprint buckets.
                apply_limit_buckets: false,
            })) {
                Ok(a) => a,
                Err(e) => {
                    let seen: Vec<String> =
                        super::wait::block_on(instance.enumerate_adapters(BACKENDS))
                            .iter()
                            .map(|a| {
                                let i = a.get_info();
                                format!("{} ({:?})", i.name, i.backend)
                            })
                            .collect();
                    return Err(Error::NoAdapter(format!(
                    "tried backends Vulkan, Metal, DX12 (never GL); adapters seen: [{}]; wgpu: {e}",
                    seen.join(", ")
                )));
                }
            };
        let info = adapter.get_info();
        eprintln!(
            "wgslam: GPU adapter \"{}\" backend {:?} type {:?} driver \"{} {}\"",
            info.name, info.backend, info.device_type, info.driver, info.driver_info
        );
        let mut features = options.features_from(adapter.features());
        let cache_folder = pipeline_cache::cache_folder()
            .filter(|_| features.contains(wgpu::Features::PIPELINE_CACHE));
        if cache_folder.is_none() {
            features.remove(wgpu::Features::PIPELINE_CACHE);
        }
        let limits = options.limits_from(adapter.limits());
        if options != DeviceOptions::default() {
            eprintln!("wgslam: GPU device with {options:?}: features {features:?}");
        }
        let (device, queue) =
            super::wait::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                label: Some("wgslam device"),
                required_features: features,
                required_limits: limits.clone(),
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            }))
            .map_err(|e| Error::Gpu(format!("cannot create a device on \"{}\": {e}", info.name)))?;

        let lost = Arc::new(Mutex::new(None));
        let lost_cb = Arc::clone(&lost);
        device.set_device_lost_callback(move |reason, msg| {
            // A device dropped by us at the end of the run is not an error.
            if reason != wgpu::DeviceLostReason::Destroyed {
                *lost_cb.lock().unwrap_or_else(|p| p.into_inner()) =
                    Some(format!("device lost ({reason:?}): {msg}"));
            }
        });
        let pipeline_cache = cache_folder
            .and_then(|folder| DiskCache::open(&device, &info, &folder))
            .map(Arc::new);
        let uncaptured = Arc::new(Mutex::new(Vec::new()));
        let uncaptured_cb = Arc::clone(&uncaptured);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            uncaptured_cb
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push(e.to_string());
        }));

        DEVICES_OPENED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(GpuContext {
            _instance: instance,
            adapter,
            device,
            queue,
            info,
            limits,
            features,
            stats: Arc::new(GpuStats::default()),
            deferred: Mutex::new(Vec::new()),
            lost,
            uncaptured,
            last_submission: Mutex::new(None),
            queue_waits: Stream::new(options.submissions == GpuSubmissions::Combined),
            cache: Arc::default(),
            pipeline_cache,
            #[cfg(target_arch = "wasm32")]
            popped_scopes: Mutex::new(Vec::new()),
        })
    }

    /// Another context on this one's device and queue (no new adapter or device): its own
    /// byte, submission and wait counters, and [`GpuContext::wait_idle`] waiting until its
    /// own submissions are done (by its own device wait or by another context's that covers
    /// them). A lost device, and an error escaping every error scope, show in every context
    /// of the device.
    pub fn share(&self) -> GpuContext {
        GpuContext {
            _instance: self._instance.clone(),
            adapter: self.adapter.clone(),
            device: self.device.clone(),
            queue: self.queue.clone(),
            info: self.info.clone(),
            limits: self.limits.clone(),
            features: self.features,
            stats: Arc::new(GpuStats::default()),
            lost: Arc::clone(&self.lost),
            uncaptured: Arc::clone(&self.uncaptured),
            last_submission: Mutex::new(None),
            queue_waits: self.queue_waits.share(),
            cache: Arc::clone(&self.cache),
            deferred: Mutex::new(Vec::new()),
            pipeline_cache: self.pipeline_cache.clone(),
            #[cfg(target_arch = "wasm32")]
            popped_scopes: Mutex::new(Vec::new()),
        }
    }

    /// The pipeline cache to create pipelines with (`None` without one).
    pub fn pipeline_cache(&self) -> Option<&wgpu::PipelineCache> {
        self.pipeline_cache.as_deref().map(|c| &c.cache)
    }

    /// The object stored under `key` on this device, built by `build` (and stored) the
    /// first time: pipelines cost 60-130 ms each on lavapipe, and a batch's concurrent jobs
    /// ([`GpuContext::share`]) need the same ones (`Kernel::new` caches through this).
    /// Threads asking for one key at once build it once; threads asking for different keys
    /// build them at the same time (`Kernels::new` builds the kernels on every core). A
    /// failed build stores nothing, so the next caller tries again. Panics when one key is
    /// asked for as two types (a broken internal contract).
    pub(crate) fn cached<T: Clone + Send + 'static>(
        &self,
        key: &str,
        build: impl FnOnce() -> Result<T>,
    ) -> Result<T> {
        let slot = {
            let mut cache = self.cache.lock().unwrap_or_else(|p| p.into_inner());
            Arc::clone(cache.entry(key.to_string()).or_default())
        };
        let mut stored = slot.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(stored) = stored.as_ref() {
            let typed = stored.downcast_ref::<T>();
            return Ok(typed
                .unwrap_or_else(|| panic!("device cache key `{key}` asked for as two types"))
                .clone());
        }
        let built = build()?;
        *stored = Some(Box::new(built.clone()));
        Ok(built)
    }

    /// The device's limits (the adapter's, requested in full, or WebGPU's defaults).
    pub fn limits(&self) -> &wgpu::Limits {
        &self.limits
    }

    /// The features enabled on the device (the subset of [`WANTED_FEATURES`] the adapter has).
    pub fn features(&self) -> wgpu::Features {
        self.features
    }

    /// Name, backend, device type and driver of the adapter.
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.info
    }

    /// The adapter itself (e.g. for format queries).
    pub fn adapter(&self) -> &wgpu::Adapter {
        &self.adapter
    }

    /// True when 64-bit integer atomics (`atomicMax` on `u64`) are enabled on the device:
    /// the key kernels are then the 64-bit ones, else their `*_portable` variants.
    pub fn has_int64_atomics(&self) -> bool {
        self.features
            .contains(wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX)
    }

    /// Workgroup count for grid-stride reductions: few on a CPU adapter (lavapipe runs a
    /// workgroup as SIMD lanes on one core; more workgroups only add partial sums), many on
    /// a real GPU.
    pub fn reduction_workgroups(&self) -> u32 {
        match self.info.device_type {
            wgpu::DeviceType::Cpu => CPU_REDUCTION_WORKGROUPS,
            _ => GPU_REDUCTION_WORKGROUPS,
        }
    }

    /// True on a CPU adapter (lavapipe, llvmpipe, SwiftShader), where workgroups run as
    /// SIMD lanes on CPU cores and grid-stride kernels want few of them.
    pub fn is_cpu_adapter(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Most workgroups a grid-stride kernel over pixels or surfels is dispatched with:
    /// [`CPU_GRID_WORKGROUPS`] on a CPU adapter, the per-dimension limit on a GPU (where
    /// one thread per item is best).
    pub fn grid_workgroups_cap(&self) -> u32 {
        match self.info.device_type {
            wgpu::DeviceType::Cpu => CPU_GRID_WORKGROUPS,
            _ => self.limits.max_compute_workgroups_per_dimension,
        }
    }

    /// Most workgroups a block-walking kernel is dispatched with: [`CPU_BLOCK_WORKGROUPS`]
    /// on a CPU adapter, the per-dimension limit on a GPU (a workgroup per block).
    pub fn block_workgroups_cap(&self) -> u32 {
        match self.info.device_type {
            wgpu::DeviceType::Cpu => CPU_BLOCK_WORKGROUPS,
            _ => self.limits.max_compute_workgroups_per_dimension,
        }
    }

    /// Largest buffer, in bytes, that can be both created and bound whole as one storage
    /// binding: `min(max_storage_buffer_binding_size, max_buffer_size)`.
    pub fn max_storage_bytes(&self) -> u64 {
        self.limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size)
    }

    /// Byte and submission counters shared by all buffers of this context.
    pub fn stats(&self) -> StatsSnapshot {
        self.stats.snapshot()
    }

    /// The shared counters (buffers hold a clone to account their own frees).
    pub(crate) fn stats_handle(&self) -> &Arc<GpuStats> {
        &self.stats
    }

    /// [`Error::Gpu`] if the device was lost or an error escaped every error scope.
    pub fn check_device(&self) -> Result<()> {
        if let Some(msg) = self.lost.lock().unwrap_or_else(|p| p.into_inner()).clone() {
            return Err(Error::Gpu(msg));
        }
        let mut unc = self.uncaptured.lock().unwrap_or_else(|p| p.into_inner());
        if !unc.is_empty() {
            let msg = unc.join("; ");
            unc.clear();
            return Err(Error::Gpu(format!("uncaptured GPU error: {msg}")));
        }
        Ok(())
    }

    /// Runs `work` (which records and submits GPU commands, or creates resources) inside
    /// pushed Validation and OutOfMemory error scopes, and turns any captured error, a lost
    /// device, or an error escaping the scopes into [`Error::Gpu`] prefixed with `what`.
    /// An error returned by `work` itself is passed through unchanged (after popping).
    ///
    /// In a browser each pop's answer is a round trip to the GPU process, which the page
    /// waits for by suspending: two per step, most of a frame's suspensions. So there the
    /// scopes are popped at once but read at the context's next wait
    /// ([`GpuContext::wait_idle`], which every read-back makes), whose suspension covers
    /// them: a step's error is reported, with its name, by the next wait instead.
    pub fn scoped<T>(&self, what: &str, work: impl FnOnce() -> Result<T>) -> Result<T> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let scope_start = self.queue_waits.handed();
        let result = work();
        #[cfg(target_arch = "wasm32")]
        {
            let _ = scope_start;
            // Scopes pop in reverse order of their pushing.
            let popped: [ScopeResult; 2] = [Box::pin(validation.pop()), Box::pin(oom.pop())];
            self.popped_scopes
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push((what.to_string(), popped));
            self.check_device()?;
            result
        }
        #[cfg(not(target_arch = "wasm32"))]
        self.read_scopes(what, scope_start, validation, oom, result)
    }

    /// [`GpuContext::scoped`]'s end natively: pops the scopes, waits for their answers, and
    /// returns `result` unless they caught an error.
    #[cfg(not(target_arch = "wasm32"))]
    fn read_scopes<T>(
        &self,
        what: &str,
        scope_start: u64,
        validation: wgpu::ErrorScopeGuard,
        oom: wgpu::ErrorScopeGuard,
        result: Result<T>,
    ) -> Result<T> {
        // Scopes pop in reverse order of their pushing.
        let validation_err = super::wait::block_on(validation.pop());
        let oom_err = super::wait::block_on(oom.pop());
        if validation_err.is_some() || oom_err.is_some() {
            // What this stream recorded in the scope may be invalid: held, it would fail
            // the `queue.submit` of whichever stream makes it, in that stream's scope.
            self.queue_waits.discard_held_since(scope_start);
        }
        let mut msgs = scope_messages(validation_err, oom_err);
        if let Err(e) = self.check_device() {
            msgs.push(e.to_string());
        }
        if !msgs.is_empty() {
            return Err(Error::Gpu(format!("{what}: {}", msgs.join("; "))));
        }
        result
    }

    /// Browser only: reads the answers of every error scope popped since the last call
    /// (waiting for any not yet in, which the wait before it has normally brought), and
    /// reports the first step whose scopes caught an error.
    #[cfg(target_arch = "wasm32")]
    pub(crate) fn read_popped_scopes(&self) -> Result<()> {
        let popped =
            std::mem::take(&mut *self.popped_scopes.lock().unwrap_or_else(|p| p.into_inner()));
        let mut first = None;
        for (what, [validation, oom]) in popped {
            let msgs = scope_messages(
                super::wait::block_on(validation),
                super::wait::block_on(oom),
            );
            if first.is_none() && !msgs.is_empty() {
                first = Some(Error::Gpu(format!("{what}: {}", msgs.join("; "))));
            }
        }
        first.map_or(Ok(()), Err)
    }
}

/// What a step's Validation and OutOfMemory error scopes caught, as message parts.
fn scope_messages(validation: Option<wgpu::Error>, oom: Option<wgpu::Error>) -> Vec<String> {
    let validation = validation.map(|e| format!("validation: {e}"));
    let oom = oom.map(|e| format!("out of memory: {e}"));
    validation.into_iter().chain(oom).collect()
}
