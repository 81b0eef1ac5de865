//! Checks of an opened sequence that need only its inputs, done before the first frame is
//! decoded rather than after the last one is tracked: intrinsics within physical bounds,
//! frame stamps distinct (and a note when a list was out of time order), and how much of
//! the sequence a ground-truth file covers, and where the ground truth jumps.
//!
//! It reads no file; [`super::open`] calls it with what it has read.

use std::path::Path;

use super::{FrameRecord, Interface, Layout, SequenceOptions, StampOrder};
use crate::geometry::camera::Intrinsics;
use crate::{Error, Result};

/// Largest accepted focal length, pixels: a 1e6 px focal length is a 0.05 degree field of
/// view on a 1000 px image, far narrower than any depth camera; 1e39 (f32 overflow) or 1e300
/// is a corrupt file.
pub const MAX_FOCAL_PX: f32 = 1e6;
/// Smallest accepted focal length, pixels: below 1 px the whole image spans more than 180
/// degrees, which a pinhole cannot.
pub const MIN_FOCAL_PX: f32 = 1.0;
/// Largest accepted `|cx|`, `|cy|`, pixels: the principal point sits on or near the image;
/// 1e6 px is far off any real sensor.
pub const MAX_PRINCIPAL_PX: f32 = 1e6;

/// Checks that `k`'s numbers are physical; `source` says where they came from (a file, or
/// `--intrinsics`) so the error can name it.
pub fn intrinsics_in_bounds(k: &Intrinsics, source: &str) -> Result<()> {
    pinhole_in_bounds([k.fx, k.fy, k.cx, k.cy], source)
}

/// [`intrinsics_in_bounds`] of `[fx, fy, cx, cy]` in pixels, as an intrinsics file gives
/// them (before the image size is known).
pub fn pinhole_in_bounds([fx, fy, cx, cy]: [f32; 4], source: &str) -> Result<()> {
    let focal_ok = |f: f32| f.is_finite() && (MIN_FOCAL_PX..=MAX_FOCAL_PX).contains(&f.abs());
    let centre_ok = |c: f32| c.is_finite() && c.abs() <= MAX_PRINCIPAL_PX;
    if focal_ok(fx) && focal_ok(fy) && centre_ok(cx) && centre_ok(cy) {
        return Ok(());
    }
    Err(Error::Argument(format!(
        "intrinsics from {source} (fx {fx} fy {fy} cx {cx} cy {cy}, pixels) are not a \
         camera's: focal lengths must be within {MIN_FOCAL_PX}..{MAX_FOCAL_PX:e} px in \
         magnitude and the principal point within {MAX_PRINCIPAL_PX:e} px; check the numbers"
    )))
}

/// Checks that the frames' stamps are distinct: a trajectory with a repeated stamp cannot
/// be evaluated, and the run would find out only after its last frame. `root` names the
/// sequence in the error.
pub fn stamps_distinct(root: &Path, frames: &[FrameRecord]) -> Result<()> {
    let mut stamps: Vec<f64> = frames.iter().map(|f| f.timestamp).collect();
    stamps.sort_by(f64::total_cmp);
    let repeats: Vec<f64> = stamps
        .windows(2)
        .filter(|w| w[0] == w[1])
        .map(|w| w[0])
        .collect();
    match repeats.first() {
        None => Ok(()),
        Some(first) => Err(Error::format(
            root,
            format!(
                "{} frame(s) share a stamp with another frame (the first at stamp {first}; \
                 stamps beyond 2^53 or near 1e17 s also collapse into one in f64): a trajectory \
                 of these frames cannot be written or evaluated; give each frame its own stamp \
                 in the frame list",
                repeats.len()
            ),
        )),
    }
}

/// Refuses `StampOrder::File` for a layout whose frames are numbered files (7-Scenes,
/// ScanNet, Replica): there is no frame list whose order it could choose, and an option
/// that does nothing is refused, in `opts.interface`'s words.
pub fn stamp_order_applies(root: &Path, layout: Layout, opts: &SequenceOptions) -> Result<()> {
    let stamped = matches!(
        layout,
        Layout::Tum | Layout::IclNuim | Layout::Eth3d | Layout::Bonn
    );
    if opts.stamp_order == StampOrder::Time || stamped {
        return Ok(());
    }
    let option = match opts.interface {
        Interface::Python => "params={\"stamp-order\": \"file\"}",
        _ => "--stamp-order file",
    };
    Err(Error::Argument(format!(
        "{option}: {} is a {} sequence, whose frames are numbered files in number order \
         (no frame list whose stamps could go backwards); leave it out",
        root.display(),
        layout.name()
    )))
}

/// A note when the ground truth at `gt_path` repeats stamps (`sorted`: its stamps in
/// order): a frame near a repeated stamp is matched to one of its poses, which one is
/// arbitrary. `None` when every stamp is its own.
pub fn repeated_stamps_note(gt_path: &Path, sorted: &[f64]) -> Option<String> {
    let repeats: Vec<f64> = sorted
        .windows(2)
        .filter(|w| w[0] == w[1])
        .map(|w| w[0])
        .collect();
    let first = repeats.first()?;
    Some(format!(
        "{}: {} pose(s) repeat the stamp of the pose before (the first at stamp {first}); a \
         frame at such a stamp is matched to one of them, which one is arbitrary: give each \
         pose its own stamp",
        gt_path.display(),
        repeats.len()
    ))
}

/// A note when `stamps`, in the order of `list`'s lines, go backwards, saying which order
/// the frames are used in (`order`) and how to choose the other (in `interface`'s words).
/// `None` when they are in order.
pub fn order_note(
    list: &Path,
    stamps: &[f64],
    order: StampOrder,
    interface: Interface,
) -> Option<String> {
    let backwards = stamps.windows(2).filter(|w| w[1] < w[0]).count();
    (backwards > 0).then(|| {
        let (file_order, chosen) = match interface {
            Interface::CommandLine => ("pass --stamp-order file", "--stamp-order file"),
            Interface::Python => (
                "pass params={\"stamp-order\": \"file\"}",
                "params={\"stamp-order\": \"file\"}",
            ),
            Interface::Page => ("the page cannot choose file order", "file order"),
        };
        let used = match order {
            StampOrder::Time => format!(
                "frames are used in order of time (sorted by stamp); if the stamps are not \
                 times (per-frame intervals, a reset clock), {file_order}"
            ),
            StampOrder::File => format!(
                "frames are used in file order ({chosen}); their stamps, and so the \
                 trajectory's, go backwards"
            ),
        };
        format!(
            "{}: stamps go backwards {backwards} time(s) in file order; {used}",
            list.display()
        )
    })
}

/// A note saying how many of `frames` the ground truth at `gt_path` covers, when it
/// covers fewer than half: `None` otherwise (ICL-NUIM's frame 0 has no pose, and a
/// recording's first and last frames often fall outside the motion capture). With no pose at all the note
/// says why there will be no ATE and what to check (an offset clock, the wrong file).
pub fn coverage_note(
    gt_path: &Path,
    gt_stamps: &[f64],
    frames: &[FrameRecord],
    max_dt: f64,
) -> Option<String> {
    let covered = frames
        .iter()
        .filter(|f| f.gt_cam_to_world.is_some())
        .count();
    if covered * 2 >= frames.len() {
        return None;
    }
    let range = |v: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(s), hi.max(s))
        });
        format!("{lo}..{hi}")
    };
    let gt_range = range(&mut gt_stamps.iter().copied());
    let frame_range = range(&mut frames.iter().map(|f| f.timestamp));
    if covered == 0 {
        return Some(format!(
            "ground truth {} covers none of the {} frames (its stamps {gt_range}, the frames' \
             {frame_range}, within {max_dt} s): no ATE or RPE will be computed; is it the \
             right file, or are its stamps offset?",
            gt_path.display(),
            frames.len()
        ));
    }
    Some(format!(
        "ground truth {} covers {covered} of the {} frames (its stamps {gt_range}, the \
         frames' {frame_range}); errors are over those frames only",
        gt_path.display(),
        frames.len()
    ))
}

/// A ground-truth step counts as a jump when its speed is more than this many times the
/// sequence's median speed: a hand-held or robot camera accelerates smoothly, so five times
/// the median within one frame interval is a reference glitch or frames missing from the
/// recording (7-Scenes redkitchen's reference moves 36 mm between frames 121 and 122, seven
/// times its median step, where two-frame ICP at full resolution measures 5-7 mm).
pub const JUMP_SPEED_FACTOR: f64 = 5.0;
/// ... and its camera centre moves at least this far (metres): below a Kinect's noise at
/// 1-2 m a step says nothing about the reference.
pub const JUMP_MIN_STEP_M: f64 = 0.02;
/// ... or it turns at least this much (degrees).
pub const JUMP_MIN_TURN_DEG: f64 = 1.0;
/// Fewest consecutive ground-truth pairs for a median speed worth comparing with.
const JUMP_MIN_PAIRS: usize = 10;

/// The angle (radians) between two poses' rotations, each first made the nearest rotation:
/// 7-Scenes' reference rotations are scaled by about 1e-4, which the trace alone reads as
/// a degree between equal poses.
fn turn(a: &glam::DMat4, b: &glam::DMat4) -> f64 {
    use crate::geometry::{rigid::nearest_rotation, se3};
    let rotation = |t: &glam::DMat4| nearest_rotation(se3::to_rt(t).0);
    let relative = rotation(b) * rotation(a).transpose();
    se3::rotation_angle(&se3::from_rt(relative, glam::DVec3::ZERO))
}

/// A note naming the ground truth's jumps: consecutive frames between which the reference
/// pose moves (camera centre) or turns faster than [`JUMP_SPEED_FACTOR`] times its median
/// speed, by at least [`JUMP_MIN_STEP_M`] or [`JUMP_MIN_TURN_DEG`]. Speeds are per stamp
/// unit, so a gap in the stamps (dropped frames of a timed recording) is no jump. `None`
/// when there is none or too little ground truth to judge. ATE and RPE are computed
/// against the reference as it is: the note says where it, not tracking, may be wrong.
/// `frames` are the run's, the first of them frame `first` of the sequence (the numbers
/// the note gives).
pub fn jump_note(frames: &[FrameRecord], first: usize) -> Option<String> {
    struct Step {
        at: usize,
        step_m: f64,
        turn_deg: f64,
        dt: f64,
    }
    let steps: Vec<Step> = frames
        .windows(2)
        .enumerate()
        .filter_map(|(i, w)| {
            let (a, b) = (w[0].gt_cam_to_world?, w[1].gt_cam_to_world?);
            let dt = w[1].timestamp - w[0].timestamp;
            let step_m = (b.w_axis - a.w_axis).truncate().length();
            let turn_deg = turn(&a, &b).to_degrees();
            (dt > 0.0).then_some(Step {
                at: i + 1,
                step_m,
                turn_deg,
                dt,
            })
        })
        .collect();
    if steps.len() < JUMP_MIN_PAIRS {
        return None;
    }
    let median = |f: &dyn Fn(&Step) -> f64| {
        let mut v: Vec<f64> = steps.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let speed = median(&|s| s.step_m / s.dt);
    let turn_speed = median(&|s| s.turn_deg / s.dt);
    let jumps: Vec<&Step> = steps
        .iter()
        .filter(|s| {
            (s.step_m >= JUMP_MIN_STEP_M && s.step_m / s.dt > JUMP_SPEED_FACTOR * speed)
                || (s.turn_deg >= JUMP_MIN_TURN_DEG
                    && s.turn_deg / s.dt > JUMP_SPEED_FACTOR * turn_speed)
        })
        .collect();
    let worst = jumps.iter().max_by(|a, b| {
        (a.step_m / a.dt / speed.max(f64::MIN_POSITIVE))
            .total_cmp(&(b.step_m / b.dt / speed.max(f64::MIN_POSITIVE)))
    })?;
    let (i, j) = (worst.at - 1, worst.at);
    let (fi, fj) = (first + i, first + j);
    Some(format!(
        "ground truth jumps {} time(s) faster than {JUMP_SPEED_FACTOR} times its median \
         speed; the largest: {:.1} mm / {:.2} deg between frames {fi} and {fj} (stamps {} and \
         {}), where its median step is {:.1} mm / {:.2} deg. A reference glitch or frames \
         missing from the recording: ATE and RPE include it",
        jumps.len(),
        1e3 * worst.step_m,
        worst.turn_deg,
        frames[i].timestamp,
        frames[j].timestamp,
        1e3 * speed * worst.dt,
        turn_speed * worst.dt,
    ))
}

/// The association window must be a finite, non-negative number of seconds.
pub(crate) fn max_time_diff(opts: &super::SequenceOptions) -> crate::Result<()> {
    if !(opts.max_time_diff.is_finite() && opts.max_time_diff >= 0.0) {
        return Err(crate::Error::Argument(format!(
            "max time difference must be finite and >= 0, got {}",
            opts.max_time_diff
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(t: f64, gt: bool) -> FrameRecord {
        FrameRecord {
            timestamp: t,
            rgb_path: "r.png".into(),
            depth_path: "d.png".into(),
            gt_cam_to_world: gt.then_some(glam::DMat4::IDENTITY),
        }
    }

    #[test]
    fn intrinsics_beyond_physical_bounds_are_refused() {
        let k = Intrinsics::ICL_NUIM;
        assert!(
            intrinsics_in_bounds(&k, "x").is_ok(),
            "negative fy is a real camera's"
        );
        for bad in [1e39f64 as f32, f32::NAN, 0.5, 2e6] {
            let e = intrinsics_in_bounds(&Intrinsics { fx: bad, ..k }, "cam.txt");
            assert!(e.unwrap_err().to_string().contains("cam.txt"), "fx {bad}");
        }
        assert!(intrinsics_in_bounds(&Intrinsics { cy: -3e6, ..k }, "x").is_err());
    }

    #[test]
    fn repeated_stamps_fail_before_any_frame() {
        let ok = [frame(1.0, false), frame(2.0, false)];
        assert!(stamps_distinct(Path::new("s"), &ok).is_ok());
        let big = 2f64.powi(53);
        let bad = [frame(big, false), frame(big + 1.0, false)];
        let e = stamps_distinct(Path::new("s"), &bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains("1 frame(s) share a stamp"), "{e}");
    }

    #[test]
    fn repeated_ground_truth_stamps_are_noted() {
        let gt = Path::new("gt.txt");
        assert_eq!(repeated_stamps_note(gt, &[1.0, 2.0, 3.0]), None);
        let n = repeated_stamps_note(gt, &[1.0, 2.0, 2.0, 3.0, 3.0]).unwrap();
        assert!(
            n.contains("gt.txt: 2 pose(s) repeat") && n.contains("at stamp 2"),
            "{n}"
        );
    }

    #[test]
    fn backwards_stamps_and_partial_ground_truth_are_noted() {
        let time = StampOrder::Time;
        let cli = Interface::CommandLine;
        assert_eq!(
            order_note(Path::new("d.txt"), &[1.0, 2.0, 3.0], time, cli),
            None
        );
        let n = order_note(Path::new("d.txt"), &[1.0, 3.0, 2.0, 4.0, 0.5], time, cli).unwrap();
        assert!(n.contains("--stamp-order file"), "{n}");
        let py = order_note(Path::new("d.txt"), &[1.0, 0.5], time, Interface::Python).unwrap();
        assert!(py.contains(r#"params={"stamp-order": "file"}"#), "{py}");
        let f = order_note(Path::new("d.txt"), &[1.0, 0.5], StampOrder::File, cli).unwrap();
        assert!(f.contains("used in file order"), "{f}");
        assert!(
            n.contains("d.txt") && n.contains("backwards 2 time(s)"),
            "{n}"
        );
        let gt = Path::new("gt.txt");
        let all = [frame(1.0, true), frame(2.0, true)];
        assert_eq!(coverage_note(gt, &[1.0, 2.0], &all, 0.02), None);
        let none = [frame(1.0, false), frame(2.0, false)];
        let n = coverage_note(gt, &[101.0, 102.0], &none, 0.02).unwrap();
        assert!(
            n.contains("covers none of the 2") && n.contains("101..102"),
            "{n}"
        );
        let half = [frame(1.0, true), frame(2.0, false)];
        assert_eq!(coverage_note(gt, &[1.0], &half, 0.02), None);
        let third = [frame(1.0, true), frame(2.0, false), frame(3.0, false)];
        let n = coverage_note(gt, &[1.0], &third, 0.02).unwrap();
        assert!(n.contains("covers 1 of the 3"), "{n}");
    }

    #[test]
    fn a_ground_truth_jump_is_noted_and_a_stamp_gap_is_not() {
        // A camera moving 5 mm per frame along x, with one 36 mm step at frame 12 (as
        // 7-Scenes' reference at frame 122).
        let at = |t: f64, x: f64| FrameRecord {
            gt_cam_to_world: Some(glam::DMat4::from_translation(glam::DVec3::new(x, 0.0, 0.0))),
            ..frame(t, true)
        };
        let mut x = 0.0;
        let mut frames = Vec::new();
        for i in 0..30 {
            x += if i == 12 { 0.036 } else { 0.005 };
            frames.push(at(i as f64, x));
        }
        let n = jump_note(&frames, 0).expect("a 36 mm step among 5 mm ones is a jump");
        assert!(
            n.contains("1 time(s)") && n.contains("36.0 mm") && n.contains("frames 11 and 12"),
            "{n}"
        );
        // The same 36 mm over a stamp gap of 8 frames (dropped frames) is the median speed.
        let mut gap = frames.clone();
        for (k, f) in gap.iter_mut().enumerate().skip(12) {
            f.timestamp = k as f64 + 7.0;
        }
        assert_eq!(jump_note(&gap, 0), None);
        // Too few pairs to judge.
        assert_eq!(jump_note(&frames[..5], 0), None);
        // Numbered as the sequence's frames; a run that stops before the jump has no note
        // (7-Scenes 0..99 was told of a jump at frames 121-122).
        let n = jump_note(&frames[2..], 2).unwrap();
        assert!(n.contains("frames 11 and 12"), "{n}");
        assert_eq!(jump_note(&frames[..12], 0), None);
    }
}
