//! wgslam: dense RGB-D SLAM with point-based fusion, and point-to-point ICP, on wgpu.
//!
//! The CPU reference lives in [`cpu`] (pure functions, no wgpu); the GPU backend in `gpu`
//! runs the same steps as WGSL compute kernels from `shaders/`.

pub mod bench;
pub mod camera;
pub mod error;
pub mod gpu;
pub mod map;
pub mod se3;

pub use error::{Error, Result};
pub mod cpu;
pub mod cpu_backend;
pub mod pipeline;
pub mod layout;
pub mod solve;
pub mod timed;
