//! Scan-to-scan odometry: registers each consecutive pair of a scan sequence (pairs in
//! parallel with rayon), chains the results into a trajectory and, with ground truth,
//! measures relative pose errors.
//!
//! Frames: pair `i` registers scan `i + 1` (source) onto scan `i` (target), giving
//! `t_source_to_target = t_{i+1 -> i}`; the trajectory is `t_scan_to_world[i + 1] =
//! t_scan_to_world[i] * t_{i+1 -> i}`, anchored at the ground-truth pose of scan 0 when
//! ground truth is given (identity otherwise). Not a mapper: no loop closure, no map.

use std::path::{Path, PathBuf};
use web_time::Instant;

use glam::DMat4;
use rayon::prelude::*;

use super::icp::{register, IcpParams, IcpResult};
use super::read::{is_cloud_file, read_cloud};
use crate::{geometry::se3, Error, Result};

/// An ordered list of scans, optionally with ground-truth poses.
#[derive(Debug, Clone)]
pub struct ScanSequence {
    /// Scan files in sequence order.
    pub scans: Vec<PathBuf>,
    /// Ground-truth `t_scan_to_world` per scan (metres), when known.
    pub gt_scan_to_world: Option<Vec<DMat4>>,
}

impl ScanSequence {
    /// Timestamp written for scan `i`: its file stem as a number when it is one, else `i`.
    pub fn stamp(&self, i: usize) -> f64 {
        stem_number(&self.scans[i]).unwrap_or(i as f64)
    }
}

fn stem_number(p: &Path) -> Option<f64> {
    p.file_stem()?.to_str()?.parse::<f64>().ok()
}

/// The entries of `dir` in natural order ([`natural_cmp`]): `2.bin` before `10.bin`, as
/// scans numbered without leading zeros are meant.
fn list_dir(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        out.push(e.map_err(|e| Error::io(dir, e))?.path());
    }
    out.sort_by(|a, b| {
        natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()).then_with(|| a.cmp(b))
    });
    Ok(out)
}

/// Compares names with runs of digits taken as numbers (`scan2` < `scan10`), the rest
/// character by character; equal numbers with different zero padding compare equal.
pub fn natural_cmp(a: &str, b: &str) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    let (mut a, mut b) = (a, b);
    loop {
        let (Some(ca), Some(cb)) = (a.chars().next(), b.chars().next()) else {
            return a.len().cmp(&b.len());
        };
        if ca.is_ascii_digit() && cb.is_ascii_digit() {
            let run = |s: &str| s.find(|c: char| !c.is_ascii_digit()).unwrap_or(s.len());
            let (ra, rb) = (run(a), run(b));
            let (da, db) = (
                a[..ra].trim_start_matches('0'),
                b[..rb].trim_start_matches('0'),
            );
            let by_number = da.len().cmp(&db.len()).then_with(|| da.cmp(db));
            if by_number != Ordering::Equal {
                return by_number;
            }
            a = &a[ra..];
            b = &b[rb..];
        } else {
            if ca != cb {
                return ca.cmp(&cb);
            }
            a = &a[ca.len_utf8()..];
            b = &b[cb.len_utf8()..];
        }
    }
}

/// Finds the scans of `dir`: the AirSim layout (`lidar/<vehicle>/NNNNNN.bin` with
/// `poses/<vehicle>/NNNNNN.txt`, the poses becoming ground truth) when `dir/lidar` exists,
/// else every cloud file directly in `dir` (see [`is_cloud_file`]) sorted by name.
pub fn discover(dir: &Path) -> Result<ScanSequence> {
    let lidar = dir.join("lidar");
    if lidar.is_dir() {
        let vehicles: Vec<PathBuf> = list_dir(&lidar)?
            .into_iter()
            .filter(|p| p.is_dir())
            .collect();
        let [vehicle] = vehicles.as_slice() else {
            return Err(Error::format(
                &lidar,
                format!(
                    "AirSim layout needs exactly one vehicle folder, found {}",
                    vehicles.len()
                ),
            ));
        };
        let scans: Vec<PathBuf> = list_dir(vehicle)?
            .into_iter()
            .filter(|p| p.extension().is_some_and(|e| e == "bin"))
            .collect();
        check_count(vehicle, scans.len())?;
        let poses_dir = dir
            .join("poses")
            .join(vehicle.file_name().unwrap_or_default());
        let gt = if poses_dir.is_dir() {
            Some(
                scans
                    .iter()
                    .map(|s| {
                        let name = s.with_extension("txt");
                        read_airsim_pose(&poses_dir.join(name.file_name().unwrap_or_default()))
                    })
                    .collect::<Result<Vec<_>>>()?,
            )
        } else {
            None
        };
        return Ok(ScanSequence {
            scans,
            gt_scan_to_world: gt,
        });
    }
    // Anything with a cloud's name but a folder is a scan: a FIFO or a device is then
    // refused by the reader, naming it, instead of being skipped without a word.
    let scans: Vec<PathBuf> = list_dir(dir)?
        .into_iter()
        .filter(|p| !p.is_dir() && is_cloud_file(p))
        .collect();
    check_count(dir, scans.len())?;
    check_stamps(&scans)?;
    Ok(ScanSequence {
        scans,
        gt_scan_to_world: None,
    })
}

/// Two scans whose names give one stamp (`1.xyz` and `01.xyz`) are an error naming both:
/// the trajectory would hold the stamp twice.
fn check_stamps(scans: &[PathBuf]) -> Result<()> {
    let mut seen = std::collections::HashMap::new();
    for s in scans {
        let Some(n) = stem_number(s) else { continue };
        if let Some(first) = seen.insert(n.to_bits(), s) {
            return Err(Error::format(
                s,
                format!(
                    "gives the same stamp {n} as {}; keep one of them",
                    first.display()
                ),
            ));
        }
    }
    Ok(())
}

fn check_count(dir: &Path, n: usize) -> Result<()> {
    if n < 2 {
        return Err(Error::format(
            dir,
            format!("odometry needs at least 2 scans, found {n}"),
        ));
    }
    Ok(())
}

/// Parses up to `n` comma- or space-separated finite numbers on a line.
fn numbers(path: &Path, line_no: usize, line: &str, n: usize) -> Result<Vec<f64>> {
    let v: Vec<f64> = line
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|t| {
            t.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| Error::parse(path, line_no, format!("`{t}` is not a finite number")))
        })
        .collect::<Result<_>>()?;
    if v.len() != n {
        return Err(Error::parse(
            path,
            line_no,
            format!("expected {n} numbers, found {}", v.len()),
        ));
    }
    Ok(v)
}

/// Reads an AirSim pose file: line 1 `x, y, z` (metres, NED), line 2 quaternion
/// `x, y, z, w`; returns `t_scan_to_world` (`p_world = R(q) p_scan + t`).
pub fn read_airsim_pose(path: &Path) -> Result<DMat4> {
    let text = crate::io::input::read_input_string(path)?;
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    if lines.len() < 2 {
        return Err(Error::format(
            path,
            "AirSim pose needs 2 lines: `x, y, z` and `qx, qy, qz, qw`",
        ));
    }
    let t = numbers(path, 1, lines[0], 3)?;
    let q = numbers(path, 2, lines[1], 4)?;
    Ok(se3::from_tum([t[0], t[1], t[2]], [q[0], q[1], q[2], q[3]]))
}

/// Ground truth for `seq` from `path`: a directory of AirSim pose files named like the
/// scans (`<stem>.txt`), or a TUM file (`stamp tx ty tz qx qy qz qw`, `#` comments) whose
/// stamps equal the scans' numeric file stems (or their indices when stems are not numbers).
pub fn read_ground_truth(path: &Path, seq: &ScanSequence) -> Result<Vec<DMat4>> {
    if path.is_dir() {
        return seq
            .scans
            .iter()
            .map(|s| {
                let name = s.with_extension("txt");
                read_airsim_pose(&path.join(name.file_name().unwrap_or_default()))
            })
            .collect();
    }
    // The one TUM trajectory reader (comments, field count, unit quaternions checked).
    let table = crate::io::read_tum(path)?;
    (0..seq.scans.len())
        .map(|i| {
            let stamp = seq.stamp(i);
            table
                .iter()
                .find(|(s, _)| (s - stamp).abs() <= 1e-6 * stamp.abs().max(1.0))
                .map(|(_, t)| *t)
                .ok_or_else(|| {
                    Error::format(
                        path,
                        format!("no pose with stamp {stamp} for {}", seq.scans[i].display()),
                    )
                })
        })
        .collect()
}

/// Rotation (degrees) and translation (metres) of `inv(gt) * est` for two relative poses.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PoseError {
    pub rotation_deg: f64,
    pub translation_m: f64,
}

/// Error of an estimated relative pose against ground truth: the residual `inv(gt) * est`.
pub fn pose_error(est: &DMat4, gt: &DMat4) -> PoseError {
    let e = se3::inverse_rigid(gt) * *est;
    PoseError {
        rotation_deg: se3::rotation_angle(&e).to_degrees(),
        translation_m: se3::translation_norm(&e),
    }
}

/// One registered pair: scan `target + 1` (source) onto scan `target`.
#[derive(Debug, Clone)]
pub struct PairResult {
    /// Index of the target scan; the source is `target + 1`.
    pub target: usize,
    /// ICP outcome; `t_source_to_target` is `t_{target+1 -> target}`.
    pub icp: IcpResult,
    /// Wall time of this registration (KD-tree build + ICP), seconds.
    pub seconds: f64,
    /// Relative pose error against ground truth, when given.
    pub error: Option<PoseError>,
}

/// Result of [`run_odometry`].
#[derive(Debug, Clone)]
pub struct Odometry {
    /// Chained `t_scan_to_world` per scan (metres).
    pub t_scan_to_world: Vec<DMat4>,
    /// One entry per consecutive pair, in order.
    pub pairs: Vec<PairResult>,
}

impl Odometry {
    /// How many pairs ICP did not converge on (chained all the same).
    pub fn not_converged(&self) -> usize {
        let converged = |p: &&PairResult| p.icp.status.is_converged();
        self.pairs.iter().filter(|p| !converged(p)).count()
    }
}

/// Reads every scan (in parallel), keeps the points with `z` in `z_range` (sensor frame,
/// metres; `None` keeps all), registers each consecutive pair (in parallel across pairs)
/// from the identity, and chains the trajectory. Pairs that do not converge are still
/// chained (their status is in [`PairResult::icp`]).
pub fn run_odometry(
    seq: &ScanSequence,
    params: &IcpParams,
    z_range: Option<(f32, f32)>,
) -> Result<Odometry> {
    let clouds: Vec<Vec<[f32; 3]>> = seq
        .scans
        .par_iter()
        .map(|p| {
            let c = read_cloud(p)?;
            Ok(match z_range {
                Some((lo, hi)) => super::cloud::crop_z(&c.points, lo, hi),
                None => c.points,
            })
        })
        .collect::<Result<_>>()?;
    let pairs: Vec<PairResult> = (0..clouds.len() - 1)
        .into_par_iter()
        .map(|i| {
            let start = Instant::now();
            let icp = register(&clouds[i + 1], &clouds[i], DMat4::IDENTITY, params)?;
            let seconds = start.elapsed().as_secs_f64();
            let error = seq.gt_scan_to_world.as_ref().map(|gt| {
                let gt_rel = se3::inverse_rigid(&gt[i]) * gt[i + 1];
                pose_error(&icp.t_source_to_target, &gt_rel)
            });
            Ok(PairResult {
                target: i,
                icp,
                seconds,
                error,
            })
        })
        .collect::<Result<_>>()?;
    let mut t = vec![seq
        .gt_scan_to_world
        .as_ref()
        .map_or(DMat4::IDENTITY, |g| g[0])];
    for p in &pairs {
        let last = *t.last().expect("trajectory starts with one pose");
        t.push(last * p.icp.t_source_to_target);
    }
    Ok(Odometry {
        t_scan_to_world: t,
        pairs,
    })
}

/// Per-pair table (tab-separated, header line): scans, status, iterations, final inlier
/// RMSE (m), outlier ratio, seconds, the 12 numbers of the 3x4 `t_source_to_target`
/// (row-major), and with ground truth the rotation (deg) and translation (m) errors.
pub fn format_pairs_tsv(seq: &ScanSequence, odo: &Odometry) -> String {
    let name = |i: usize| {
        seq.scans[i]
            .file_name()
            .map_or_else(|| i.to_string(), |n| n.to_string_lossy().into_owned())
    };
    let mut s = String::from("source\ttarget\tstatus\titerations\trmse_m\toutlier_ratio\tseconds");
    for r in 0..3 {
        for c in 0..4 {
            s.push_str(&format!("\tT{r}{c}"));
        }
    }
    s.push_str("\trot_err_deg\ttrans_err_m\n");
    for p in &odo.pairs {
        let t = &p.icp.t_source_to_target;
        s.push_str(&format!(
            "{}\t{}\t{}\t{}\t{:.6}\t{:.4}\t{:.4}",
            name(p.target + 1),
            name(p.target),
            p.icp.status,
            p.icp.iteration_count(),
            p.icp.final_stats.rmse,
            p.icp.final_stats.outlier_ratio,
            p.seconds
        ));
        for r in 0..3 {
            let row = t.row(r);
            for v in [row.x, row.y, row.z, row.w] {
                s.push_str(&format!("\t{v:.9}"));
            }
        }
        match p.error {
            Some(e) => s.push_str(&format!(
                "\t{:.4}\t{:.4}\n",
                e.rotation_deg, e.translation_m
            )),
            None => s.push_str("\t\t\n"),
        }
    }
    s
}

/// Summary of the relative pose errors of all pairs.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ErrorSummary {
    pub pairs: usize,
    pub mean_rotation_deg: f64,
    pub max_rotation_deg: f64,
    pub mean_translation_m: f64,
    pub max_translation_m: f64,
    /// Distance between the last chained and ground-truth positions, metres.
    pub end_position_error_m: f64,
    /// Ground-truth path length, metres.
    pub gt_path_length_m: f64,
}

/// One line, as `wgslam scan` prints it: the pairs' relative pose errors (mean and largest)
/// and the end drift against the path's length.
impl std::fmt::Display for ErrorSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "relative pose error over {} pairs: rotation mean {:.3} max {:.3} deg, translation \
             mean {:.3} max {:.3} m; end position error {:.3} m over {:.2} m of path",
            self.pairs,
            self.mean_rotation_deg,
            self.max_rotation_deg,
            self.mean_translation_m,
            self.max_translation_m,
            self.end_position_error_m,
            self.gt_path_length_m
        )
    }
}

/// Summarises [`PairResult::error`] and the end drift; `None` without ground truth.
pub fn summarize(seq: &ScanSequence, odo: &Odometry) -> Option<ErrorSummary> {
    let gt = seq.gt_scan_to_world.as_ref()?;
    let errs: Vec<PoseError> = odo.pairs.iter().filter_map(|p| p.error).collect();
    let n = errs.len().max(1) as f64;
    let last = gt.len() - 1;
    Some(ErrorSummary {
        pairs: errs.len(),
        mean_rotation_deg: errs.iter().map(|e| e.rotation_deg).sum::<f64>() / n,
        max_rotation_deg: errs.iter().map(|e| e.rotation_deg).fold(0.0, f64::max),
        mean_translation_m: errs.iter().map(|e| e.translation_m).sum::<f64>() / n,
        max_translation_m: errs.iter().map(|e| e.translation_m).fold(0.0, f64::max),
        end_position_error_m: (odo.t_scan_to_world[last].w_axis - gt[last].w_axis)
            .truncate()
            .length(),
        gt_path_length_m: gt
            .windows(2)
            .map(|w| (w[1].w_axis - w[0].w_axis).truncate().length())
            .sum(),
    })
}
