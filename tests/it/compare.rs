//! `wgslam compare` (`wgslam::tools::compare`): the lockstep mode passes on noisy frames
//! with the robust profile (where two free-running trackers drift apart), is exact for a
//! backend against itself, and names the stage of a real difference; the free mode stays
//! available and the report says which mode ran.

use crate::common;

use common::cli::wgslam;
use common::harness::{gpu, plain};
use wgslam::cpu::arith::Arith;
use wgslam::dataset::{self, Sequence, SequenceOptions};
use wgslam::gpu::GpuBackend;
use wgslam::slam::backend::{Backend, Inspect};
use wgslam::slam::cpu_backend::CpuBackend;
use wgslam::slam::params::{Profile, SlamParams};
use wgslam::tools::compare::{compare, Comparison, Mode, PerturbedCpu, Plant};

fn bundled_noisy() -> Sequence {
    dataset::open(&common::bundled_icl_noisy(), &SequenceOptions::default()).unwrap()
}

/// Lockstep over frames 1..=last of `seq` with the robust profile.
fn lockstep<A: Backend + Inspect, B: Backend + Inspect>(
    a: A,
    b: B,
    seq: &Sequence,
    last: usize,
) -> Comparison {
    let params = SlamParams::profile(Profile::Robust);
    compare(
        a,
        b,
        seq,
        1,
        last,
        params.validate().unwrap(),
        Mode::LOCKSTEP,
    )
    .unwrap()
}

/// The GPU against the CPU reference on the bundled noisy frames with the robust profile:
/// no per-frame tolerance exceeded, and every frame's map compared.
fn lockstep_passes_on_bundled_noisy_frames(gpu: GpuBackend) {
    let seq = bundled_noisy();
    let last = seq.len() - 1;
    let c = lockstep(CpuBackend::new(), gpu, &seq, last);
    eprintln!("worst over frames 1..={last}: {:?}", c.worst);
    assert!(c.violations.is_empty(), "{:#?}", c.violations);
    assert_eq!(c.mode, Mode::LOCKSTEP);
    assert_eq!(c.frames.len(), last);
    assert!(c.frames.iter().all(|f| f.map.is_some()));
    // The frames were tracked and fused (not trivially equal).
    assert!(c.frames.iter().skip(1).all(|f| f.system_rel_diff.is_some()));
    assert!(c.map.surfels.0 > 10_000, "{:?}", c.map);
    // Fusion compared kernel by kernel on every frame: fuse_select's choices agree but for
    // a few pixels, and a fused count that differs shows as new-surfel flags that differ.
    // The maps are the robust profile's, downsampled by 2.
    let pixels = (seq.intrinsics.width / 2 * (seq.intrinsics.height / 2)) as f64;
    for f in &c.frames {
        let k = f
            .fusion
            .as_ref()
            .expect("lockstep compares fusion per kernel");
        eprintln!("frame {}: fusion per kernel {k:?}", f.index);
        assert!(
            k.assoc_pixels as f64 <= FUSION_CHOICE_MISMATCH_MAX_FRACTION * pixels,
            "frame {}: {k:?}",
            f.index
        );
        let (ca, cb) = f.fused_surfels.expect("every frame fused");
        assert!(ca.abs_diff(cb) <= k.flag_slots, "frame {}: {k:?}", f.index);
    }
}

/// Pixels whose `fuse_select` choice may differ between the backends in lockstep, as a
/// fraction of the frame: lavapipe's fused multiply-adds move a surfel's off-ray distance
/// by an ulp, which flips the choice between two surfels about equally near a pixel's ray.
/// Measured at most 35 of 76,800 pixels (0.05%) on the bundled noisy frames.
const FUSION_CHOICE_MISMATCH_MAX_FRACTION: f64 = 1e-3;

/// The CPU reference against itself: lockstep leaves no difference at all.
fn lockstep_of_a_backend_against_itself_is_exact() {
    let seq = bundled_noisy();
    let c = lockstep(CpuBackend::new(), CpuBackend::new(), &seq, 4);
    assert!(c.violations.is_empty(), "{:#?}", c.violations);
    let w = &c.worst;
    let all = [
        w.vertex_max_abs_m,
        w.normal_max_deg,
        w.validity_mismatch_fraction,
        w.system_rel_diff,
        w.pose_diff_mm,
        w.pose_diff_deg,
        w.fused_surfels_rel_diff,
        w.surfels_rel_diff,
        w.map_unmatched_fraction,
        w.map_max_match_m,
        w.map_unexplained_fraction,
        w.map_weight_sum_rel_diff,
        w.fusion_clear_flips as f64,
        w.fusion_clear_flip_relative_margin,
    ];
    assert!(all.iter().all(|&x| x == 0.0), "{w:?}");
    // Kernel by kernel too.
    for f in &c.frames {
        let k = f
            .fusion
            .as_ref()
            .expect("lockstep compares fusion per kernel");
        assert_eq!(k.first_difference(true), None, "frame {}: {k:?}", f.index);
    }
}

/// How many violations name `stage` (one per frame at most).
fn frames_naming(c: &Comparison, stage: &str) -> usize {
    let needle = format!(": {stage}: ");
    // A stage may exceed several bounds in one frame (the map has three): count frames.
    let frames: std::collections::BTreeSet<&str> = c
        .violations
        .iter()
        .filter_map(|v| v.split_once(&needle).map(|(frame, _)| frame))
        .collect();
    frames.len()
}

/// Lockstep catches a map that B received wrong, and says where: the whole map 1 mm off
/// shows in the pose after ICP and in the map after the frame (the first system compared
/// is the finest level's, which B reaches already moved onto the shifted map by the
/// coarser levels, so it need not differ); 2 % of the surfels 5 mm off (too few to move
/// the pose) show in the map after the frame. The frame maps, made from the raw frame
/// alone, stay clean.
fn lockstep_names_the_stage_of_a_perturbed_map() {
    let seq = bundled_noisy();
    let shifted = |shift_um, every| {
        PerturbedCpu::with(Arith::Exact, Some(Plant::ShiftedUpload { shift_um, every }))
    };
    let whole = lockstep(CpuBackend::new(), shifted(1000, 1), &seq, 3);
    eprintln!("whole map 1 mm off: {:#?}", whole.violations);
    // Frame 1 starts from the empty map (nothing to perturb); frames 2 and 3 track on it.
    assert_eq!(frames_naming(&whole, "pose after ICP"), 2);
    assert_eq!(frames_naming(&whole, "map after the frame"), 2);
    assert_eq!(frames_naming(&whole, "preprocess"), 0);
    // The per-kernel comparison of fusion finds the moved surfels where they enter it:
    // fuse_select picks other surfels (or merges give other surfels) on frames 2 and 3.
    for f in &whole.frames[1..] {
        let k = f
            .fusion
            .as_ref()
            .expect("lockstep compares fusion per kernel");
        let first = k.first_difference(true).unwrap_or_default();
        eprintln!("frame {}: first fusion kernel to differ: {first}", f.index);
        assert!(
            first.starts_with("fuse_select") || first.starts_with("fuse_merge_chosen"),
            "frame {}: {k:?}",
            f.index
        );
    }

    let some = lockstep(CpuBackend::new(), shifted(5000, 50), &seq, 3);
    eprintln!("2 % of the map 5 mm off: {:#?}", some.violations);
    assert_eq!(frames_naming(&some, "map after the frame"), 2);
    assert_eq!(frames_naming(&some, "preprocess"), 0);
}

/// The command line: lockstep by default, `--free` for the end-to-end mode; the printed
/// summary and the JSON say which ran. On the bundled noise-free frames both pass.
fn cli_reports_the_mode() {
    let out = common::temp_dir("compare-cli");
    for (extra, mode) in [(None, "lockstep"), (Some("--free"), "free")] {
        let json = out.join(format!("{mode}.json"));
        let mut args = vec![
            "compare",
            "--frames",
            "1..5",
            "--json",
            json.to_str().unwrap(),
        ];
        args.extend(extra);
        let o = wgslam(&args);
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(o.status.success(), "{text}");
        assert!(text.contains(&format!("mode: {mode}")), "{text}");
        assert!(
            text.contains(&format!("documented {mode} tolerances")),
            "{text}"
        );
        let c = common::read_json(&json);
        assert_eq!(c["mode"]["name"], mode, "{}", c["mode"]);
    }
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        gpu("lockstep_passes_on_bundled_noisy_frames", |ctx| {
            lockstep_passes_on_bundled_noisy_frames(GpuBackend::new(ctx).unwrap())
        }),
        plain(
            "lockstep_of_a_backend_against_itself_is_exact",
            lockstep_of_a_backend_against_itself_is_exact,
        ),
        plain(
            "lockstep_names_the_stage_of_a_perturbed_map",
            lockstep_names_the_stage_of_a_perturbed_map,
        ),
        gpu("cli_reports_the_mode", |_ctx| cli_reports_the_mode()),
    ]
}
