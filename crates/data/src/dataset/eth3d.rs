//! ETH3D SLAM benchmark layout: TUM-like (`rgb/`, `depth/` with 16-bit PNG depth at 5000 per
//! metre, `groundtruth.txt` in TUM format), with its own association list `associated.txt`
//! (`rgb_stamp rgb/x.png depth_stamp depth/x.png`, colour first) and the intrinsics in
//! `calibration.txt` (one line `fx fy cx cy`, pixels; the image size is the images').
//! A copy without `associated.txt` but with `rgb.txt` and `depth.txt` is associated as TUM.

use std::path::{Path, PathBuf};

use super::matrix_file::read_numbers;
use crate::io::text::finite_f64;
use crate::{Error, Result};

/// The intrinsics file that marks the layout.
pub const CALIBRATION: &str = "calibration.txt";

/// One line of `associated.txt`; paths relative to the root, the stamp is the depth's.
#[derive(Debug, Clone, PartialEq)]
pub struct Association {
    /// Depth stamp, seconds.
    pub stamp: f64,
    pub rgb_path: PathBuf,
    pub depth_path: PathBuf,
}

/// Reads `associated.txt`; errors name `file:line` and quote the line.
pub fn read_associated(path: &Path) -> Result<Vec<Association>> {
    let text = super::source::read_string(path, crate::io::input::InputKind::List)?;
    let mut out = Vec::new();
    for (lineno, line) in crate::io::text::data_lines(&text) {
        let f: Vec<&str> = line.split_whitespace().collect();
        let stamp = (f.len() == 4).then(|| finite_f64(f[2])).flatten();
        let Some(stamp) = stamp else {
            return Err(Error::parse(
                path,
                lineno,
                format!("expected `rgb_stamp rgb/x.png depth_stamp depth/x.png`: {line:?}"),
            ));
        };
        out.push(Association {
            stamp,
            rgb_path: PathBuf::from(f[1]),
            depth_path: PathBuf::from(f[3]),
        });
    }
    Ok(out)
}

/// `fx fy cx cy` from `calibration.txt`; an error naming the file unless it holds exactly
/// four finite numbers with non-zero focal lengths.
pub fn read_calibration(path: &Path) -> Result<[f32; 4]> {
    let v = read_numbers(path)?;
    if v.len() != 4 || v.iter().any(|x| !x.is_finite()) || v[0] == 0.0 || v[1] == 0.0 {
        return Err(Error::format(
            path,
            format!(
                "expected one line `fx fy cx cy` (four finite numbers, fx and fy non-zero), \
                 found {v:?}"
            ),
        ));
    }
    let k = [v[0] as f32, v[1] as f32, v[2] as f32, v[3] as f32];
    super::checks::pinhole_in_bounds(k, &path.display().to_string())?;
    Ok(k)
}
