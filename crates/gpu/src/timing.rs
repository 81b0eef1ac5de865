//! Per-stage GPU timing: one compute pass per named stage, with timestamp queries at its
//! start and end when the device has `TIMESTAMP_QUERY`, else host wall time.
//!
//! Not a profiler: it measures whole passes, and in wall-time mode it can only measure
//! everything from the first pass to the read-back (one entry), because the host cannot
//! see where one pass ends inside a submission.

use web_time::Instant;

use super::buffers::map_read;
use super::context::GpuContext;
use crate::Result;

/// Where a [`StageTime`] came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum TimeSource {
    /// GPU timestamps around the stage's pass.
    GpuTimestamps,
    /// Host wall clock from the first pass to the read-back (includes submission and wait).
    Wall,
}

/// The duration of one named stage, in milliseconds.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StageTime {
    pub name: String,
    pub ms: f64,
    pub source: TimeSource,
}

struct Queries {
    set: wgpu::QuerySet,
    /// `QUERY_RESOLVE | COPY_SRC`, 2 x max_stages u64 ticks.
    resolve: wgpu::Buffer,
    /// Nanoseconds per tick.
    period_ns: f64,
}

/// Hands out one compute pass per stage and collects their durations.
pub struct StageTimer {
    queries: Option<Queries>,
    max_stages: u32,
    names: Vec<String>,
    wall_start: Option<Instant>,
}

impl StageTimer {
    /// A timer for up to `max_stages` passes between two [`StageTimer::read`] calls
    /// (passes beyond that are run untimed). Uses timestamps when the device has them.
    pub fn new(ctx: &GpuContext, max_stages: u32) -> StageTimer {
        let queries = ctx
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
            .then(|| {
                let count = 2 * max_stages.max(1);
                Queries {
                    set: ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                        label: Some("wgslam stage timestamps"),
                        ty: wgpu::QueryType::Timestamp,
                        count,
                    }),
                    resolve: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("wgslam timestamp resolve"),
                        size: count as u64 * 8,
                        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                        mapped_at_creation: false,
                    }),
                    period_ns: ctx.queue.get_timestamp_period() as f64,
                }
            });
        StageTimer {
            queries,
            max_stages: max_stages.max(1),
            names: Vec::new(),
            wall_start: None,
        }
    }

    /// True when stage times come from GPU timestamps.
    pub fn uses_timestamps(&self) -> bool {
        self.queries.is_some()
    }

    /// Begins the compute pass of stage `name` on `encoder`.
    pub fn begin_pass<'e>(
        &mut self,
        encoder: &'e mut wgpu::CommandEncoder,
        name: &str,
    ) -> wgpu::ComputePass<'e> {
        self.wall_start.get_or_insert_with(Instant::now);
        let slot = self.names.len() as u32;
        let timestamp_writes = match &self.queries {
            Some(q) if slot < self.max_stages => {
                self.names.push(name.to_string());
                Some(wgpu::ComputePassTimestampWrites {
                    query_set: &q.set,
                    beginning_of_pass_write_index: Some(2 * slot),
                    end_of_pass_write_index: Some(2 * slot + 1),
                })
            }
            _ => None,
        };
        encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(name),
            timestamp_writes,
        })
    }

    /// Records the resolve of this round's timestamps; call on the last encoder before
    /// submitting it (no-op in wall-time mode).
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(q) = &self.queries {
            let n = 2 * self.names.len() as u32;
            if n > 0 {
                encoder.resolve_query_set(&q.set, 0..n, &q.resolve, 0);
            }
        }
    }

    /// Waits for the GPU, returns this round's stage times and starts a new round.
    /// Timestamp mode: one entry per timed stage, in pass order. Wall mode: one entry
    /// `"all stages"` from the first pass to now.
    pub fn read(&mut self, ctx: &GpuContext) -> Result<Vec<StageTime>> {
        let names = std::mem::take(&mut self.names);
        let start = self.wall_start.take();
        let Some(q) = &self.queries else {
            ctx.wait_idle()?;
            return Ok(start
                .map(|s| StageTime {
                    name: "all stages".to_string(),
                    ms: s.elapsed().as_secs_f64() * 1e3,
                    source: TimeSource::Wall,
                })
                .into_iter()
                .collect());
        };
        if names.is_empty() {
            return Ok(Vec::new());
        }
        let bytes = names.len() as u64 * 16;
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wgslam timestamp staging"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = ctx.encoder("timestamp copy");
        enc.copy_buffer_to_buffer(&q.resolve, 0, &staging, 0, bytes);
        ctx.submit(enc);
        let ticks: Vec<u64> = map_read(ctx, &staging, bytemuck::pod_collect_to_vec)?;
        Ok(names
            .into_iter()
            .enumerate()
            .map(|(i, name)| StageTime {
                name,
                ms: ticks[2 * i + 1].wrapping_sub(ticks[2 * i]) as f64 * q.period_ns * 1e-6,
                source: TimeSource::GpuTimestamps,
            })
            .collect())
    }
}
