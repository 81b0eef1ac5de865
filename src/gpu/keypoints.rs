//! The GPU side of feature-based relocalisation: `keypoint_detect`'s and
//! `keypoint_describe`'s buffers (made at the first call, re-made when a call needs more
//! room), dispatches and read-backs. Both run only on keyframes and lost frames.

use super::backend::GpuBackend;
use super::buffers::{GpuArray, ParamBuffer, Readback};
use super::context::GpuContext;
use super::recording::{record_passes, submit_profiled};
use crate::layout::{Keypoint, KeypointParams, DESCRIPTOR_WORDS};
use crate::slam::backend::Described;
use crate::Result;

/// The keypoint kernels' buffers, sized for `capacity` keypoints and `tests` tests.
pub(super) struct KeypointBuffers {
    capacity: usize,
    tests: usize,
    params: ParamBuffer<KeypointParams>,
    keypoints: GpuArray<Keypoint>,
    counter: GpuArray<u32>,
    pattern: GpuArray<[i32; 4]>,
    descriptors: GpuArray<u32>,
    points: GpuArray<[f32; 4]>,
    keypoints_back: Readback<Keypoint>,
    counter_back: Readback<u32>,
    descriptors_back: Readback<u32>,
    points_back: Readback<[f32; 4]>,
}

impl KeypointBuffers {
    fn new(ctx: &GpuContext, p: &KeypointParams, capacity: usize, tests: usize) -> Result<Self> {
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

impl GpuBackend {
    /// Buffers for at least `capacity` keypoints and `tests` tests.
    fn keypoint_buffers(
        &mut self,
        p: &KeypointParams,
        capacity: usize,
        tests: usize,
    ) -> Result<()> {
        let fits = self
            .keypoints
            .as_ref()
            .is_some_and(|b| b.capacity >= capacity && b.tests >= tests);
        if !fits {
            let capacity = capacity.max(1);
            let tests = tests.max(1);
            self.keypoints = Some(KeypointBuffers::new(&self.ctx, p, capacity, tests)?);
        }
        Ok(())
    }

    /// `keypoint_detect`; see `Backend::detect_keypoints`.
    pub(super) fn detect_keypoints_on_gpu(
        &mut self,
        params: &KeypointParams,
    ) -> Result<(Vec<Keypoint>, u32)> {
        self.keypoint_buffers(params, params.capacity as usize, 1)?;
        let b = self.keypoints.as_mut().expect("just made");
        let frame = self
            .frame
            .as_ref()
            .expect("preprocess() runs before any other step");
        let ctx = &self.ctx;
        let grid = self.kernels.keypoint_detect.grid_workgroups_for_image(
            ctx,
            params.width,
            params.height,
        );
        ctx.scoped("keypoint_detect", || {
            b.params.write(ctx, params);
            let group = self.kernels.keypoint_detect.bind_group(
                ctx,
                &[
                    ("params", b.params.binding()),
                    ("color", frame.color.binding()),
                    ("normal_depth", frame.normal_depth.binding()),
                    ("keypoints", b.keypoints.binding()),
                    ("counter", b.counter.binding()),
                ],
            );
            let mut enc = ctx.encoder("keypoint_detect");
            b.counter.clear(&mut enc);
            record_passes(
                ctx,
                &mut self.profiler,
                &mut enc,
                &[(&self.kernels.keypoint_detect, &group, grid)],
            )?;
            b.counter_back.copy_from(&mut enc, &b.counter, 1);
            b.keypoints_back
                .copy_from(&mut enc, &b.keypoints, params.capacity as usize);
            submit_profiled(ctx, &mut self.profiler, enc)?;
            let found = b.counter_back.read(ctx)?[0];
            let mut kps = b.keypoints_back.read(ctx)?;
            kps.truncate(found.min(params.capacity) as usize);
            Ok((kps, found))
        })
    }

    /// `keypoint_describe`; see `Backend::describe_keypoints`.
    pub(super) fn describe_keypoints_on_gpu(
        &mut self,
        params: &KeypointParams,
        keypoints: &[Keypoint],
        pattern: &[[i32; 4]],
    ) -> Result<Described> {
        let n = params.count as usize;
        assert!(keypoints.len() >= n && pattern.len() >= params.tests as usize);
        if n == 0 {
            return Ok((vec![], vec![]));
        }
        self.keypoint_buffers(params, n, params.tests as usize)?;
        let b = self.keypoints.as_mut().expect("just made");
        let frame = self
            .frame
            .as_ref()
            .expect("preprocess() runs before any other step");
        let ctx = &self.ctx;
        ctx.scoped("keypoint_describe", || {
            b.params.write(ctx, params);
            b.keypoints.upload(ctx, &keypoints[..n])?;
            b.pattern.upload(ctx, &pattern[..params.tests as usize])?;
            let group = self.kernels.keypoint_describe.bind_group(
                ctx,
                &[
                    ("params", b.params.binding()),
                    ("color", frame.color.binding()),
                    ("vertex", frame.vertex.binding()),
                    ("keypoints", b.keypoints.binding()),
                    ("pattern", b.pattern.binding()),
                    ("descriptors", b.descriptors.binding()),
                    ("points", b.points.binding()),
                ],
            );
            let workgroups = (n as u32)
                .div_ceil(64)
                .min(ctx.reduction_workgroups().max(1));
            let mut enc = ctx.encoder("keypoint_describe");
            record_passes(
                ctx,
                &mut self.profiler,
                &mut enc,
                &[(&self.kernels.keypoint_describe, &group, [workgroups, 1])],
            )?;
            b.descriptors_back
                .copy_from(&mut enc, &b.descriptors, n * DESCRIPTOR_WORDS);
            b.points_back.copy_from(&mut enc, &b.points, n);
            submit_profiled(ctx, &mut self.profiler, enc)?;
            let words = b.descriptors_back.read(ctx)?;
            let points = b.points_back.read(ctx)?;
            let descriptors = words
                .chunks_exact(DESCRIPTOR_WORDS)
                .map(|c| c.try_into().expect("chunks of DESCRIPTOR_WORDS"))
                .collect();
            Ok((descriptors, points))
        })
    }
}
