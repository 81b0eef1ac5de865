//! The harness of the integration tests (the one test crate `it`, `harness = false` in
//! Cargo.toml), on libtest-mimic: a test that cannot run here (no GPU adapter, no
//! `../shared/data`) is an `ignored` trial whose reason is shown, never a silent pass.
//!
//! A module of `it` (one file, or a directory) keeps its tests as plain functions and ends with
//!
//! ```ignore
//! pub fn tests() -> Vec<common::harness::Test> {
//!     vec![
//!         plain("name", a_plain_test),                   // fn()
//!         gpu("gpu_name", a_gpu_test),                   // fn(GpuContext)
//!         shared("shared_name", a_full_sequence_test),   // fn(&Path): ../shared/data
//!         gpu_shared("both", |ctx, data| ...),           // fn(GpuContext, &Path)
//!     ]
//! }
//! ```
//!
//! `tests/it/main.rs` collects every module's tests, names each `MODULE::name` ([`in_module`],
//! so that `cargo test --test it MODULE` runs one module) and passes them all to [`run`].
//!
//! Whether a GPU adapter exists is decided once per process (only when a selected trial
//! needs one), as is whether `../shared/data` is a directory. A trial that cannot run is
//! marked ignored with its reason as the trial's kind (`test [no GPU adapter] name ...
//! ignored`; both reasons when both are missing), and the ignored tests are listed with
//! the full reason on stderr before the run. Each GPU trial
//! still opens its own context, as the tests always have
//! ([`wgslam::gpu::test_support::gpu_for_test`]).
//!
//! Environment: `WGSLAM_REQUIRE_GPU=1` makes a missing adapter a failure and
//! `WGSLAM_REQUIRE_DATA=1` a missing `../shared/data`; `.ci/run` sets both.
//! `WGSLAM_IT_GPU_ONLY=1` registers only the tests that need a GPU (a context of their
//! own, or a `wgslam` child on the GPU: those are registered as [`gpu`] tests too), and
//! prints how many it left out: `.ci/run`'s second pass under WebGPU's limits, which cannot
//! change a test that touches no GPU. Command-line
//! arguments are libtest's (`FILTER`, `--exact`, `--skip`, `--ignored`, `--include-ignored`,
//! `--list`, `--test-threads`, `-q`); `RUST_TEST_THREADS` is honoured as libtest does.
//! Unlike libtest, output is not captured: a test's `eprintln!` lines appear as it runs.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use libtest_mimic::{Arguments, Completion, Failed, Trial};
use wgslam::gpu::test_support::{gpu_for_test, NoGpu};
use wgslam::gpu::{GpuBackend, GpuContext};

/// Environment variable that turns a missing `../shared/data` from a skip into a failure.
pub const REQUIRE_DATA_ENV: &str = "WGSLAM_REQUIRE_DATA";

/// Trial kind (shown in brackets before the name) of a GPU test skipped for want of an adapter.
pub const NO_GPU_KIND: &str = "no GPU adapter";
/// Trial kind of a test skipped because `../shared/data` is absent.
pub const NO_DATA_KIND: &str = "no ../shared/data";

/// Environment variable that keeps only the tests that need a GPU (see the module docs).
pub const GPU_ONLY_ENV: &str = "WGSLAM_IT_GPU_ONLY";

/// True when `WGSLAM_REQUIRE_DATA=1`.
pub fn data_required() -> bool {
    std::env::var(REQUIRE_DATA_ENV).is_ok_and(|v| v == "1")
}

/// The full data sets next to the repository: ICL-NUIM `icl_living_room_kt2/` (210 frames)
/// and `lidar/`.
pub fn shared_data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data")
}

/// What a test body may return: nothing (it ran; a panic fails it), or a [`Completion`]
/// when it can only find out while running that it cannot run here (see [`skipped`]).
pub trait Finish {
    /// The body's result as libtest-mimic's.
    fn finish(self) -> Completion;
}

impl Finish for () {
    fn finish(self) -> Completion {
        Completion::Completed
    }
}

impl Finish for Completion {
    fn finish(self) -> Completion {
        self
    }
}

/// A body's way to report, while running, that it cannot run here (an adapter without a
/// feature): the trial shows as `ignored (reason)` and counts as ignored.
pub fn skipped(reason: impl ToString) -> Completion {
    Completion::ignored_with(reason)
}

/// What a body receives: a GPU context when the test needs one, the data directory when
/// it needs that.
type Body = Box<dyn FnOnce(Option<GpuContext>, Option<&Path>) -> Completion + Send>;

/// One registered test: its name, what it needs, and its body.
pub struct Test {
    name: String,
    needs_gpu: bool,
    needs_data: bool,
    body: Body,
}

/// A test that needs neither a GPU nor `../shared/data`.
pub fn plain<R: Finish>(name: &'static str, f: impl FnOnce() -> R + Send + 'static) -> Test {
    Test {
        name: name.to_string(),
        needs_gpu: false,
        needs_data: false,
        body: Box::new(move |_, _| f().finish()),
    }
}

/// A GPU backend on the trial's context (panics when it cannot be made).
pub fn gpu_backend(ctx: GpuContext) -> GpuBackend {
    GpuBackend::new(ctx).expect("GPU backend")
}

/// A [`gpu`] trial whose body takes a fresh [`gpu_backend`] instead of the context.
pub fn gpu_backend_test<R: Finish + 'static>(name: &'static str, f: fn(GpuBackend) -> R) -> Test {
    gpu(name, move |ctx| f(gpu_backend(ctx)))
}

/// A test that gets a fresh GPU context of its own.
pub fn gpu<R: Finish>(
    name: &'static str,
    f: impl FnOnce(GpuContext) -> R + Send + 'static,
) -> Test {
    Test {
        name: name.to_string(),
        needs_gpu: true,
        needs_data: false,
        body: Box::new(move |ctx, _| f(ctx.expect("a GPU test gets a context")).finish()),
    }
}

/// A test that reads the full data sets in `../shared/data` (it gets that directory).
pub fn shared<R: Finish>(name: &'static str, f: impl FnOnce(&Path) -> R + Send + 'static) -> Test {
    Test {
        name: name.to_string(),
        needs_gpu: false,
        needs_data: true,
        body: Box::new(move |_, data| f(data.expect("a data test gets the directory")).finish()),
    }
}

/// A GPU test over the full data sets.
pub fn gpu_shared<R: Finish>(
    name: &'static str,
    f: impl FnOnce(GpuContext, &Path) -> R + Send + 'static,
) -> Test {
    Test {
        name: name.to_string(),
        needs_gpu: true,
        needs_data: true,
        body: Box::new(move |ctx, data| {
            f(
                ctx.expect("a GPU test gets a context"),
                data.expect("a data test gets the directory"),
            )
            .finish()
        }),
    }
}

/// Why a test that needs `../shared/data` cannot run here, if it cannot: `Ok(None)` when
/// the directory exists, `Ok(Some(reason))` to skip, `Err(message)` to fail.
fn data_status() -> Result<Option<String>, String> {
    let dir = shared_data_dir();
    if dir.is_dir() {
        Ok(None)
    } else if data_required() {
        Err(format!(
            "{} is absent and {REQUIRE_DATA_ENV}=1",
            dir.display()
        ))
    } else {
        Ok(Some(format!(
            "{} is absent (the full ICL-NUIM sequence and LiDAR sets); \
             set {REQUIRE_DATA_ENV}=1 to fail instead",
            dir.display()
        )))
    }
}

/// Probes the GPU once: `Some(reason)` when GPU tests are to be skipped. A failure
/// (adapter required, broken device) is not a skip: each GPU test then runs and fails
/// with the message.
fn gpu_skip_reason() -> Option<String> {
    match gpu_for_test() {
        Ok(_probe) => None,
        Err(NoGpu::Skip(why)) => Some(why),
        Err(NoGpu::Fail(_)) => None,
    }
}

/// Runs one test: opens what it needs (or skips / fails without it), then the body.
fn run_one(test: Test) -> Result<Completion, Failed> {
    let dir = shared_data_dir();
    if test.needs_data {
        match data_status() {
            Ok(None) => {}
            // Reached only with --ignored / --include-ignored.
            Ok(Some(why)) => return Ok(skipped(why)),
            Err(why) => return Err(why.into()),
        }
    }
    let ctx = if test.needs_gpu {
        match gpu_for_test() {
            Ok(ctx) => Some(ctx),
            // Reached only with --ignored / --include-ignored, or if the adapter vanished.
            Err(NoGpu::Skip(why)) => return Ok(skipped(why)),
            Err(NoGpu::Fail(why)) => return Err(why.into()),
        }
    } else {
        None
    };
    let data = test.needs_data.then_some(dir.as_path());
    Ok((test.body)(ctx, data))
}

/// The tests of the module `module` of `it`, each renamed `module::name`.
pub fn in_module(module: &str, tests: Vec<Test>) -> Vec<Test> {
    tests
        .into_iter()
        .map(|test| Test {
            name: format!("{module}::{}", test.name),
            ..test
        })
        .collect()
}

/// Parses libtest's arguments, marks the tests that cannot run here as ignored (printing
/// why), runs them, and returns the exit code (non-zero when any failed).
pub fn run(mut tests: Vec<Test>) -> ExitCode {
    if std::env::var(GPU_ONLY_ENV).is_ok_and(|v| v == "1") {
        let all = tests.len();
        tests.retain(|t| t.needs_gpu);
        eprintln!(
            "{GPU_ONLY_ENV}=1: {} of {all} tests need a GPU and are registered; the {} \
             others are left out (not run, not counted)",
            tests.len(),
            all - tests.len()
        );
    }
    let mut names: Vec<&str> = tests.iter().map(|t| t.name.as_str()).collect();
    names.sort_unstable();
    if let Some(twice) = names.windows(2).find(|w| w[0] == w[1]) {
        panic!("two tests are named {}", twice[0]);
    }
    let mut args = Arguments::from_args();
    if args.test_threads.is_none() {
        args.test_threads = std::env::var("RUST_TEST_THREADS")
            .ok()
            .and_then(|v| v.parse().ok());
    }
    // Probe the GPU only if a test the filter selects needs it.
    let gpu_skip = tests
        .iter()
        .any(|t| t.needs_gpu && selected(&args, &t.name))
        .then(gpu_skip_reason)
        .flatten();
    let data_skip = data_status().ok().flatten();

    // Tests skipped for the same reason(s), listed before the run: (kind, reason, names).
    let mut skipped_by_reason: Vec<(String, String, Vec<String>)> = Vec::new();
    let mut trials = Vec::with_capacity(tests.len());
    for test in tests {
        let mut kinds = Vec::new();
        let mut whys = Vec::new();
        if let (true, Some(why)) = (test.needs_gpu, &gpu_skip) {
            kinds.push(NO_GPU_KIND);
            whys.push(why.as_str());
        }
        if let (true, Some(why)) = (test.needs_data, &data_skip) {
            kinds.push(NO_DATA_KIND);
            whys.push(why.as_str());
        }
        let name = test.name.clone();
        let mut trial = Trial::ignorable_test(name.clone(), move || run_one(test));
        if !kinds.is_empty() {
            let (kind, why) = (kinds.join(", "), whys.join("; "));
            trial = trial.with_kind(kind.clone()).with_ignored_flag(true);
            if selected(&args, &name) {
                match skipped_by_reason.iter_mut().find(|(k, _, _)| *k == kind) {
                    Some((_, _, names)) => names.push(name),
                    None => skipped_by_reason.push((kind, why, vec![name])),
                }
            }
        }
        trials.push(trial);
    }
    if !args.list {
        for (kind, why, names) in &skipped_by_reason {
            eprintln!(
                "ignored [{kind}]: {} test(s): {}\n  reason: {why}",
                names.len(),
                names.join(", ")
            );
        }
    }
    libtest_mimic::run(&args, trials).exit_code()
}

/// Whether the name filters (`FILTER`, `--exact`, `--skip`) select the test `name`. The
/// stand-in trial carries the ignored flag so that `--ignored` does not filter it out.
fn selected(args: &Arguments, name: &str) -> bool {
    !args.is_filtered_out(&Trial::test(name, || Ok(())).with_ignored_flag(true))
}
