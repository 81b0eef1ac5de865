//! The GPU side of feature-based relocalisation: `keypoint_detect`'s and
//! `keypoint_describe`'s buffers (made at the first call, re-made when a call needs more
//! room) and read-backs. Both run only on keyframes and lost frames; the steps themselves
//! are in `super::single_steps`, the kernels bound by their registry rows over
//! [`bindings`].

use super::bind_groups::OnDemand;
use super::buffers::{GpuArray, Readback};
use super::context::GpuContext;
use crate::layout::{Keypoint, DESCRIPTOR_WORDS};
use crate::Result;

/// The keypoint kernels' buffers, sized for `capacity` keypoints and `tests` tests.
pub(super) struct KeypointBuffers {
    pub capacity: usize,
    pub tests: usize,
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
    pub fn new(ctx: &GpuContext, capacity: usize, tests: usize) -> Result<Self> {
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

/// Both keypoint kernels' buffers by the names they declare them with (each kernel takes
/// what its WGSL declares), `None` before the first keypoint step.
pub(super) fn bindings(b: Option<&KeypointBuffers>) -> OnDemand<'_> {
    vec![
        ("keypoints", b.map(|b| b.keypoints.binding())),
        ("counter", b.map(|b| b.counter.binding())),
        ("pattern", b.map(|b| b.pattern.binding())),
        ("descriptors", b.map(|b| b.descriptors.binding())),
        ("points", b.map(|b| b.points.binding())),
    ]
}

/// Makes `slot` hold buffers for at least `capacity` keypoints and `tests` tests (re-made,
/// never grown in place). Returns whether it made them (the bind groups that bind them
/// are then stale).
pub(super) fn ensure(
    slot: &mut Option<KeypointBuffers>,
    ctx: &GpuContext,
    capacity: usize,
    tests: usize,
) -> Result<bool> {
    let fits = slot
        .as_ref()
        .is_some_and(|b| b.capacity >= capacity && b.tests >= tests);
    if !fits {
        *slot = Some(KeypointBuffers::new(ctx, capacity.max(1), tests.max(1))?);
    }
    Ok(!fits)
}
