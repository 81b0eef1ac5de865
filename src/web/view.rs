//! The page's live view: the map drawn by the GPU renderer ([`crate::render::gpu`]) from the
//! user's orbit camera ([`Orbit`] around the map's overview camera), the current input
//! frame's colour and depth as RGBA pictures, and each frame's outcome in words. During a
//! run, [`LiveView`] (a [`FrameObserver`]) downloads the map every few frames and draws it;
//! after the run the page asks for a new picture on every interaction.

use std::cell::RefCell;
use std::rc::Rc;

use glam::{DMat4, DVec3};

use crate::dataset::RawFrame;
use crate::geometry::camera::Intrinsics;
use crate::gpu::context::{DeviceOptions, GpuContext};
use crate::layout::map::SurfelMap;
use crate::render::gpu::GpuRenderer;
use crate::render::orbit::Orbit;
use crate::render::outputs::overview_camera;
use crate::render::{MapCloud, RenderBackend, RenderSettings, View};
use crate::slam::report::TrackStatus;
use crate::tools::run::{FrameObserver, FrameOutcome};
use crate::Result;

/// The live view's size, pixels: the page's canvas, fixed from the start.
pub const VIEW_SIZE: (u32, u32) = (640, 480);

/// Frames between two map downloads during a run: a download reads back 48 bytes a surfel
/// and a picture costs a render, together about a frame's time in the browser; every fifth
/// frame keeps the view moving at a fifth of the cost.
pub const FRAMES_PER_MAP_VIEW: usize = 5;

/// Depth drawn black at this distance and beyond, metres: the far end of the useful range
/// of the structured-light and time-of-flight sensors these datasets come from.
pub const DEPTH_VIEW_FAR_M: f32 = 5.0;

thread_local! {
    /// The renderer, made once per page (creating its pipelines costs a second or more).
    static RENDERER: RefCell<Option<Rc<(GpuContext, GpuRenderer)>>> = const { RefCell::new(None) };
}

/// The map seen by `orbit` around the overview camera of `map` and `trajectory`
/// (`t_cam_to_world`, the run's world frame; `intrinsics` of the dataset, whose `fy` sign
/// fixes the handedness), as RGBA8 of [`VIEW_SIZE`], row-major. White for an empty map.
pub fn render_map(
    map: &SurfelMap,
    trajectory: &[(f64, DMat4)],
    intrinsics: &Intrinsics,
    orbit: &Orbit,
) -> Result<Vec<u8>> {
    let (w, h) = VIEW_SIZE;
    if map.is_empty() {
        return Ok(vec![255; (w * h * 4) as usize]);
    }
    let renderer = match RENDERER.with_borrow(|r| r.clone()) {
        Some(r) => r,
        None => {
            let ctx = GpuContext::with_options(DeviceOptions::default())?;
            let kernels = GpuRenderer::new(&ctx)?;
            let r = Rc::new((ctx, kernels));
            RENDERER.with_borrow_mut(|slot| *slot = Some(Rc::clone(&r)));
            r
        }
    };
    let base = overview_camera(map, trajectory, intrinsics, VIEW_SIZE)?;
    // The target: the map's mean point moved onto the base camera's optical axis, so the
    // picture turns about its centre.
    let n = map.len() as f64;
    let mean = map.position_weight.iter().fold(DVec3::ZERO, |s, p| {
        s + DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
    }) / n;
    let eye = base.t_cam_to_world.w_axis.truncate();
    let ahead = base.t_cam_to_world.z_axis.truncate();
    let target = eye + ahead * (mean - eye).dot(ahead).max(0.0);
    let camera = orbit.apply(&base, target);
    let backend = RenderBackend::Gpu {
        ctx: &renderer.0,
        kernels: &renderer.1,
    };
    let cloud = MapCloud::new(map);
    let image = backend.render(
        &cloud.cloud(),
        &camera,
        View::Color,
        &RenderSettings::default(),
    )?;
    Ok(image
        .pixels()
        .flat_map(|p| [p.0[0], p.0[1], p.0[2], 255])
        .collect())
}

/// A frame's colour as RGBA8, row-major, full resolution.
pub fn color_rgba(raw: &RawFrame) -> Vec<u8> {
    raw.rgb
        .iter()
        .flat_map(|c| [c[0], c[1], c[2], 255])
        .collect()
}

/// A frame's depth as grey RGBA8 (near light, [`DEPTH_VIEW_FAR_M`] and beyond black), no
/// reading dark red; `depth_scale` raw units per metre.
pub fn depth_rgba(raw: &RawFrame, depth_scale: f32) -> Vec<u8> {
    raw.depth
        .iter()
        .flat_map(|&d| {
            if d == 0 {
                return [90, 0, 0, 255];
            }
            let t = (d as f32 / depth_scale / DEPTH_VIEW_FAR_M).min(1.0);
            let g = (255.0 * (1.0 - t)).round() as u8;
            [g, g, g, 255]
        })
        .collect()
}

/// A frame's outcome in words for the progress line (not the enum's names).
pub fn status_words(status: &TrackStatus) -> String {
    match status {
        TrackStatus::Given => "pose given (first frame)".into(),
        TrackStatus::Converged => "tracked".into(),
        TrackStatus::MaxIterations => "tracked (iteration limit reached)".into(),
        TrackStatus::Stopped(why) => format!("tracked, stopped early ({why})"),
        TrackStatus::Relocalised { keyframe_frame } => {
            format!("relocalised at the keyframe of frame {keyframe_frame}")
        }
        TrackStatus::Lost(why) => format!("lost ({why})"),
        TrackStatus::EmptyDepth => "skipped: no depth reading".into(),
    }
}

/// What the page sees of a frame while the run goes.
pub struct Shown {
    /// Colour and depth pictures of the frame ([`color_rgba`], [`depth_rgba`]) and their
    /// width and height.
    pub color: Vec<u8>,
    pub depth: Vec<u8>,
    pub size: (u32, u32),
    /// A new map picture, when one was drawn after this frame.
    pub map: Option<Vec<u8>>,
    /// The tracked camera positions so far, `stamp, x, y, z` each (the run's world frame,
    /// metres).
    pub path: Vec<f64>,
}

/// The run's observer for the live view: keeps the tracked poses and the last downloaded
/// map, draws the map every [`FRAMES_PER_MAP_VIEW`] frames (and after the last) from the
/// orbit `orbit()` returns, and hands each frame's pictures to `show`.
pub struct LiveView<'a> {
    pub first: usize,
    pub last: usize,
    pub intrinsics: Intrinsics,
    pub depth_scale: f32,
    pub trajectory: Vec<(f64, DMat4)>,
    pub map: Option<SurfelMap>,
    pub orbit: &'a dyn Fn() -> Orbit,
    pub show: &'a dyn Fn(Shown),
}

impl FrameObserver for LiveView<'_> {
    fn wants_map(&mut self, index: usize) -> bool {
        (index - self.first) % FRAMES_PER_MAP_VIEW == 0 || index == self.last
    }

    fn frame(
        &mut self,
        raw: &RawFrame,
        outcome: &FrameOutcome,
        map: Option<&SurfelMap>,
    ) -> Result<()> {
        if outcome.report.status.is_tracked() {
            self.trajectory
                .push((outcome.timestamp, outcome.report.t_cam_to_world));
        }
        let picture = match map {
            Some(m) => {
                let p = render_map(m, &self.trajectory, &self.intrinsics, &(self.orbit)())?;
                self.map = Some(m.clone());
                Some(p)
            }
            None => None,
        };
        (self.show)(Shown {
            color: color_rgba(raw),
            depth: depth_rgba(raw, self.depth_scale),
            size: (raw.width, raw.height),
            map: picture,
            path: self
                .trajectory
                .iter()
                .flat_map(|(stamp, t)| [*stamp, t.w_axis.x, t.w_axis.y, t.w_axis.z])
                .collect(),
        });
        Ok(())
    }
}
