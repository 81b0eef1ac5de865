//! wgslam's bottom floor: what every other part stands on, and nothing above it.
//!
//! | module | what |
//! |---|---|
//! | [`geometry`] | SE(3), pinhole intrinsics, rigid alignment of point pairs (f64, host) |
//! | [`layout`] | the `#[repr(C)]` structs shared with the WGSL kernels (`shaders/common.wgsl`, `shaders/scan_common.wgsl`), and the host surfel map in the GPU's packing |
//! | [`cpu`] | the CPU twins of the WGSL kernels: pure functions over typed slices, the shader's shape line by line |
//! | [`error`] | [`Error`]: one documented variant per kind of thing a user can cause or meet, for every floor |
//! | [`stats`] | the one median |
//! | [`seeded`] | the one fixed-seed number stream (splitmix64) |
//! | [`cpu_backend`] | the CPU reference backend: the steps as calls of the twins, in the plans' order |
//! | [`backend`] | the steps every backend implements (the CPU reference's twins, the GPU's kernels), and the maps they exchange |
//! | [`plan`] | each step's kernels in order, written once for both backends |
//! | [`registry`] | one row per kernel: its shader's text, its twin, its id, how the GPU engine binds it |
//! | [`fused_view`] | when the last fusion's index map is the next prediction's |
//!
//! Not here: wgpu (the GPU backend is `crates/gpu`), files, datasets, the frame loop. Those are in the `wgslam` package above
//! this crate (which re-exports these modules under the same names), and a path from here
//! to them does not compile: the workspace is the wall between the floors.

pub mod backend;
pub mod cpu;
pub mod cpu_backend;
pub mod error;
pub mod fused_view;
pub mod geometry;
pub mod layout;
pub mod plan;
pub mod registry;
pub mod seeded;
pub mod stats;

pub use error::{Error, Result};
