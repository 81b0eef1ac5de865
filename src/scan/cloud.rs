//! Point clouds for scan registration: xyz points (metres, f32) plus reading statistics,
//! and back-projection of a depth image into a cloud.
//!
//! This is not a surfel map: no normals, colours or weights (see `crate::layout::map` for those).

use crate::geometry::camera::Intrinsics;

/// What a reader saw while building a [`PointCloud`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct CloudStats {
    /// Point records in the file (finite or not).
    pub records: usize,
    /// Records dropped because a coordinate was NaN or infinite.
    pub dropped_non_finite: usize,
}

/// An unordered set of 3D points in the sensor frame of the file (metres).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    /// Finite points, `[x, y, z]` in metres, in file order.
    pub points: Vec<[f32; 3]>,
    /// Counts seen while reading (records, dropped non-finite records).
    pub stats: CloudStats,
}

impl PointCloud {
    /// Builds a cloud from raw records, dropping (and counting) non-finite ones.
    pub fn from_records(records: impl IntoIterator<Item = [f32; 3]>) -> PointCloud {
        let mut cloud = PointCloud::default();
        for p in records {
            cloud.push_record(p);
        }
        cloud
    }

    /// Adds one record: kept when all three coordinates are finite, else counted as dropped.
    pub fn push_record(&mut self, p: [f32; 3]) {
        self.stats.records += 1;
        if p.iter().all(|c| c.is_finite()) {
            self.points.push(p);
        } else {
            self.stats.dropped_non_finite += 1;
        }
    }

    /// Number of (finite) points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the cloud holds no finite point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Keeps the points whose `z` (sensor frame, metres) lies in `[min_z, max_z]`: a crop
/// that removes e.g. the ground of a LiDAR scan (whose rings move with the sensor and pull
/// point-to-point ICP towards zero motion). Either bound may be infinite.
pub fn crop_z(points: &[[f32; 3]], min_z: f32, max_z: f32) -> Vec<[f32; 3]> {
    points
        .iter()
        .copied()
        .filter(|p| p[2] >= min_z && p[2] <= max_z)
        .collect()
}

/// Back-projects a depth image into camera-frame points (metres).
///
/// `depth` is row-major, `intrinsics.width * intrinsics.height` raw values; a value `d`
/// means `d / depth_scale` metres (5000 for TUM / ICL-NUIM) and 0 means invalid. Only every
/// `stride`-th pixel in each direction is used (`stride >= 1`; 0 is treated as 1). Pixel
/// `(u, v)` goes through [`crate::cpu::back_project`] as given, so a negative `fy` (ICL-NUIM)
/// keeps the dataset's own camera frame.
///
/// A `depth` slice shorter than the image is a broken contract and panics.
pub fn cloud_from_depth(
    depth: &[u16],
    intrinsics: Intrinsics,
    depth_scale: f32,
    stride: usize,
) -> Vec<[f32; 3]> {
    let (w, h) = (intrinsics.width as usize, intrinsics.height as usize);
    assert!(
        depth.len() >= w * h,
        "cloud_from_depth: depth has {} values, intrinsics need {}x{}",
        depth.len(),
        w,
        h
    );
    let stride = stride.max(1);
    let mut points = Vec::with_capacity((w / stride + 1) * (h / stride + 1));
    for v in (0..h).step_by(stride) {
        for u in (0..w).step_by(stride) {
            let d = depth[v * w + u];
            if d == 0 {
                continue;
            }
            let z = d as f32 / depth_scale;
            // The one back-projection of the crate, `depth_to_vertex`'s, so scan clouds
            // and vertex maps agree to the bit.
            let p = crate::cpu::back_project(intrinsics.floats(), [u as u32, v as u32], z);
            points.push(p.to_array());
        }
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_records_are_dropped_and_counted() {
        let c = PointCloud::from_records([
            [1.0, 2.0, 3.0],
            [f32::NAN, 0.0, 0.0],
            [0.0, f32::INFINITY, 0.0],
            [4.0, 5.0, 6.0],
        ]);
        assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(
            c.stats,
            CloudStats {
                records: 4,
                dropped_non_finite: 2
            }
        );
    }

    #[test]
    fn depth_back_projection_honours_negative_fy_and_stride() {
        let k = Intrinsics {
            width: 4,
            height: 2,
            fx: 2.0,
            fy: -2.0,
            cx: 1.0,
            cy: 0.0,
        };
        // 0 is invalid; 5000 is 1 m at TUM scale.
        let depth = [5000, 0, 10000, 5000, 0, 0, 0, 5000];
        let all = cloud_from_depth(&depth, k, 5000.0, 1);
        assert_eq!(all.len(), 4);
        assert_eq!(all[0], [-0.5, 0.0, 1.0]);
        assert_eq!(all[1], [1.0, 0.0, 2.0]);
        // Row 1 is below the principal point: with fy < 0 its y is negative.
        assert_eq!(all[3], [1.0, -0.5, 1.0]);
        let strided = cloud_from_depth(&depth, k, 5000.0, 2);
        assert_eq!(strided, vec![[-0.5, 0.0, 1.0], [1.0, 0.0, 2.0]]);
    }
}
