//! wgslam: dense RGB-D SLAM with point-based fusion, and point-to-point ICP, on wgpu.
//!
//! The CPU reference lives in [`cpu`] (pure functions, no wgpu) and [`cpu_backend`]; the
//! GPU backend in [`gpu`] runs the same steps as WGSL compute kernels from `shaders/`.
//! [`pipeline`] holds the frame's steps, generic over a backend; [`run`] is the batch job;
//! [`scan`] is point-to-point ICP for point clouds.

pub mod any_backend;
pub mod bench;
pub mod camera;
pub mod cli;
pub mod compare;
pub mod cpu;
pub mod cpu_backend;
pub mod dataset;
pub mod error;
pub mod eval;
pub mod gpu;
pub mod instrumented;
pub mod io;
pub mod layout;
pub mod map;
pub mod pipeline;
pub mod run;
pub mod scan;
pub mod scan_cli;
pub mod se3;
pub mod solve;
pub mod stats;
pub mod two_frame;

pub use error::{Error, Result};
pub mod plot;
pub mod render;
pub mod render_cli;
pub mod rigid;
