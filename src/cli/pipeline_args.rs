//! The options of every command that runs the dense pipeline (`run`, `icp`, `compare`,
//! `bench`): the sequence, `--params FILE.toml` and [`ParamOverrides`], the one key table
//! of parameter files and of batch manifests' `overrides` (docs/params-file.md).
//!
//! Precedence: the profile's values < the parameter file's < the command line's
//! ([`PipelineArgs::resolve`]); the file's parser is [`super::params_file`].

use std::path::PathBuf;

use clap::Args;
use serde::Serialize;

use crate::dataset::{self, SequenceOptions};
use crate::geometry::camera::Intrinsics;
use crate::slam::params::{
    Association, BilateralSettings, PoseSource, Profile, SlamParams, UnstableRemoval,
};
use crate::{Error, Result};

/// The sequence, a parameter file and the overrides: flattened into `run`, `icp`,
/// `compare` and `bench`, so they all accept the same options.
#[derive(Debug, Clone, Default, Args)]
pub struct PipelineArgs {
    /// Sequence directory in any layout wgslam reads (TUM RGB-D, ICL-NUIM, ETH3D, Bonn,
    /// 7-Scenes/3DMatch, ScanNet, Replica; detected); default: the bundled frames.
    pub dataset: Option<PathBuf>,
    /// Read parameters from this TOML file: the options below without the dashes, e.g.
    /// `icp-dist = 0.08`, `bilateral = true`, `icp-level-iters = [10, 5, 4]`, `profile =
    /// "assignment"`; options given on the command line win (docs/params-file.md).
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
    #[command(flatten)]
    pub set: ParamOverrides,
}

/// Every option a parameter file (and a batch manifest's `overrides`) may set: how the
/// sequence is read, the profile, and each of its values. Unset values are the profile's
/// (or the sequence's); the defaults are in the help of each.
#[derive(Debug, Clone, Default, PartialEq, Args, Serialize)]
#[serde(rename_all = "kebab-case")]
#[command(next_help_heading = "Parameters (each also a key of a --params file)")]
pub struct ParamOverrides {
    /// Ground-truth file (TUM format) instead of the layout's default.
    #[arg(long)]
    pub gt: Option<PathBuf>,
    /// Intrinsics preset: icl, fr1, fr2, fr3 (overrides camera.json).
    #[arg(long)]
    pub camera: Option<String>,
    /// Intrinsics override "fx,fy,cx,cy" in pixels (image size from the frames' preset/json).
    #[arg(long)]
    pub intrinsics: Option<String>,
    /// Raw depth units per metre (default: camera.json or 5000).
    #[arg(long)]
    pub depth_scale: Option<f32>,
    /// Largest timestamp difference for association, seconds (default 0.02).
    #[arg(long)]
    pub max_time_diff: Option<f64>,
    /// Parameter set to start from: the robust tracker and fusion for real (noisy) depth,
    /// the default, or the course assignment's exact algorithm.
    #[arg(long, value_enum)]
    pub profile: Option<Profile>,
    /// Keep every N-th pixel in each direction (default 2).
    #[arg(long)]
    pub downsample: Option<u32>,
    /// ICP correspondence distance threshold, metres (assignment 0.07, robust 0.10).
    #[arg(long)]
    pub icp_dist: Option<f32>,
    /// ICP normal-angle threshold, degrees; 180 turns it off (assignment 180, robust 20).
    #[arg(long)]
    pub icp_angle: Option<f32>,
    /// Huber threshold on ICP residuals, metres; 0 turns it off (assignment 0, robust 0.02).
    #[arg(long)]
    pub icp_huber: Option<f32>,
    /// ICP iterations per pyramid level, coarse to fine: "10,5,4" is three levels (each
    /// half the size of the next finer one), at most 10 iterations at the coarsest and 4 at
    /// the full maps; one number is single-level ICP (assignment 10, robust 10,5,4).
    #[arg(long, value_delimiter = ',', value_name = "N,...")]
    pub icp_level_iters: Option<Vec<usize>>,
    /// Weigh each ICP row by the depth-noise model (assignment false, robust true).
    #[arg(long)]
    pub icp_noise_weight: Option<bool>,
    /// ICP stops when the increment's rotation (rad) and translation (m) are both below
    /// this (assignment 1e-6, robust 1e-5).
    #[arg(long)]
    pub icp_min_increment: Option<f64>,
    /// Degenerate geometry: eigen-directions of the ICP system below this fraction of the
    /// largest eigenvalue get no update (robust 1e-4); 0 refuses such a system instead
    /// (assignment).
    #[arg(long)]
    pub icp_degenerate_ratio: Option<f64>,
    /// Report frames whose tracking fails the health test as lost instead of fusing them
    /// (both profiles true; false accepts every pose ICP returns).
    #[arg(long)]
    pub tracking_health: Option<bool>,
    /// Health test: lost below this fraction of candidate pixels that are ICP inliers
    /// (0.3).
    #[arg(long)]
    pub health_min_inliers: Option<f64>,
    /// Health test: lost when the RMS residual is above this many times its typical value
    /// (4).
    #[arg(long)]
    pub health_max_residual_ratio: Option<f64>,
    /// After a lost frame, try ICP from the poses of similar keyframes (randomised-fern
    /// database) (both profiles true; false retries only from the last tracked pose).
    #[arg(long)]
    pub relocalise: Option<bool>,
    /// Loop closure: verified loops to old keyframes bend the trajectory and the map
    /// (robust on, assignment off; `off` gives the trajectories of a run without it, bit
    /// for bit). Takes on/off or true/false.
    #[arg(long, value_parser = clap::builder::BoolishValueParser::new())]
    pub loop_closure: Option<bool>,
    /// Coarser ICP pyramid levels: half-width of the averaging window, pixels of the finer
    /// level (1).
    #[arg(long)]
    pub pyramid_radius: Option<u32>,
    /// Coarser ICP pyramid levels: neighbours whose depth differs from the sampled pixel's
    /// by more than this times its depth squared (1/m) are left out of the average (0.03).
    #[arg(long)]
    pub pyramid_depth_gate_z2: Option<f32>,
    /// Fusion distance threshold, metres (assignment 0.03, robust 0.05).
    #[arg(long)]
    pub fuse_dist: Option<f32>,
    /// Fusion normal-angle threshold, degrees (assignment 5, robust 60).
    #[arg(long)]
    pub fuse_angle: Option<f32>,
    /// How fusion pairs pixels with surfels (assignment projective, robust best-candidate).
    #[arg(long, value_enum)]
    pub fuse_association: Option<Association>,
    /// Confidence of a measurement over its distance from the image centre: the Gaussian's
    /// sigma (normalised, 1 at the corners); 0 weighs every measurement 1 (assignment 0,
    /// robust 0.6).
    #[arg(long)]
    pub confidence_sigma: Option<f32>,
    /// Best-candidate fusion's duplicate pruning: a surfel that was not refreshed retires
    /// when the surfel its pixel merged into lies within this many times the larger radius
    /// (and faces the same way, and is at least as confident); 0 turns it off (assignment
    /// 0, robust 0.5). It runs on the frames the unstable-surfel removal runs after
    /// (--removal-every), or every frame without the removal.
    #[arg(long)]
    pub prune_scale: Option<f32>,
    /// Removal of unstable surfels: surfels with fewer observations than this whose last
    /// one is more than --unstable-max-age frames old are removed after each fusion; 0
    /// turns the removal off (assignment off, robust 20).
    #[arg(long)]
    pub stable_weight: Option<f32>,
    /// Removal of unstable surfels: frames an unstable surfel may go unobserved (assignment
    /// off, robust 20; with the assignment profile, either flag turns the removal on).
    #[arg(long)]
    pub unstable_max_age: Option<u32>,
    /// Removal of unstable surfels: run it after every N-th frame (robust 10).
    #[arg(long)]
    pub removal_every: Option<u32>,
    /// Valid depth range, metres: nearer pixels are invalid (both profiles 0.1).
    #[arg(long)]
    pub min_depth: Option<f32>,
    /// Valid depth range, metres: farther pixels are invalid (both profiles 10).
    #[arg(long)]
    pub max_depth: Option<f32>,
    /// Normals across a depth jump larger than this, metres, are invalid (both 0.1).
    #[arg(long)]
    pub max_depth_jump: Option<f32>,
    /// Smooth the depth with an edge-preserving bilateral filter before the normals, ICP
    /// and fusion (KinectFusion's; for noisy sensors) with the --bilateral-* settings
    /// below, which take effect only with it; without it the profile decides (assignment
    /// off, robust on with the defaults). In a file: `bilateral = true`.
    #[arg(long)]
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub bilateral: bool,
    /// Bilateral filter window half-width, pixels of the (downsampled) maps (default 1).
    #[arg(long)]
    pub bilateral_radius: Option<u32>,
    /// Bilateral filter spatial sigma, pixels of the (downsampled) maps (default 1).
    #[arg(long)]
    pub bilateral_sigma_space: Option<f32>,
    /// Bilateral filter depth sigma, metres (at depth 0, see --bilateral-sigma-depth-z2;
    /// default 0).
    #[arg(long)]
    pub bilateral_sigma_depth: Option<f32>,
    /// Bilateral filter depth sigma's growth with depth squared, 1/m: sigma_depth + this x
    /// z² (default 0.01).
    #[arg(long)]
    pub bilateral_sigma_depth_z2: Option<f32>,
}

impl ParamOverrides {
    /// `self`'s values where set, `lower`'s elsewhere (a switch is on when either is on).
    /// Destructures both, so a new option cannot be forgotten here.
    pub fn over(self, lower: ParamOverrides) -> ParamOverrides {
        let ParamOverrides {
            gt,
            camera,
            intrinsics,
            depth_scale,
            max_time_diff,
            profile,
            downsample,
            icp_dist,
            icp_angle,
            icp_huber,
            icp_level_iters,
            icp_noise_weight,
            icp_min_increment,
            icp_degenerate_ratio,
            tracking_health,
            health_min_inliers,
            health_max_residual_ratio,
            relocalise,
            loop_closure,
            pyramid_radius,
            pyramid_depth_gate_z2,
            fuse_dist,
            fuse_angle,
            fuse_association,
            confidence_sigma,
            prune_scale,
            stable_weight,
            unstable_max_age,
            removal_every,
            min_depth,
            max_depth,
            max_depth_jump,
            bilateral,
            bilateral_radius,
            bilateral_sigma_space,
            bilateral_sigma_depth,
            bilateral_sigma_depth_z2,
        } = self;
        ParamOverrides {
            gt: gt.or(lower.gt),
            camera: camera.or(lower.camera),
            intrinsics: intrinsics.or(lower.intrinsics),
            depth_scale: depth_scale.or(lower.depth_scale),
            max_time_diff: max_time_diff.or(lower.max_time_diff),
            profile: profile.or(lower.profile),
            downsample: downsample.or(lower.downsample),
            icp_dist: icp_dist.or(lower.icp_dist),
            icp_angle: icp_angle.or(lower.icp_angle),
            icp_huber: icp_huber.or(lower.icp_huber),
            icp_level_iters: icp_level_iters.or(lower.icp_level_iters),
            icp_noise_weight: icp_noise_weight.or(lower.icp_noise_weight),
            icp_min_increment: icp_min_increment.or(lower.icp_min_increment),
            icp_degenerate_ratio: icp_degenerate_ratio.or(lower.icp_degenerate_ratio),
            tracking_health: tracking_health.or(lower.tracking_health),
            health_min_inliers: health_min_inliers.or(lower.health_min_inliers),
            health_max_residual_ratio: health_max_residual_ratio
                .or(lower.health_max_residual_ratio),
            relocalise: relocalise.or(lower.relocalise),
            loop_closure: loop_closure.or(lower.loop_closure),
            pyramid_radius: pyramid_radius.or(lower.pyramid_radius),
            pyramid_depth_gate_z2: pyramid_depth_gate_z2.or(lower.pyramid_depth_gate_z2),
            fuse_dist: fuse_dist.or(lower.fuse_dist),
            fuse_angle: fuse_angle.or(lower.fuse_angle),
            fuse_association: fuse_association.or(lower.fuse_association),
            confidence_sigma: confidence_sigma.or(lower.confidence_sigma),
            prune_scale: prune_scale.or(lower.prune_scale),
            stable_weight: stable_weight.or(lower.stable_weight),
            unstable_max_age: unstable_max_age.or(lower.unstable_max_age),
            removal_every: removal_every.or(lower.removal_every),
            min_depth: min_depth.or(lower.min_depth),
            max_depth: max_depth.or(lower.max_depth),
            max_depth_jump: max_depth_jump.or(lower.max_depth_jump),
            bilateral: bilateral || lower.bilateral,
            bilateral_radius: bilateral_radius.or(lower.bilateral_radius),
            bilateral_sigma_space: bilateral_sigma_space.or(lower.bilateral_sigma_space),
            bilateral_sigma_depth: bilateral_sigma_depth.or(lower.bilateral_sigma_depth),
            bilateral_sigma_depth_z2: bilateral_sigma_depth_z2.or(lower.bilateral_sigma_depth_z2),
        }
    }

    /// The pipeline's parameters: the profile's (robust without `profile`), each set value
    /// in place of the profile's, with `poses`; validated ([`SlamParams::validate`]).
    pub fn slam_params(&self, poses: PoseSource) -> Result<SlamParams> {
        let mut p = SlamParams::profile(self.profile.unwrap_or(Profile::Robust));
        p.poses = poses;
        fn set<T: Clone>(field: &mut T, value: &Option<T>) {
            if let Some(v) = value {
                *field = v.clone();
            }
        }
        let (input, icp, fusion) = (&mut p.input, &mut p.icp, &mut p.fusion);
        set(&mut input.downsample, &self.downsample);
        set(&mut input.min_depth_m, &self.min_depth);
        set(&mut input.max_depth_m, &self.max_depth);
        set(&mut p.normals.max_depth_jump_m, &self.max_depth_jump);
        set(&mut icp.dist_m, &self.icp_dist);
        set(&mut icp.normal_deg, &self.icp_angle);
        set(&mut icp.huber_m, &self.icp_huber);
        set(&mut icp.level_iters, &self.icp_level_iters);
        set(&mut icp.noise_weight, &self.icp_noise_weight);
        set(&mut icp.min_increment, &self.icp_min_increment);
        set(&mut icp.degenerate_eigen_ratio, &self.icp_degenerate_ratio);
        if self.tracking_health == Some(false) {
            p.health = None;
        }
        if let Some(h) = &mut p.health {
            set(&mut h.min_inlier_fraction, &self.health_min_inliers);
            set(&mut h.max_residual_ratio, &self.health_max_residual_ratio);
        }
        if self.relocalise == Some(false) {
            p.relocalisation = None;
        }
        match self.loop_closure {
            Some(false) => p.loop_closure = None,
            Some(true) if p.loop_closure.is_none() => {
                p.loop_closure = Some(crate::slam::params::LoopSettings::default())
            }
            _ => {}
        }
        // Loop closure reuses the relocalisation keyframes: without them it is off, and
        // refused when asked for by name.
        if p.relocalisation.is_none() || p.health.is_none() {
            if self.loop_closure == Some(true) {
                return Err(crate::Error::Argument(
                    "--loop-closure on needs the keyframe database: --tracking-health and \
                     --relocalise must be on"
                        .into(),
                ));
            }
            p.loop_closure = None;
        }
        set(&mut icp.pyramid.radius_px, &self.pyramid_radius);
        set(
            &mut icp.pyramid.max_depth_diff_per_m2,
            &self.pyramid_depth_gate_z2,
        );
        set(&mut fusion.dist_m, &self.fuse_dist);
        set(&mut fusion.normal_deg, &self.fuse_angle);
        set(&mut fusion.association, &self.fuse_association);
        set(&mut fusion.confidence_sigma, &self.confidence_sigma);
        set(&mut fusion.prune_scale, &self.prune_scale);
        // --stable-weight 0 turns the removal off; any of the three otherwise overrides the
        // profile's rule (or the robust one's, when the profile has none).
        fusion.unstable_removal = match (
            self.stable_weight,
            self.unstable_max_age,
            self.removal_every,
        ) {
            (Some(0.0), _, _) => None,
            (None, None, None) => fusion.unstable_removal,
            (w, age, every) => {
                let base = fusion.unstable_removal.unwrap_or_default();
                Some(UnstableRemoval {
                    stable_weight: w.unwrap_or(base.stable_weight),
                    max_age_frames: age.unwrap_or(base.max_age_frames),
                    every_frames: every.unwrap_or(base.every_frames),
                })
            }
        };
        // --bilateral turns the filter on with its flags' settings; without it the
        // profile decides.
        if self.bilateral {
            let d = BilateralSettings::default();
            p.bilateral = Some(BilateralSettings {
                radius_px: self.bilateral_radius.unwrap_or(d.radius_px),
                sigma_space_px: self.bilateral_sigma_space.unwrap_or(d.sigma_space_px),
                sigma_depth_m: self.bilateral_sigma_depth.unwrap_or(d.sigma_depth_m),
                sigma_depth_per_m2: self
                    .bilateral_sigma_depth_z2
                    .unwrap_or(d.sigma_depth_per_m2),
            });
        }
        p.validate()?;
        Ok(p)
    }

    /// How to open the sequence: the dataset options set here, the layout's otherwise.
    pub fn sequence_options(&self) -> Result<SequenceOptions> {
        let mut intrinsics = match &self.camera {
            Some(name) => Some(Intrinsics::preset(name).ok_or_else(|| {
                Error::Argument(format!(
                    "unknown camera preset {name:?} (icl, fr1, fr2, fr3)"
                ))
            })?),
            None => None,
        };
        if let Some(s) = &self.intrinsics {
            let v: Vec<f32> = s
                .split(',')
                .map(|x| x.trim().parse::<f32>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| Error::Argument(format!("--intrinsics {s:?}: want fx,fy,cx,cy")))?;
            if v.len() != 4 || v[0] == 0.0 || v[1] == 0.0 || v.iter().any(|x| !x.is_finite()) {
                return Err(Error::Argument(format!(
                    "--intrinsics {s:?}: want four finite numbers fx,fy,cx,cy with fx, fy \
                     non-zero"
                )));
            }
            let base = intrinsics.unwrap_or(Intrinsics::ICL_NUIM);
            intrinsics = Some(Intrinsics {
                fx: v[0],
                fy: v[1],
                cx: v[2],
                cy: v[3],
                ..base
            });
        }
        Ok(SequenceOptions {
            gt_path: self.gt.clone(),
            intrinsics,
            depth_scale: self.depth_scale,
            max_time_diff: self.max_time_diff.unwrap_or(dataset::DEFAULT_MAX_TIME_DIFF),
        })
    }
}

impl PipelineArgs {
    /// The sequence and the overrides in effect: the command line's over the parameter
    /// file's (over the profile's, applied by [`Setup::slam_params`]).
    pub fn resolve(&self) -> Result<Setup> {
        let file = match &self.params {
            Some(path) => ParamOverrides::read(path)?,
            None => ParamOverrides::default(),
        };
        Ok(Setup {
            dataset: self.dataset.clone(),
            set: self.set.clone().over(file),
        })
    }
}

/// What a pipeline command runs on and with: [`PipelineArgs`] with the parameter file
/// read in.
#[derive(Debug, Clone)]
pub struct Setup {
    /// The sequence's folder; `None` for the bundled frames.
    pub dataset: Option<PathBuf>,
    /// Every override in effect (command line over file).
    pub set: ParamOverrides,
}

impl Setup {
    /// Opens the sequence with the dataset options applied, and prints what opening it
    /// decided on the user's behalf ([`dataset::Sequence::notes`]) on stderr.
    pub fn open_sequence(&self) -> Result<dataset::Sequence> {
        let root = self
            .dataset
            .clone()
            .unwrap_or_else(crate::cli::bundled_dataset);
        let seq = dataset::open(&root, &self.set.sequence_options()?)?;
        for note in &seq.notes {
            eprintln!("note: {note}");
        }
        Ok(seq)
    }

    /// The pipeline's parameters ([`ParamOverrides::slam_params`]), validated.
    pub fn slam_params(&self, poses: PoseSource) -> Result<SlamParams> {
        self.set.slam_params(poses)
    }

    /// Writes every override in effect into a parameter file in a new temporary folder
    /// (atomically) for a child process of this executable; the folder is removed when the
    /// returned guard is dropped. `what` names the folder (`bench`).
    pub fn child_params(&self, what: &str) -> Result<ChildParams> {
        let dir = std::env::temp_dir().join(format!("wgslam-{what}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).map_err(|e| Error::write(&dir, e))?;
        let guard = ChildParams {
            path: dir.join("params.toml"),
            dir,
        };
        let text = self.set.to_toml()?;
        crate::io::atomic::write_atomic(&guard.path, |w| {
            w.write_all(text.as_bytes())
                .map_err(|e| Error::write(&guard.path, e))
        })?;
        Ok(guard)
    }

    /// A child's arguments for the same sequence and parameters: the dataset folder (when
    /// given) and `--params FILE`.
    pub fn handoff_args(&self, params: &ChildParams) -> Vec<String> {
        let mut args: Vec<String> = self
            .dataset
            .iter()
            .map(|d| d.display().to_string())
            .collect();
        args.extend(["--params".into(), params.path.display().to_string()]);
        args
    }
}

/// A parameter file for child processes ([`Setup::child_params`]); its folder is removed
/// on drop.
#[derive(Debug)]
pub struct ChildParams {
    dir: PathBuf,
    /// The file.
    pub path: PathBuf,
}

impl Drop for ChildParams {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Without `--frames`, a run starts at the first frame with ground truth (ICL-NUIM's frame 0
/// has none), so the map and trajectory share the ground truth's world frame.
pub(crate) fn default_first_frame(seq: &dataset::Sequence) -> usize {
    match seq.default_first_frame() {
        i if i > 0 => {
            eprintln!(
                "note: starting at frame {i}, the first with ground truth (use --frames to change)"
            );
            i
        }
        _ => 0,
    }
}

/// Frames from `--frames`, or from the first frame with ground truth to at most `count`
/// frames later (`usize::MAX` for all).
pub(crate) fn frame_range(
    seq: &dataset::Sequence,
    frames: &Option<String>,
    count: usize,
) -> Result<(usize, usize)> {
    let (first, last) = match frames {
        Some(r) => dataset::parse_range(r)?,
        None => {
            let first = default_first_frame(seq);
            (first, (seq.len() - 1).min(first.saturating_add(count - 1)))
        }
    };
    let r = seq.select(first, last)?;
    Ok((*r.start(), *r.end()))
}
