//! Dense RGB-D SLAM's frame loop and the backends that run it: the fixed step list
//! ([`pipeline`]) and the parts it drives per frame (`tracker`, `recovery`, `loop_closer`;
//! what it reports: [`report`]), the host-side 6x6 solve ([`solve`]), the surfel map as the
//! host holds it (`crate::layout::map`), the CPU reference backend ([`cpu_backend`]), the run-time choice between it
//! and the GPU backend (`any_backend`) and a step-watching decorator (`instrumented`).
//! The GPU backend itself lives in [`crate::gpu::backend`], beside the wgpu code it needs.

pub mod any_backend;
// The steps every backend implements, their plans, and the fused view: the bottom floor
// (crates/core), which the GPU engine (crates/gpu) stands on too.
pub use wgslam_core::{backend, fused_view, plan};
#[cfg(test)]
mod bilateral_quality;
pub mod cpu_backend;
pub mod features;
pub mod health;
pub(crate) mod instrumented;
pub mod keyframes;
pub(crate) mod loop_closer;
pub mod loops;
pub mod loops_check;
pub mod params;
pub mod pipeline;
pub mod pose_graph;
pub(crate) mod recovery;
pub mod report;
pub(crate) mod seeded;
pub mod solve;
pub(crate) mod step_params;
pub(crate) mod tracker;
