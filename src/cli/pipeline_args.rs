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
use crate::geometry::camera::{Distortion, Intrinsics};
use crate::slam::params::{
    Association, Key, PoseSource, Profile, SlamParams, Tracking, ValidParams,
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

/// Declares [`ParamOverrides`] from one list of options, each with its help, its clap
/// attributes, its type and, for a pipeline parameter, the [`SlamParams`] key it sets
/// (`=> "icp.dist_m"`; the dataset's options and `profile` have none). From the list come
/// the flags, the keys of parameter files and manifests (the flags' long names), the
/// merge [`ParamOverrides::over`] and the keys set [`ParamOverrides::keys_set`]: an option
/// is written once, and cannot be left out of any of them.
macro_rules! param_overrides {
    ($(#[$struct_meta:meta])* pub struct ParamOverrides {
        $( $(#[$meta:meta])* $name:ident: $ty:ty $(=> $key:literal)?, )*
    }) => {
        $(#[$struct_meta])*
        pub struct ParamOverrides {
            $( $(#[$meta])* pub $name: $ty, )*
            /// Values a parameter file sets by [`SlamParams`] key in its sections (`[icp]`
            /// then `dist_m = 0.08`), in file order; the options win over them. Not an
            /// option of the command line.
            #[arg(skip)]
            #[serde(skip)]
            pub section_keys: Vec<Key>,
        }

        impl ParamOverrides {
            /// `self`'s values where set, `lower`'s elsewhere (a switch is on when either is
            /// on).
            pub fn over(self, lower: ParamOverrides) -> ParamOverrides {
                ParamOverrides {
                    $( $name: Setting::over(self.$name, lower.$name), )*
                    // In order of precedence: the later key wins.
                    section_keys: lower.section_keys.into_iter().chain(self.section_keys).collect(),
                }
            }

            /// Each option: its long name (the file's key), the [`SlamParams`] key it sets
            /// (if any) and its value as TOML (`None` when unset).
            pub fn options(&self) -> Vec<OptionEntry> {
                vec![$(
                    OptionEntry {
                        flag: stringify!($name).replace('_', "-"),
                        key: None $(.or(Some($key)))?,
                        value: Setting::toml(&self.$name),
                    },
                )*]
            }
        }
    };
}

/// One option of [`ParamOverrides::options`].
#[derive(Debug, Clone, PartialEq)]
pub struct OptionEntry {
    /// The long name, without the dashes: the key of parameter files and manifests.
    pub flag: String,
    /// The [`SlamParams`] key it sets (`icp.dist_m`), `None` for the dataset's options and
    /// `profile`.
    pub key: Option<&'static str>,
    /// Its value, if set.
    pub value: Option<toml::Value>,
}

/// An option's field: an `Option` of a value, or a switch.
trait Setting: Sized {
    /// `self` where set, `lower` elsewhere.
    fn over(self, lower: Self) -> Self;
    /// The value as TOML, when set.
    fn toml(&self) -> Option<toml::Value>;
}

impl<T: Serialize> Setting for Option<T> {
    fn over(self, lower: Self) -> Self {
        self.or(lower)
    }
    fn toml(&self) -> Option<toml::Value> {
        self.as_ref()
            .map(|v| toml::Value::try_from(v).expect("an option's value is TOML"))
    }
}

impl Setting for bool {
    fn over(self, lower: Self) -> Self {
        self || lower
    }
    fn toml(&self) -> Option<toml::Value> {
        self.then_some(toml::Value::Boolean(true))
    }
}

param_overrides! {
    /// Every option a parameter file (and a batch manifest's `overrides`) may set: how the
    /// sequence is read, the profile, and each of its values. Unset values are the profile's
    /// (or the sequence's); the defaults are in the help of each.
    #[derive(Debug, Clone, Default, PartialEq, Args, Serialize)]
    #[serde(rename_all = "kebab-case")]
    #[command(next_help_heading = "Parameters (each also a key of a --params file)")]
    pub struct ParamOverrides {
    /// Ground-truth file (TUM format) instead of the layout's default.
    #[arg(long)]
    gt: Option<PathBuf>,
    /// Camera preset: icl, fr1, fr2, fr3 (overrides camera.json; fr1 and fr2 with their
    /// published lens distortion, removed from the frames as they are decoded).
    #[arg(long)]
    camera: Option<String>,
    /// Intrinsics override "fx,fy,cx,cy" in pixels (image size from the frames' preset/json).
    #[arg(long)]
    intrinsics: Option<String>,
    /// Raw depth units per metre (default: camera.json's, else the layout's: 5000 for TUM
    /// and ICL-NUIM, 1000 for 7-Scenes, ...). The file key `[input] depth_scale` is the same
    /// value; the flag wins over a file, a file over the dataset's own.
    #[arg(long)]
    depth_scale: Option<f32> => "input.depth_scale",
    /// Largest timestamp difference for association, seconds (default 0.02).
    #[arg(long)]
    max_time_diff: Option<f64>,
    /// Frame order of a frame list whose stamps go backwards (TUM's depth.txt, ICL-NUIM's
    /// associations.txt, ETH3D's associated.txt): time (by stamp, the default) or file
    /// (by line); other layouts number their frames and refuse it.
    #[arg(long, value_enum)]
    stamp_order: Option<dataset::StampOrder>,
    /// A recording's (ROS bag, MCAP) depth topic, a sensor_msgs/Image in 16UC1 or 32FC1;
    /// needed only when it has more than one.
    #[arg(long)]
    depth_topic: Option<String>,
    /// A recording's colour topic, a sensor_msgs/Image (rgb8, bgr8, rgba8, bgra8, mono8)
    /// or a JPEG/PNG CompressedImage; needed only when it has more than one.
    #[arg(long)]
    color_topic: Option<String>,
    /// Parameter set to start from: the robust tracker and fusion for real (noisy) depth,
    /// the default, or the course assignment's exact algorithm.
    #[arg(long, value_enum)]
    profile: Option<Profile>,
    /// Keep every N-th pixel in each direction (default: 1 on the GPU backend, 2 where the
    /// CPU reference runs).
    #[arg(long)]
    downsample: Option<u32> => "input.downsample",
    /// ICP correspondence distance threshold, metres (assignment 0.07, robust 0.10).
    #[arg(long)]
    icp_dist: Option<f32> => "icp.dist_m",
    /// ICP normal-angle threshold, degrees; 180 turns it off (assignment 180, robust 20).
    #[arg(long)]
    icp_angle: Option<f32> => "icp.normal_deg",
    /// ICP normal-angle threshold at full resolution (--downsample 1, the finest level),
    /// degrees; 0 takes --icp-angle's (assignment 0, robust 30).
    #[arg(long)]
    icp_full_res_angle: Option<f32> => "icp.full_res_normal_deg",
    /// ICP normal-angle threshold at the finest level of a second attempt at full resolution
    /// (--downsample 1) from the last pose, made when the first fails the health test,
    /// degrees; 0 makes none (assignment 0, robust 30).
    #[arg(long)]
    icp_retry_angle: Option<f32> => "icp.full_res_retry_normal_deg",
    /// Huber threshold on ICP residuals, metres; 0 turns it off (assignment 0, robust 0.02).
    #[arg(long)]
    icp_huber: Option<f32> => "icp.huber_m",
    /// What tracking aligns: the depth (geometric, the default) or depth and colour (rgbd:
    /// a photometric term at the full maps; see docs/rgbd-tracking.md).
    #[arg(long, value_enum, value_name = "MODE")]
    tracking: Option<Tracking> => "icp.tracking",
    /// With --tracking rgbd: the photometric term's weight relative to the geometric one,
    /// each normalised by its mean squared residual of the iteration, so that it has no
    /// unit (default 0.3).
    #[arg(long)]
    photometric_weight: Option<f64> => "icp.photometric_weight",
    /// With --tracking rgbd: the pyramid levels that carry the photometric term, "0" the
    /// full maps (the default), "0,1,2" every level of a three-level schedule.
    #[arg(long, value_delimiter = ',', value_name = "L,...")]
    photometric_levels: Option<Vec<usize>> => "icp.photometric_levels",
    /// ICP iterations per pyramid level, coarse to fine: "10,5,4" is three levels (each
    /// half the size of the next finer one), at most 10 iterations at the coarsest and 4 at
    /// the full maps; one number is single-level ICP (assignment 10, robust 10,5,4).
    #[arg(long, value_delimiter = ',', value_name = "N,...")]
    icp_level_iters: Option<Vec<usize>> => "icp.level_iters",
    /// Weigh each ICP row by the depth-noise model (assignment false, robust true).
    #[arg(long)]
    icp_noise_weight: Option<bool> => "icp.noise_weight",
    /// ICP stops when the increment's rotation (rad) and translation (m) are both below
    /// this (assignment 1e-6, robust 1e-5).
    #[arg(long)]
    icp_min_increment: Option<f64> => "icp.min_increment",
    /// Degenerate geometry: eigen-directions of the ICP system below this fraction of the
    /// largest eigenvalue get no update (robust 1e-4); 0 refuses such a system instead
    /// (assignment).
    #[arg(long)]
    icp_degenerate_ratio: Option<f64> => "icp.degenerate_eigen_ratio",
    /// Report frames whose tracking fails the health test as lost instead of fusing them
    /// (both profiles true; false accepts every pose ICP returns).
    #[arg(long)]
    tracking_health: Option<bool> => "health.enabled",
    /// Health test: lost below this fraction of candidate pixels that are ICP inliers
    /// (0.3).
    #[arg(long)]
    health_min_inliers: Option<f64> => "health.min_inlier_fraction",
    /// Health test: lost when the RMS residual is above this many times its typical value
    /// (4).
    #[arg(long)]
    health_max_residual_ratio: Option<f64> => "health.max_residual_ratio",
    /// After a lost frame, try ICP from the poses of similar keyframes (randomised-fern
    /// database) (both profiles true; false retries only from the last tracked pose).
    #[arg(long)]
    relocalise: Option<bool> => "relocalisation.enabled",
    /// Loop closure: verified loops to old keyframes bend the trajectory and the map
    /// (robust on, assignment off; `off` gives the trajectories of a run without it, bit
    /// for bit). Takes on/off or true/false.
    #[arg(long, value_parser = clap::builder::BoolishValueParser::new())]
    loop_closure: Option<bool> => "loop_closure.enabled",
    /// Coarser ICP pyramid levels: half-width of the averaging window, pixels of the finer
    /// level (1).
    #[arg(long)]
    pyramid_radius: Option<u32> => "icp.pyramid.radius_px",
    /// Coarser ICP pyramid levels: neighbours whose depth differs from the sampled pixel's
    /// by more than this times its depth squared (1/m) are left out of the average (0.03).
    #[arg(long)]
    pyramid_depth_gate_z2: Option<f32> => "icp.pyramid.max_depth_diff_per_m2",
    /// Fusion distance threshold, metres (assignment 0.03, robust 0.05).
    #[arg(long)]
    fuse_dist: Option<f32> => "fusion.dist_m",
    /// Best-candidate fusion's depth gate for a surfel fused many times, metres: the gate
    /// narrows from --fuse-dist towards it as the surfel's weight grows; 0 keeps
    /// --fuse-dist for every surfel (both profiles 0; docs/robust-profile.md measures 0.04).
    #[arg(long)]
    fuse_dist_confident: Option<f32> => "fusion.dist_confident_m",
    /// Fusion normal-angle threshold, degrees (assignment 5, robust 60).
    #[arg(long)]
    fuse_angle: Option<f32> => "fusion.normal_deg",
    /// How fusion pairs pixels with surfels (assignment projective, robust best-candidate).
    #[arg(long, value_enum)]
    fuse_association: Option<Association> => "fusion.association",
    /// Confidence of a measurement over its distance from the image centre: the Gaussian's
    /// sigma (normalised, 1 at the corners); 0 weighs every measurement 1 (assignment 0,
    /// robust 0.6).
    #[arg(long)]
    confidence_sigma: Option<f32> => "fusion.confidence_sigma",
    /// Best-candidate fusion's duplicate pruning: a surfel that was not refreshed retires
    /// when the surfel its pixel merged into lies within this many times the larger radius
    /// (and faces the same way, and is at least as confident); 0 turns it off (assignment
    /// 0, robust 0.5). It runs on the frames the unstable-surfel removal runs after
    /// (--removal-every), or every frame without the removal.
    #[arg(long)]
    prune_scale: Option<f32> => "fusion.prune_scale",
    /// Removal of unstable surfels: surfels with fewer observations than this whose last
    /// one is more than --unstable-max-age frames old are removed after each fusion; 0
    /// turns the removal off (assignment off, robust 20).
    #[arg(long)]
    stable_weight: Option<f32> => "fusion.unstable_removal.stable_weight",
    /// Removal of unstable surfels: frames an unstable surfel may go unobserved (assignment
    /// off, robust 20; with the assignment profile, either flag turns the removal on).
    #[arg(long)]
    unstable_max_age: Option<u32> => "fusion.unstable_removal.max_age_frames",
    /// Removal of unstable surfels: run it after every N-th frame (robust 10).
    #[arg(long)]
    removal_every: Option<u32> => "fusion.unstable_removal.every_frames",
    /// Valid depth range, metres: nearer pixels are invalid (both profiles 0.1).
    #[arg(long)]
    min_depth: Option<f32> => "input.min_depth_m",
    /// Valid depth range, metres: farther pixels are invalid (both profiles 10).
    #[arg(long)]
    max_depth: Option<f32> => "input.max_depth_m",
    /// Normals across a depth jump larger than this, metres, are invalid (both 0.1).
    #[arg(long)]
    max_depth_jump: Option<f32> => "normals.max_depth_jump_m",
    /// Smooth the depth with an edge-preserving bilateral filter for the normals and the
    /// coarser ICP levels (KinectFusion's; for noisy sensors); without it the profile
    /// decides (assignment off, robust on). The --bilateral-* settings below tune the
    /// filter that runs; for the assignment profile they need this flag. In a file:
    /// `bilateral = true`.
    #[arg(long)]
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    bilateral: bool => "bilateral.enabled",
    /// Bilateral filter window half-width, pixels of the (downsampled) maps (default 1).
    #[arg(long)]
    bilateral_radius: Option<u32> => "bilateral.radius_px",
    /// Bilateral filter spatial sigma, pixels of the (downsampled) maps (default 1).
    #[arg(long)]
    bilateral_sigma_space: Option<f32> => "bilateral.sigma_space_px",
    /// Bilateral filter depth sigma, metres (at depth 0, see --bilateral-sigma-depth-z2;
    /// default 0).
    #[arg(long)]
    bilateral_sigma_depth: Option<f32> => "bilateral.sigma_depth_m",
    /// Bilateral filter depth sigma's growth with depth squared, 1/m: sigma_depth + this x
    /// z² (default 0.01).
    #[arg(long)]
    bilateral_sigma_depth_z2: Option<f32> => "bilateral.sigma_depth_per_m2",
    /// Whether the filtered depth also makes the full-resolution points that ICP and
    /// fusion use (default false: they keep the raw depth, and the filter makes the
    /// normals and the coarser ICP levels; docs/robust-profile.md).
    #[arg(long)]
    bilateral_filter_points: Option<bool> => "bilateral.filter_points",
    }
}

impl ParamOverrides {
    /// The [`SlamParams`] keys set: the sections' (in order), then the options' (in the
    /// options' order; so an option wins over a section's key).
    pub fn keys_set(&self) -> Vec<Key> {
        let options = self
            .options()
            .into_iter()
            .filter_map(|o| Some((o.key?.to_string(), o.value?)));
        self.section_keys.iter().cloned().chain(options).collect()
    }

    /// `Err` naming the flag when a `--bilateral-*` setting is given for a profile that
    /// runs no bilateral filter (the assignment's) without `--bilateral`: the settings tune
    /// the filter and do not switch it on. With the robust profile's filter they apply as
    /// given (they were once dropped there without a word).
    fn check_bilateral_settings(&self, profile: Profile) -> Result<()> {
        if self.bilateral || SlamParams::profile(profile).bilateral.is_some() {
            return Ok(());
        }
        match self
            .options()
            .into_iter()
            .find(|o| o.value.is_some() && o.key.is_some_and(|k| k.starts_with("bilateral.")))
        {
            Some(o) => Err(Error::Argument(format!(
                "--{} tunes the bilateral filter, which the {} profile does not run: \
                 add --bilateral (in a file: `bilateral = true`)",
                o.flag,
                format!("{profile:?}").to_lowercase()
            ))),
            None => Ok(()),
        }
    }

    /// Whether `input.downsample` is set (`--downsample`, a file's `downsample` or
    /// `[input] downsample`); unset, the run's backends choose it
    /// ([`crate::slam::params::resolution`]).
    pub fn sets_downsample(&self) -> bool {
        self.keys_set()
            .iter()
            .any(|(key, _)| key == "input.downsample")
    }

    /// The pipeline's parameters: the profile's (robust without `profile`) with each set
    /// value in place ([`SlamParams::with_keys`]) and `poses`, validated (the one time: a
    /// run takes the [`ValidParams`] as they are). An error names the key and the flag that
    /// sets it (`` `fusion.dist_m` (--fuse-dist) 0 must be positive ``).
    pub fn slam_params(&self, poses: PoseSource) -> Result<ValidParams> {
        let profile = self.profile.unwrap_or(Profile::Robust);
        self.check_bilateral_settings(profile)?;
        SlamParams::with_keys(profile, poses, &self.keys_set()).map_err(|e| match e {
            Error::Argument(why) => Error::Argument(with_flags(&why)),
            other => other,
        })
    }

    /// How to open the sequence: the dataset options set here, the layout's otherwise.
    /// `params` are these overrides' [`ParamOverrides::slam_params`]: a depth scale set
    /// here (by flag or file) is their `input.depth_scale`, checked by their validation
    /// alone.
    pub fn sequence_options(&self, params: &ValidParams) -> Result<SequenceOptions> {
        let mut intrinsics = match &self.camera {
            Some(name) => Some(Intrinsics::preset(name).ok_or_else(|| {
                Error::Argument(format!(
                    "unknown camera preset {name:?} (icl, fr1, fr2, fr3)"
                ))
            })?),
            None => None,
        };
        if let Some(s) = &self.intrinsics {
            let base = intrinsics.unwrap_or(Intrinsics::ICL_NUIM);
            intrinsics = Some(
                base.with_focal_centre(s)
                    .map_err(|why| Error::Argument(format!("--intrinsics {s:?}: {why}")))?,
            );
        }
        Ok(SequenceOptions {
            gt_path: self.gt.clone(),
            intrinsics,
            // A preset's lens (freiburg1 and 2), kept under `--intrinsics`' focal lengths.
            distortion: self.camera.as_deref().and_then(Distortion::preset),
            depth_scale: self.sets_depth_scale().then_some(params.input.depth_scale),
            max_time_diff: self.max_time_diff.unwrap_or(dataset::DEFAULT_MAX_TIME_DIFF),
            stamp_order: self.stamp_order.unwrap_or_default(),
            interface: dataset::Interface::CommandLine,
            depth_topic: self.depth_topic.clone(),
            color_topic: self.color_topic.clone(),
        })
    }

    /// Whether the user set the raw depth units per metre: the key `input.depth_scale` is
    /// among [`ParamOverrides::keys_set`] (the flag `--depth-scale`, a file's top-level
    /// `depth-scale` or its `[input] depth_scale`, the later winning as there). Unset, the
    /// dataset's own decides (`camera.json`, else the layout's convention): the one order of
    /// precedence, applied once when the sequence is opened ([`dataset::open`]), whose value
    /// the pipeline's `input.depth_scale` then records (`Slam::for_sequence`).
    fn sets_depth_scale(&self) -> bool {
        self.keys_set()
            .iter()
            .any(|(key, _)| key == "input.depth_scale")
    }
}

/// `why` with each backquoted key followed by the flag that sets it: `` `icp.dist_m` ``
/// becomes `` `icp.dist_m` (--icp-dist) ``.
fn with_flags(why: &str) -> String {
    let mut out = why.to_string();
    for o in ParamOverrides::default().options() {
        if let Some(key) = o.key {
            let quoted = format!("`{key}`");
            out = out.replace(&quoted, &format!("{quoted} (--{})", o.flag));
        }
    }
    out
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
    /// Opens the sequence with the dataset options applied (the depth scale of `params`,
    /// [`Setup::slam_params`], when the overrides set one), and prints what opening it
    /// decided on the user's behalf ([`dataset::Sequence::notes`]) on stderr.
    pub fn open_sequence(&self, params: &ValidParams) -> Result<dataset::Sequence> {
        self.open_sequence_for(params, dataset::Interface::CommandLine)
    }

    /// [`Setup::open_sequence`] for `interface`: its errors name that interface's controls
    /// (a language binding's keywords where the command line's flags would be named).
    pub fn open_sequence_for(
        &self,
        params: &ValidParams,
        interface: dataset::Interface,
    ) -> Result<dataset::Sequence> {
        let root = self
            .dataset
            .clone()
            .unwrap_or_else(crate::cli::bundled_dataset);
        let opts = dataset::SequenceOptions {
            interface,
            ..self.set.sequence_options(params)?
        };
        let seq = dataset::open(&root, &opts)?;
        for note in &seq.notes {
            eprintln!("note: {note}");
        }
        Ok(seq)
    }

    /// The pipeline's parameters ([`ParamOverrides::slam_params`]), validated: once per
    /// run, before the sequence is opened with them ([`Setup::open_sequence`]).
    pub fn slam_params(&self, poses: PoseSource) -> Result<ValidParams> {
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
