//! Small text files of numbers that frame-per-file layouts use: a 4x4 camera-to-world pose
//! (`frame-NNNNNN.pose.txt`, ScanNet's `pose/N.txt`, a line of Replica's `traj.txt`) and a
//! pinhole matrix K (`camera-intrinsics.txt` 3x3, ScanNet's `intrinsic_depth.txt` 4x4).
//!
//! Numbers are separated by any whitespace (commas too); `inf`, `-inf` and `nan` parse, so
//! a pose ScanNet marks as failed (`-inf` entries) reads as "no pose" instead of an error.

use std::path::Path;

use glam::DMat4;

use crate::{Error, Result};

/// Largest accepted deviation of a pose's bottom row from `0 0 0 1`: files print at least 6
/// significant digits, so anything larger is a transposed or corrupt matrix.
pub const BOTTOM_ROW_TOL: f64 = 1e-4;

/// Largest accepted deviation of a pose's rotation from a rotation: `max |RᵀR - I|` and
/// `|det R - 1|`. Files print at least 6 significant digits, which moves `RᵀR` by ~1e-6; a
/// scaled matrix (`1000·I`), an all-zero block or a reflection is far beyond 1e-3.
pub const ROTATION_TOL: f64 = 1e-3;

/// Every number in `text` (whitespace- or comma-separated); `what` names the file in errors.
pub fn parse_numbers(path: &Path, text: &str) -> Result<Vec<f64>> {
    text.split(|c: char| c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<f64>()
                .map_err(|_| Error::format(path, format!("{s:?} is not a number")))
        })
        .collect()
}

/// Reads every number of the file at `path`.
pub fn read_numbers(path: &Path) -> Result<Vec<f64>> {
    let text = super::source::read_string(path, crate::io::input::InputKind::Matrix)?;
    parse_numbers(path, &text)
}

/// A camera-to-world pose from 16 row-major numbers; `Ok(None)` when any is not finite
/// (ScanNet writes `-inf` for frames its reconstruction lost). `path` names the file in
/// errors: fewer or more than 16 numbers, or a bottom row that is not `0 0 0 1`.
pub fn pose_from_row_major(path: &Path, v: &[f64]) -> Result<Option<DMat4>> {
    if v.len() != 16 {
        return Err(Error::format(
            path,
            format!(
                "a pose needs 16 numbers (a 4x4 camera-to-world matrix, row by row), found {}",
                v.len()
            ),
        ));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Ok(None);
    }
    let bottom = [v[12], v[13], v[14], v[15] - 1.0];
    if bottom.iter().any(|x| x.abs() > BOTTOM_ROW_TOL) {
        return Err(Error::format(
            path,
            format!(
                "the pose's last row is {} {} {} {}, not 0 0 0 1 (a transposed or corrupt matrix)",
                v[12], v[13], v[14], v[15]
            ),
        ));
    }
    check_rigid(path, v)?;
    // glam is column-major: column j is (v[j], v[4 + j], v[8 + j], v[12 + j]).
    Ok(Some(DMat4::from_cols_array(&[
        v[0], v[4], v[8], v[12], v[1], v[5], v[9], v[13], v[2], v[6], v[10], v[14], v[3], v[7],
        v[11], v[15],
    ])))
}

/// Checks that the row-major 4x4 `v` is a rigid motion: its 3x3 block orthonormal within
/// [`ROTATION_TOL`] with determinant +1, its translation within
/// [`crate::io::trajectory::MAX_COORDINATE_M`]. Errors name `path` and say what is wrong.
fn check_rigid(path: &Path, v: &[f64]) -> Result<()> {
    let r = |i: usize, j: usize| v[i * 4 + j];
    let mut worst = 0.0f64;
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| r(k, i) * r(k, j)).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            worst = worst.max((dot - want).abs());
        }
    }
    let det = r(0, 0) * (r(1, 1) * r(2, 2) - r(1, 2) * r(2, 1))
        - r(0, 1) * (r(1, 0) * r(2, 2) - r(1, 2) * r(2, 0))
        + r(0, 2) * (r(1, 0) * r(2, 1) - r(1, 1) * r(2, 0));
    if worst > ROTATION_TOL || (det - 1.0).abs() > ROTATION_TOL {
        let what = if det < 0.0 {
            "a reflection"
        } else {
            "scaled, sheared or degenerate"
        };
        return Err(Error::format(
            path,
            format!(
                "the pose's 3x3 rotation block is not a rotation ({what}: |RᵀR - I| up to \
                 {worst:.3e}, det {det:.6}; allowed {ROTATION_TOL:e}); a camera pose must be a \
                 rigid motion"
            ),
        ));
    }
    let max_m = crate::io::trajectory::MAX_COORDINATE_M;
    if [v[3], v[7], v[11]].iter().any(|t| t.abs() > max_m) {
        return Err(Error::format(
            path,
            format!(
                "the pose's translation ({} {} {}) is beyond {max_m:e} m: not a camera position",
                v[3], v[7], v[11]
            ),
        ));
    }
    Ok(())
}

/// Reads a 4x4 camera-to-world pose file ([`pose_from_row_major`]).
pub fn read_pose(path: &Path) -> Result<Option<DMat4>> {
    pose_from_row_major(path, &read_numbers(path)?)
}

/// Pinhole parameters `(fx, fy, cx, cy)` in pixels of a K matrix file: 3x3 or the upper-left
/// of a 4x4 (ScanNet), row-major. Errors name the file: another count, a non-finite or zero
/// focal length, or a matrix that is not a pinhole K (non-zero skew or last row).
pub fn read_k(path: &Path) -> Result<[f32; 4]> {
    let v = read_numbers(path)?;
    let n = match v.len() {
        9 => 3,
        16 => 4,
        other => {
            return Err(Error::format(
                path,
                format!("expected a 3x3 or 4x4 intrinsics matrix (9 or 16 numbers), found {other}"),
            ))
        }
    };
    let at = |r: usize, c: usize| v[r * n + c];
    let (fx, fy, cx, cy) = (at(0, 0), at(1, 1), at(0, 2), at(1, 2));
    let pinhole = at(0, 1) == 0.0 && at(1, 0) == 0.0 && at(2, 0) == 0.0 && at(2, 1) == 0.0;
    let finite = [fx, fy, cx, cy].iter().all(|x| x.is_finite());
    if !finite || fx == 0.0 || fy == 0.0 || !pinhole || (at(2, 2) - 1.0).abs() > 1e-9 {
        return Err(Error::format(
            path,
            format!(
                "not a pinhole K matrix [fx 0 cx; 0 fy cy; 0 0 1] with non-zero focal lengths: \
                 {v:?}"
            ),
        ));
    }
    let k = [fx as f32, fy as f32, cx as f32, cy as f32];
    super::checks::pinhole_in_bounds(k, &path.display().to_string())?;
    Ok(k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_major_pose_becomes_camera_to_world() {
        let p = Path::new("p.txt");
        let v = parse_numbers(p, "1 0 0 1.5\n0 0 -1 2\n0 1 0 3\n0 0 0 1\n").unwrap();
        let m = pose_from_row_major(p, &v).unwrap().unwrap();
        assert_eq!(m.w_axis.truncate(), glam::DVec3::new(1.5, 2.0, 3.0));
        // The camera's y axis (column 1) maps to world z.
        assert_eq!(m.y_axis.truncate(), glam::DVec3::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn infinite_pose_is_none_short_pose_an_error() {
        let p = Path::new("p.txt");
        let inf = parse_numbers(p, &["-inf"; 16].join(" ")).unwrap();
        assert_eq!(pose_from_row_major(p, &inf).unwrap(), None);
        let short = parse_numbers(p, "1 0 0 0 0 1 0 0 0 0 1 0").unwrap();
        let err = pose_from_row_major(p, &short).unwrap_err().to_string();
        assert!(err.contains("p.txt") && err.contains("found 12"), "{err}");
        let transposed = parse_numbers(p, "1 0 0 0 0 1 0 0 0 0 1 0 4 5 6 1").unwrap();
        assert!(pose_from_row_major(p, &transposed).is_err());
    }

    #[test]
    fn poses_that_are_not_rigid_motions_are_refused() {
        let p = Path::new("p.txt");
        let err = |text: &str| {
            let v = parse_numbers(p, text).unwrap();
            pose_from_row_major(p, &v).unwrap_err().to_string()
        };
        let zero = err("0 0 0 1  0 0 0 2  0 0 0 3  0 0 0 1");
        assert!(
            zero.contains("p.txt") && zero.contains("not a rotation"),
            "{zero}"
        );
        let scaled = err("1000 0 0 0  0 1000 0 0  0 0 1000 0  0 0 0 1");
        assert!(scaled.contains("scaled"), "{scaled}");
        let reflection = err("-1 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1");
        assert!(reflection.contains("a reflection"), "{reflection}");
        let far = err("1 0 0 1e12  0 1 0 0  0 0 1 0  0 0 0 1");
        assert!(far.contains("beyond"), "{far}");
        // Six printed digits of a real rotation pass.
        let v = parse_numbers(p, "0.866025 -0.5 0 1  0.5 0.866025 0 2  0 0 1 3  0 0 0 1").unwrap();
        assert!(pose_from_row_major(p, &v).unwrap().is_some());
    }
}
