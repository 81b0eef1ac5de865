//! The jobs a user runs on top of the SLAM core, as library functions the CLI calls:
//! the batch run over a sequence with its outputs ([`run`]), the two-frame ICP experiment
//! (`two_frame`), the CPU-vs-GPU comparison (`compare`) and the benchmark (`bench`, with
//! the round trips it counts per frame: `round_trips`, and N GPU streams at once in one
//! process: `streams`; the CPU reference on one thread against many: `thread_scaling`);
//! with the `rerun` feature, the Rerun recording of a run (`rerun_log`).
//! They compute and write results; parsing arguments and printing tables is `crate::cli`.

pub mod bench;
pub mod compare;
pub(crate) mod long_run;
#[cfg(feature = "rerun")]
pub(crate) mod rerun_log;
pub mod round_trips;
pub mod run;
// Threads, one per stream: native only (a browser tab has one).
#[cfg(not(target_arch = "wasm32"))]
pub mod streams;
// Thread pools: native only, as above.
#[cfg(not(target_arch = "wasm32"))]
pub mod thread_scaling;
pub(crate) mod two_frame;
