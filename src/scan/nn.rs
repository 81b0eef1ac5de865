//! Nearest neighbours in a fixed target cloud for point-to-point ICP: the
//! [`NearestNeighbours`] interface that the ICP loop (`icp.rs`) queries, and its CPU
//! implementation over a KD-tree. The GPU implementations live in `gpu.rs`.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use crate::geometry::align::CrossCovariance;
use crate::{Error, Result};

/// Nearest-neighbour search in a fixed target cloud.
pub trait NearestNeighbours: Sync {
    /// The target cloud (metres, target frame); indices returned by `nearest` point here.
    fn points(&self) -> &[[f32; 3]];
    /// For each query (target frame, metres): `(index of the nearest target point,
    /// squared distance in m^2)`, written into `out` (same length as `queries`).
    fn nearest(&self, queries: &[[f32; 3]], out: &mut [(u32, f32)]) -> Result<()>;

    /// Optionally the whole correspondence step at once: the [`CrossCovariance`] of the
    /// inlier pairs (nearest neighbour within `radius_sq`, m^2) of `queries` (target frame,
    /// metres). `None` (the default) makes ICP call [`NearestNeighbours::nearest`] and
    /// reduce on the CPU in f64; the GPU target reduces on the device instead.
    fn reduce_pairs(
        &self,
        _queries: &[[f32; 3]],
        _radius_sq: f64,
    ) -> Result<Option<CrossCovariance>> {
        Ok(None)
    }
}

/// CPU nearest neighbours through a kiddo (5.x) immutable KD-tree. The immutable tree is
/// used because the mutable one panics when more than a bucket of points share one
/// coordinate (which quantised depth images and flat LiDAR scenes produce). kiddo 5 stays:
/// its `ImmutableKdTree::new_from_slice` + `nearest_one::<SquaredEuclidean>` is all ICP
/// needs, and 6.x would only change the API.
pub struct KdTreeTarget<'a> {
    tree: ImmutableKdTree<f32, 3>,
    points: &'a [[f32; 3]],
}

impl<'a> KdTreeTarget<'a> {
    /// Builds the tree over `target` (metres). Errors on an empty target.
    pub fn new(target: &'a [[f32; 3]]) -> Result<KdTreeTarget<'a>> {
        if target.is_empty() {
            return Err(Error::Argument("target cloud is empty".into()));
        }
        // The tree's search panics on NaN distances.
        if let Some(i) = target.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(Error::Argument(format!(
                "target point {i} is not finite ({:?})",
                target[i]
            )));
        }
        Ok(KdTreeTarget {
            tree: ImmutableKdTree::new_from_slice(target),
            points: target,
        })
    }
}

/// Queries per rayon task: below this the threading overhead exceeds the work.
const QUERIES_PER_TASK: usize = 256;

impl NearestNeighbours for KdTreeTarget<'_> {
    fn points(&self) -> &[[f32; 3]] {
        self.points
    }
    fn nearest(&self, queries: &[[f32; 3]], out: &mut [(u32, f32)]) -> Result<()> {
        if let Some(i) = queries
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(Error::Argument(format!(
                "query point {i} is not finite ({:?})",
                queries[i]
            )));
        }
        queries
            .par_iter()
            .zip(out.par_iter_mut())
            .with_min_len(QUERIES_PER_TASK)
            .for_each(|(q, o)| {
                let nn = self.tree.nearest_one::<SquaredEuclidean>(q);
                *o = (nn.item as u32, nn.distance);
            });
        Ok(())
    }
}
