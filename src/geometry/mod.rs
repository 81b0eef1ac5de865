//! Geometry shared by dense SLAM, scan registration and evaluation: rigid transforms and
//! SE(3) ([`se3`]), pinhole intrinsics ([`camera`]) and the SVD rotation step of rigid
//! alignment (`rigid`). Double precision, host only; the per-pixel f32 maths the kernels
//! share lives in `cpu/mod.rs` and `shaders/common.wgsl`.

pub mod camera;
pub(crate) mod rigid;
pub mod se3;
