//! The layout contract between Rust and WGSL: every params struct a kernel reads (bound as a read-only storage buffer, see `gpu::kernel::BindingKind::Params`).
//!
//! Each struct is `#[repr(C)]` + `bytemuck::Pod` and mirrors the WGSL struct of the same
//! name in `shaders/common.wgsl` (which points back here). No `vec3`/`mat3`: only scalars,
//! 4-vectors, 4x4 matrices and the nested [`Camera`] (the intrinsics and image size, the
//! one definition of the camera block), padded explicitly to 16 bytes. `tests/it/layout.rs`
//! checks sizes and offsets against naga's layout of the WGSL side, the nested struct's
//! members included.
//!
//! Per-pixel and per-surfel arrays are plain arrays of texels, not structs: vertex maps,
//! the `normal_depth` map (normal xyz, depth in w) and colour maps are `[f32; 4]`
//! (`vec4<f32>`, rgba32float textures on the GPU); the surfel map is the three packed arrays
//! of `map::SurfelMap`; raw depth is `u16` (an r16uint texture); raw colour is RGBA8 packed
//! into one `u32` (`r | g << 8 | b << 16 | 255 << 24`, an rgba8uint texture).
//!
//! Submodules: [`map`] (the surfel map on the host, in the map arrays' packing), [`render`]
//! (the render kernels' struct) and [`scan`] (the scan kernels').

use bytemuck::{Pod, Zeroable};
use glam::DMat4;

use crate::geometry::camera::Intrinsics;

pub mod map;
pub mod render;
pub mod scan;

/// A 4x4 f32 matrix, column-major (`mat4x4<f32>` in WGSL).
pub type GpuMat4 = [[f32; 4]; 4];

/// Converts an f64 pose to the column-major f32 matrix the kernels use.
pub fn gpu_mat4(t: &DMat4) -> GpuMat4 {
    let c = t.to_cols_array_2d();
    c.map(|col| col.map(|x| x as f32))
}

/// A pinhole camera as the kernels read it (mirrors `Camera` in common.wgsl): the
/// intrinsics and image size of [`Intrinsics`], nested as `camera` in every params struct
/// whose kernel projects or back-projects. Made from `Intrinsics` only by [`Camera::new`].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Camera {
    /// Focal lengths and principal point, pixels (`fy` may be negative).
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
    /// Padding to a multiple of 16 bytes.
    pub _pad0: u32,
    pub _pad1: u32,
}

impl Camera {
    /// The camera of intrinsics `k`.
    pub fn new(k: &Intrinsics) -> Camera {
        let [fx, fy, cx, cy] = k.floats();
        Camera {
            fx,
            fy,
            cx,
            cy,
            width: k.width,
            height: k.height,
            _pad0: 0,
            _pad1: 0,
        }
    }
}

/// Parameters of `depth_to_vertex` (mirrors `PreprocessParams` in common.wgsl).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct PreprocessParams {
    /// Intrinsics and size of the output (downsampled) maps, pixels.
    pub camera: Camera,
    /// Raw frame size in pixels.
    pub raw_width: u32,
    pub raw_height: u32,
    /// Output pixel `(u, v)` reads raw pixel `(stride u, stride v)`.
    pub stride: u32,
    /// Raw depth units per metre (5000 for TUM and ICL-NUIM).
    pub depth_scale: f32,
    /// Depths outside `[min_depth_m, max_depth_m]` are invalid.
    pub min_depth_m: f32,
    pub max_depth_m: f32,
    pub _pad0: u32,
    pub _pad1: u32,
}

/// Parameters of `vertex_to_normal` (mirrors `NormalParams` in common.wgsl).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct NormalParams {
    pub width: u32,
    pub height: u32,
    /// A neighbour whose depth differs by more than this (metres) makes the normal invalid.
    pub max_depth_jump_m: f32,
    pub _pad: u32,
}

/// Parameters of `pyramid_depth` and `pyramid_model` (mirrors `PyramidParams` in
/// common.wgsl): one coarse level of the ICP pyramid, made from the next finer level.
/// Coarse pixel `(u, v)` samples finer pixel `(2u, 2v)`, so the coarse intrinsics are the
/// finer ones halved (`Intrinsics::downsampled(2)`) and the coarse size is the finer size
/// halved, rounded up. `pyramid_model` reads only the camera's `width` and `height`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct PyramidParams {
    /// Intrinsics and size of the coarse level, pixels: its vertices are re-built with them.
    pub camera: Camera,
    /// Size of the finer level read, pixels.
    pub fine_width: u32,
    pub fine_height: u32,
    /// Half-width of the averaging window around the sampled finer pixel, finer pixels:
    /// (2 radius_px + 1)² neighbours, clipped at the border.
    pub radius_px: u32,
    /// Neighbours whose depth differs from the sampled pixel's depth `z` by more than
    /// `max_depth_diff_m + max_depth_diff_per_m2 * z²` (metres) are left out of the mean.
    pub max_depth_diff_m: f32,
    /// The gate's growth with the square of the depth, 1/m.
    pub max_depth_diff_per_m2: f32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

impl PyramidParams {
    /// The level below `fine` (its intrinsics halved, `Intrinsics::downsampled(2)`), with
    /// the window half-width and the depth gate (metres, and its growth with depth², 1/m).
    pub fn halving(
        fine: &Intrinsics,
        radius_px: u32,
        max_depth_diff_m: f32,
        max_depth_diff_per_m2: f32,
    ) -> PyramidParams {
        PyramidParams {
            camera: Camera::new(&fine.downsampled(2)),
            fine_width: fine.width,
            fine_height: fine.height,
            radius_px,
            max_depth_diff_m,
            max_depth_diff_per_m2,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        }
    }
}

/// Parameters of `intensity_pyramid` at one pyramid level (mirrors `IntensityParams` in
/// common.wgsl): level 0 reads the frame's colour map (RGB 0..255), a coarser level the
/// finer level's intensity patches (`x`: intensity 0..1); coarse pixel `(u, v)` is centred
/// on finer pixel `(2u, 2v)`, the convention of `PyramidParams`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct IntensityParams {
    /// This level's size in pixels.
    pub width: u32,
    pub height: u32,
    /// Size of the map read (at level 0 the colour map, of the same size), pixels.
    pub fine_width: u32,
    pub fine_height: u32,
    /// The pyramid level: 0 converts colour to intensity, above 0 downsamples.
    pub level: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

impl IntensityParams {
    /// The parameters of every level of a pyramid whose level 0 is `width` x `height` and
    /// whose coarser levels are `coarser` (sizes in pixels), level 0 first.
    pub fn levels(width: u32, height: u32, coarser: &[[u32; 2]]) -> Vec<IntensityParams> {
        let mut out = vec![IntensityParams {
            width,
            height,
            fine_width: width,
            fine_height: height,
            level: 0,
            ..Zeroable::zeroed()
        }];
        for (l, &[w, h]) in coarser.iter().enumerate() {
            let fine = out[l];
            out.push(IntensityParams {
                width: w,
                height: h,
                fine_width: fine.width,
                fine_height: fine.height,
                level: l as u32 + 1,
                ..Zeroable::zeroed()
            });
        }
        out
    }
}

/// Parameters of `bilateral_filter` (mirrors `BilateralParams` in common.wgsl).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct BilateralParams {
    /// Intrinsics and size of the (downsampled) maps, pixels: the filtered vertex is
    /// re-built with them.
    pub camera: Camera,
    /// Half-width of the window: (2 radius_px + 1)² neighbours, clipped at the border.
    pub radius_px: u32,
    /// Spatial Gaussian's standard deviation, pixels of the map.
    pub sigma_space_px: f32,
    /// Range Gaussian's standard deviation on the depth difference, metres:
    /// `sigma_depth_m + sigma_depth_per_m2 * z²` at the pixel's depth `z`.
    pub sigma_depth_m: f32,
    /// The range sigma's growth with the square of the depth, 1/m.
    pub sigma_depth_per_m2: f32,
    /// 1: level 0's points (`vertex_to_normal`'s `point_map`) are the filtered map; 0:
    /// the unfiltered one. Read by the plan (`plan::preprocess`), not by the kernel.
    pub filter_points: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// Parameters of `project_model` and `predict_model` (mirrors `ProjectParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct ProjectParams {
    /// World to camera of the view the map is rendered from.
    pub t_world_to_cam: GpuMat4,
    /// Intrinsics and size of the rendered view, pixels.
    pub camera: Camera,
    /// Number of valid surfels (entries past it are ignored).
    pub surfel_count: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// Parameters of `icp_reduce` (mirrors `IcpParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct IcpParams {
    /// Current estimate of world to camera for the new frame.
    pub t_world_to_cam: GpuMat4,
    /// Intrinsics and size of the pyramid level's maps, pixels.
    pub camera: Camera,
    /// Filter 2: correspondences farther apart than this (metres) are rejected.
    pub dist_m: f32,
    /// Filter 2, angle: rejected unless the cosine between the model normal (moved into
    /// the camera) and the frame normal exceeds this; below -1 the gate is off.
    pub cos_normal_threshold: f32,
    /// Huber threshold on the point-to-plane residual, metres: rows with `|b|` above it
    /// get weight `huber_m / |b|`; 0 turns the robust weight off.
    pub huber_m: f32,
    /// 1: weight each row by the depth noise model ([`crate::cpu::icp_reduce::noise_weight`]);
    /// 0: unweighted.
    pub noise_weighting: u32,
    /// `photo_reduce` (the photometric term): a model point is used only where the frame's
    /// depth at the pixel it projects to is within this of the point's depth, metres (an
    /// occluded or disoccluded point is skipped).
    pub photo_depth_gate_m: f32,
    /// `photo_reduce`: Huber threshold on the intensity residual, intensity units (0..1);
    /// 0 turns the weight off.
    pub photo_huber: f32,
    /// `photo_reduce`: pixels whose frame intensity gradient is below this (intensity units
    /// per pixel) add nothing (flat texture constrains no motion).
    pub photo_gradient_min: f32,
    /// `photo_reduce` at a pyramid level walks that level's pixels `(u, v)`; its source is
    /// the level-0 prediction's pixel `(step u, step v)` (`2^level`: the very points
    /// `pyramid_model` subsamples for the level), whose predicted intensity is read there.
    pub photo_source_step: u32,
    /// `photo_reduce`: the level-0 prediction's width in pixels (the row length of
    /// `pred_intensity`).
    pub photo_source_width: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// Parameters of `fuse_merge` and `fuse_add` (mirrors `FuseParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct FuseParams {
    /// Tracked world to camera of the frame being fused.
    pub t_world_to_cam: GpuMat4,
    /// Its inverse, camera to world.
    pub t_cam_to_world: GpuMat4,
    /// Intrinsics and size of the frame's maps, pixels.
    pub camera: Camera,
    /// Surfels in the map before this frame.
    pub surfel_count: u32,
    /// Sequence position of the frame, stored in `last_frame`.
    pub frame_id: u32,
    /// Filter 2 of fusion: position distance in metres.
    pub dist_m: f32,
    /// Filter 2 of fusion: cosine of the maximum normal angle.
    pub cos_normal_threshold: f32,
    /// Allocated surfel slots; `fuse_add` never writes at or past it.
    pub capacity: u32,
    /// How pixels find their surfel: [`ASSOCIATION_PROJECTIVE`] (the assignment: every
    /// surfel merges with the pixel it projects to, gates on distance and angle) or
    /// [`ASSOCIATION_BEST_CANDIDATE`] (`fuse_select` first picks one surfel per pixel
    /// within depth, angle and radius gates; a surfel merges only with the pixel that chose
    /// it).
    pub association: u32,
    /// Standard deviation of the confidence of a pixel's measurement over its distance from
    /// the image centre (normalised: 1 at the corners); 0 gives every measurement weight 1
    /// (the assignment's counts). See `pixel_confidence` in common.wgsl.
    pub confidence_sigma: f32,
    /// Best-candidate association's pruning of duplicate surfels (`fuse_prune`): a surfel
    /// that was not refreshed retires when the surfel its pixel merged into lies within
    /// this many times the larger of their radii; 0 turns pruning off.
    pub prune_scale: f32,
    /// Best-candidate fusion's depth gate for a confident surfel, metres (at most
    /// `dist_m`; equal to it for one gate for every surfel): see
    /// `cpu::fuse_depth_gate`.
    pub dist_confident_m: f32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// Threads of each block's workgroup of the scan (`SCAN_THREADS` in prefix_sum_reduce.wgsl
/// and prefix_sum.wgsl).
pub const SCAN_THREADS: u32 = 64;
/// Flags per thread of the scan (`SCAN_ITEMS`).
pub const SCAN_ITEMS: u32 = 32;
/// Flags per block and workgroup of the scan (`SCAN_BLOCK`), `SCAN_THREADS * SCAN_ITEMS`.
pub const SCAN_BLOCK: u32 = SCAN_THREADS * SCAN_ITEMS;

/// Blocks (workgroups of `prefix_sum_reduce` and `prefix_sum`, entries of `block_sums`)
/// of a scan over `n` flags.
pub fn scan_blocks(n: usize) -> usize {
    n.div_ceil(SCAN_BLOCK as usize)
}

/// The scan's parameters for a scan of `n` flags (fusion's new-surfel flags, one per entry
/// of append order; compaction's keep flags, one per surfel): only `surfel_count` (= n) is
/// read.
pub fn scan_params(n: usize) -> CompactParams {
    CompactParams {
        surfel_count: n as u32,
        frame_id: 0,
        stable_weight: 0.0,
        max_age_frames: 0,
    }
}

/// `FuseParams::association`: each surfel merges with the pixel it projects to.
pub const ASSOCIATION_PROJECTIVE: u32 = 0;
/// `FuseParams::association`: each pixel picks its best surfel (`fuse_select`).
pub const ASSOCIATION_BEST_CANDIDATE: u32 = 1;

/// Parameters of `compact_flags`, `prefix_sum` and `compact_scatter`, the removal of
/// unstable surfels and the stream compaction of the map (mirrors `CompactParams`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct CompactParams {
    /// Surfels in the map before compaction (filled in by the backend).
    pub surfel_count: u32,
    /// Sequence position of the frame just fused (the surfels' `last_frame` is compared
    /// with it).
    pub frame_id: u32,
    /// A surfel whose weight (observations) is below this ...
    pub stable_weight: f32,
    /// ... and whose `last_frame` is more than this many frames before `frame_id` is
    /// removed.
    pub max_age_frames: u32,
}

/// Parameters of `deform_surfels`, the map's deformation after a loop closure (mirrors
/// `DeformParams` in common.wgsl).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct DeformParams {
    /// Surfels in the map (filled in by the backend).
    pub surfel_count: u32,
    /// Entries of the node table (at least 1).
    pub node_count: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

/// One node of `deform_surfels`' table (mirrors `DeformNode` in common.wgsl): a frame of
/// the pose graph and the correction its optimisation gave, a world-frame rigid transform
/// (new pose times old pose inverse, camera to world) as the top three rows of a 4x4
/// matrix. The table is sorted by `frame`; a surfel blends the corrections of the two
/// nodes whose frames bracket its `last_frame` (see `cpu::deform_surfels`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct DeformNode {
    /// Sequence position of the node's frame.
    pub frame: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
    /// Row `r` of the correction: `[R_r0, R_r1, R_r2, t_r]`, metres.
    pub rows: [[f32; 4]; 3],
}

/// Parameters of `fern_encode` (mirrors `FernParams` in common.wgsl): the frame's level-0
/// size and the cell each fern averages over (the image cut into a grid of
/// [`FERN_GRID`] cells, rounded up, as ElasticFusion's ferns read an image downsampled
/// to 80 x 60).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct FernParams {
    /// Level-0 map size, pixels.
    pub width: u32,
    pub height: u32,
    /// One cell's size, pixels.
    pub cell_width: u32,
    pub cell_height: u32,
    /// Ferns to encode (entries of `ferns` and `codes`).
    pub fern_count: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// One randomised fern (mirrors `Fern` in common.wgsl): a cell of the grid and four
/// thresholds; its code is four bits, mean red, green and blue (0..255) and mean depth
/// (metres) of the cell's valid pixels each above its threshold.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Fern {
    /// Cell column and row in the [`FERN_GRID`].
    pub cell_u: u32,
    pub cell_v: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    /// Red, green, blue (0..255) and depth (metres) thresholds.
    pub threshold: [f32; 4],
}

/// The fern grid, cells across and down (ElasticFusion's 80 x 60 small image).
pub const FERN_GRID: [u32; 2] = [80, 60];
/// The code of a fern whose cell has no valid depth (mirrors `FERN_NO_DEPTH` in
/// common.wgsl): never equal to a real code (0..15).
pub const FERN_NO_DEPTH: u32 = 16;

/// Parameters of `keypoint_detect` and `keypoint_describe` (mirrors `KeypointParams` in
/// common.wgsl): corners of the level-0 colour for feature-based relocalisation.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct KeypointParams {
    /// Level-0 map size, pixels.
    pub width: u32,
    pub height: u32,
    /// `keypoint_detect`: a pixel is a corner when its Harris response (grey levels 0..255,
    /// 3x3 window of central differences) is above this and above its 8 neighbours'.
    pub threshold: f32,
    /// `keypoint_detect`: room in the candidate list (more are counted, not stored).
    pub capacity: u32,
    /// `keypoint_describe`: keypoints to describe, and binary tests per descriptor.
    pub count: u32,
    pub tests: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

/// A detected corner (mirrors `Keypoint` in common.wgsl): its pixel and Harris response.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Keypoint {
    pub u: u32,
    pub v: u32,
    pub score: f32,
    pub _pad: u32,
}

/// Binary tests per keypoint descriptor (BRIEF's 256), in 32-bit words.
pub const DESCRIPTOR_WORDS: usize = 8;

/// Floats in one reduced ICP system: 21 (upper triangle of AᵀA, row-major) + 6 (Aᵀb)
/// + inlier count + sum of squared residuals (mirrors `ICP_SYSTEM_LEN` in common.wgsl).
pub const ICP_SYSTEM_LEN: usize = 29;
/// Index of the first of the 6 Aᵀb entries in the system (after the 21 of AᵀA).
pub const ICP_ATB_OFFSET: usize = 21;
/// Index of the inlier count in the system.
pub const ICP_COUNT_INDEX: usize = 27;
/// Index of the sum of squared residuals (m²) in the system.
pub const ICP_RESIDUAL_INDEX: usize = 28;

/// Surfels per culling block (mirrors `BLOCK_SURFELS` in common.wgsl): the map is cut into
/// runs of this many consecutive slots, each with a world-frame bounding box
/// (`block_bounds`), and the kernels that walk the map (`project_model`, `fuse_select`,
/// `fuse_merge`) skip a block whose box the camera cannot see. 1024 slots: a box per 16 KiB
/// of positions, small enough that the surfels a frame appends (in append order, see
/// [`APPEND_TILE_PX`]) make compact boxes, large enough that the boxes cost nothing to test.
pub const BLOCK_SURFELS: u32 = 1024;

/// Side, pixels, of the square image tiles that order a frame's new surfels (mirrors
/// `APPEND_TILE_PX` in common.wgsl). `fuse_add` appends in *append order*: tiles in Morton
/// (Z) order over the tile grid, pixels row-major inside a tile (`cpu::append_index`). So a
/// block of consecutive new surfels comes from one compact patch of the image, and its box
/// is small in every direction; in pixel order a block was a strip of rows across the whole
/// image, which no turn of the camera could cull. 16: a tile's 256 pixels are a quarter of
/// a block, so a fully new frame fills each block from a 32 x 32 pixel square.
pub const APPEND_TILE_PX: u32 = 16;

/// Length of the per-pixel arrays indexed in append order (`fuse_flags`' flags and their
/// prefix sum) for a `width` x `height` image: one past the largest
/// `cpu::append_index`. The Morton order leaves holes for tiles outside the image (about
/// 0.7x more slots than pixels at 640 x 480); they stay zero, so the prefix sum skips them.
pub fn append_slots(width: u32, height: u32) -> usize {
    let tiles = |n: u32| n.div_ceil(APPEND_TILE_PX);
    let last_tile = (0..tiles(width))
        .flat_map(|tx| (0..tiles(height)).map(move |ty| morton_2d(tx, ty)))
        .max()
        .unwrap_or(0);
    (last_tile as usize + 1) * (APPEND_TILE_PX * APPEND_TILE_PX) as usize
}

/// Interleaves the bits of `x` (even bits) and `y` (odd bits), each below 2^16: the Morton
/// (Z-order) code of a tile. Mirrors `morton_2d` in common.wgsl.
#[inline]
pub fn morton_2d(x: u32, y: u32) -> u32 {
    spread_bits(x) | (spread_bits(y) << 1)
}

/// The low 16 bits of `v` moved to the even bit positions (bit k to bit 2k). Mirrors
/// `spread_bits` in common.wgsl.
#[inline]
fn spread_bits(v: u32) -> u32 {
    let mut x = v & 0x0000_ffff;
    x = (x | (x << 8)) & 0x00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333;
    (x | (x << 1)) & 0x5555_5555
}

/// u32s per block in `block_bounds`: the box's min xyz, a pad, its max xyz, a pad, each
/// coordinate as [`ordered_from_f32`] so that unsigned `atomicMin`/`atomicMax` order them
/// as floats.
pub const BLOCK_BOUNDS_U32S: usize = 8;

/// One chunk of the GPU surfel map (mirrors `MapChunk` in common.wgsl): the map is a list of
/// chunks, each three storage buffers of `slots` surfels (see `gpu::map_buffers`), and a
/// kernel that walks the map is dispatched once per chunk with the chunk's `MapChunk`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Pod, Zeroable)]
pub struct MapChunk {
    /// Map-wide index of the chunk's slot 0 (a multiple of [`BLOCK_SURFELS`]).
    pub base: u32,
    /// Slots in the chunk (a multiple of [`BLOCK_SURFELS`]).
    pub slots: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

impl MapChunk {
    /// The whole map as one chunk of `slots` slots (the CPU backend's map, and tests that
    /// call a twin on a whole map).
    pub fn whole(slots: usize) -> MapChunk {
        MapChunk {
            base: 0,
            slots: slots as u32,
            _pad0: 0,
            _pad1: 0,
        }
    }
}

/// Parameters of `block_bounds` (mirrors `BoundsParams` in common.wgsl): recompute the
/// boxes of blocks `block_from..` up to the block of the last surfel.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Pod, Zeroable)]
pub struct BoundsParams {
    /// Surfels in the map.
    pub surfel_count: u32,
    /// First block whose box is recomputed.
    pub block_from: u32,
    pub _pad0: u32,
    pub _pad1: u32,
}

impl BoundsParams {
    /// Recompute the boxes of a map of `surfel_count` surfels from the block holding surfel
    /// `dirty_from` on (what fusion appended to; 0 after a compaction or an upload).
    pub fn stale(surfel_count: usize, dirty_from: usize) -> BoundsParams {
        BoundsParams {
            surfel_count: surfel_count as u32,
            block_from: (dirty_from / BLOCK_SURFELS as usize) as u32,
            _pad0: 0,
            _pad1: 0,
        }
    }
}

/// An f32 as a u32 whose unsigned order is the float order (negative floats: all bits
/// flipped; others: the sign bit set), so boxes can grow with integer atomics. Mirrors
/// `ordered_from_f32` in common.wgsl.
pub fn ordered_from_f32(x: f32) -> u32 {
    let bits = x.to_bits();
    if bits & 0x8000_0000 != 0 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

/// The inverse of [`ordered_from_f32`]. Mirrors `f32_from_ordered` in common.wgsl.
pub fn f32_from_ordered(u: u32) -> f32 {
    if u & 0x8000_0000 != 0 {
        f32::from_bits(u & 0x7fff_ffff)
    } else {
        f32::from_bits(!u)
    }
}

/// Packs RGB8 into the `u32` layout the GPU reads (`r | g << 8 | b << 16 | 255 << 24`).
pub fn pack_rgba8(rgb: [u8; 3]) -> u32 {
    rgb[0] as u32 | (rgb[1] as u32) << 8 | (rgb[2] as u32) << 16 | 255 << 24
}
