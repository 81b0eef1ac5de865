//! The browser build's entry points (wasm32 only, `deploy/web`): the page hands over the
//! bundled sequence's files, runs dense SLAM over them on the GPU through WebGPU, and reads
//! back what `wgslam run` prints (the same [`summary_lines`] over the same [`Metrics`]),
//! both trajectories and a render of the map by the GPU renderer of [`crate::render`].
//!
//! Not a second pipeline: the run is [`run_observed`] on a [`GpuBackend`], as on the command
//! line. What differs is only how waits happen (see [`crate::gpu::wait`]): every GPU wait
//! suspends the WebAssembly stack through JSPI, so [`wgslam_web_run`], the one entry point
//! that waits, is a plain WebAssembly export (no wasm-bindgen wrapper) that the page calls
//! through `WebAssembly.promising`. The other entry points return at once.
//!
//! Calling order: [`add_file`] for every file of the dataset folder, optionally
//! [`set_progress`], then `wgslam_web_run` (awaited), then [`result_json`] and
//! [`render_rgba`], or [`last_error`] when the run returned non-zero.

use std::cell::RefCell;
use std::path::Path;

use glam::DMat4;
use serde::Serialize;
use wasm_bindgen::prelude::*;

use crate::dataset::{open_in_memory, InMemoryFiles, DEFAULT_MAX_TIME_DIFF};
use crate::gpu::context::{DeviceOptions, GpuContext};
use crate::gpu::GpuBackend;
use crate::render::gpu::GpuRenderer;
use crate::render::outputs::overview_camera;
use crate::render::{MapCloud, RenderBackend, RenderSettings, View, DEFAULT_SIZE};
use crate::slam::params::{Profile, SlamParams};
use crate::tools::run::{run_observed, summary_lines, Decode, FrameOutcome, Metrics};
use crate::Result;

/// What the page gave and what the last run left.
#[derive(Default)]
struct State {
    files: InMemoryFiles,
    progress: Option<js_sys::Function>,
    result: Option<String>,
    render: Option<Vec<u8>>,
    error: Option<String>,
}

thread_local! {
    static STATE: RefCell<State> = RefCell::new(State::default());
}

/// Adds one file of the dataset folder: `path` as the command line would name it
/// (`assets/icl_living_room_kt2/rgb/0.png`), `bytes` its contents.
#[wasm_bindgen]
pub fn add_file(path: &str, bytes: Vec<u8>) {
    STATE.with_borrow_mut(|s| s.files.insert(path, bytes));
}

/// Sets the function called after each frame with `(frames done, frames in all, surfels,
/// the frame's pipeline milliseconds, the frame's status)`.
#[wasm_bindgen]
pub fn set_progress(callback: js_sys::Function) {
    STATE.with_borrow_mut(|s| s.progress = Some(callback));
}

/// The last run's results as JSON (the private `WebResult`: the summary lines, `Metrics`,
/// both trajectories, per-frame times), or `undefined` before one finished.
#[wasm_bindgen]
pub fn result_json() -> Option<String> {
    STATE.with_borrow(|s| s.result.clone())
}

/// The last run's map render as RGBA8, `render_width x render_height` of [`result_json`],
/// row-major; `undefined` without one.
#[wasm_bindgen]
pub fn render_rgba() -> Option<Vec<u8>> {
    STATE.with_borrow(|s| s.render.clone())
}

/// Why the last run failed, or `undefined`.
#[wasm_bindgen]
pub fn last_error() -> Option<String> {
    STATE.with_borrow(|s| s.error.clone())
}

/// Everything the page shows of a run.
#[derive(Serialize)]
struct WebResult<'a> {
    /// The lines `wgslam run` prints, from the same code.
    summary: Vec<String>,
    metrics: &'a Metrics,
    /// Whether the 64-bit or the portable key kernels ran. (The adapter's name is the
    /// page's to read: wgpu leaves it empty on WebGPU.)
    key_kernels: &'static str,
    /// Tracked camera positions `[stamp, x, y, z]` (world frame, metres).
    estimate: Vec<[f64; 4]>,
    /// The same, moved by the rigid alignment of the aligned ATE (`eval::align_rigid` over
    /// the pairs `eval::ate` uses) into the ground truth's frame; empty without ground
    /// truth. The run's own world frame is its first camera's, not the dataset's.
    estimate_aligned: Vec<[f64; 4]>,
    /// Ground-truth camera positions `[stamp, x, y, z]` of the run's frames.
    ground_truth: Vec<[f64; 4]>,
    /// Pipeline milliseconds per frame, in order.
    frame_ms: Vec<f64>,
    render_width: u32,
    render_height: u32,
    /// Which renderer drew the picture (`gpu`).
    render_backend: &'static str,
}

/// Runs dense SLAM over frames `first..=last` (a negative `first`: the command line's
/// default, the first frame with ground truth; a negative `last`: the last frame) of the files given by [`add_file`] under
/// `assets/icl_living_room_kt2` with the default parameters of `wgslam run` (the robust
/// profile, tracked poses) on the WebGPU adapter. Returns 0 on success, 1 on an error
/// ([`last_error`]). Must be called through `WebAssembly.promising` (it suspends while the
/// GPU works).
#[no_mangle]
pub extern "C" fn wgslam_web_run(first: i32, last: i32) -> u32 {
    // A panic aborts the module (a trap, which rejects the page's promise) and prints
    // nothing on wasm32: leave its message where the page looks, `globalThis.wgslamPanic`.
    std::panic::set_hook(Box::new(|info| {
        let _ = js_sys::Reflect::set(
            &js_sys::global(),
            &"wgslamPanic".into(),
            &info.to_string().into(),
        );
    }));
    // Earlier results go, so a failed run never shows a previous run's numbers.
    STATE.with_borrow_mut(|s| {
        s.result = None;
        s.render = None;
        s.error = None;
    });
    let frame = |i: i32| usize::try_from(i).ok();
    match run(frame(first), frame(last)) {
        Ok((json, rgba)) => {
            STATE.with_borrow_mut(|s| {
                s.result = Some(json);
                s.render = Some(rgba);
            });
            0
        }
        Err(e) => {
            STATE.with_borrow_mut(|s| s.error = Some(e.to_string()));
            1
        }
    }
}

/// The root the page's files are under: the bundled sequence's path in the repository, so
/// `metrics.dataset` reads as the command line's.
const ROOT: &str = "assets/icl_living_room_kt2";

fn run(first: Option<usize>, last: Option<usize>) -> Result<(String, Vec<u8>)> {
    // The files stay in the state (a later run needs them again); the sequence gets a copy.
    let files = STATE.with_borrow(|s| s.files.clone());
    let seq = open_in_memory(Path::new(ROOT), files, DEFAULT_MAX_TIME_DIFF)?;
    let first = first.unwrap_or_else(|| seq.default_first_frame());
    let last = last.unwrap_or(seq.len() - 1);
    let range = seq.select(first, last)?;
    let total = range.clone().count();
    // The browser's own adapter and limits: features the adapter lacks (64-bit atomics
    // everywhere today) select the portable kernels.
    let ctx = GpuContext::with_options(DeviceOptions::default())?;
    let key_kernels = if ctx.has_int64_atomics() {
        "64-bit"
    } else {
        "portable 32-bit"
    };
    let backend = GpuBackend::new(ctx)?;
    let progress = STATE.with_borrow(|s| s.progress.clone());
    let mut done = 0u32;
    let on_frame = |f: &FrameOutcome| {
        done += 1;
        if let Some(cb) = &progress {
            let args = js_sys::Array::of5(
                &done.into(),
                &(total as u32).into(),
                &(f.report.surfels as u32).into(),
                &(f.seconds * 1e3).into(),
                &format!("{:?}", f.report.status).into(),
            );
            // A throwing progress callback is the page's bug; it does not stop the run.
            let _ = cb.apply(&JsValue::NULL, &args);
        }
    };
    let params = SlamParams::profile(Profile::Robust);
    let result = run_observed(
        backend,
        &seq,
        range,
        params,
        Decode::BeforeEachFrame,
        on_frame,
        None,
    )?;

    // As `trajectory.tum`: after loop closure when a loop bent it.
    let est = result.trajectory();
    let position = |(stamp, t): &(f64, DMat4)| {
        let p = t.w_axis;
        [*stamp, p.x, p.y, p.z]
    };
    let gt: Vec<[f64; 4]> = result
        .frames
        .iter()
        .filter_map(|f| {
            let g = seq.frames[f.index].gt_cam_to_world?;
            Some(position(&(f.timestamp, g)))
        })
        .collect();

    let gt_poses = seq.ground_truth();
    let pairs = crate::eval::associate(&est, &gt_poses, crate::eval::DEFAULT_MAX_DT);
    let estimate_aligned = if pairs.is_empty() {
        Vec::new()
    } else {
        let e: Vec<_> = pairs
            .iter()
            .map(|&(i, _)| est[i].1.w_axis.truncate())
            .collect();
        let g: Vec<_> = pairs
            .iter()
            .map(|&(_, j)| gt_poses[j].1.w_axis.truncate())
            .collect();
        let t_est_to_gt = crate::eval::align_rigid(&e, &g)?;
        est.iter()
            .map(|(stamp, t)| position(&(*stamp, t_est_to_gt * *t)))
            .collect()
    };

    // The map from the default viewpoint of `map_color.png`, by the GPU renderer on a
    // device of its own (the run's went with its backend).
    let (w, h) = DEFAULT_SIZE;
    let rgba = if result.map.is_empty() {
        vec![255; (w * h * 4) as usize]
    } else {
        let ctx = GpuContext::with_options(DeviceOptions::default())?;
        let kernels = GpuRenderer::new(&ctx)?;
        let renderer = RenderBackend::Gpu {
            ctx: &ctx,
            kernels: &kernels,
        };
        let camera = overview_camera(&result.map, &est, &seq.intrinsics, DEFAULT_SIZE)?;
        let map_cloud = MapCloud::new(&result.map);
        let image = renderer.render(
            &map_cloud.cloud(),
            &camera,
            View::Color,
            &RenderSettings::default(),
        )?;
        image
            .pixels()
            .flat_map(|p| [p.0[0], p.0[1], p.0[2], 255])
            .collect()
    };

    let out = WebResult {
        summary: summary_lines(&result.metrics),
        metrics: &result.metrics,
        key_kernels,
        estimate: est.iter().map(position).collect(),
        estimate_aligned,
        ground_truth: gt,
        frame_ms: result.frames.iter().map(|f| f.seconds * 1e3).collect(),
        render_width: w,
        render_height: h,
        render_backend: "gpu",
    };
    let json = serde_json::to_string(&out)
        .map_err(|e| crate::Error::encode("the page's result".to_string(), e))?;
    Ok((json, rgba))
}
