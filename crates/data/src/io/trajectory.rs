//! TUM RGB-D trajectory files: `stamp tx ty tz qx qy qz qw` per line, camera-to-world.
//!
//! Translations in metres, unit quaternions scalar-last. `#` lines and blank lines are
//! comments. The stamp is seconds for TUM data and the frame index for ICL-NUIM's
//! `*.gt.freiburg`; this module does not care which. It does not associate or evaluate
//! (see [`crate::eval`]).

use std::io::Write;
use std::path::Path;

use glam::DMat4;

use crate::geometry::se3;
use crate::io::atomic::write_atomic;
use crate::{Error, Result};

/// Largest accepted `| |q| - 1 |`. Files print 4 to 9 significant digits, so rounding moves
/// the norm by at most ~1e-4; a norm off by more than 1% is a wrong column or a corrupt file,
/// not rounding.
pub const QUATERNION_NORM_TOL: f64 = 1e-2;

/// The largest position coordinate read, metres: far beyond any trajectory (UTM northings
/// are ~1e7 m), far below where squared distances overflow (1e300 printed "ATE NaN mm").
pub const MAX_COORDINATE_M: f64 = 1e9;

/// One pose per line: `(stamp, t_cam_to_world)`, in file order.
pub type Trajectory = Vec<(f64, DMat4)>;

/// Reads a TUM trajectory file. Errors name `path:line` and the field for a wrong number
/// of fields, an unparsable or non-finite number, or a non-unit quaternion. They never
/// quote the file's text: a ground-truth path can name any file (a batch manifest's `gt`
/// override), and an error ends up in logs and in a batch's report.
pub fn read_tum(path: &Path) -> Result<Trajectory> {
    let text = crate::io::input::read_input_string(path)?;
    parse_tum(path, &text)
}

/// Parses the text of a TUM trajectory file (`path` is only used in error messages).
pub fn parse_tum(path: &Path, text: &str) -> Result<Trajectory> {
    let mut out = Vec::new();
    for (lineno, line) in crate::io::text::data_lines(text) {
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 8 {
            return Err(Error::parse(
                path,
                lineno,
                format!(
                    "expected 8 fields `stamp tx ty tz qx qy qz qw`, found {}",
                    fields.len()
                ),
            ));
        }
        let mut v = [0.0f64; 8];
        for (k, f) in fields.iter().enumerate() {
            v[k] = f.parse::<f64>().map_err(|_| {
                Error::parse(path, lineno, format!("field {} is not a number", k + 1))
            })?;
            if !v[k].is_finite() {
                return Err(Error::parse(
                    path,
                    lineno,
                    format!("field {} is not finite", k + 1),
                ));
            }
        }
        if let Some(k) = (1..4).find(|&k| v[k].abs() > MAX_COORDINATE_M) {
            return Err(Error::parse(
                path,
                lineno,
                format!(
                    "field {} is beyond {MAX_COORDINATE_M:e} m: not a camera position (the \
                     errors of such numbers overflow)",
                    k + 1
                ),
            ));
        }
        let q = [v[4], v[5], v[6], v[7]];
        let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > QUATERNION_NORM_TOL {
            return Err(Error::parse(
                path,
                lineno,
                format!("quaternion (qx qy qz qw) has norm {norm:.6}, expected 1"),
            ));
        }
        out.push((v[0], se3::from_tum([v[1], v[2], v[3]], q)));
    }
    Ok(out)
}

/// Formats a stamp: integers (ICL-NUIM frame indices) without decimals, others with 6.
fn format_stamp(s: f64) -> String {
    if s.fract() == 0.0 && s.abs() < 1e15 {
        format!("{}", s as i64)
    } else {
        format!("{s:.6}")
    }
}

/// The header's frames of a camera trajectory ([`write_tum`]).
pub const TUM_CAMERA_FRAMES: &str = "camera to world";

/// Writes `(stamp, t_cam_to_world)` poses as a TUM trajectory (atomically), one line each:
/// stamp (see above), translation in metres and quaternion `qx qy qz qw` (`qw >= 0`), with
/// 9 decimals. Errors on a non-finite pose (nothing is written then).
pub fn write_tum(path: &Path, poses: &[(f64, DMat4)]) -> Result<()> {
    write_tum_of(path, TUM_CAMERA_FRAMES, poses)
}

/// [`write_tum`] for poses of another sensor: `frames` names them in the header line
/// (e.g. `scan to world`).
pub fn write_tum_of(path: &Path, frames: &str, poses: &[(f64, DMat4)]) -> Result<()> {
    write_atomic(path, |w: &mut dyn Write| {
        write_tum_to(w, path, frames, poses)
    })
}

/// The bytes of [`write_tum_of`] into any writer (the browser build's downloads fill a
/// `Vec<u8>`); `path` names the file in errors.
pub fn write_tum_to(
    w: &mut dyn Write,
    path: &Path,
    frames: &str,
    poses: &[(f64, DMat4)],
) -> Result<()> {
    let io = |e| Error::write(path, e);
    writeln!(w, "# timestamp tx ty tz qx qy qz qw ({frames}, metres)").map_err(io)?;
    for (k, (stamp, pose)) in poses.iter().enumerate() {
        if !stamp.is_finite() || !pose.is_finite() {
            return Err(Error::format(
                path,
                format!("pose {k} (stamp {stamp}) is not finite; refusing to write it"),
            ));
        }
        let (t, q) = se3::to_tum(pose);
        writeln!(
            w,
            "{} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}",
            format_stamp(*stamp),
            t[0],
            t[1],
            t[2],
            q[0],
            q[1],
            q[2],
            q[3]
        )
        .map_err(io)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_format() {
        assert_eq!(format_stamp(17.0), "17");
        assert_eq!(format_stamp(1305031102.175304), "1305031102.175304");
    }

    #[test]
    fn parse_errors_name_the_line() {
        let p = Path::new("gt.txt");
        let e = parse_tum(p, "# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n").unwrap_err();
        assert!(matches!(e, Error::Parse { line: 3, .. }), "{e}");
        let e = parse_tum(p, "1 0 0 x 0 0 0 1\n").unwrap_err();
        assert!(e.to_string().contains("field 4 is not a number"), "{e}");
        let e = parse_tum(p, "1 0 0 0 0 0 0 2\n").unwrap_err();
        assert!(e.to_string().contains("norm 2.0"), "{e}");
        let e = parse_tum(p, "1 0 0 NaN 0 0 0 1\n").unwrap_err();
        assert!(e.to_string().contains("not finite"), "{e}");
    }
}
