//! `wgslam icp`: two-frame ICP of a sequence's frames, every iteration printed.

use std::path::PathBuf;

use clap::Args;

use super::pipeline_args::PipelineArgs;
use crate::slam::any_backend::{self, BackendChoice};
use crate::slam::params::PoseSource;
use crate::tools::two_frame;
use crate::Result;

#[derive(Debug, Args)]
pub struct IcpArgs {
    /// Implementation: auto, cpu or gpu.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Source frame (its points are the model).
    #[arg(long, default_value_t = 10)]
    pub source: usize,
    /// Target frame (aligned to the source); default 50, or the last frame of a shorter
    /// sequence (the bundled one has 24).
    #[arg(long)]
    pub target: Option<usize>,
    /// Write result.json and before/after overlay pictures (icp_before.png, icp_after.png)
    /// here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    // The sequence, a parameter file and the parameters (last, so their help heading
    // follows this command's own options).
    #[command(flatten)]
    pub pipeline: PipelineArgs,
}

/// Runs `wgslam icp`.
pub fn execute(a: IcpArgs) -> Result<()> {
    let setup = a.pipeline.resolve()?;
    let params = setup.slam_params(PoseSource::Track)?;
    let seq = setup.open_sequence(&params)?;
    let target = a.target.unwrap_or(50.min(seq.len() - 1));
    seq.select(a.source.min(target), a.source.max(target))?;
    let r = two_frame::align_frames(
        any_backend::open(a.backend)?,
        &seq,
        a.source,
        target,
        params,
    )?;
    println!("frames {} -> {target}", a.source);
    println!("iter  level  inliers  mean squared residual (m^2)");
    for (i, it) in r.iterations.iter().enumerate() {
        println!(
            "{i:4}  {:5}  {:7}  {:.6e}",
            it.level, it.inliers, it.mean_sq_residual
        );
    }
    println!("status: {:?}", r.status);
    let t = glam::DMat4::from_cols_array_2d(&r.t_source_to_target);
    println!("T_source_to_target (row-major):");
    for row in 0..4 {
        let rv = t.row(row);
        println!("  {:10.6} {:10.6} {:10.6} {:10.6}", rv.x, rv.y, rv.z, rv.w);
    }
    if let (Some(re), Some(te), Some((gr, gt))) =
        (r.rotation_error_deg, r.translation_error_m, r.gt_motion)
    {
        println!(
            "against ground truth: rotation error {re:.4} deg, translation error {:.2} mm \
             (true motion {gr:.2} deg, {:.1} mm)",
            te * 1e3,
            gt * 1e3
        );
    }
    if let Some(out) = &a.out {
        let [result, before, after] = two_frame::write_outputs(out, &r, &seq)?;
        println!(
            "wrote {}, {} and {} (source orange, target blue)",
            result.display(),
            before.display(),
            after.display()
        );
    }
    Ok(())
}
