//! Scan registration: point-cloud readers, point-to-point ICP and scan-to-scan odometry.
//!
//! Pose convention everywhere in this module: a registration result `t_source_to_target`
//! maps SOURCE coordinates into TARGET coordinates (metres). Trajectories are
//! `t_scan_to_world`. This is not the dense RGB-D tracker (point-to-plane, projective).

pub(crate) mod bench;
// The GPU nearest-neighbour search shares wgpu objects with rayon's threads (`Send +
// Sync`), which the browser's WebGPU objects are not; scans are a native tool's job.
#[cfg(not(target_arch = "wasm32"))]
pub(crate) mod bench_scan;
pub(crate) mod cloud;
#[cfg(not(target_arch = "wasm32"))]
pub mod gpu;
pub(crate) mod icp;
pub(crate) mod kernel_target;
pub(crate) mod nn;
pub mod odometry;
pub mod read;
pub mod write;

/// The one depth-PNG decoder (16-bit single channel), shared with the RGB-D loader.
pub use crate::dataset::frame::load_depth as load_depth_png;
pub use crate::geometry::align::{best_rigid_transform, CrossCovariance};
pub use cloud::{cloud_from_depth, crop_z, CloudStats, PointCloud};
pub use icp::{register, register_with, IcpParams, IcpResult, IcpStatus, IterationStats, Samples};
pub use kernel_target::{NnMethod, TwinTarget};
pub use nn::{KdTreeTarget, NearestNeighbours};
pub use read::{read_cloud, read_kitti_bin, read_matrix4, read_pcd, read_ply_xyz, read_xyz_text};
