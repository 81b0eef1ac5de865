//! TUM RGB-D layout: `rgb.txt` and `depth.txt` (`timestamp path` lines) plus optional
//! `groundtruth.txt`, and the greedy nearest-timestamp association of the TUM benchmark.
//!
//! Only file lists and association live here; decoding is in [`super::frame`].

use std::path::{Path, PathBuf};

use crate::io::text::finite_f64;
use crate::{Error, Result};

/// One `timestamp path` entry of `rgb.txt` or `depth.txt`; `path` is relative to the root.
#[derive(Debug, Clone, PartialEq)]
pub struct ListEntry {
    /// Seconds.
    pub stamp: f64,
    pub path: PathBuf,
}

/// Reads a TUM file list (`#` comments and blank lines skipped). Errors name `file:line`.
pub fn read_list(path: &Path) -> Result<Vec<ListEntry>> {
    let text = super::source::read_string(path, crate::io::input::InputKind::List)?;
    let mut out = Vec::new();
    for (lineno, line) in crate::io::text::data_lines(&text) {
        let mut it = line.split_whitespace();
        let (Some(stamp), Some(file), None) = (it.next(), it.next(), it.next()) else {
            return Err(Error::parse(
                path,
                lineno,
                format!("expected `timestamp path`: {line:?}"),
            ));
        };
        let stamp = finite_f64(stamp).ok_or_else(|| {
            Error::parse(
                path,
                lineno,
                format!("timestamp {stamp:?} is not a number: {line:?}"),
            )
        })?;
        out.push(ListEntry {
            stamp,
            path: PathBuf::from(file),
        });
    }
    Ok(out)
}

/// Greedy association as in the TUM benchmark's `associate.py`: every pair `(a, b)` with
/// `|stamp_a - stamp_b| <= max_dt` is a candidate (inclusive, as [`nearest_within`], so
/// `--max-time-diff 0` pairs identical stamps, and stamps so large that `stamp ± max_dt`
/// rounds back to the stamp, ICL-NUIM indices near 1e15, still pair with equal ones);
/// candidates are taken in order of
/// increasing `|dt|` when neither side is used yet. Returns index pairs `(ia, ib)` sorted by
/// `a`'s stamp. Ties in `|dt|` are broken by index so the result is deterministic.
pub fn associate(a: &[f64], b: &[f64], max_dt: f64) -> Vec<(usize, usize)> {
    // Sort b once and look up each a's window by binary search: O((n + m) log m + pairs).
    let mut b_order: Vec<usize> = (0..b.len()).collect();
    b_order.sort_by(|&i, &j| b[i].total_cmp(&b[j]));
    let b_sorted: Vec<f64> = b_order.iter().map(|&i| b[i]).collect();
    let mut cand: Vec<(f64, usize, usize)> = Vec::new();
    for (ia, &sa) in a.iter().enumerate() {
        let lo = b_sorted.partition_point(|&sb| sb < sa - max_dt);
        for (k, &sb) in b_sorted.iter().enumerate().skip(lo) {
            if sb > sa + max_dt {
                break;
            }
            if (sa - sb).abs() <= max_dt {
                cand.push(((sa - sb).abs(), ia, b_order[k]));
            }
        }
    }
    cand.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    let mut used_a = vec![false; a.len()];
    let mut used_b = vec![false; b.len()];
    let mut out = Vec::new();
    for (_, ia, ib) in cand {
        if !used_a[ia] && !used_b[ib] {
            used_a[ia] = true;
            used_b[ib] = true;
            out.push((ia, ib));
        }
    }
    out.sort_by(|x, y| a[x.0].total_cmp(&a[y.0]).then(x.0.cmp(&y.0)));
    out
}

/// Index of the stamp in `sorted` nearest to `t` if it is within `max_dt` (`sorted` ascending).
pub fn nearest_within(sorted: &[f64], t: f64, max_dt: f64) -> Option<usize> {
    let k = sorted.partition_point(|&s| s < t);
    let mut best: Option<(usize, f64)> = None;
    for j in [k.wrapping_sub(1), k] {
        if let Some(&s) = sorted.get(j) {
            let d = (s - t).abs();
            if d <= max_dt && best.is_none_or(|(_, bd)| d < bd) {
                best = Some((j, d));
            }
        }
    }
    best.map(|(j, _)| j)
}

/// Gives each frame of `seq` the pose of the nearest stamp of the TUM trajectory `path`
/// within the window, with notes on repeated stamps and on frames without one.
pub(crate) fn attach_ground_truth(
    seq: &mut super::Sequence,
    path: Option<&std::path::PathBuf>,
    opts: &super::SequenceOptions,
) -> Result<()> {
    let Some(path) = path else {
        return Ok(());
    };
    let frames = &mut seq.frames;
    let notes = &mut seq.notes;
    let text = super::source::read_string(path, crate::io::input::InputKind::List)?;
    let mut gt = crate::io::trajectory::parse_tum(path, &text)?;
    gt.sort_by(|a, b| a.0.total_cmp(&b.0));
    let gt_stamps: Vec<f64> = gt.iter().map(|g| g.0).collect();
    notes.extend(super::checks::repeated_stamps_note(path, &gt_stamps));
    for f in frames.iter_mut() {
        f.gt_cam_to_world =
            nearest_within(&gt_stamps, f.timestamp, opts.max_time_diff).map(|k| gt[k].1);
    }
    notes.extend(super::checks::coverage_note(
        path,
        &gt_stamps,
        frames,
        opts.max_time_diff,
    ));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn association_is_inclusive_and_survives_large_stamps() {
        // `--max-time-diff 0` with identical stamps used to pair nothing.
        assert_eq!(associate(&[1.0, 2.0], &[2.0, 1.0], 0.0), [(0, 1), (1, 0)]);
        // Near 1e15, `stamp - 0.02` rounds back to the stamp (1 ulp is 0.125).
        let a: Vec<f64> = (0..3).map(|i| 1e15 + i as f64).collect();
        assert_eq!(associate(&a, &a, 0.02), [(0, 0), (1, 1), (2, 2)]);
    }

    #[test]
    fn greedy_takes_best_pairs_first() {
        // a[1] is closer to b[0] than a[0] is, so a[0] must fall back to b[1] or nothing.
        let a = [0.000, 0.010, 0.050];
        let b = [0.012, 0.030, 0.051];
        let pairs = associate(&a, &b, 0.02);
        assert_eq!(pairs, vec![(1, 0), (2, 2)]);
        let pairs = associate(&a, &b, 0.031);
        assert_eq!(pairs, vec![(0, 1), (1, 0), (2, 2)]);
    }

    #[test]
    fn nearest_respects_max_dt() {
        let s = [1.0, 2.0, 3.0];
        assert_eq!(nearest_within(&s, 2.4, 0.5), Some(1));
        assert_eq!(nearest_within(&s, 2.6, 0.5), Some(2));
        assert_eq!(nearest_within(&s, 3.6, 0.5), None);
        assert_eq!(nearest_within(&s, 0.0, 0.5), None);
    }
}
