//! wgslam: dense RGB-D SLAM with point-based fusion, and point-to-point ICP, on wgpu.
//!
//! ## The library's API
//!
//! What a program needs is re-exported at the crate root: open a sequence
//! ([`open_sequence`], [`SequenceOptions`], [`Sequence`]), configure ([`SlamParams`],
//! [`Profile`], [`SlamParams::validate`], which makes the [`ValidParams`] a run takes),
//! choose a backend ([`open_backend`],
//! [`BackendChoice`]), run ([`run`], giving a [`RunResult`]) and read the results
//! ([`Metrics`], the [`SurfelMap`], the per-frame [`FrameOutcome`]s) or write them as the
//! command line does ([`write_outputs`]); [`Error`] says what went wrong.
//!
//! ```no_run
//! use std::path::Path;
//!
//! let seq = wgslam::open_sequence(Path::new("assets/icl_living_room_kt2"), &Default::default())?;
//! let params = wgslam::SlamParams::profile(wgslam::Profile::Robust).validate()?;
//! let backend = wgslam::open_backend(wgslam::BackendChoice::Auto)?;
//! let result = wgslam::run(backend, &seq, 0, seq.len() - 1, params, |_frame| {})?;
//! println!("{} surfels, ATE {:?}", result.map.len(), result.metrics.accuracy);
//! # Ok::<(), wgslam::Error>(())
//! ```
//!
//! The modules below are public so that the tool's own binary, tests, examples and
//! benchmarks can reach the kernels, twins and buffers they check; they are hidden from
//! these docs and carry no stability promise.
//!
//! The tree is the architecture:
//!
//! | module | what |
//! |---|---|
//! | [`slam`] | the frame's step list generic over a backend ([`slam::pipeline`]), the 6x6 solve, the host map, the CPU reference backend |
//! | [`cpu`] | the CPU twins of the WGSL kernels: pure functions, no wgpu |
//! | [`gpu`] | wgpu context, kernels, buffers and textures, the GPU backend |
//! | [`layout`] | `#[repr(C)]` structs shared with `shaders/common.wgsl` |
//! | [`scan`] | point-to-point ICP for point clouds (readers, nearest neighbours, odometry) |
//! | [`geometry`] | SE(3), intrinsics, the rigid-alignment rotation |
//! | [`dataset`], [`io`] | sequences in; trajectories, PLY and atomic writes |
//! | `eval`, `stats` | ATE / RPE with the TUM benchmark's definitions; medians |
//! | [`mesh`] | triangle meshes of a map: TSDF of the surfels, surface nets, PLY / OBJ |
//! | [`render`] | headless pictures of maps and overlays, trajectory plots |
//! | [`tools`] | the jobs: run, two-frame ICP, CPU-vs-GPU compare, bench |
//! | `batch` | many runs from a TOML manifest: resumable, shardable over Slurm / Kubernetes arrays, one report |
//! | `cli` | argument parsing and printing only (native only, as `batch`) |
//! | `web` | the browser build's entry points (wasm32 only; `deploy/web`) |

// The command line's helpers in `tools` and `scan` are compiled but unused in the browser
// build, which has no command line.
#![cfg_attr(target_arch = "wasm32", allow(dead_code))]

// The command line and `wgslam batch` (signals, file locks, processes) are native only.
#[cfg(not(target_arch = "wasm32"))]
pub(crate) mod batch;
#[cfg(not(target_arch = "wasm32"))]
#[doc(hidden)]
pub mod cli;
#[doc(hidden)]
pub mod mesh;
#[doc(hidden)]
pub mod render;
#[doc(hidden)]
pub mod scan;
#[doc(hidden)]
pub mod slam;
// The floors below, crates of their own that cannot import anything above them: here
// their modules keep their paths (`crate::cpu`, `wgslam::gpu`, `wgslam::dataset`).
// crates/core: the maths, the layout contract, the CPU twins, the backend steps and plans,
// the error kinds; crates/gpu: the GPU engine; crates/data: datasets and files.
pub use wgslam_core::error;
pub(crate) use wgslam_core::stats;
#[doc(hidden)]
pub use wgslam_core::{cpu, geometry, layout, seeded};
#[doc(hidden)]
pub use wgslam_data::{dataset, eval, io};
#[doc(hidden)]
pub use wgslam_gpu as gpu;
#[doc(hidden)]
pub mod tools;
/// The crate-private readers of user files, for the seeded fuzz replay
/// (tests/it/fuzz_replay.rs): each parses its input and drops the result.
#[cfg(not(target_arch = "wasm32"))]
#[doc(hidden)]
pub mod fuzz_entry {
    use std::path::Path;

    /// A params file's text (`--params FILE`), as `ParamOverrides::from_toml` reads it.
    pub fn params_toml(text: &str) -> std::result::Result<(), String> {
        crate::cli::pipeline_args::ParamOverrides::from_toml(text).map(|_| ())
    }

    /// A batch manifest's text as if read from `path` (`wgslam batch MANIFEST`).
    pub fn manifest(path: &Path, text: &str) -> crate::Result<()> {
        crate::batch::manifest::Manifest::parse(path, text).map(|_| ())
    }
}
// The browser build's entry points (deploy/web).
#[cfg(target_arch = "wasm32")]
pub mod web;

pub use error::{Error, Result};

pub use dataset::{open as open_sequence, Sequence, SequenceOptions};
pub use layout::map::SurfelMap;
pub use slam::any_backend::{
    open as open_backend, open_shared as open_backend_shared, AnyBackend, BackendChoice,
};
pub use slam::params::{Profile, SlamParams, ValidParams};
pub use tools::run::{run, write_outputs, FrameOutcome, Metrics, RunResult};
