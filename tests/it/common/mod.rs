//! Shared helpers for the integration tests: running the executable ([`cli`]), the harness that shows a skipped test as
//! ignored with its reason ([`harness`]), naga checks of WGSL ([`wgsl`]), raw bundled
//! frames and ground truth ([`frames`]), the bundled LiDAR pair and nearest-neighbour
//! kernel inputs ([`scans`]), a run's ATE ([`ate_m`]), and where the data is. `tests/it/main.rs` declares it (`mod common;`);
//! each test module takes it with `use crate::common;` and uses what it needs.

#![allow(dead_code)]

pub mod cli;
pub mod frames;
pub mod harness;
pub mod scans;
pub mod wgsl;

use std::path::{Path, PathBuf};

use wgslam::slam::backend::{Backend, PreprocessSteps};
use wgslam::slam::pipeline::Slam;

/// ATE bar over noisy ICL-NUIM frames (bundled or shared), metres: the tracking issues'
/// 10 mm (measured 2.3-6.7 mm).
pub const ATE_NOISY_MAX_M: f64 = 0.010;
/// 7-Scenes (real Kinect v1) against its KinectFusion reference poses, which are good to
/// 1-2 cm, metres: measured 18-21 mm on frames 0..299 and the splices, both backends, with
/// and without loop closure.
pub const ATE_7SCENES_MAX_M: f64 = 0.030;
/// Closing loops may move the ATE by noise either way; it must not grow by more than this
/// (metres): a millimetre, a tenth of the noisy bar.
pub const LOOP_ATE_SLACK_M: f64 = 0.001;

/// `assets/NAME` in the clone.
pub fn asset(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(name)
}

/// The JSON file at `path` (a run's metrics.json, a bench's or batch's report).
pub fn read_json(path: impl AsRef<Path>) -> serde_json::Value {
    let text = std::fs::read_to_string(path.as_ref()).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// project_model's twin over the whole of `map` (one chunk) at `proj`, culled by `bounds`
/// (per block its box; [`whole_map_bounds`](wgslam::cpu::block_bounds::whole_map_bounds)
/// when `None`), each pixel's key written to `keys` (a `u64` slice, or a key pass).
pub fn project_map(
    proj: &wgslam::layout::ProjectParams,
    map: &wgslam::layout::map::SurfelMap,
    bounds: Option<&[[u32; 4]]>,
    keys: wgslam::cpu::binding::Binding,
) {
    use wgslam::cpu::{binding::Binding, block_bounds, project_model};
    let whole = wgslam::layout::MapChunk::whole(map.len());
    let own_bounds;
    let bounds = match bounds {
        Some(b) => b,
        None => {
            own_bounds = block_bounds::whole_map_bounds(&map.position_weight);
            &own_bounds
        }
    };
    project_model::project_model(&mut [
        Binding::of(proj),
        Binding::of(&whole),
        Binding::read(bounds),
        Binding::read(&map.position_weight),
        keys,
    ]);
}

/// The bundled sequence `assets/NAME`, opened with the default options.
pub fn open_asset(name: &str) -> wgslam::dataset::Sequence {
    let options = wgslam::dataset::SequenceOptions::default();
    wgslam::dataset::open(&asset(name), &options).unwrap()
}

/// The bundled real frames (always present in a clone).
pub fn bundled_icl() -> PathBuf {
    asset("icl_living_room_kt2")
}

/// The same 24 frames with Kinect-like depth noise (depth only; the colour images are the
/// clean subset's, which are byte-identical).
pub fn bundled_icl_noisy() -> PathBuf {
    asset("icl_living_room_kt2_noisy")
}

/// The full 210-frame ICL-NUIM sequence inside the shared data directory that
/// [`harness::shared`] tests receive (`../shared/data`).
pub fn shared_icl(data: &Path) -> PathBuf {
    data.join("icl_living_room_kt2")
}

/// The full noisy sequence (frames 0..209) inside the shared data directory.
pub fn shared_icl_noisy(data: &Path) -> PathBuf {
    data.join("icl_living_room_kt2_noisy")
}

/// A run of frames `first..=last` of `seq` on the CPU reference backend with `params`,
/// validated first (a test's parameters are valid: panics if not).
pub fn run_cpu(
    seq: &wgslam::Sequence,
    first: usize,
    last: usize,
    params: wgslam::SlamParams,
) -> wgslam::Result<wgslam::tools::run::RunResult> {
    let params = params.validate().expect("a test's parameters are valid");
    let backend = wgslam::slam::cpu_backend::CpuBackend::new();
    wgslam::tools::run::run(backend, seq, first, last, params, |_| {})
}

/// A run's ATE RMSE after alignment, metres (the run must have ground truth).
pub fn ate_m(r: &wgslam::tools::run::RunResult) -> f64 {
    r.metrics
        .accuracy
        .as_ref()
        .expect("ground truth")
        .ate_rmse_aligned_m
}

/// A fresh empty directory under the system temp dir, `wgslam-test-PID-NAME`, removed
/// when the test that made it finishes (see [`Scratch`]).
pub fn temp_dir(name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("wgslam-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create temp dir");
    Scratch(d)
}

/// A test's scratch directory ([`temp_dir`]): used as a `Path`, removed on drop unless the
/// test is panicking, so a failure leaves its files to look at and a pass leaves nothing
/// (each full `cargo test` used to leave about 45 MB under /tmp).
pub struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// `s`'s `preprocess` steps at level 0 only (no pyramid), with the bilateral filter as its
/// parameters say.
pub fn level_0<B: Backend>(s: &Slam<B>) -> PreprocessSteps {
    PreprocessSteps {
        pyramid: vec![],
        ..s.preprocess_steps()
    }
}

/// [`level_0`] without the bilateral filter: `depth_to_vertex` and `vertex_to_normal` alone.
pub fn unfiltered_level_0<B: Backend>(s: &Slam<B>) -> PreprocessSteps {
    PreprocessSteps {
        bilateral: None,
        ..level_0(s)
    }
}
