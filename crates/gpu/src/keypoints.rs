//! The GPU side of feature-based relocalisation: `keypoint_detect`'s and
//! `keypoint_describe`'s buffers (made at the first call, re-made when a call needs more
//! room) and read-backs. Both run only on keyframes and lost frames; the steps themselves
//! are in `super::single_steps`.

use super::buffers::{GpuArray, ParamBuffer, Readback};
use super::context::GpuContext;
use crate::layout::{Keypoint, KeypointParams, DESCRIPTOR_WORDS};
use crate::Result;

/// The keypoint kernels' buffers, sized for `capacity` keypoints and `tests` tests.
pub(super) struct KeypointBuffers {
    pub capacity: usize,
    pub tests: usize,
    pub params: ParamBuffer<KeypointParams>,
    pub keypoints: GpuArray<Keypoint>,
    pub counter: GpuArray<u32>,
    pub pattern: GpuArray<[i32; 4]>,
    pub descriptors: GpuArray<u32>,
    pub points: GpuArray<[f32; 4]>,
    pub keypoints_back: Readback<Keypoint>,
    pub counter_back: Readback<u32>,
    pub descriptors_back: Readback<u32>,
    pub points_back: Readback<[f32; 4]>,
}

impl KeypointBuffers {
    pub fn new(
        ctx: &GpuContext,
        p: &KeypointParams,
        capacity: usize,
        tests: usize,
    ) -> Result<Self> {
        let array = |label: &str, n: usize| -> Result<GpuArray<u32>> {
            let mut a = GpuArray::new(ctx, label, n)?;
            a.set_len(n);
            Ok(a)
        };
        let mut keypoints = GpuArray::new(ctx, "keypoints", capacity)?;
        keypoints.set_len(capacity);
        let mut pattern = GpuArray::new(ctx, "descriptor pattern", tests)?;
        pattern.set_len(tests);
        let mut points = GpuArray::new(ctx, "keypoint points", capacity)?;
        points.set_len(capacity);
        Ok(KeypointBuffers {
            capacity,
            tests,
            params: ParamBuffer::new(ctx, "KeypointParams", p),
            keypoints,
            counter: array("keypoint counter", 1)?,
            pattern,
            descriptors: array("descriptors", capacity * DESCRIPTOR_WORDS)?,
            points,
            keypoints_back: Readback::new(ctx, "keypoints read-back", capacity),
            counter_back: Readback::new(ctx, "keypoint counter read-back", 1),
            descriptors_back: Readback::new(
                ctx,
                "descriptors read-back",
                capacity * DESCRIPTOR_WORDS,
            ),
            points_back: Readback::new(ctx, "keypoint points read-back", capacity),
        })
    }
}

impl KeypointBuffers {
    /// Both keypoint kernels' resources besides the frame's maps (each kernel takes what
    /// its WGSL declares).
    pub fn pool(&self) -> Vec<(&'static str, wgpu::BindingResource<'_>)> {
        vec![
            ("params", self.params.binding()),
            ("keypoints", self.keypoints.binding()),
            ("counter", self.counter.binding()),
            ("pattern", self.pattern.binding()),
            ("descriptors", self.descriptors.binding()),
            ("points", self.points.binding()),
        ]
    }
}

/// Makes `slot` hold buffers for at least `capacity` keypoints and `tests` tests (re-made,
/// never grown in place).
pub(super) fn ensure<'a>(
    slot: &'a mut Option<KeypointBuffers>,
    ctx: &GpuContext,
    p: &KeypointParams,
    capacity: usize,
    tests: usize,
) -> Result<&'a mut KeypointBuffers> {
    let fits = slot
        .as_ref()
        .is_some_and(|b| b.capacity >= capacity && b.tests >= tests);
    if !fits {
        *slot = Some(KeypointBuffers::new(ctx, p, capacity.max(1), tests.max(1))?);
    }
    Ok(slot.as_mut().expect("just made"))
}
