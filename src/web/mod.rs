//! The browser build's entry points (wasm32 only, `deploy/web`): the page lists a dataset
//! folder's files (picked, dropped or the bundled frames), runs dense SLAM over them on the
//! GPU through WebGPU while showing each input frame and the growing map, and then offers
//! what `wgslam run` prints (the same [`summary_lines`] over the same [`Metrics`]) and
//! writes (the same bytes, [`output_bytes`]), a mesh, and the map from any viewpoint.
//!
//! Not a second pipeline: the folder is opened by [`dataset::open_with`] (layout detection
//! and every reader, over the page's files: `files.rs`), the run is [`run_observed`] on a
//! [`GpuBackend`], as on the command line. What differs is how waits happen (see
//! [`crate::gpu::wait`]): every GPU wait and every file read suspends the WebAssembly stack
//! (through JSPI, or through Binaryen's asyncify where the browser lacks JSPI), so the entry
//! points that wait, [`wgslam_web_run`] and [`wgslam_web_render`], are plain WebAssembly
//! exports (no wasm-bindgen wrapper) that the page calls through its suspending wrapper
//! (`call` in `deploy/web/suspend.js`), one at a time. The others return at once;
//! [`wgslam_suspend_stack`] gives the asyncify build its buffer.
//!
//! Calling order: [`clear_files`], [`add_file`] for every file of the folder, [`set_reader`],
//! [`configure`]; optionally [`set_progress`] and [`set_frame_view`]; `wgslam_web_run`
//! (awaited); then [`result_json`], [`download`], and [`set_orbit`] with
//! `wgslam_web_render` (awaited) and [`render_rgba`] as the user turns the view, or
//! [`last_error`] when a call returned non-zero.

mod files;
mod view;

use std::cell::RefCell;
use std::path::PathBuf;
use std::sync::Arc;

use glam::DMat4;
use serde::Serialize;
use wasm_bindgen::prelude::*;

use crate::dataset::{self, Sequence, SequenceOptions};
use crate::geometry::camera::{Distortion, Intrinsics};
use crate::gpu::context::{DeviceOptions, GpuContext};
use crate::gpu::GpuBackend;
use crate::layout::map::SurfelMap;
use crate::render::orbit::Orbit;
use crate::slam::params::{Profile, SlamParams};
use crate::tools::run::{
    output_bytes, run_observed, summary_lines, Decode, FrameOutcome, Metrics, RunResult,
};
use crate::Result;
use files::PageFiles;
use view::{render_map, status_words, LiveView, Shown, VIEW_SIZE};

/// What the page gave and what the last run left.
struct State {
    files: PageFiles,
    root: PathBuf,
    profile: Profile,
    /// The camera chosen on the page, in place of the folder's (`None`: the folder's
    /// `camera.json` or its layout's).
    camera: Option<PageCamera>,
    progress: Option<js_sys::Function>,
    frame_view: Option<js_sys::Function>,
    orbit: Orbit,
    result: Option<String>,
    /// The last map picture, RGBA8 of [`VIEW_SIZE`].
    render: Option<Vec<u8>>,
    /// The last input frame's colour and depth pictures (its map picture is `render`).
    frame: Option<Shown>,
    /// The finished run's output files, the map and what its view needs.
    outputs: Vec<(&'static str, Vec<u8>)>,
    map: Option<SurfelMap>,
    trajectory: Vec<(f64, DMat4)>,
    intrinsics: Option<Intrinsics>,
    error: Option<String>,
}

thread_local! {
    static STATE: RefCell<State> = RefCell::new(State {
        files: PageFiles::default(),
        root: PathBuf::new(),
        profile: Profile::Robust,
        camera: None,
        progress: None,
        frame_view: None,
        orbit: Orbit::default(),
        result: None,
        render: None,
        frame: None,
        outputs: Vec::new(),
        map: None,
        trajectory: Vec::new(),
        intrinsics: None,
        error: None,
    });
}

/// Forgets the listed files (before listing another folder's).
#[wasm_bindgen]
pub fn clear_files() {
    STATE.with_borrow_mut(|s| s.files = PageFiles::default());
}

/// Lists one file of the dataset folder: `path` as the folder's name joined with the path
/// inside it (`my_scan/rgb/0.png`), `bytes` its size. Its contents are read only when the
/// run needs them, through the reader of [`set_reader`].
#[wasm_bindgen]
pub fn add_file(path: &str, bytes: f64) {
    STATE.with_borrow_mut(|s| s.files.list.insert(path, bytes as u64));
}

/// Sets the function that reads a listed file: `read(path) -> Promise<Uint8Array>`.
#[wasm_bindgen]
pub fn set_reader(read: js_sys::Function) {
    files::set_reader(read);
}

/// Sets the folder to open (`root`, as the listed paths start), the parameter profile
/// (`robust` or `assignment`, as `wgslam run --profile`) and the camera (as `--camera` or
/// `--intrinsics`: `page_camera`); an error message for an unknown profile or camera,
/// else `undefined`.
#[wasm_bindgen]
pub fn configure(root: &str, profile: &str, camera: &str) -> Option<String> {
    let parsed: std::result::Result<Profile, _> = serde_json::from_value(profile.into());
    let Ok(p) = parsed else {
        return Some(format!("unknown profile {profile:?}: robust or assignment"));
    };
    let camera = match page_camera(camera) {
        Ok(c) => c,
        Err(why) => return Some(why),
    };
    STATE.with_borrow_mut(|s| {
        s.root = PathBuf::from(root);
        s.profile = p;
        s.camera = camera;
    });
    None
}

/// A camera chosen on the page: its pinhole values and its lens, if it has one.
type PageCamera = (Intrinsics, Option<Distortion>);

/// The page's camera setting: empty for the folder's own (`camera.json` or the layout's
/// files), a preset's name (`fr1`, `fr2`, `fr3`, `icl`, as `--camera`), or four numbers
/// `fx,fy,cx,cy` in pixels of 640x480 frames (as `--intrinsics` without `--camera`); with
/// a preset, its lens ([`Distortion::preset`]).
fn page_camera(setting: &str) -> std::result::Result<Option<PageCamera>, String> {
    let setting = setting.trim();
    if setting.is_empty() {
        return Ok(None);
    }
    if let Some(preset) = Intrinsics::preset(setting) {
        return Ok(Some((preset, Distortion::preset(setting))));
    }
    Intrinsics::ICL_NUIM
        .with_focal_centre(setting)
        .map(|k| Some((k, None)))
        .map_err(|why| {
            format!("camera {setting:?}: a preset (fr1, fr2, fr3, icl) or the four numbers; {why}")
        })
}

/// Sets the function called after each frame with `(frames done, frames in all, map
/// points, the frame's pipeline milliseconds, what happened to the frame in words)`.
#[wasm_bindgen]
pub fn set_progress(callback: js_sys::Function) {
    STATE.with_borrow_mut(|s| s.progress = Some(callback));
}

/// Sets the function called after each frame with `(has a new map picture)`: the frame's
/// pictures ([`frame_rgba`], [`depth_rgba`], [`frame_width`], [`frame_height`]) and the
/// camera path ([`live_path`]) and, when the argument is true, the map's ([`render_rgba`])
/// are new.
#[wasm_bindgen]
pub fn set_frame_view(callback: js_sys::Function) {
    STATE.with_borrow_mut(|s| s.frame_view = Some(callback));
}

/// Sets the view of the map: turn and tilt (radians), zoom (distance multiple) and pan
/// (distance units), see [`Orbit`]. Used by the next picture (during a run, the next map
/// download's; after it, [`wgslam_web_render`]'s).
#[wasm_bindgen]
pub fn set_orbit(yaw_rad: f64, pitch_rad: f64, zoom: f64, pan_x: f64, pan_y: f64) {
    STATE.with_borrow_mut(|s| {
        s.orbit = Orbit {
            yaw_rad,
            pitch_rad,
            zoom,
            pan: [pan_x, pan_y],
        }
    });
}

/// The last run's results as JSON (the private `WebResult`), or `undefined`.
#[wasm_bindgen]
pub fn result_json() -> Option<String> {
    STATE.with_borrow(|s| s.result.clone())
}

/// The last map picture as RGBA8, [`view_width`] x [`view_height`], row-major.
#[wasm_bindgen]
pub fn render_rgba() -> Option<Vec<u8>> {
    STATE.with_borrow(|s| s.render.clone())
}

/// The map picture's width, pixels (fixed).
#[wasm_bindgen]
pub fn view_width() -> u32 {
    VIEW_SIZE.0
}

/// The map picture's height, pixels (fixed).
#[wasm_bindgen]
pub fn view_height() -> u32 {
    VIEW_SIZE.1
}

/// The last input frame's colour as RGBA8, [`frame_width`] x [`frame_height`].
#[wasm_bindgen]
pub fn frame_rgba() -> Option<Vec<u8>> {
    STATE.with_borrow(|s| s.frame.as_ref().map(|f| f.color.clone()))
}

/// The last input frame's depth as grey RGBA8 (near light, no reading dark red).
#[wasm_bindgen]
pub fn depth_rgba() -> Option<Vec<u8>> {
    STATE.with_borrow(|s| s.frame.as_ref().map(|f| f.depth.clone()))
}

/// The tracked camera positions of the run so far, `stamp, x, y, z` after one another (the
/// run's world frame, metres); empty before the first frame.
#[wasm_bindgen]
pub fn live_path() -> Vec<f64> {
    STATE.with_borrow(|s| s.frame.as_ref().map(|f| f.path.clone()).unwrap_or_default())
}

/// The last input frame's width, pixels (0 before one).
#[wasm_bindgen]
pub fn frame_width() -> u32 {
    STATE.with_borrow(|s| s.frame.as_ref().map_or(0, |f| f.size.0))
}

/// The last input frame's height, pixels (0 before one).
#[wasm_bindgen]
pub fn frame_height() -> u32 {
    STATE.with_borrow(|s| s.frame.as_ref().map_or(0, |f| f.size.1))
}

/// One file of the finished run: `trajectory.tum`, `trajectory_odometry.tum`, `map.ply`,
/// `metrics.json`, `frames.json` (the bytes `wgslam run` writes), or `mesh.ply` (the map's
/// mesh with `wgslam mesh`'s defaults, made now); `undefined` for another name, before a
/// run, or when the mesh fails ([`last_error`]).
#[wasm_bindgen]
pub fn download(name: &str) -> Option<Vec<u8>> {
    if name == "mesh.ply" {
        let map = STATE.with_borrow(|s| s.map.clone())?;
        return match crate::mesh::mesh_from_map(&map, &crate::mesh::MeshParams::default()) {
            Ok(mesh) => Some(crate::mesh::write::ply_bytes(&mesh)),
            Err(e) => {
                STATE.with_borrow_mut(|s| s.error = Some(e.to_string()));
                None
            }
        };
    }
    STATE.with_borrow(|s| {
        s.outputs
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, b)| b.clone())
    })
}

/// Why the last call failed, or `undefined`.
#[wasm_bindgen]
pub fn last_error() -> Option<String> {
    STATE.with_borrow(|s| s.error.clone())
}

/// Everything the page shows of a run.
#[derive(Serialize)]
struct WebResult<'a> {
    /// The lines `wgslam run` prints, from the same code.
    summary: Vec<String>,
    /// What opening decided on the user's behalf, as `wgslam run` prints it.
    notes: &'a [String],
    metrics: &'a Metrics,
    /// The dataset's layout as users know it.
    layout: &'static str,
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
    /// The names [`download`] offers.
    downloads: Vec<&'static str>,
}

/// Runs dense SLAM over frames `first..=last` (a negative `first`: the command line's
/// default, the first frame with ground truth; a negative `last`: the last frame) of the
/// folder [`configure`] named, with its profile's parameters and tracked poses, on the
/// WebGPU adapter. Returns 0 on success, 1 on an error ([`last_error`]). Must be called
/// through the page's suspending wrapper (it suspends while the GPU works and files are
/// read).
#[no_mangle]
pub extern "C" fn wgslam_web_run(first: i32, last: i32) -> u32 {
    set_panic_hook();
    // Earlier results go, so a failed run never shows a previous run's numbers.
    STATE.with_borrow_mut(|s| {
        s.result = None;
        s.render = None;
        s.frame = None;
        s.outputs.clear();
        s.map = None;
        s.trajectory.clear();
        s.error = None;
    });
    let frame = |i: i32| usize::try_from(i).ok();
    finish(run(frame(first), frame(last)))
}

/// Draws the finished run's map from the orbit of [`set_orbit`] into [`render_rgba`].
/// Returns 0 on success, 1 on an error or without a finished run ([`last_error`]). Must be
/// called through the page's suspending wrapper, never while [`wgslam_web_run`] runs.
#[no_mangle]
pub extern "C" fn wgslam_web_render() -> u32 {
    set_panic_hook();
    let (map, trajectory, intrinsics, orbit) =
        STATE.with_borrow(|s| (s.map.clone(), s.trajectory.clone(), s.intrinsics, s.orbit));
    let (Some(map), Some(intrinsics)) = (map, intrinsics) else {
        return finish(Err(crate::Error::Argument(
            "no finished run to draw".into(),
        )));
    };
    // No borrow of the state is held while the GPU works (the page may set the orbit then).
    let picture = render_map(&map, &trajectory, &intrinsics, &orbit);
    finish(picture.map(|p| STATE.with_borrow_mut(|s| s.render = Some(p))))
}

/// 0 for `Ok`; 1 with the error left for [`last_error`].
fn finish(result: Result<()>) -> u32 {
    match result {
        Ok(()) => 0,
        Err(e) => {
            STATE.with_borrow_mut(|s| s.error = Some(e.to_string()));
            1
        }
    }
}

/// A panic aborts the module (a trap, which rejects the page's promise) and prints nothing
/// on wasm32: its message goes where the page looks, `globalThis.wgslamPanic`.
/// Room for `bytes` bytes (8-byte aligned, zeroed, never freed) in the module's memory, at
/// the address returned: the asyncify build's buffer, where a suspended stack's functions
/// keep their locals until it resumes (`deploy/web/suspend.js` asks for it once). Returns 0
/// when `bytes` is 0.
#[no_mangle]
pub extern "C" fn wgslam_suspend_stack(bytes: u32) -> u32 {
    if bytes == 0 {
        return 0;
    }
    let words = vec![0u64; bytes.div_ceil(8) as usize];
    // wasm32: an address is 32 bits.
    Vec::leak(words).as_mut_ptr() as usize as u32
}

fn set_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let _ = js_sys::Reflect::set(
            &js_sys::global(),
            &"wgslamPanic".into(),
            &info.to_string().into(),
        );
    }));
}

/// Runs dense SLAM over frames `first..=last` of the page's files (by default from the
/// first frame with ground truth to the last) on the browser's GPU, showing each frame
/// through the page's callbacks, and keeps the result (see [`keep_result`]).
fn run(first: Option<usize>, last: Option<usize>) -> Result<()> {
    let (files, root, profile, camera) =
        STATE.with_borrow(|s| (s.files.clone(), s.root.clone(), s.profile, s.camera));
    if files.list.is_empty() {
        return Err(crate::Error::Argument(
            "no files: pick or drop a dataset folder first".into(),
        ));
    }
    let opts = SequenceOptions {
        interface: dataset::Interface::Page,
        intrinsics: camera.map(|c| c.0),
        distortion: camera.and_then(|c| c.1),
        ..SequenceOptions::default()
    };
    let mut seq = dataset::open_with(Arc::new(files), &root, &opts)?;
    let first = first.unwrap_or_else(|| seq.default_first_frame());
    let last = last.unwrap_or(seq.len() - 1);
    let range = seq.select(first, last)?;
    seq.notes.extend(seq.jump_note(range.clone()));
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
    let (progress, frame_view) = STATE.with_borrow(|s| (s.progress.clone(), s.frame_view.clone()));
    let mut done = 0u32;
    let on_frame = |f: &FrameOutcome| {
        done += 1;
        if let Some(cb) = &progress {
            let args = js_sys::Array::of5(
                &done.into(),
                &(total as u32).into(),
                &(f.report.surfels_before as u32).into(),
                &(f.seconds * 1e3).into(),
                &status_words(&f.report.status).into(),
            );
            // A throwing callback is the page's bug; it does not stop the run.
            let _ = cb.apply(&JsValue::NULL, &args);
        }
    };
    let orbit = || STATE.with_borrow(|s| s.orbit);
    let show = |mut shown: Shown| {
        let picture = shown.map.take();
        let new_map = picture.is_some();
        STATE.with_borrow_mut(|s| {
            s.frame = Some(shown);
            if picture.is_some() {
                s.render = picture;
            }
        });
        if let Some(cb) = &frame_view {
            let _ = cb.call1(&JsValue::NULL, &new_map.into());
        }
    };
    let mut live = LiveView {
        first,
        last,
        intrinsics: seq.intrinsics,
        depth_scale: seq.depth_scale,
        trajectory: Vec::new(),
        map: None,
        orbit: &orbit,
        show: &show,
    };
    // The page's one validation of the parameters it runs with.
    let params = SlamParams::profile(profile).validate()?;
    let result = run_observed(
        backend,
        &seq,
        range,
        params,
        Decode::BeforeEachFrame,
        on_frame,
        Some(&mut live),
    )?;

    keep_result(result, &seq, key_kernels)
}

/// Keeps a finished run in the state: what the page shows of it ([`WebResult`], as JSON),
/// its output files, its map and trajectory for [`wgslam_web_render`]. `key_kernels`:
/// which key kernels ran.
fn keep_result(result: RunResult, seq: &Sequence, key_kernels: &'static str) -> Result<()> {
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
    let estimate_aligned = aligned(&est, &seq.ground_truth())?
        .iter()
        .map(position)
        .collect();
    let outputs = output_bytes(&result)?;
    let mut downloads: Vec<&'static str> = outputs.iter().map(|(n, _)| *n).collect();
    downloads.push("mesh.ply");
    let out = WebResult {
        summary: summary_lines(&result.metrics),
        notes: &seq.notes,
        metrics: &result.metrics,
        layout: seq.layout.name(),
        key_kernels,
        estimate: est.iter().map(position).collect(),
        estimate_aligned,
        ground_truth: gt,
        downloads,
    };
    let json = serde_json::to_string(&out)
        .map_err(|e| crate::Error::encode("the page's result".to_string(), e))?;
    STATE.with_borrow_mut(|s| {
        s.result = Some(json);
        s.outputs = outputs;
        s.map = Some(result.map);
        s.trajectory = est;
        s.intrinsics = Some(seq.intrinsics);
    });
    Ok(())
}

/// `est` moved by the rigid alignment of the aligned ATE into the ground truth's frame
/// (`eval::align_rigid` over the pairs `eval::ate` uses); empty without pairs.
fn aligned(est: &[(f64, DMat4)], gt: &[(f64, DMat4)]) -> Result<Vec<(f64, DMat4)>> {
    let (e, g) = crate::eval::associated_positions(est, gt, crate::eval::DEFAULT_MAX_DT);
    if e.is_empty() {
        return Ok(Vec::new());
    }
    let t_est_to_gt = crate::eval::align_rigid(&e, &g)?;
    Ok(est.iter().map(|(s, t)| (*s, t_est_to_gt * *t)).collect())
}
