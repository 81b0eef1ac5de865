//! wgslam: dense RGB-D SLAM with point-based fusion, and point-to-point ICP, on wgpu.
