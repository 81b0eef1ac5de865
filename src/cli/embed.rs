//! What a language binding (the Python package, `python/`) reaches through the library: the
//! command line's entry point from argument strings, parameters from a parameter file's
//! text, and a whole run's sequence, frame range and parameters resolved exactly as
//! `wgslam run` resolves them. Not a second command line: each function here is the path
//! `wgslam run` itself takes, so a binding gives the same results and the same error
//! messages.

use std::ffi::OsString;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use clap::Parser;

use super::pipeline_args::{default_first_frame, ParamOverrides, Setup};
use super::{execute, Cli};
use crate::dataset::{self, Sequence};
use crate::slam::params::{PoseSource, ValidParams};
use crate::{Error, Result};

/// The interface whose words a binding's dataset errors use: the one binding is Python's.
const BINDING: dataset::Interface = dataset::Interface::Python;

/// What the errors of a parameter text name in place of a file's path.
const PARAMS_TEXT_NAME: &str = "params";

/// The `wgslam` executable: parses `args` (the program's name first, as
/// [`std::env::args_os`] gives them), runs the command, prints an error as `error: ...` on
/// stderr, and returns the process exit status: 0 on success, 130 when interrupted (128 +
/// SIGINT, as a shell reports a process Ctrl-C stopped), clap's status for a usage error
/// (2; 0 for `--help` and `--version`), 1 for any other error.
pub fn main(args: impl IntoIterator<Item = OsString>) -> u8 {
    restore_sigpipe();
    quiet_display_probe();
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            // On stdout for --help and --version, on stderr for a usage error.
            let _ = e.print();
            return u8::try_from(e.exit_code()).unwrap_or(2);
        }
    };
    match execute(cli) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            match e {
                Error::Interrupted(_) => 130,
                _ => 1,
            }
        }
    }
}

/// A closed pipe ends the process quietly, as it does a C tool: Rust ignores SIGPIPE, so
/// `wgslam batch list M | head -1` made `println!` panic on the broken pipe.
#[cfg(unix)]
fn restore_sigpipe() {
    // SAFETY: setting a signal's disposition to the default; called first thing by the
    // executable's entry point, where nothing else handles SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn restore_sigpipe() {}

/// Keeps a window-system probe from printing what reads as an error of ours.
///
/// Mesa's implicit Vulkan layer `VK_LAYER_MESA_device_select` connects to the Wayland and X
/// servers while adapters are enumerated, to learn which GPU drives the display. On a
/// headless machine (no valid `XDG_RUNTIME_DIR`) libwayland then prints "error:
/// XDG_RUNTIME_DIR is invalid or not set in the environment." twice before wgslam's first
/// line. wgslam draws on no display and picks its adapter itself (high performance first),
/// so there the layer is switched off through its own documented switch, `NODEVICE_SELECT=1`.
/// A user who sets `NODEVICE_SELECT` or `MESA_VK_DEVICE_SELECT` keeps the layer as they
/// set it. Runs before the command starts any thread, so setting the variable races with
/// none of ours.
#[cfg(all(unix, not(target_os = "macos")))]
pub fn quiet_display_probe() {
    let is_set = |key: &str| std::env::var_os(key).is_some();
    if is_set("NODEVICE_SELECT") || is_set("MESA_VK_DEVICE_SELECT") {
        return;
    }
    let runtime_dir_ok =
        std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|dir| std::path::Path::new(&dir).is_dir());
    if !runtime_dir_ok {
        std::env::set_var("NODEVICE_SELECT", "1");
    }
}

/// Nothing to quiet where Mesa's device-select layer does not probe a display server.
#[cfg(not(all(unix, not(target_os = "macos"))))]
pub fn quiet_display_probe() {}

/// The overrides of a parameter file's text (`--params FILE.toml`, docs/params-file.md);
/// errors name the text `params` where a file's would name the file.
fn overrides(params_toml: &str) -> Result<ParamOverrides> {
    ParamOverrides::from_toml(params_toml).map_err(|why| Error::format(PARAMS_TEXT_NAME, why))
}

/// The pipeline's parameters from a parameter file's text, as `wgslam run --params FILE`
/// makes them: the profile's (robust unless the text sets `profile`) with the text's keys
/// in place and `poses`, validated (the one time: [`ValidParams`]). The dataset keys (`camera`, `intrinsics`,
/// `depth-scale`, `gt`, ...) are accepted and not used here: they open a sequence
/// ([`resolve_run`]); a stream of frames gives its camera itself.
pub fn params_from_toml(params_toml: &str, poses: PoseSource) -> Result<TextParams> {
    let set = overrides(params_toml)?;
    Ok(TextParams {
        params: set.slam_params(poses)?,
        sets_downsample: set.sets_downsample(),
    })
}

/// A parameter text's validated parameters ([`params_from_toml`]).
#[derive(Debug, Clone)]
pub struct TextParams {
    /// The validated parameters.
    pub params: ValidParams,
    /// Whether the text set `input.downsample`; unset, the backend that runs the frames
    /// chooses it (`crate::slam::params::resolution::for_backends`), as for `wgslam run`.
    pub sets_downsample: bool,
}

/// A whole run as `wgslam run` resolves it before its first frame.
#[derive(Debug, Clone)]
pub struct RunSetup {
    /// The opened sequence (its notes already printed on stderr).
    pub sequence: Sequence,
    /// The frames to run, by position in the sequence.
    pub frames: RangeInclusive<usize>,
    /// The validated parameters.
    pub params: ValidParams,
    /// Whether the parameters set `input.downsample`; unset, the backend that runs them
    /// chooses it (`crate::slam::params::resolution::for_backends`).
    pub sets_downsample: bool,
}

/// The sequence and overrides of `wgslam run DATASET --params FILE`.
fn setup(dataset: Option<&Path>, params_toml: &str) -> Result<Setup> {
    Ok(Setup {
        dataset: dataset.map(PathBuf::from),
        set: overrides(params_toml)?,
    })
}

/// Opens `dataset` (`None`: the bundled frames) as `wgslam run DATASET --params FILE`
/// opens it, with the dataset keys of the parameter text `params_toml` (`camera`,
/// `intrinsics`, `depth-scale`, `gt`, `max-time-diff`); what opening decided on the user's
/// behalf is printed on stderr as `note: ...`, as by the command line. The text's
/// parameters are validated (a depth scale it sets is their `input.depth_scale`).
pub fn open_sequence(dataset: Option<&Path>, params_toml: &str) -> Result<Sequence> {
    let setup = setup(dataset, params_toml)?;
    setup.open_sequence_for(&setup.slam_params(PoseSource::Track)?, BINDING)
}

/// Resolves `wgslam run DATASET --frames FRAMES --params FILE --poses POSES` without
/// running it: `dataset` the sequence's folder (`None`: the bundled frames), `frames` an
/// inclusive range `"A..B"` by position (`None`: from the first frame with ground truth to
/// the last), `params_toml` a parameter file's text (dataset keys included).
pub fn resolve_run(
    dataset: Option<&Path>,
    frames: Option<&str>,
    params_toml: &str,
    poses: PoseSource,
) -> Result<RunSetup> {
    let setup = setup(dataset, params_toml)?;
    let params = setup.slam_params(poses)?;
    let sequence = setup.open_sequence_for(&params, BINDING)?;
    let (first, last) = match frames {
        Some(r) => dataset::parse_range(r)?,
        None => (default_first_frame(&sequence), sequence.len() - 1),
    };
    let frames = sequence.select(first, last)?;
    if let Some(note) = sequence.jump_note(frames.clone()) {
        eprintln!("note: {note}");
    }
    Ok(RunSetup {
        sequence,
        frames,
        params,
        sets_downsample: setup.set.sets_downsample(),
    })
}

/// Raw depth at `depth_scale` units per metre from depth in metres (`f32`, one per pixel):
/// each value `round(metres x depth_scale)`; a value that is not finite, not positive, or
/// beyond the largest raw value (65535 / `depth_scale` metres) becomes 0, the pipeline's
/// "no reading".
pub fn raw_depth_from_metres(metres: &[f32], depth_scale: f32) -> Vec<u16> {
    metres
        .iter()
        .map(|&m| {
            let raw = (m * depth_scale).round();
            match raw.is_finite() && raw > 0.0 && raw <= f32::from(u16::MAX) {
                true => raw as u16,
                false => 0,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Metres become the raw units the dataset readers give, and everything the pipeline
    /// could misread (NaN, infinities, negatives, out of range) becomes "no reading".
    #[test]
    fn metres_to_raw_depth_rounds_and_drops_what_is_not_a_reading() {
        let m = [
            1.0,
            0.0002,
            0.0001,
            13.107,
            13.108,
            -1.0,
            f32::NAN,
            f32::INFINITY,
        ];
        assert_eq!(
            raw_depth_from_metres(&m, 5000.0),
            [5000, 1, 1, 65535, 0, 0, 0, 0]
        );
    }

    /// A run's parameters are validated once, where they are made, and never again: not
    /// when the sequence is opened with them, not by the run; a value out of range is
    /// refused there, by that one check, naming its key and flag once.
    #[test]
    fn a_run_validates_its_parameters_once() {
        use crate::slam::cpu_backend::CpuBackend;
        use crate::slam::params::valid::validations_on_this_thread as validations;
        use crate::tools::run::{run_observed, Decode};
        let before = validations();
        let setup = resolve_run(None, Some("1..2"), "fuse-dist = 0.04", PoseSource::Track);
        let setup = setup.unwrap();
        assert_eq!(validations() - before, 1, "resolving the run");
        let (seq, frames) = (&setup.sequence, setup.frames.clone());
        let r = run_observed(
            CpuBackend::new(),
            seq,
            frames,
            setup.params,
            Decode::BeforeEachFrame,
            |_| {},
            None,
        )
        .unwrap();
        assert_eq!(r.frames.len(), 2);
        assert_eq!(r.metrics.params.fusion.dist_m, 0.04);
        assert_eq!(validations() - before, 1, "the run checked them again");
        let before = validations();
        let err = resolve_run(None, None, "fuse-dist = 0", PoseSource::Track).unwrap_err();
        let msg = err.to_string();
        assert_eq!(validations() - before, 1);
        assert_eq!(
            msg.matches("`fusion.dist_m` (--fuse-dist)").count(),
            1,
            "{msg}"
        );
    }

    /// A parameter text's errors are the parameter file's, naming the text `params`.
    #[test]
    fn parameter_text_errors_name_the_key() {
        let err = params_from_toml("no-such-key = 1", PoseSource::Track).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.starts_with("params: unknown key `no-such-key`"),
            "{msg}"
        );
        let p = params_from_toml("profile = \"assignment\"", PoseSource::Track).unwrap();
        assert_eq!(
            p.params,
            ValidParams::profile(crate::slam::params::Profile::Assignment)
        );
        assert!(!p.sets_downsample);
        let p = params_from_toml("[input]\ndownsample = 1", PoseSource::Track).unwrap();
        assert!(p.sets_downsample);
    }
}
