//! Reading input files with bounds: only regular files (never a device such as `/dev/zero`,
//! a FIFO that blocks forever, a socket or a folder), and at most [`max_input_bytes`]
//! bytes, so a hostile or mistaken path fails with a clear error instead of filling memory.
//!
//! The limits of the whole tool are here too, each with its default, the variable that
//! overrides it and the error that names both: input file size, batch jobs per manifest,
//! frames of a `run --revisit` sequence.

use std::io::Read;
use std::path::Path;

use crate::{Error, Result};

/// Default of [`max_input_bytes`]: 4 GiB, past the largest point cloud or trajectory this
/// tool is meant for (a 10^8-point binary PCD is 1.2 GB).
pub const DEFAULT_MAX_INPUT_BYTES: u64 = 4 << 30;
/// Default of [`max_jobs`]: a manifest's job count; a grid of 10 lists of 4 values is 10^6
/// jobs, which takes minutes and gigabytes only to list.
pub const DEFAULT_MAX_JOBS: u64 = 10_000;
/// Default of [`max_revisit_frames`]: 10^6 frames is days of SLAM; the frame list alone
/// costs ~100 bytes a frame.
pub const DEFAULT_MAX_REVISIT_FRAMES: u64 = 1_000_000;

/// Hard ceiling of [`max_revisit_frames`], whatever `WGSLAM_MAX_REVISIT_FRAMES` says: 10^7
/// frames (~4 days at 30 Hz) of ~100-byte frame records is 1 GB before the first frame;
/// 10^13 frames once asked for 1.9 PB and aborted.
pub const HARD_MAX_REVISIT_FRAMES: u64 = 10_000_000;

/// A limit: `var`'s value when set (a whole number up to `ceiling`), else `default`.
fn limit(var: &str, default: u64, ceiling: u64) -> Result<u64> {
    let v = match std::env::var(var) {
        Err(_) => return Ok(default),
        Ok(v) => v,
    };
    let n: u64 = v
        .trim()
        .parse()
        .map_err(|_| Error::Argument(format!("{var}={v:?} is not a whole number (a limit)")))?;
    if n > ceiling {
        return Err(Error::Argument(format!(
            "{var}={n} is beyond the most this tool can hold, {ceiling}; choose a smaller limit"
        )));
    }
    Ok(n)
}

/// The largest input file read, bytes: `WGSLAM_MAX_INPUT_BYTES`, default
/// [`DEFAULT_MAX_INPUT_BYTES`].
pub fn max_input_bytes() -> Result<u64> {
    limit("WGSLAM_MAX_INPUT_BYTES", DEFAULT_MAX_INPUT_BYTES, u64::MAX)
}

/// The most jobs a batch manifest may expand to: `WGSLAM_MAX_JOBS`, default
/// [`DEFAULT_MAX_JOBS`].
pub fn max_jobs() -> Result<u64> {
    limit("WGSLAM_MAX_JOBS", DEFAULT_MAX_JOBS, u64::MAX)
}

/// The longest `run --revisit` sequence, frames: `WGSLAM_MAX_REVISIT_FRAMES` (at most
/// [`HARD_MAX_REVISIT_FRAMES`]), default [`DEFAULT_MAX_REVISIT_FRAMES`].
pub fn max_revisit_frames() -> Result<u64> {
    limit(
        "WGSLAM_MAX_REVISIT_FRAMES",
        DEFAULT_MAX_REVISIT_FRAMES,
        HARD_MAX_REVISIT_FRAMES,
    )
}

/// What an input file is, for its size cap: each kind is bounded by what such a file can
/// reasonably hold, so `/dev/zero`, a sparse file or a wrong path fails in milliseconds
/// with an error that names the file, the kind and the cap. [`max_input_bytes`] bounds
/// every kind from above (so lowering it lowers them all).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// One 4x4 pose or a K matrix (`frame-N.pose.txt`, ScanNet `pose/N.txt`,
    /// `camera-intrinsics.txt`, ETH3D's `calibration.txt`): a few hundred bytes.
    Matrix,
    /// A small settings file: `camera.json`, `cam_params.json`, a `--params` TOML.
    Settings,
    /// A batch manifest or `batch.json`: a few megabytes at most.
    Manifest,
    /// A list of frames or a trajectory (`rgb.txt`, `associations.txt`, `traj.txt`,
    /// `groundtruth.txt`, a TUM estimate), or a record a run wrote (`metrics.json`,
    /// `frames.json`, a job's `job.json`): ~100 bytes a frame.
    List,
    /// One colour or depth image.
    Image,
    /// A point cloud or a log (PLY, PCD, XYZ, a run log): up to [`max_input_bytes`].
    Cloud,
    /// A recording (ROS bag, MCAP file): streamed a message at a time, never read whole,
    /// so its size is not capped; each message is capped at [`MAX_IMAGE_BYTES`]
    /// (`dataset/bag`).
    Recording,
}

/// Cap of an [`InputKind::Matrix`] file, bytes: 16 numbers of 24 characters with
/// comments are under 1 KiB; 64 KiB leaves room for any header a tool writes.
pub const MAX_MATRIX_BYTES: u64 = 64 << 10;
/// Cap of an [`InputKind::Settings`] file, bytes: settings are tens of lines.
pub const MAX_SETTINGS_BYTES: u64 = 4 << 20;
/// Cap of an [`InputKind::Manifest`] file, bytes: [`DEFAULT_MAX_JOBS`] jobs of ~1 KiB each
/// is 10 MB (a `batch.json` lists every job), with room for a raised job limit.
pub const MAX_MANIFEST_BYTES: u64 = 64 << 20;
/// Cap of an [`InputKind::List`] file, bytes: [`DEFAULT_MAX_REVISIT_FRAMES`] frames of
/// ~100 bytes a line, with room for long paths.
pub const MAX_LIST_BYTES: u64 = 512 << 20;
/// Cap of an [`InputKind::Image`] file, bytes: an uncompressed 16-bit 8K RGB image is
/// ~200 MB; no compressed camera frame comes near.
pub const MAX_IMAGE_BYTES: u64 = 256 << 20;

impl InputKind {
    /// This kind's cap in bytes, at most [`max_input_bytes`].
    pub fn max_bytes(self) -> Result<u64> {
        let own = match self {
            InputKind::Matrix => MAX_MATRIX_BYTES,
            InputKind::Settings => MAX_SETTINGS_BYTES,
            InputKind::Manifest => MAX_MANIFEST_BYTES,
            InputKind::List => MAX_LIST_BYTES,
            InputKind::Image => MAX_IMAGE_BYTES,
            InputKind::Cloud => u64::MAX,
            InputKind::Recording => return Ok(u64::MAX),
        };
        Ok(own.min(max_input_bytes()?))
    }

    /// The kind's name in errors.
    fn name(self) -> &'static str {
        match self {
            InputKind::Matrix => "a pose or intrinsics matrix file",
            InputKind::Settings => "a settings file",
            InputKind::Manifest => "a manifest",
            InputKind::List => "a frame list or trajectory",
            InputKind::Image => "an image",
            InputKind::Cloud => "an input file",
            InputKind::Recording => "a recording",
        }
    }
}

/// Why `m` is not a regular file, or `None` when it is one.
fn not_regular(m: &std::fs::Metadata) -> Option<&'static str> {
    if m.is_file() {
        None
    } else if m.is_dir() {
        Some("a folder")
    } else {
        Some("not a regular file (a device, a FIFO or a socket)")
    }
}

fn refuse_kind(path: &Path, kind: &str) -> Error {
    Error::format(path, format!("is {kind}; wgslam reads only regular files"))
}

/// Whether anything is at `path` (a file, a folder, a FIFO, a link even if broken or
/// looping). An optional input (intrinsics, a trajectory, ground truth) that is present
/// in this sense is read, so a folder or a FIFO in its place is an error naming it
/// instead of being taken as missing and replaced by a default.
pub fn present(path: &Path) -> bool {
    path.symlink_metadata().is_ok()
}

/// Checks that `path` is a regular file (following links) of at most
/// [`max_input_bytes`]; returns its size.
pub fn check_input(path: &Path) -> Result<u64> {
    check_kind(path, InputKind::Cloud)
}

/// Checks that `path` is a regular file (following links) within `kind`'s cap; returns
/// its size. A link loop or a missing file is an I/O error naming the path.
pub fn check_kind(path: &Path, kind: InputKind) -> Result<u64> {
    let m = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if let Some(what) = not_regular(&m) {
        return Err(refuse_kind(path, what));
    }
    let max = kind.max_bytes()?;
    if m.len() > max {
        return Err(too_big(path, m.len(), max, kind));
    }
    Ok(m.len())
}

/// The error for a file of `len` bytes over `kind`'s cap `max`.
pub(crate) fn too_big(path: &Path, len: u64, max: u64, kind: InputKind) -> Error {
    Error::format(
        path,
        format!(
            "is {len} bytes, more than the limit of {max} bytes for {} \
             (WGSLAM_MAX_INPUT_BYTES lowers it; a wrong path is the likelier cause)",
            kind.name()
        ),
    )
}

/// Opens `path` for reading as `kind`: never blocking on the open (`O_NONBLOCK`, so a
/// FIFO with no writer cannot hang it), then refusing anything the open handle says is
/// not a regular file, or is larger than the cap. Returns the file limited to cap + 1
/// bytes (so a file that grows while read is caught by [`read_kind`]) and its size.
pub fn open_kind(path: &Path, kind: InputKind) -> Result<(std::io::Take<std::fs::File>, u64)> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(|e| Error::io(path, e))?;
    let m = file.metadata().map_err(|e| Error::io(path, e))?;
    if let Some(what) = not_regular(&m) {
        return Err(refuse_kind(path, what));
    }
    let max = kind.max_bytes()?;
    if m.len() > max {
        return Err(too_big(path, m.len(), max, kind));
    }
    Ok((file.take(max.saturating_add(1)), m.len()))
}

/// Reads a whole regular file of `kind` within its cap ([`open_kind`]); a file that grows
/// past the cap while being read is refused too. The one way this crate reads an input
/// file (`tests/it/hostile/bounded.rs` checks the sources for any other).
pub fn read_kind(path: &Path, kind: InputKind) -> Result<Vec<u8>> {
    let (mut file, len) = open_kind(path, kind)?;
    let max = kind.max_bytes()?;
    let mut bytes = Vec::with_capacity(len.min(max) as usize);
    file.read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > max {
        return Err(too_big(path, bytes.len() as u64, max, kind));
    }
    Ok(bytes)
}

/// [`read_kind`] as UTF-8 text; a leading byte-order mark is dropped.
pub fn read_kind_string(path: &Path, kind: InputKind) -> Result<String> {
    text_of(path, read_kind(path, kind)?)
}

/// A file's bytes as UTF-8 text without a leading byte-order mark; `path` names it in
/// errors.
pub fn text_of(path: &Path, bytes: Vec<u8>) -> Result<String> {
    let mut text = String::from_utf8(bytes)
        .map_err(|e| Error::format(path, format!("not UTF-8 text: {e}")))?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// Reads a regular file of at most [`max_input_bytes`] ([`read_kind`] as a
/// [`InputKind::Cloud`]).
pub fn read_input(path: &Path) -> Result<Vec<u8>> {
    read_kind(path, InputKind::Cloud)
}

/// [`read_input`] as UTF-8 text.
pub fn read_input_string(path: &Path) -> Result<String> {
    read_kind_string(path, InputKind::Cloud)
}
