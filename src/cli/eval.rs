//! `wgslam eval`: ATE and RPE of an estimated TUM trajectory against a ground truth.

use std::path::PathBuf;

use clap::Args;

use crate::{eval, io, Result};

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Estimated trajectory, TUM format.
    pub estimate: PathBuf,
    /// Ground truth: a TUM trajectory file (ICL-NUIM's *.gt.freiburg works), or a dataset
    /// folder in any layout `run` reads, whose own ground truth is used (7-Scenes and
    /// ScanNet pose files, Replica's traj.txt, ...).
    pub ground_truth: PathBuf,
    /// RPE frame distance.
    #[arg(long, default_value_t = 1)]
    pub delta: usize,
    /// Write a trajectory plot (estimate vs ground truth from above, and the error over
    /// frames) to this PNG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// Runs `wgslam eval`.
pub fn execute(a: EvalArgs) -> Result<()> {
    let est = io::trajectory::read_tum(&a.estimate)?;
    let gt = if a.ground_truth.is_dir() {
        // Only the ground truth is used: a layout with no recorded intrinsics (plain TUM)
        // gets a placeholder instead of an error asking for `--intrinsics`, which `eval`
        // neither takes nor needs.
        let opts = crate::dataset::SequenceOptions {
            intrinsics: Some(crate::geometry::camera::Intrinsics::ICL_NUIM),
            ..crate::dataset::SequenceOptions::default()
        };
        let seq = crate::dataset::open(&a.ground_truth, &opts)?;
        for note in &seq.notes {
            eprintln!("note: {note}");
        }
        if !seq.has_ground_truth() {
            return Err(crate::Error::format(
                &a.ground_truth,
                format!("the {} dataset here has no ground truth", seq.layout.name()),
            ));
        }
        seq.ground_truth()
    } else {
        let gt = io::trajectory::read_tum(&a.ground_truth)?;
        let mut stamps: Vec<f64> = gt.iter().map(|p| p.0).collect();
        stamps.sort_by(f64::total_cmp);
        if let Some(note) = crate::dataset::repeated_stamps_note(&a.ground_truth, &stamps) {
            eprintln!("note: {note}");
        }
        gt
    };
    let aligned = eval::ate(&est, &gt, true)?;
    let unaligned = eval::ate(&est, &gt, false)?;
    let rpe = eval::rpe(&est, &gt, a.delta)?;
    println!(
        "ATE RMSE {:.3} mm aligned, {:.3} mm unaligned ({} poses)",
        aligned.rmse_m * 1e3,
        unaligned.rmse_m * 1e3,
        aligned.pairs
    );
    println!(
        "RPE (delta {}): translation RMSE {:.3} mm, rotation RMSE {:.4} deg ({} pairs)",
        a.delta,
        rpe.trans_rmse_m * 1e3,
        rpe.rot_rmse_deg,
        rpe.pairs
    );
    if let Some(path) = &a.plot {
        crate::render::plot::write_trajectory_plot(path, &est, &gt)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
