//! Unit tests of loop closure's rules (`slam::loops`): bends, contradictions and how a
//! correction is measured, on a synthetic straight run.

use glam::{DMat4, DVec3};

use super::{Candidate, LoopAction, LoopClosure, LoopKind, Snapshot};
use crate::slam::keyframes::KeyframeDatabase;
use crate::slam::params::{LoopSettings, RelocalisationSettings};
use crate::slam::solve::IcpIteration;

/// A camera moving 10 mm per frame along x, frames 0..=`last`, with a keyframe (a
/// node and a snapshot) at frame 0; a node every 10 frames.
fn straight_run(last: u32) -> LoopClosure {
    let mut lc = LoopClosure::new(LoopSettings::default(), 1);
    for f in 0..=last {
        let snapshot = (f == 0).then(|| {
            Snapshot::new(
                vec![[0.0, 0.0, 1.0, 1.0]; 10],
                vec![[0.0, 0.0, -1.0, 1.0]; 10],
            )
        });
        lc.record(f, pose(f), snapshot);
    }
    lc
}

fn pose(frame: u32) -> DMat4 {
    DMat4::from_translation(DVec3::new(0.01 * frame as f64, 0.0, 0.0))
}

/// Records the frames after the last one up to `frame`, tracking on from the last
/// pose as now estimated (its offset along y kept, as after a bend).
fn record_to(lc: &mut LoopClosure, frame: u32) {
    let last = lc.poses().last().unwrap();
    let (next, y) = (last.frame + 1, last.estimate.w_axis.y);
    for f in next..=frame {
        let shift = DMat4::from_translation(DVec3::new(0.0, y, 0.0));
        lc.record(f, shift * pose(f), None);
    }
}

/// Records frames up to `frame` and a verified loop of it to keyframe 0 that puts
/// it `offset_m` along y from its tracked pose; returns what `close` did.
fn loop_at(lc: &mut LoopClosure, frame: u32, offset_m: f64) -> Option<LoopAction> {
    record_to(lc, frame);
    let tracked = lc.poses().last().unwrap().estimate;
    let t_loop = DMat4::from_translation(DVec3::new(0.0, offset_m, 0.0)) * tracked;
    verified_loop(lc, frame, &t_loop)
}

/// Records frames up to `frame` and a verified loop of it to keyframe 0 that turns it
/// `deg` about its own centre (its optical axis); returns what `close` did.
fn turning_loop_at(lc: &mut LoopClosure, frame: u32, deg: f64) -> Option<LoopAction> {
    record_to(lc, frame);
    let tracked = lc.poses().last().unwrap().estimate;
    let t_loop = tracked * DMat4::from_rotation_z(deg.to_radians());
    verified_loop(lc, frame, &t_loop)
}

/// Judges and closes a loop of the last recorded `frame` to keyframe 0 that puts it at
/// `t_loop` (camera to world); returns what `close` did.
fn verified_loop(lc: &mut LoopClosure, frame: u32, t_loop: &DMat4) -> Option<LoopAction> {
    let candidate = Candidate {
        keyframe_frame: 0,
        kind: LoopKind::Global,
        similarity: Some(1.0),
    };
    let it = IcpIteration {
        level: 1,
        inliers: 10,
        mean_sq_residual: 1e-6,
        eigen_ratio: Some(0.01),
        ..IcpIteration::default()
    };
    let tracked = lc.poses().last().unwrap().estimate;
    lc.judge(frame, &candidate, &[it], None, &tracked, t_loop)
        .unwrap();
    let mut db = KeyframeDatabase::new(&RelocalisationSettings::default());
    let (nodes, _) = lc.close(frame, 0, t_loop, &mut db);
    let record = lc.loops().last().unwrap();
    assert_eq!(nodes.is_some(), record.action == Some(LoopAction::Bent));
    record.action
}

/// A confirmed 30 mm loop on a trajectory with no other loop bends, and the bend
/// takes most of the disagreement off its edge.
#[test]
fn a_free_loop_bends() {
    let mut lc = straight_run(100);
    assert_eq!(
        loop_at(&mut lc, 105, 0.03),
        Some(LoopAction::AwaitingConfirmation)
    );
    assert_eq!(loop_at(&mut lc, 110, 0.03), Some(LoopAction::Bent));
    let check = lc.loops().last().unwrap().check.unwrap();
    assert!(check.loop_after <= 0.5 * check.loop_before, "{check:?}");
    assert_eq!(check.other_loop_growth, 0.0);
}

/// A loop at 105/110 bent frame 110 30 mm along y; loops at 125/130 then claim 30 mm
/// back, against what the first one measured 20 frames earlier (healthy tracking
/// cannot drift 60 mm in 20 frames): bending for them would tear the first loop's
/// edge, so the loop is rejected and nothing moves.
#[test]
fn a_loop_the_graph_contradicts_is_rejected() {
    let mut lc = straight_run(100);
    loop_at(&mut lc, 105, 0.03);
    assert_eq!(loop_at(&mut lc, 110, 0.03), Some(LoopAction::Bent));
    record_to(&mut lc, 120);
    let before: Vec<DMat4> = lc.poses().iter().map(|p| p.estimate).collect();
    assert_eq!(
        loop_at(&mut lc, 125, -0.03),
        Some(LoopAction::AwaitingConfirmation)
    );
    assert_eq!(loop_at(&mut lc, 130, -0.03), None);
    let record = lc.loops().last().unwrap();
    let check = record.check.unwrap();
    assert!(
        check.other_loop_growth > LoopSettings::default().other_edge_slack_m,
        "{check:?}"
    );
    assert!(record.rejected.as_deref().unwrap().contains("another loop"));
    assert!(record.optimised.is_none());
    let after: Vec<DMat4> = lc.poses().iter().map(|p| p.estimate).collect();
    assert_eq!(before[..], after[..before.len()], "nothing moved");
}

/// A loop's correction is measured as the camera sees it, wherever the world's origin
/// is: frames 105 and 110 (1.05 and 1.1 m from the origin) are turned 1.2 and 2
/// degrees about their own centres. Each moves its camera 0 mm, and the two agree
/// within 1 degree and 10 mm, so the second confirms the first and bends. As
/// differences of camera-to-world poses they would read 22 mm and disagree by 16 mm.
#[test]
fn a_loops_correction_does_not_depend_on_the_worlds_origin() {
    let mut lc = straight_run(100);
    let first = turning_loop_at(&mut lc, 105, 1.2);
    let second = turning_loop_at(&mut lc, 110, 2.0);
    assert_eq!(
        [first, second],
        [
            Some(LoopAction::AwaitingConfirmation),
            Some(LoopAction::Bent)
        ]
    );
    let measured = &lc.loops()[0];
    assert!(measured.correction_m < 1e-9, "{}", measured.correction_m);
    let turn = measured.correction_deg;
    assert!((turn - 1.2).abs() < 1e-6, "{turn}");
}
