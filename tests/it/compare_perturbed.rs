//! `compare` holds for any rounding WGSL allows, proven without a GPU: the CPU twins with
//! their arithmetic perturbed within the spec's accuracy table (`wgslam::cpu::arith`, as
//! `tools::compare::PerturbedCpu`) pass against the exact twins, lockstep and free, and
//! planted bugs (one sign flipped in a row of the ICP system, merges skipped) still fail
//! it, naming the stage: one sign flipped in a row of the ICP system, merges skipped, and
//! fusion's off-ray gate 1 % wide (caught by judging each pixel whose fusion decision
//! differs against its knife edge, `tools::compare::decisions`).

use std::path::Path;

use crate::common;

use common::harness::{plain, shared};
use wgslam::cpu::arith::Arith;
use wgslam::dataset::{self, Sequence, SequenceOptions};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{Profile, SlamParams};
use wgslam::tools::compare::{compare, Comparison, Mode, PerturbedCpu, Plant, DEFAULT_SEED};

fn bundled_noisy() -> Sequence {
    dataset::open(&common::bundled_icl_noisy(), &SequenceOptions::default()).unwrap()
}

/// The exact twins against `b` over frames `first..=last` in `mode` (robust profile).
fn against(b: PerturbedCpu, seq: &Sequence, first: usize, last: usize, mode: Mode) -> Comparison {
    let params = SlamParams::profile(Profile::Robust);
    compare(
        CpuBackend::new(),
        b,
        seq,
        first,
        last,
        params.validate().unwrap(),
        mode,
    )
    .unwrap()
}

/// Perturbed against exact passes in `mode`, and the perturbation changed something (the
/// comparison was not of two identical runs).
fn perturbed_passes(seq: &Sequence, first: usize, last: usize, mode: Mode) {
    let c = against(PerturbedCpu::new(DEFAULT_SEED), seq, first, last, mode);
    eprintln!("{} {first}..={last}: worst {:?}", mode.name(), c.worst);
    assert!(c.violations.is_empty(), "{:#?}", c.violations);
    assert!(c.worst.system_rel_diff > 0.0, "{:?}", c.worst);
    assert!(c.worst.pose_diff_mm > 0.0, "{:?}", c.worst);
    assert!(c.worst.vertex_max_abs_m > 0.0, "{:?}", c.worst);
    if let Mode::Lockstep { .. } = mode {
        // Decisions did differ, and every one of them sat on a knife edge.
        let differing: usize = c
            .frames
            .iter()
            .filter_map(|f| f.decisions.as_ref())
            .map(|d| d.differing_pixels)
            .sum();
        eprintln!("fusion decisions differing: {differing} pixels, none clear");
        assert_eq!(c.worst.fusion_clear_flips, 0, "{:?}", c.worst);
    }
}

fn perturbed_passes_on_bundled_frames() {
    let seq = bundled_noisy();
    let last = seq.len() - 1;
    perturbed_passes(&seq, 1, last, Mode::LOCKSTEP);
    perturbed_passes(&seq, 1, last, Mode::Free);
}

fn perturbed_passes_on_7scenes(data: &Path) {
    let dir = data.join("7scenes_redkitchen");
    let seq = dataset::open(&dir, &SequenceOptions::default()).unwrap();
    perturbed_passes(&seq, 0, 20, Mode::LOCKSTEP);
    perturbed_passes(&seq, 0, 20, Mode::Free);
}

/// `mode` over the first frames with `plant` in the perturbed twins: some violation names
/// one of `stages`.
fn planted_bug_fails(plant: Plant, mode: Mode, stages: &[&str]) {
    let seq = bundled_noisy();
    let b = PerturbedCpu::with(Arith::Perturbed { seed: DEFAULT_SEED }, Some(plant));
    let c = against(b, &seq, 1, PLANTED_LAST_FRAME, mode);
    eprintln!("{plant:?}: {:#?}", c.violations);
    for f in &c.frames {
        eprintln!("frame {}: fusion decisions {:?}", f.index, f.decisions);
    }
    assert!(
        c.violations
            .iter()
            .any(|v| stages.iter().any(|s| v.contains(&format!(": {s}: ")))),
        "{plant:?} not caught at {stages:?}: {:#?}",
        c.violations
    );
}

/// Frames 1..=this for the planted bugs: frame 1 fuses the first map, frames 2.. track and
/// fuse against it.
const PLANTED_LAST_FRAME: usize = 6;

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "perturbed_passes_on_bundled_frames",
            perturbed_passes_on_bundled_frames,
        ),
        shared("perturbed_passes_on_7scenes", perturbed_passes_on_7scenes),
        plain("planted_wrong_sign_in_a_system_row_fails", || {
            planted_bug_fails(
                Plant::SystemRowSign,
                Mode::LOCKSTEP,
                &["first ICP system", "pose after ICP"],
            )
        }),
        // The free mode's pose bound grows with the run (a random walk of per-frame
        // differences, `tolerance::pose_max_mm`): a wrong row must still fail it.
        plain("planted_wrong_sign_fails_the_free_mode_too", || {
            planted_bug_fails(Plant::SystemRowSign, Mode::Free, &["pose after ICP"])
        }),
        plain("planted_skipped_merge_fails", || {
            planted_bug_fails(
                Plant::SkippedMerge,
                Mode::LOCKSTEP,
                &["map after the frame"],
            )
        }),
        plain("planted_gate_off_by_one_percent_fails", || {
            planted_bug_fails(
                Plant::FusionGateOnePercent,
                Mode::LOCKSTEP,
                &["fusion decisions"],
            )
        }),
    ]
}
