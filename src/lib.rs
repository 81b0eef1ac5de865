//! wgslam: dense RGB-D SLAM with point-based fusion, and point-to-point ICP, on wgpu.
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
//! | [`eval`], [`stats`] | ATE / RPE with the TUM benchmark's definitions; medians |
//! | [`render`] | headless pictures of maps and overlays, trajectory plots |
//! | [`tools`] | the jobs: run, two-frame ICP, CPU-vs-GPU compare, bench |
//! | [`batch`] | many runs from a TOML manifest: resumable, shardable over Slurm / Kubernetes arrays, one report |
//! | [`cli`] | argument parsing and printing only |

pub mod batch;
pub mod cli;
pub mod cpu;
pub mod dataset;
pub mod error;
pub mod eval;
pub mod geometry;
pub mod gpu;
pub mod io;
pub mod layout;
pub mod render;
pub mod scan;
pub mod slam;
pub mod stats;
pub mod tools;

pub use error::{Error, Result};
