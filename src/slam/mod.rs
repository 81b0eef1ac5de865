//! Dense RGB-D SLAM's frame loop and the backends that run it: the fixed step list
//! ([`pipeline`]) and the parts it drives per frame (`tracker`, `recovery`, `loop_closer`;
//! what it reports: [`report`]), the host-side 6x6 solve ([`solve`]), the surfel map as the
//! host holds it (`crate::layout::map`), the run-time choice between the CPU reference
//! backend ([`cpu_backend`]) and the GPU backend (`any_backend`) and a step-watching
//! decorator (`instrumented`). Both backends are floors below: the CPU reference in the core
//! crate beside the twins and the plans, the GPU backend in [`crate::gpu::backend`] (the
//! crate `wgslam-gpu`), beside the wgpu code it needs.

pub mod any_backend;
// The steps every backend implements, their plans, the fused view and the CPU reference
// backend: the bottom floor (crates/core), which the GPU engine (crates/gpu) stands on too.
pub use wgslam_core::{backend, cpu_backend, fused_view, plan};
#[cfg(test)]
mod bilateral_quality;
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
pub mod solve;
pub(crate) mod step_params;
pub(crate) mod tracker;
