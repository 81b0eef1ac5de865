//! `wgslam compare`: the CPU reference and the GPU on the same frames, their differences
//! per stage and frame against the documented tolerances.

use std::path::PathBuf;

use clap::Args;

use super::pipeline_args::{frame_range, PipelineArgs};
use crate::slam::any_backend::{self, BackendChoice};
use crate::slam::backend::SlamBackend;
use crate::slam::params::PoseSource;
use crate::tools::{compare, run};
use crate::{Error, Result};

#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Inclusive frame range "A..B" (default: 20 frames from the first with ground truth).
    #[arg(long)]
    pub frames: Option<String>,
    /// Let each backend track on its own state (end to end, as two separate runs) instead
    /// of the default lockstep, where the GPU starts every frame from the CPU's map and pose.
    #[arg(long)]
    pub free: bool,
    /// Lockstep: compare the maps after every K-th frame (and after the last).
    #[arg(long, value_name = "K", default_value_t = 1)]
    pub map_every: usize,
    /// Compare the CPU reference against itself with its arithmetic perturbed as a
    /// conformant GPU may round (fused multiply-adds, ulps of division, sqrt and normalize,
    /// another reduction order; `wgslam::cpu::arith`) instead of against the GPU: needs no
    /// GPU, and shows the tolerances hold for any legal rounding.
    #[arg(long)]
    pub perturbed_cpu: bool,
    /// Write the full comparison as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    // The sequence, a parameter file and the parameters (last, so their help heading
    // follows this command's own options).
    #[command(flatten)]
    pub pipeline: PipelineArgs,
}

/// Runs `wgslam compare`.
pub fn execute(a: CompareArgs) -> Result<()> {
    let setup = a.pipeline.resolve()?;
    let params = setup.slam_params(PoseSource::Track)?;
    let seq = setup.open_sequence(&params)?;
    let (first, last) = frame_range(&seq, &a.frames, 20)?;
    let mode = if a.free {
        compare::Mode::Free
    } else {
        compare::Mode::Lockstep {
            map_every: a.map_every.max(1),
        }
    };
    let other: Box<dyn SlamBackend> = match a.perturbed_cpu {
        true => Box::new(compare::PerturbedCpu::new(compare::DEFAULT_SEED)),
        false => any_backend::open(BackendChoice::Gpu)?,
    };
    let cpu = any_backend::open(BackendChoice::Cpu)?;
    println!("mode: {}", describe_mode(mode));
    let c = compare::compare(cpu, other, &seq, first, last, params, mode)?;
    print_frames(&c.frames);
    print_final_map(&c.map);
    print_worst(&c);
    if let Some(path) = &a.json {
        run::write_json(path, &c)?;
    }
    verdict(&c)
}

/// How `mode` drives the two backends, in words.
fn describe_mode(mode: compare::Mode) -> String {
    match mode {
        compare::Mode::Lockstep { map_every } => format!(
            "lockstep (the GPU starts every frame from the CPU's map and pose; maps \
             compared every {map_every} frame(s) and after the last)"
        ),
        compare::Mode::Free => "free (each backend tracks on its own state)".into(),
    }
}

/// The table of per-frame differences, a line per frame.
fn print_frames(frames: &[compare::FrameDiff]) {
    println!(
        "frame  vertex(m)  normal(deg)  valid-mismatch  system-rel   pose(mm)  pose(deg)  \
         fused cpu/gpu    surfels cpu/gpu  map-unmatched  fusion assoc/flags/offsets"
    );
    for f in frames {
        let opt = |x: Option<String>| x.unwrap_or_else(|| "-".into());
        println!(
            "{:5}  {:9.2e}  {:11.5}  {:13.5}%  {:>10}  {:9.5}  {:9.6}  {:>15}  {:>15}  {:>13}  {:>26}",
            f.index,
            f.maps.vertex_max_abs_m,
            f.maps.normal_max_deg,
            f.maps.validity_mismatch_fraction * 100.0,
            opt(f.system_rel_diff.map(|r| format!("{r:.2e}"))),
            f.pose_diff_mm,
            f.pose_diff_deg,
            opt(f.fused_surfels.map(|(a, b)| format!("{a}/{b}"))),
            format!("{}/{}", f.surfels.0, f.surfels.1),
            opt(f
                .map
                .as_ref()
                .map(|m| format!("{:.4}%", m.unmatched_fraction() * 100.0))),
            // Fusion kernel by kernel: pixels or slots that differ (lockstep mode).
            opt(f.fusion.as_ref().map(|k| format!(
                "{}/{}/{}",
                k.assoc_pixels, k.flag_slots, k.offset_slots
            ))),
        );
    }
}

/// The line on the maps after the last frame.
fn print_final_map(map: &compare::SurfelMapDiff) {
    println!(
        "map after the last frame: {} vs {} surfels; unmatched within {} mm: {:.4}% cpu, \
         {:.4}% gpu; match distance mean {:.2e} m, max {:.2e} m",
        map.surfels.0,
        map.surfels.1,
        map.match_radius_m * 1e3,
        map.unmatched_a_fraction * 100.0,
        map.unmatched_b_fraction * 100.0,
        map.mean_match_m,
        map.max_match_m
    );
}

/// The line on the largest difference of each kind.
fn print_worst(c: &compare::Comparison) {
    let w = &c.worst;
    println!(
        "worst ({} mode, {} frames): vertex {:.2e} m, normal {:.5} deg, validity {:.5}%, \
         system {:.2e}, pose {:.5} mm / {:.6} deg, surfel counts {:.2e} fused / {:.2e} after \
         the frame, map unmatched {:.4}% (max match {:.2e} m), unexplained {:.4}%, total \
         weight {:.2e}, fusion decisions clear of their knife edge {} (largest margin {:.2e} \
         of the gate)",
        c.mode.name(),
        c.frames.len(),
        w.vertex_max_abs_m,
        w.normal_max_deg,
        w.validity_mismatch_fraction * 100.0,
        w.system_rel_diff,
        w.pose_diff_mm,
        w.pose_diff_deg,
        w.fused_surfels_rel_diff,
        w.surfels_rel_diff,
        w.map_unmatched_fraction * 100.0,
        w.map_max_match_m,
        w.map_unexplained_fraction * 100.0,
        w.map_weight_sum_rel_diff,
        w.fusion_clear_flips,
        w.fusion_clear_flip_relative_margin
    );
}

/// Agreement, or each tolerance exceeded and an error counting them.
fn verdict(c: &compare::Comparison) -> Result<()> {
    if c.violations.is_empty() {
        println!(
            "backends agree within the documented {} tolerances (src/tools/compare/tolerance.rs)",
            c.mode.name()
        );
        Ok(())
    } else {
        for v in &c.violations {
            println!("beyond tolerance: {v}");
        }
        Err(Error::Numerical(format!(
            "{} comparisons beyond the {} tolerances",
            c.violations.len(),
            c.mode.name()
        )))
    }
}
