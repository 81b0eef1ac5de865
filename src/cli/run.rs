//! `wgslam run`: dense SLAM over a sequence, its outputs written and summarised.

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};

use super::pipeline_args::{default_first_frame, PipelineArgs};
use crate::batch::in_process::{Embedded, RunHooks};
use crate::dataset;
use crate::io::outputs::OutputSet;
use crate::layout::map::SurfelMap;
use crate::slam::any_backend::{self, BackendChoice};
use crate::slam::params::{resolution, PoseSource};
use crate::tools::run;
use crate::{Error, Result};

/// Pose source for `run`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PosesChoice {
    /// Frame-to-model ICP tracking.
    Track,
    /// Ground-truth poses, no tracking (fusion only).
    Gt,
}

#[derive(Debug, Args)]
pub struct RunArgs {
    /// Implementation: auto, cpu or gpu.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Inclusive frame range "A..B" by position in the sequence (default: all frames from
    /// the first with ground truth).
    #[arg(long)]
    pub frames: Option<String>,
    /// Poses from tracking or from ground truth.
    #[arg(long, value_enum, default_value_t = PosesChoice::Track)]
    pub poses: PosesChoice,
    /// Play the frame range forwards, backwards, forwards ... for this many frames (a long
    /// sequence that revisits the same scene; stamps become positions 0, 1, ...).
    #[arg(long, value_name = "FRAMES")]
    pub revisit: Option<usize>,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Stop with an error when the map passes this many surfels (about 92 bytes each in
    /// memory and 31 in map.ply: the default is ~1.8 GB and a 620 MB map.ply). The
    /// assignment profile never removes surfels, so a long revisiting run grows without
    /// end (1000 frames made 75 M).
    #[arg(long, value_name = "SURFELS", default_value_t = DEFAULT_MAX_SURFELS)]
    pub max_surfels: usize,
    /// (for `wgslam batch`) Print `progress DONE TOTAL` on stdout after every frame.
    #[arg(long, hide = true)]
    pub progress_lines: bool,
    /// Also write a Rerun recording of the run here (camera path, ground truth, colour and
    /// depth images, the map every few frames; open it with `rerun FILE.rrd`). Needs a
    /// binary built with `--features rerun`; without it this flag fails with a message.
    #[arg(long, value_name = "FILE.rrd")]
    pub rerun: Option<PathBuf>,
    /// With --rerun: log the map (at most 100k of its surfels) after every N-th frame, and
    /// after the last.
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub rerun_map_every: usize,
    /// Also write mesh.ply: a triangle mesh of the map with vertex colours (a TSDF of the
    /// surfels at 1 cm voxels, surface nets; `wgslam mesh` makes one from a map.ply).
    #[arg(long)]
    pub mesh: bool,
    #[command(flatten)]
    pub decode: DecodeArgs,
    // The sequence, a parameter file and the parameters (last, so their help heading
    // follows this command's own options).
    #[command(flatten)]
    pub pipeline: PipelineArgs,
}

/// How the frame loop's frames are decoded: `--decode-threads`, of `run` (and so of
/// `batch`'s jobs) and `bench`. Not a pipeline parameter: it changes no output, so it is
/// not a key of parameter files.
#[derive(Debug, Clone, Copy, Default, Args)]
pub struct DecodeArgs {
    /// Threads that load and decode frames ahead of the frame loop (PNG/JPEG; frames still
    /// reach the pipeline in order; default: one per core); 0 decodes each frame on the
    /// loop's thread before it.
    #[arg(long, value_name = "N")]
    pub decode_threads: Option<usize>,
}

impl DecodeArgs {
    /// Where frames are decoded.
    pub fn decode(&self) -> run::Decode {
        self.decode_threads
            .map_or_else(run::Decode::ahead_on_every_core, run::Decode::with_threads)
    }

    /// The flag as a child process's arguments (none when unset).
    pub fn child_args(&self) -> Vec<String> {
        self.decode_threads
            .map(|n| vec!["--decode-threads".to_string(), n.to_string()])
            .unwrap_or_default()
    }
}

/// The mesh `run --mesh` writes beside map.ply.
pub const MESH_FILE: &str = "mesh.ply";

/// Meshes `map` into `path` (`run --mesh`) and says its size, time and accuracy.
fn write_run_mesh(path: &Path, map: &SurfelMap, say: &dyn Fn(&str)) -> Result<()> {
    let start = web_time::Instant::now();
    let params = crate::mesh::MeshParams::default();
    let surfels = crate::mesh::MapSurfels::new(map);
    // Over the cap the run's other outputs still count: a note, and no mesh.ply.
    if let Err(over) = crate::mesh::check_volume(&surfels.surfels(), &params) {
        say(&format!(
            "note: --mesh: {}",
            over.describe(
                map.len(),
                params.voxel_m,
                "no mesh.ply written; mesh map.ply with `wgslam mesh --max-memory-mib` or a \
                 coarser --voxel"
            )
        ));
        return Ok(());
    }
    let mesh = crate::mesh::mesh_from_surfels(&surfels.surfels(), &params)?;
    say(&format!(
        "mesh: {} vertices, {} triangles in {:.2} s",
        mesh.positions.len(),
        mesh.triangles.len(),
        start.elapsed().as_secs_f64()
    ));
    if mesh.is_empty() {
        say("note: the map makes no surface; mesh.ply has no triangle");
    } else {
        let a = crate::mesh::accuracy::measure(
            &mesh,
            &surfels.positions,
            Some(&surfels.normals),
            super::mesh::COVERED_WITHIN_MM,
        )?;
        for line in super::mesh::accuracy_lines(&a) {
            say(&line);
        }
    }
    crate::mesh::write::write_mesh(path, &mesh)
}

/// Default of `run --max-surfels`.
pub const DEFAULT_MAX_SURFELS: usize = 20_000_000;

/// Checks the map's size at every frame (the map it was tracked against) against
/// `--max-surfels`, then shows the frame to the recording when there is one.
struct MapCap<'a> {
    max_surfels: usize,
    recording: Option<&'a mut dyn run::FrameObserver>,
    /// A batch's hooks when the run is embedded in one: their `stop` ends the run.
    hooks: Option<&'a RunHooks<'a>>,
}

impl run::FrameObserver for MapCap<'_> {
    fn wants_map(&mut self, index: usize) -> bool {
        self.recording
            .as_deref_mut()
            .is_some_and(|r| r.wants_map(index))
    }

    fn frame(
        &mut self,
        raw: &dataset::RawFrame,
        outcome: &run::FrameOutcome,
        map: Option<&crate::layout::map::SurfelMap>,
    ) -> Result<()> {
        if self.hooks.is_some_and(|h| (h.stop)()) {
            return Err(Error::Interrupted(format!(
                "stopped after frame {}; nothing was written",
                outcome.index
            )));
        }
        // The map this frame met: the last frame's fusion's (`surfels_before`).
        let when = format!("at frame {}", outcome.index);
        check_map_cap(outcome.report.surfels_before, self.max_surfels, &when)?;
        match self.recording.as_deref_mut() {
            Some(r) => r.frame(raw, outcome, map),
            None => Ok(()),
        }
    }
}

/// [`Error::Capacity`] when a map of `surfels` surfels, the one `when` (`at frame N`,
/// `after the last frame`), passes `--max-surfels`.
fn check_map_cap(surfels: usize, max_surfels: usize, when: &str) -> Result<()> {
    if surfels <= max_surfels {
        return Ok(());
    }
    Err(Error::Capacity(format!(
        "{when} the map held {surfels} surfels, more than --max-surfels {max_surfels} (about \
         {:.0} MB in memory); nothing was written. Raise --max-surfels, run fewer frames, or \
         use --profile robust, which removes unstable surfels",
        surfels as f64 * SURFEL_BYTES_IN_MEMORY / 1e6
    )))
}

/// Memory per surfel, measured: 75 M surfels took 6.9 GB.
const SURFEL_BYTES_IN_MEMORY: f64 = 92.0;

/// A progress bar on stderr, hidden when stderr is not a terminal.
fn progress_bar(len: usize) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} frames {msg}",
        )
        .expect("static template")
        .progress_chars("=> "),
    );
    bar
}

/// Runs `wgslam run`.
pub fn execute(a: RunArgs) -> Result<()> {
    execute_in(a, None)
}

/// Runs `wgslam run`, in a batch's process when `embedded` says so: on its backend, with
/// no progress bar, every line it would print handed to its hooks, and no peak memory in
/// `metrics.json` (the process's peak is every concurrent job's).
pub fn execute_in(a: RunArgs, embedded: Option<Embedded>) -> Result<()> {
    let (backend, hooks) = match embedded {
        Some(e) => (Some(e.backend), Some(e.hooks)),
        None => (None, None),
    };
    let hooks = hooks.as_ref();
    let say = |line: &str| match hooks {
        Some(h) => (h.say)(line),
        None => println!("{line}"),
    };
    let setup = a.pipeline.resolve()?;
    let poses = match a.poses {
        PosesChoice::Track => PoseSource::Track,
        PosesChoice::Gt => PoseSource::GroundTruth,
    };
    let params = setup.slam_params(poses)?;
    let (seq, range) = frames_to_run(&a, setup.open_sequence(&params)?)?;
    let bar = match hooks {
        Some(_) => indicatif::ProgressBar::hidden(),
        None => progress_bar(range.clone().count()),
    };
    let total = range.clone().count();
    let on_frame = |f: &run::FrameOutcome| report_frame(f, &bar, hooks, a.progress_lines, total);
    // The outputs are staged beside --out and moved into it as a set after the run; a bad
    // --out (a file, a folder of other files) fails here, before any frame.
    if a.rerun.is_some() && a.rerun_map_every == 0 {
        return Err(Error::Argument(
            "--rerun-map-every must be at least 1".into(),
        ));
    }
    let rerun_in_out = rerun_in_out(&a);
    let outputs = stage_outputs(&a.out, rerun_in_out.as_deref())?;
    let rerun_path = match &rerun_in_out {
        Some(name) => Some(outputs.dir().join(name)),
        None => a.rerun.clone(),
    };
    let mut recording = open_recording(rerun_path.as_deref(), a.rerun_map_every, &seq, &range)?;
    let backend = match backend {
        Some(b) => b,
        None => any_backend::open(a.backend)?,
    };
    let sets_downsample = setup.set.sets_downsample();
    let (params, downsample_from) =
        resolution::for_backends(params, sets_downsample, &[backend.name()])?;
    let mut result = run::run_observed(
        backend,
        &seq,
        range,
        params,
        a.decode.decode(),
        on_frame,
        Some(&mut MapCap {
            max_surfels: a.max_surfels,
            recording: recording.as_mut().map(|r| r as &mut dyn run::FrameObserver),
            hooks,
        }),
    )?;
    bar.finish_and_clear();
    check_map_cap(result.map.len(), a.max_surfels, "after the last frame")?;
    result.metrics.downsample_from = Some(downsample_from);
    if hooks.is_some() {
        result.metrics.peak_memory_mib = None;
    }
    let pictures = write_staged(&a, outputs.dir(), &result, &seq, &say)?;
    let recorded = recording.map(|r| r.finish(&result.map)).transpose()?;
    let recorded = recorded.map(|p| match &rerun_in_out {
        Some(name) => a.out.join(name),
        None => p,
    });
    outputs.commit()?;
    print_summary(&result.metrics, &a.out, &say);
    for p in pictures.iter().chain(&recorded) {
        say(&format!("wrote {}", p.display()));
    }
    Ok(())
}

/// Shows that frame `f` of `total` is done: on the bar, as a `progress DONE TOTAL` line
/// with `progress_lines`, to a batch's hooks; then logs its events (see [`frame_events`]).
fn report_frame(
    f: &run::FrameOutcome,
    bar: &indicatif::ProgressBar,
    hooks: Option<&RunHooks<'_>>,
    progress_lines: bool,
    total: usize,
) {
    bar.set_message(format!("{} surfels", f.report.surfels_before));
    bar.inc(1);
    if progress_lines {
        use std::io::Write;
        println!("progress {} {total}", bar.position());
        let _ = std::io::stdout().flush();
    }
    if let Some(h) = hooks {
        (h.progress)(bar.position(), total as u64);
    }
    // Every frame without a tracked pose is reported, on a terminal above the bar and
    // in a log (no terminal, the bar hidden) on stderr.
    for line in frame_events(f) {
        if let Some(h) = hooks {
            (h.say)(&line);
        } else if bar.is_hidden() {
            eprintln!("{line}");
        } else {
            bar.println(line);
        }
    }
}

/// The sequence and the frame range the run covers: `--frames` (by default every frame
/// from the first with ground truth), played forwards and backwards for `--revisit` frames
/// when that is given (then a new sequence whose range starts at 0).
fn frames_to_run(
    a: &RunArgs,
    seq: dataset::Sequence,
) -> Result<(dataset::Sequence, RangeInclusive<usize>)> {
    let (first, last) = match &a.frames {
        Some(r) => dataset::parse_range(r)?,
        None => (default_first_frame(&seq), seq.len() - 1),
    };
    let range = seq.select(first, last)?;
    if let Some(note) = seq.jump_note(range.clone()) {
        eprintln!("note: {note}");
    }
    match a.revisit {
        Some(total) => {
            let max = crate::io::input::max_revisit_frames()?;
            if total as u64 > max {
                return Err(Error::Argument(format!(
                    "--revisit {total}: more than {max} frames (WGSLAM_MAX_REVISIT_FRAMES \
                     raises the limit)"
                )));
            }
            let long = seq.revisiting(first, last, total)?;
            Ok((long, 0..=total - 1))
        }
        None => Ok((seq, range)),
    }
}

/// The lines a frame gives the log: each loop closure tried (accepted, and what it moved,
/// or rejected and why), and a lost, relocalised or skipped frame.
fn frame_events(f: &run::FrameOutcome) -> Vec<String> {
    use crate::slam::loops::LoopAction;
    use crate::slam::pipeline::TrackStatus;
    let mut events: Vec<String> = f
        .report
        .loops
        .iter()
        .map(|l| match &l.rejected {
            None => format!(
                "frame {}: loop to the keyframe of frame {} ({:?}) accepted, correction \
                 {:.1} mm / {:.2} deg{}",
                l.frame,
                l.keyframe_frame,
                l.kind,
                1e3 * l.correction_m,
                l.correction_deg,
                match l.action {
                    Some(LoopAction::Bent) => "; confirmed: trajectory and map bent",
                    Some(LoopAction::AwaitingConfirmation) => {
                        "; above noise: awaiting a second verification"
                    }
                    _ => " (within noise: nothing moved)",
                }
            ),
            Some(why) => format!(
                "frame {}: loop candidate, keyframe of frame {} ({:?}), rejected: {why}",
                l.frame, l.keyframe_frame, l.kind
            ),
        })
        .collect();
    let event = match &f.report.status {
        TrackStatus::Lost(why) => Some(format!(
            "frame {}: tracking lost ({why}); not fused{}",
            f.index,
            match f.report.relocalisation.len() {
                0 => String::new(),
                n => format!(", {n} relocalisation attempt(s) failed"),
            }
        )),
        TrackStatus::Relocalised { keyframe_frame } => Some(format!(
            "frame {}: relocalised from the keyframe of frame {keyframe_frame}",
            f.index
        )),
        TrackStatus::EmptyDepth => Some(format!("frame {}: no valid depth; skipped", f.index)),
        _ => None,
    };
    events.extend(event);
    events
}

/// The file name of a `--rerun` recording asked for inside `--out`: one of the output set,
/// staged and moved in with it.
fn rerun_in_out(a: &RunArgs) -> Option<String> {
    a.rerun
        .as_deref()
        .filter(|p| p.parent().is_some_and(|dir| same_folder(dir, &a.out)))
        .and_then(|p| p.file_name())
        .map(|n| n.to_string_lossy().into_owned())
}

/// Begins the output set in `out`: the run's files, the recording named `rerun_in_out`,
/// and always mesh.ply, so that a run without --mesh may replace one with it (the commit
/// then removes the old mesh with the old set).
fn stage_outputs(out: &Path, rerun_in_out: Option<&str>) -> Result<OutputSet> {
    let mut names: Vec<&str> = run::OUTPUT_FILES.to_vec();
    names.extend(rerun_in_out);
    names.push(MESH_FILE);
    OutputSet::begin(out, &names)
}

/// Writes the run's files, its pictures and (with `--mesh`) mesh.ply into the staging
/// folder `dir`; returns the pictures' and mesh's paths as they will be in `--out`.
fn write_staged(
    a: &RunArgs,
    dir: &Path,
    result: &run::RunResult,
    seq: &dataset::Sequence,
    say: &dyn Fn(&str),
) -> Result<Vec<PathBuf>> {
    let mut pictures = run::write_files_and_pictures(dir, result, seq)?;
    if a.mesh {
        let path = dir.join(MESH_FILE);
        write_run_mesh(&path, &result.map, say)?;
        pictures.push(path);
    }
    Ok(pictures
        .iter()
        .filter_map(|p| p.file_name().map(|n| a.out.join(n)))
        .collect())
}

/// `run --rerun FILE`'s recording.
#[cfg(feature = "rerun")]
use crate::tools::rerun_log::RerunLog as Recording;

/// Without the `rerun` feature there is never a recording (`--rerun` fails up front), so
/// the type has no values and its methods cannot be called.
#[cfg(not(feature = "rerun"))]
enum Recording {}

#[cfg(not(feature = "rerun"))]
impl Recording {
    fn finish(self, _map: &crate::layout::map::SurfelMap) -> Result<PathBuf> {
        match self {}
    }
}

#[cfg(not(feature = "rerun"))]
impl run::FrameObserver for Recording {
    fn wants_map(&mut self, _index: usize) -> bool {
        match *self {}
    }
    fn frame(
        &mut self,
        _raw: &dataset::RawFrame,
        _outcome: &run::FrameOutcome,
        _map: Option<&crate::layout::map::SurfelMap>,
    ) -> Result<()> {
        match *self {}
    }
}

/// The recording `--rerun` asks for, started over the run's frames.
#[cfg(feature = "rerun")]
fn open_recording(
    path: Option<&Path>,
    map_every: usize,
    seq: &dataset::Sequence,
    range: &std::ops::RangeInclusive<usize>,
) -> Result<Option<Recording>> {
    path.map(|path| Recording::create(path, seq, *range.start(), *range.end(), map_every))
        .transpose()
}

/// Without the `rerun` feature: an error naming the feature when `--rerun` is given.
#[cfg(not(feature = "rerun"))]
fn open_recording(
    path: Option<&Path>,
    _map_every: usize,
    _seq: &dataset::Sequence,
    _range: &std::ops::RangeInclusive<usize>,
) -> Result<Option<Recording>> {
    match path {
        Some(_) => Err(Error::Argument(
            "--rerun needs a wgslam built with the `rerun` feature \
             (cargo build --release --features rerun); this binary was built without it"
                .into(),
        )),
        None => Ok(None),
    }
}

fn print_summary(m: &run::Metrics, out: &Path, say: &dyn Fn(&str)) {
    for line in run::summary_lines(m) {
        say(&line);
    }
    say(&format!(
        "wrote {}/{{trajectory.tum, trajectory_odometry.tum, map.ply, metrics.json, frames.json}}",
        out.display()
    ));
}

/// Whether `a` and `b` name the same folder: by their canonical paths where both exist,
/// else as written.
fn same_folder(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}
