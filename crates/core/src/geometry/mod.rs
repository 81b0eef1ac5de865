//! Geometry shared by dense SLAM, scan registration and evaluation: rigid transforms and
//! SE(3) ([`se3`]), pinhole intrinsics ([`camera`]), the SVD rotation step of rigid
//! alignment (`rigid`) and the closed-form alignment of point pairs ([`align`]). Double precision, host only; the per-pixel f32 maths the kernels
//! share lives in `cpu/mod.rs` and `shaders/common.wgsl`.

pub mod align;
pub mod camera;
pub mod rigid;
pub mod se3;
