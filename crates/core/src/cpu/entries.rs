//! The CPU mirrors of the shared entry points (`shaders/pixel_grid.wgsl`,
//! `shaders/visible_surfels.wgsl`, `shaders/system_grid.wgsl`; see `gpu::shaders::ENTRIES`): the loop a kernel of one
//! shape runs around its per-item function. Every item is visited once; [`pixel_grid`]'s
//! items run in parallel ([`super::invocations`]: each writes only its own outputs),
//! [`system_grid`]'s rows are made in parallel and summed row by row, and
//! [`visible_surfels`] visits block by block, then surfel by surfel, in order (its key
//! and merge twins are order-dependent or write through `&mut`; see their notes).

use super::{block_visible, chunk_blocks, decode_corner};
use crate::layout::{FuseParams, GpuMat4, MapChunk, ProjectParams, BLOCK_SURFELS};
use crate::layout::{ICP_ATB_OFFSET, ICP_COUNT_INDEX, ICP_RESIDUAL_INDEX, ICP_SYSTEM_LEN};

/// Mirrors `pixel_grid.wgsl`'s `main`: `per_pixel(texel)` for every texel `(u, v)` of a
/// `width` x `height` image, in parallel ([`super::invocations::par_for_each_invocation`]:
/// `per_pixel` writes through [`super::invocations::Storage`], only its own texels).
#[inline]
pub fn pixel_grid(width: u32, height: u32, per_pixel: impl Fn([u32; 2]) + Sync + Send) {
    let w = width as usize;
    super::invocations::par_for_each_invocation(w * height as usize, |i| {
        per_pixel([(i % w) as u32, (i / w) as u32]);
    });
}

/// What [`visible_surfels`] reads of a kernel's params (the fields `visible_surfels.wgsl`
/// names): the camera a map chunk is culled against.
pub trait SurfelView {
    /// `(t_world_to_cam, (fx, fy, cx, cy), (width, height), surfel_count)`.
    fn view(&self) -> (&GpuMat4, [f32; 4], [u32; 2], u32);
}

/// The two params structs that carry a culling view (`ProjectParams`, `FuseParams`), whose
/// fields of the same names (`t_world_to_cam`, `camera`, `surfel_count`) are those
/// [`SurfelView`] reads.
macro_rules! surfel_view {
    ($($params:ty),*) => {$(
        impl SurfelView for $params {
            fn view(&self) -> (&GpuMat4, [f32; 4], [u32; 2], u32) {
                let cam = super::camera_intrinsics(&self.camera);
                (&self.t_world_to_cam, cam, [self.camera.width, self.camera.height], self.surfel_count)
            }
        }
    )*};
}
surfel_view!(ProjectParams, FuseParams);

/// Mirrors `visible_surfels.wgsl`'s `main`: `per_surfel(i, slot)` for every surfel `i`
/// (map-wide index; `slot` = `i - chunk.base`, in the chunk's arrays) of the chunk's first
/// `surfel_count` whose block's world-frame box may be in view of `params`' camera
/// ([`SurfelView`]). The blocks run in parallel, as the shader's workgroups do
/// (`invocations::par_for_each_group`), so `per_surfel` writes as an invocation may.
#[inline]
pub fn visible_surfels(
    params: &(impl SurfelView + Sync),
    chunk: &MapChunk,
    block_boxes: &[[u32; 4]],
    per_surfel: impl Fn(u32, u32) + Sync + Send,
) {
    let (t_world_to_cam, cam, size, surfel_count) = params.view();
    let (blocks, span_end) = chunk_blocks(chunk, surfel_count);
    let block_surfels = BLOCK_SURFELS as usize;
    super::invocations::par_for_each_group(blocks as usize, block_surfels, |b| {
        let b = b as u32;
        let block = (chunk.base / BLOCK_SURFELS + b) as usize;
        let lo = decode_corner(block_boxes[2 * block]);
        let hi = decode_corner(block_boxes[2 * block + 1]);
        if !block_visible(t_world_to_cam, cam, size[0], size[1], lo, hi) {
            return;
        }
        let end = (chunk.base + (b + 1) * BLOCK_SURFELS).min(span_end);
        for i in chunk.base + b * BLOCK_SURFELS..end {
            per_surfel(i, i - chunk.base);
        }
    });
}

/// Mirrors `system_grid.wgsl`'s `main`: the 29-float normal-equation system summed over
/// the rows `system_row(texel)` gives for every texel of a `width` x `height` image, summed
/// row by row (`None`: the pixel adds nothing), in f64 (the GPU sums f32 partials per thread and
/// workgroup, the host in f64; see `arith::accumulate`).
#[inline]
pub fn system_grid(
    width: u32,
    height: u32,
    system_row: impl Fn([u32; 2]) -> Option<([f32; 6], f32)> + Sync + Send,
) -> [f64; ICP_SYSTEM_LEN] {
    let w = width as usize;
    // Fixed runs of rows in parallel, each summed in pixel order, then the runs' sums in
    // order: the same bits on any number of threads.
    super::invocations::par_sum_rows(
        w * height as usize,
        || [0.0f64; ICP_SYSTEM_LEN],
        |sys, i| {
            if let Some((a, b)) = system_row([(i % w) as u32, (i / w) as u32]) {
                super::arith::accumulate(sys, i as u32, |s| accumulate(s, &a, b));
            }
        },
        |sys, partial| sys.iter_mut().zip(partial).for_each(|(s, p)| *s += p),
    )
}

/// `partials` as the one partial system a CPU reduction writes (`icp_reduce`,
/// `photo_reduce`: the shader's one workgroup, its sums f64). Panics (an internal contract:
/// the CPU backend binds one system's entries) on another length.
pub fn one_partial(partials: &mut [f64]) -> &mut [f64; ICP_SYSTEM_LEN] {
    let given = partials.len();
    partials.try_into().unwrap_or_else(|_| {
        panic!("a CPU reduction writes one partial system ({ICP_SYSTEM_LEN} f64), given {given}")
    })
}

/// The row of a point `p` (camera frame) whose residual `b` moves along direction `d` (the
/// frame normal, or the intensity gradient through the projection) under the twist
/// `(alpha, beta, gamma, tx, ty, tz)`: `a = [(p x d), d]` and `b`, both scaled by
/// `s = sqrt(weight)`. Mirrors `scaled_row` in system_grid.wgsl.
#[inline]
pub fn scaled_row(p: glam::Vec3, d: glam::Vec3, b: f32, s: f32) -> ([f32; 6], f32) {
    let pxd = p.cross(d) * s;
    let ds = d * s;
    ([pxd.x, pxd.y, pxd.z, ds.x, ds.y, ds.z], b * s)
}

/// Adds one row to a 29-entry system: 21 of AᵀA (upper triangle, row-major), 6 of Aᵀb,
/// the count and the squared residual. Mirrors `accumulate` in system_grid.wgsl.
#[inline]
pub fn accumulate(sys: &mut [f64; ICP_SYSTEM_LEN], a: &[f32; 6], b: f32) {
    let mut k = 0;
    for r in 0..6 {
        for c in r..6 {
            sys[k] += a[r] as f64 * a[c] as f64;
            k += 1;
        }
    }
    for r in 0..6 {
        sys[ICP_ATB_OFFSET + r] += a[r] as f64 * b as f64;
    }
    sys[ICP_COUNT_INDEX] += 1.0;
    sys[ICP_RESIDUAL_INDEX] += b as f64 * b as f64;
}
