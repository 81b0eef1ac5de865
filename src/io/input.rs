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

/// A limit: `var`'s value when set (a whole number), else `default`.
fn limit(var: &str, default: u64) -> Result<u64> {
    match std::env::var(var) {
        Err(_) => Ok(default),
        Ok(v) => v
            .trim()
            .parse()
            .map_err(|_| Error::Argument(format!("{var}={v:?} is not a whole number (a limit)"))),
    }
}

/// The largest input file read, bytes: `WGSLAM_MAX_INPUT_BYTES`, default
/// [`DEFAULT_MAX_INPUT_BYTES`].
pub fn max_input_bytes() -> Result<u64> {
    limit("WGSLAM_MAX_INPUT_BYTES", DEFAULT_MAX_INPUT_BYTES)
}

/// The most jobs a batch manifest may expand to: `WGSLAM_MAX_JOBS`, default
/// [`DEFAULT_MAX_JOBS`].
pub fn max_jobs() -> Result<u64> {
    limit("WGSLAM_MAX_JOBS", DEFAULT_MAX_JOBS)
}

/// The longest `run --revisit` sequence, frames: `WGSLAM_MAX_REVISIT_FRAMES`, default
/// [`DEFAULT_MAX_REVISIT_FRAMES`].
pub fn max_revisit_frames() -> Result<u64> {
    limit("WGSLAM_MAX_REVISIT_FRAMES", DEFAULT_MAX_REVISIT_FRAMES)
}

/// Checks that `path` is a regular file (following links) of at most
/// [`max_input_bytes`]; returns its size.
pub fn check_input(path: &Path) -> Result<u64> {
    let m = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !m.is_file() {
        let kind = if m.is_dir() {
            "a folder"
        } else {
            "not a regular file (a device, a FIFO or a socket)"
        };
        return Err(Error::format(
            path,
            format!("is {kind}; wgslam reads only regular files"),
        ));
    }
    let max = max_input_bytes()?;
    if m.len() > max {
        return Err(too_big(path, m.len(), max));
    }
    Ok(m.len())
}

fn too_big(path: &Path, len: u64, max: u64) -> Error {
    Error::format(
        path,
        format!(
            "is {len} bytes, more than the input limit of {max} bytes \
             (WGSLAM_MAX_INPUT_BYTES raises it)"
        ),
    )
}

/// Reads a regular file of at most [`max_input_bytes`] ([`check_input`]); a file that
/// grows past the limit while being read is refused too.
pub fn read_input(path: &Path) -> Result<Vec<u8>> {
    let len = check_input(path)?;
    let max = max_input_bytes()?;
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(max.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > max {
        return Err(too_big(path, bytes.len() as u64, max));
    }
    Ok(bytes)
}

/// [`read_input`] as UTF-8 text.
pub fn read_input_string(path: &Path) -> Result<String> {
    String::from_utf8(read_input(path)?)
        .map_err(|e| Error::format(path, format!("not UTF-8 text: {e}")))
}
