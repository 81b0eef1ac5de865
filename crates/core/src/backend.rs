//! The two backend traits. [`Backend`] is the pipeline's steps (`preprocess`, `predict`,
//! `icp_system`, `fuse`, `compact`), each one or a few kernels; [`Inspect`] copies maps in
//! and out of a backend, which only the tools (outputs, `compare`, `bench`) and the tests
//! need. Both are implemented by the CPU reference (`wgslam::slam::cpu_backend`) and the
//! GPU (`wgslam_gpu::backend`); [`SlamBackend`] is the two together, for `Box<dyn _>`.
//! Also the per-frame maps the traits exchange. Not the step order: see [`crate::plan`].

use crate::layout::map::SurfelMap;
use crate::layout::{
    BilateralParams, CompactParams, DeformNode, Fern, FernParams, FuseParams, IcpParams,
    IntensityParams, Keypoint, KeypointParams, NormalParams, PreprocessParams, ProjectParams,
    PyramidParams, DESCRIPTOR_WORDS, ICP_SYSTEM_LEN,
};
use crate::Result;

/// The per-frame maps a backend holds after `preprocess` (downloaded for comparison), in
/// the kernels' representation: `depth_to_vertex`'s two outputs, `bilateral_filter`'s and
/// `vertex_to_normal`'s.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameMaps {
    /// Camera-frame vertices, metres, `w = 1` valid / `0` invalid: `depth_to_vertex`'s
    /// output, unfiltered.
    pub vertex: Vec<[f32; 4]>,
    /// `bilateral_filter`'s output (same representation), which `normal_depth` was made
    /// from; empty when the last `preprocess` ran without the filter.
    pub filtered_vertex: Vec<[f32; 4]>,
    /// Camera-frame unit normals with the point's depth (metres, > 0) in `w`: the
    /// unfiltered vertex's, or the filtered one's with `BilateralParams::filter_points`;
    /// all zero where invalid (see `cpu::vertex_to_normal`).
    pub normal_depth: Vec<[f32; 4]>,
    /// RGB 0..255.
    pub color: Vec<[f32; 4]>,
    /// The ICP pyramid's coarser levels 1, 2, ... (empty with a one-level schedule).
    pub pyramid: Vec<FrameLevel>,
}

/// One coarser level of the frame's ICP pyramid (level `l >= 1`), in the representation
/// of level 0's maps, at that level's size.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameLevel {
    /// `pyramid_depth`'s output: camera-frame vertices, metres, `w = 1` / `0`.
    pub vertex: Vec<[f32; 4]>,
    /// `vertex_to_normal` of `vertex`: camera-frame normal, depth in w, zero where invalid.
    pub normal_depth: Vec<[f32; 4]>,
}

/// [`Backend::rgbd_system`]'s two 29-entry systems: the geometric, then the photometric.
pub type RgbdSystems = [[f64; ICP_SYSTEM_LEN]; 2];

/// What [`Backend::preprocess`] runs on a frame: its kernels' parameters, made once a frame
/// by `Slam::preprocess_steps` (`crate::slam::step_params`).
#[derive(Debug, Clone, PartialEq)]
pub struct PreprocessSteps {
    /// `depth_to_vertex`'s.
    pub params: PreprocessParams,
    /// `bilateral_filter`'s; `None`: no filter.
    pub bilateral: Option<BilateralParams>,
    /// `vertex_to_normal`'s at level 0.
    pub normal: NormalParams,
    /// The coarser levels 1, 2, ... (empty: level 0 only).
    pub pyramid: Vec<PyramidLevel>,
}

/// The parameters that make one coarser level `l >= 1` of the frame's and the model's
/// pyramids from level `l - 1`: `pyramid_depth`'s and `pyramid_model`'s, and
/// `vertex_to_normal`'s at the level's size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PyramidLevel {
    pub down: PyramidParams,
    pub normal: NormalParams,
}

impl PyramidLevel {
    /// `intensity_pyramid`'s parameters at every level of a frame of `width` x `height`
    /// pixels whose coarser levels are `pyramid`'s, level 0 first.
    pub fn intensity_params(width: u32, height: u32, pyramid: &[Self]) -> Vec<IntensityParams> {
        let coarser: Vec<[u32; 2]> = pyramid
            .iter()
            .map(|l| [l.down.camera.width, l.down.camera.height])
            .collect();
        IntensityParams::levels(width, height, &coarser)
    }
}

impl FrameMaps {
    /// The normal map decoded from `normal_depth` (xyz, `w = 1` valid / `0` invalid), for
    /// reports and comparisons.
    pub fn normal_map(&self) -> Vec<[f32; 4]> {
        Self::normal_map_of(&self.normal_depth)
    }

    /// The normal map decoded from any `normal_depth` map (a pyramid level's too).
    pub fn normal_map_of(normal_depth: &[[f32; 4]]) -> Vec<[f32; 4]> {
        normal_depth
            .iter()
            .map(|n| {
                if n[3] > 0.0 {
                    [n[0], n[1], n[2], 1.0]
                } else {
                    [0.0; 4]
                }
            })
            .collect()
    }
}

/// Predicted model vertex and normal maps of one pyramid level (world frame, `w = 1` valid).
pub type Prediction = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// The keypoints a `describe_keypoints` describes: the first `params.count` of
/// `keypoints`, each with the first `params.tests` tests of `pattern` (pairs of pixel
/// offsets).
#[derive(Debug, Clone, Copy)]
pub struct ToDescribe<'a> {
    pub params: &'a KeypointParams,
    pub keypoints: &'a [Keypoint],
    pub pattern: &'a [[i32; 4]],
}

/// What the last `fuse` left in its per-pixel buffers, one kernel's output each, none of
/// them overwritten by a later kernel of the step: `wgslam compare` checks fusion kernel by
/// kernel with these. Empty before the first fusion.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FusionBuffers {
    /// `fuse_select`'s choice per pixel (`pack_depth_index(off_ray_m, surfel)`), or with
    /// projective association `fuse_merge`'s merged flag; width x height.
    pub assoc: Vec<u64>,
    /// `fuse_merge_chosen`'s merged surfel per pixel (two entries each; see the kernel),
    /// best-candidate association only (left as the last such fusion wrote it otherwise).
    pub merged: Vec<[f32; 4]>,
    /// `fuse_flags`' new-surfel flag per append slot (`layout::append_slots`).
    pub flags: Vec<u32>,
    /// `prefix_sum`'s slot per new surfel, per append slot.
    pub offsets: Vec<u32>,
}

/// Work counters a backend reports for the benchmark.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BackendCounters {
    /// Bytes read back from the device since creation.
    pub readback_bytes: u64,
    /// Command submissions since creation.
    pub submissions: u64,
    /// Submissions the device got from the backend's thread since creation: its own, and
    /// other streams' made with them in one `queue.submit` on a shared queue (GPU contexts
    /// made by `GpuContext::share`). Equal to `submissions` for a lone stream.
    pub device_submissions: u64,
    /// Host waits for the device since creation (each read-back is one), in a device wait
    /// of the backend's own.
    pub waits: u64,
    /// Host waits served by another stream's device wait on a shared queue (GPU contexts
    /// made by `GpuContext::share`): no device wait of the backend's own.
    pub shared_waits: u64,
}

/// `describe_keypoints`' result: each keypoint's descriptor, and its vertex (CAMERA frame,
/// metres, `w = 1` valid / `0`).
pub type Described = (Vec<[u32; DESCRIPTOR_WORDS]>, Vec<[f32; 4]>);

/// The next frame's raw images (as [`Backend::preprocess`] takes them), handed to
/// [`Backend::fuse`] so that a backend which uploads its frames can upload them while the
/// fusion runs rather than after its wait.
#[derive(Debug, Clone, Copy)]
pub struct NextFrame<'a> {
    /// The frame's id, as the pipeline will process it.
    pub frame_id: u32,
    /// u16 depth units, raw_width x raw_height.
    pub depth: &'a [u16],
    /// Packed RGBA8, raw_width x raw_height.
    pub rgba: &'a [u32],
}

/// Runs the kernel steps of one frame. Every method mirrors one or two kernels.
pub trait Backend {
    /// Short name for logs and reports (`cpu`, `gpu`).
    fn name(&self) -> &'static str;
    /// `depth_to_vertex`, then `bilateral_filter` when `steps.bilateral` is given, then
    /// `vertex_to_normal` on the filtered vertex map (or on the unfiltered one without the
    /// filter; the points' depth from the unfiltered map unless `filter_points`) on a raw
    /// frame (`depth`: u16 depth units; `rgba`: packed RGBA8, both raw_width x raw_height).
    /// The unfiltered vertex map is kept either way. Then, for each entry of
    /// `steps.pyramid` (levels 1, 2, ...), `pyramid_depth` from the finer level's vertex map
    /// (at level 0 the one the normals were made from) and `vertex_to_normal`.
    fn preprocess(&mut self, steps: &PreprocessSteps, depth: &[u16], rgba: &[u32]) -> Result<()>;
    /// [`Backend::preprocess`] on the images of frame `frame_id` that the last `fuse` was
    /// handed as its [`NextFrame`] and uploaded while the fusion ran. `Ok(false)`, doing
    /// nothing, when it holds no such images (a backend that never uploads ahead, another
    /// frame's, or a frame of another size): then call `preprocess`.
    fn preprocess_staged(&mut self, steps: &PreprocessSteps, frame_id: u32) -> Result<bool> {
        let _ = (steps, frame_id);
        Ok(false)
    }
    /// `project_model` then `predict_model` at `params.t_world_to_cam`
    /// (`surfel_count` is filled in by the backend), then `pyramid_model` for each entry of
    /// `pyramid` (the same levels as the last `preprocess`'s). When the map last changed in
    /// a best-candidate `fuse` at the same view ([`crate::fused_view::FusedView`]), that fusion's index map
    /// stands in for `project_model`'s.
    fn predict(&mut self, params: &ProjectParams, pyramid: &[PyramidLevel]) -> Result<()>;
    /// `icp_reduce` at the current estimate on pyramid level `level` (0 = finest; `params`
    /// carry that level's size and intrinsics): the summed 29-entry system.
    fn icp_system(&mut self, level: usize, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]>;
    /// RGB-D tracking's systems at pyramid level `level` (`params` at that level's size and
    /// intrinsics), in one submission and one read-back: `icp_reduce`'s geometric system
    /// (as [`Backend::icp_system`]) and `photo_reduce`'s photometric one (intensity
    /// residuals against the last `predict`'s predicted intensity; see
    /// `cpu::photo_reduce`). The first call at a level after a `preprocess` also makes the
    /// frame's intensity pyramid down to that level where not made yet
    /// (`intensity_pyramid`, finest first, in the same submission): geometric tracking
    /// never pays for it, nor RGB-D tracking for levels it does not use.
    fn rgbd_system(&mut self, level: usize, params: &IcpParams) -> Result<RgbdSystems>;
    /// `icp_candidates` at level 0 (`params` at level 0's size and intrinsics): source
    /// pixels of the last `predict` that pass ICP's filter 1 at `params.t_world_to_cam`.
    fn count_candidates(&mut self, params: &IcpParams) -> Result<u64>;
    /// `fern_encode` over the last `preprocess`'s level-0 maps: the code of each of the
    /// first `params.fern_count` of `ferns` (for the relocalisation keyframe database).
    fn encode_ferns(&mut self, params: &FernParams, ferns: &[Fern]) -> Result<Vec<u32>>;
    /// `keypoint_detect` over the last `preprocess`'s level-0 maps: the corners found (at
    /// most `params.capacity`, in no particular order) and how many there were.
    fn detect_keypoints(&mut self, params: &KeypointParams) -> Result<(Vec<Keypoint>, u32)>;
    /// `keypoint_describe` of the keypoints `what` names: each one's descriptor and
    /// camera-frame vertex.
    fn describe_keypoints(&mut self, what: ToDescribe) -> Result<Described>;
    /// `fuse_merge` (projective) or `fuse_select` + `fuse_merge_chosen` (+ `fuse_prune`
    /// with a prune scale) (best candidate), then `fuse_add` (`surfel_count` and
    /// `capacity` are filled in by the backend, which grows the map first when needed).
    /// Returns without waiting for the fusion: the surfels it added are counted by the next
    /// [`Backend::surfel_count`] (on a GPU, from a read-back that the next frame's first
    /// wait completes). A backend that uploads its frames (the GPU's) may upload `next`, the
    /// next frame's raw images, while the fusion runs, for [`Backend::preprocess_staged`];
    /// others ignore it.
    fn fuse(&mut self, params: &FuseParams, next: Option<NextFrame<'_>>) -> Result<()>;
    /// `compact_flags`, `prefix_sum`, then `compact_scatter` into a second map, which
    /// becomes the map: removes the unstable surfels and moves the survivors to the front
    /// in their order (`surfel_count` is filled in by the backend). Returns surfels after.
    fn compact(&mut self, params: &CompactParams) -> Result<usize>;
    /// `deform_surfels` (after a loop closure): every surfel moves with the corrections of
    /// the two `nodes` (sorted by frame) nearest its last frame. Then the culling boxes
    /// are stale and no fused view stands in for the next prediction.
    fn deform(&mut self, nodes: &[DeformNode]) -> Result<()>;
    /// The last `preprocess`'s maps at pyramid `level` (0 = finest): the camera-frame
    /// vertex map and `normal_depth` (a loop-closure keyframe's snapshot).
    fn frame_level(&mut self, level: usize) -> Result<Prediction>;
    /// Replaces pyramid `level`'s predicted vertex and normal maps (world frame, `w = 1`
    /// valid, that level's size) until the next `predict`: ICP at that level then
    /// registers the frame against them (a loop closure's verification).
    fn set_prediction(&mut self, level: usize, prediction: &Prediction) -> Result<()>;
    /// Surfels in the map. After a `fuse`, a GPU learns its count from a read-back: at no
    /// wait of its own once a later wait (the next ICP iteration's) has completed it, else
    /// by waiting for the fusion.
    fn surfel_count(&mut self) -> Result<usize>;
    /// Blocks until all submitted work has finished (for per-stage wall-clock timing;
    /// a no-op for the CPU).
    fn finish(&mut self) -> Result<()> {
        Ok(())
    }
}

/// Copies in and out of a backend, for outputs, comparisons and tests; the pipeline's
/// steps never call these.
pub trait Inspect {
    /// The whole map (for export and comparison).
    fn download_map(&mut self) -> Result<SurfelMap>;
    /// Replaces the map with `map` (growing the storage if needed): to resume from a saved
    /// map, or to put this backend into another's state (`wgslam compare`'s lockstep mode).
    /// [`crate::Error::Capacity`] when the backend cannot hold it.
    fn upload_map(&mut self, map: &SurfelMap) -> Result<()>;
    /// The current frame's maps.
    fn download_frame(&mut self) -> Result<FrameMaps>;
    /// The predicted model vertex and normal maps (world frame) of pyramid level `level`
    /// (0 = finest); empty before the first frame or beyond the pyramid.
    fn download_prediction(&mut self, level: usize) -> Result<Prediction>;
    /// The last `fuse`'s per-pixel buffers ([`FusionBuffers`]).
    fn download_fusion(&mut self) -> Result<FusionBuffers>;
    /// Work counters (zero for the CPU).
    fn counters(&self) -> BackendCounters {
        BackendCounters::default()
    }
}

/// Inside an `impl Inspect for W`, where `W` wraps another backend in the field named
/// `$inner`: `download_frame`, `download_prediction`, `download_fusion` and `counters`
/// passed through to it unchanged (the wrappers that time, record or perturb a backend
/// change none of these).
#[macro_export]
macro_rules! inspect_through {
    ($inner:ident) => {
        fn download_frame(&mut self) -> $crate::Result<$crate::backend::FrameMaps> {
            self.$inner.download_frame()
        }
        fn download_prediction(
            &mut self,
            level: usize,
        ) -> $crate::Result<$crate::backend::Prediction> {
            self.$inner.download_prediction(level)
        }
        fn download_fusion(&mut self) -> $crate::Result<$crate::backend::FusionBuffers> {
            self.$inner.download_fusion()
        }
        fn counters(&self) -> $crate::backend::BackendCounters {
            self.$inner.counters()
        }
    };
}

/// A backend that can also be inspected: what the command line runs (`Box<dyn
/// SlamBackend>`, see `wgslam::slam::any_backend::AnyBackend`). `Send` on native targets
/// ([`MaybeSend`]), so that a boxed backend can run on a thread other than the one that
/// opened it (the Python package processes frames with the interpreter's lock released).
pub trait SlamBackend: Backend + Inspect + MaybeSend {}

impl<T: Backend + Inspect + MaybeSend + ?Sized> SlamBackend for T {}

/// `Send` on native targets, so a boxed backend can move to another thread; nothing on
/// wasm32, where the browser's WebGPU objects belong to the page's one thread (wgpu's
/// WebGPU types are not `Send`).
#[cfg(not(target_arch = "wasm32"))]
pub trait MaybeSend: Send {}
#[cfg(not(target_arch = "wasm32"))]
impl<T: Send + ?Sized> MaybeSend for T {}
/// `Send` on native targets; nothing on wasm32 (see the native definition).
#[cfg(target_arch = "wasm32")]
pub trait MaybeSend {}
#[cfg(target_arch = "wasm32")]
impl<T: ?Sized> MaybeSend for T {}

/// A boxed backend is a backend (the CLI picks CPU or GPU at run time): every step goes to
/// the box's content. The one hand-written forwarding of the trait besides
/// `wgslam::slam::instrumented::Instrumented`.
impl<B: Backend + ?Sized> Backend for Box<B> {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn preprocess(&mut self, steps: &PreprocessSteps, depth: &[u16], rgba: &[u32]) -> Result<()> {
        (**self).preprocess(steps, depth, rgba)
    }
    fn preprocess_staged(&mut self, steps: &PreprocessSteps, frame_id: u32) -> Result<bool> {
        (**self).preprocess_staged(steps, frame_id)
    }
    fn predict(&mut self, params: &ProjectParams, pyramid: &[PyramidLevel]) -> Result<()> {
        (**self).predict(params, pyramid)
    }
    fn icp_system(&mut self, level: usize, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        (**self).icp_system(level, params)
    }
    fn rgbd_system(&mut self, level: usize, params: &IcpParams) -> Result<RgbdSystems> {
        (**self).rgbd_system(level, params)
    }
    fn encode_ferns(&mut self, params: &FernParams, ferns: &[Fern]) -> Result<Vec<u32>> {
        (**self).encode_ferns(params, ferns)
    }
    fn count_candidates(&mut self, params: &IcpParams) -> Result<u64> {
        (**self).count_candidates(params)
    }
    fn detect_keypoints(&mut self, params: &KeypointParams) -> Result<(Vec<Keypoint>, u32)> {
        (**self).detect_keypoints(params)
    }
    fn describe_keypoints(&mut self, what: ToDescribe) -> Result<Described> {
        (**self).describe_keypoints(what)
    }
    fn fuse(&mut self, params: &FuseParams, next: Option<NextFrame<'_>>) -> Result<()> {
        (**self).fuse(params, next)
    }
    fn compact(&mut self, params: &CompactParams) -> Result<usize> {
        (**self).compact(params)
    }
    fn deform(&mut self, nodes: &[DeformNode]) -> Result<()> {
        (**self).deform(nodes)
    }
    fn frame_level(&mut self, level: usize) -> Result<Prediction> {
        (**self).frame_level(level)
    }
    fn set_prediction(&mut self, level: usize, prediction: &Prediction) -> Result<()> {
        (**self).set_prediction(level, prediction)
    }
    fn surfel_count(&mut self) -> Result<usize> {
        (**self).surfel_count()
    }
    fn finish(&mut self) -> Result<()> {
        (**self).finish()
    }
}

impl<B: Inspect + ?Sized> Inspect for Box<B> {
    fn download_map(&mut self) -> Result<SurfelMap> {
        (**self).download_map()
    }
    fn upload_map(&mut self, map: &SurfelMap) -> Result<()> {
        (**self).upload_map(map)
    }
    fn download_frame(&mut self) -> Result<FrameMaps> {
        (**self).download_frame()
    }
    fn download_prediction(&mut self, level: usize) -> Result<Prediction> {
        (**self).download_prediction(level)
    }
    fn download_fusion(&mut self) -> Result<FusionBuffers> {
        (**self).download_fusion()
    }
    fn counters(&self) -> BackendCounters {
        (**self).counters()
    }
}
