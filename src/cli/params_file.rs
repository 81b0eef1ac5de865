//! Parameter files (`--params FILE.toml`, docs/params-file.md) and batch manifests'
//! `overrides`: one parser over one key table, [`ParamOverrides`]'s options.
//!
//! A key is an option's long name without the dashes, a value that of the command line
//! (TOML scalars as written, lists joined by commas: [`option_value`], the manifest's
//! value forms): each `key = value` is parsed as `--key=value` by the clap definition of
//! the flag itself, so a value means the same in a file, a manifest and on the command
//! line. A switch (`bilateral`) is on with `true` and absent with `false`.

use std::path::Path;

use clap::{ArgAction, Args, Command, FromArgMatches};

use super::pipeline_args::ParamOverrides;
use crate::batch::manifest::option_value;
use crate::{Error, Result};

impl ParamOverrides {
    /// The clap definition of these options alone (the parser of files and manifests).
    fn command() -> Command {
        ParamOverrides::augment_args(Command::new("params").no_binary_name(true))
    }

    /// The keys a parameter file may set: the options' long names, in help order.
    pub fn keys() -> Vec<String> {
        ParamOverrides::command()
            .get_arguments()
            .filter_map(|a| a.get_long().map(String::from))
            .collect()
    }

    /// Parses `(key, value)` pairs, each value in the command-line form, as the flags
    /// `--key=value` (a switch: `true` on, `false` absent). The error names the key: an
    /// unknown one (with the list of known keys) or a value its option refuses.
    pub fn from_pairs<'a>(
        pairs: impl IntoIterator<Item = (&'a str, &'a str)>,
    ) -> std::result::Result<ParamOverrides, String> {
        let cmd = ParamOverrides::command();
        let mut args = Vec::new();
        for (key, value) in pairs {
            let Some(arg) = cmd.get_arguments().find(|a| a.get_long() == Some(key)) else {
                return Err(format!(
                    "unknown key `{key}`; the keys are: {}",
                    ParamOverrides::keys().join(", ")
                ));
            };
            let flag = if matches!(arg.get_action(), ArgAction::SetTrue) {
                match value {
                    "true" => Some(format!("--{key}")),
                    "false" => None,
                    _ => return Err(format!("`{key}` wants true or false, not {value:?}")),
                }
            } else {
                Some(format!("--{key}={value}"))
            };
            if let Some(flag) = flag {
                // Alone first, so a refused value is reported with its key.
                if let Err(e) = cmd.clone().try_get_matches_from([&flag]) {
                    return Err(format!("`{key} = {value:?}`: {}", clap_reason(&e)));
                }
                args.push(flag);
            }
        }
        let m = cmd
            .try_get_matches_from(&args)
            .map_err(|e| clap_reason(&e))?;
        ParamOverrides::from_arg_matches(&m).map_err(|e| clap_reason(&e))
    }

    /// Parses a parameter file's text: a TOML table of keys with the value forms of
    /// [`option_value`] (a number, string, boolean, or a list for `icp-level-iters`).
    pub fn from_toml(text: &str) -> std::result::Result<ParamOverrides, String> {
        let table: toml::Table =
            toml::from_str(text).map_err(|e| format!("not a parameter file (TOML): {e}"))?;
        let mut pairs = Vec::new();
        for (key, value) in &table {
            let v = option_value(value).ok_or_else(|| {
                format!("`{key}`: want a number, string, boolean or a list of them, not {value}")
            })?;
            pairs.push((key.as_str(), v));
        }
        ParamOverrides::from_pairs(pairs.iter().map(|(k, v)| (*k, v.as_str())))
    }

    /// Reads the parameter file `path`; its errors name the file.
    pub fn read(path: &Path) -> Result<ParamOverrides> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        ParamOverrides::from_toml(&text).map_err(|why| Error::format(path, why))
    }

    /// These overrides as a parameter file that [`ParamOverrides::from_toml`] reads back
    /// as `self` (the unset ones left out).
    pub fn to_toml(&self) -> Result<String> {
        toml::to_string(self).map_err(|e| Error::encode("the parameter file", e))
    }
}

/// The first line of a clap error without its `error: ` prefix.
fn clap_reason(e: &clap::Error) -> String {
    let text = e.to_string();
    let first = text.lines().next().unwrap_or_default();
    first.strip_prefix("error: ").unwrap_or(first).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::pipeline_args::PipelineArgs;
    use crate::slam::params::{Association, BilateralSettings, PoseSource, Profile, SlamParams};
    use clap::Parser;

    /// The overrides `wgslam run ARGS` parses to.
    fn flags(args: &[&str]) -> ParamOverrides {
        let cli = crate::cli::Cli::try_parse_from(["wgslam", "run"].iter().chain(args))
            .unwrap_or_else(|e| panic!("{args:?}: {e}"));
        match cli.command {
            crate::cli::Command::Run(a) => a.pipeline.set,
            _ => unreachable!(),
        }
    }

    fn params(o: &ParamOverrides) -> SlamParams {
        o.slam_params(PoseSource::Track).unwrap()
    }

    /// A file setting a value gives the same parameters as the flag, for every form.
    #[test]
    fn file_values_mean_what_the_flags_mean() {
        let cases: [(&str, &[&str]); 9] = [
            ("icp-dist = 0.08", &["--icp-dist", "0.08"]),
            ("fuse-dist = 0.05", &["--fuse-dist", "0.05"]),
            ("icp-min-increment = 1e-5", &["--icp-min-increment", "1e-5"]),
            ("bilateral = true", &["--bilateral"]),
            (
                "icp-level-iters = [10, 5, 4]",
                &["--icp-level-iters", "10,5,4"],
            ),
            ("icp-level-iters = \"3,2\"", &["--icp-level-iters", "3,2"]),
            ("profile = \"assignment\"", &["--profile", "assignment"]),
            (
                "fuse-association = \"projective\"\nstable-weight = 0",
                &["--fuse-association", "projective", "--stable-weight", "0"],
            ),
            (
                "downsample = 4\nicp-noise-weight = false",
                &["--downsample", "4", "--icp-noise-weight", "false"],
            ),
        ];
        for (file, args) in cases {
            let from_file = ParamOverrides::from_toml(file).unwrap();
            assert_eq!(from_file, flags(args), "{file}");
            assert_eq!(params(&from_file), params(&flags(args)), "{file}");
        }
        // `bilateral = false` is the switch left out: the profile decides.
        let off = ParamOverrides::from_toml("bilateral = false").unwrap();
        assert_eq!(off, ParamOverrides::default());
        // The robust default written out changes nothing.
        let same = ParamOverrides::from_toml("fuse-dist = 0.05").unwrap();
        assert_eq!(params(&same), SlamParams::default());
    }

    /// Command line over file over profile, value by value.
    #[test]
    fn flags_override_the_file() {
        let file = ParamOverrides::from_toml(
            "profile = \"assignment\"\nicp-dist = 0.08\nfuse-angle = 7\nbilateral = true",
        )
        .unwrap();
        let merged = flags(&["--icp-dist", "0.09", "--downsample", "4"]).over(file);
        let p = params(&merged);
        assert_eq!(p.profile, Profile::Assignment, "from the file");
        assert_eq!(p.icp.dist_m, 0.09, "the flag wins");
        assert_eq!(p.fusion.normal_deg, 7.0, "from the file");
        assert_eq!(p.input.downsample, 4, "from the flag");
        assert_eq!(p.bilateral, Some(BilateralSettings::default()));
        assert_eq!(p.fusion.dist_m, 0.03, "the assignment's");
        let none = PipelineArgs::default().resolve().unwrap();
        assert_eq!(none.set, ParamOverrides::default());
    }

    #[test]
    fn unknown_keys_and_bad_values_are_named() {
        let err = ParamOverrides::from_toml("icp-dits = 0.1").unwrap_err();
        assert!(err.contains("`icp-dits`"), "{err}");
        assert!(
            err.contains("icp-dist") && err.contains("fuse-dist"),
            "lists the keys: {err}"
        );
        for (file, key) in [
            ("icp-dist = \"far\"", "icp-dist"),
            ("fuse-association = \"nearest\"", "fuse-association"),
            ("icp-level-iters = [10, \"x\"]", "icp-level-iters"),
            ("bilateral = 1", "bilateral"),
            ("downsample = -2", "downsample"),
            ("pyramid-radius = { a = 1 }", "pyramid-radius"),
        ] {
            let err = ParamOverrides::from_toml(file).unwrap_err();
            assert!(err.contains(key), "{file}: {err}");
        }
        assert!(ParamOverrides::from_toml("icp-dist = ")
            .unwrap_err()
            .contains("TOML"));
        // Keys outside the table are refused even when they are other `run` options.
        for key in ["frames", "backend", "out", "poses", "params", "revisit"] {
            let err = ParamOverrides::from_toml(&format!("{key} = \"1\"")).unwrap_err();
            assert!(err.contains("unknown key"), "{key}: {err}");
        }
    }

    /// Every key written by `to_toml` reads back as the same value: the serde names are
    /// the clap names.
    #[test]
    fn written_files_read_back() {
        let all = ParamOverrides {
            gt: Some("a/gt.txt".into()),
            camera: Some("fr1".into()),
            intrinsics: Some("500,500,319.5,239.5".into()),
            depth_scale: Some(1000.0),
            max_time_diff: Some(0.03),
            profile: Some(Profile::Assignment),
            downsample: Some(4),
            icp_dist: Some(0.08),
            icp_angle: Some(25.0),
            icp_huber: Some(0.015),
            icp_level_iters: Some(vec![6, 3]),
            icp_noise_weight: Some(true),
            icp_min_increment: Some(1e-5),
            icp_degenerate_ratio: Some(1e-3),
            tracking_health: Some(false),
            health_min_inliers: Some(0.25),
            health_max_residual_ratio: Some(5.0),
            relocalise: Some(false),
            loop_closure: Some(true),
            pyramid_radius: Some(2),
            pyramid_depth_gate_z2: Some(0.1),
            fuse_dist: Some(0.012_345_679),
            fuse_angle: Some(33.3),
            fuse_association: Some(Association::BestCandidate),
            confidence_sigma: Some(0.7),
            prune_scale: Some(0.4),
            stable_weight: Some(12.5),
            unstable_max_age: Some(9),
            removal_every: Some(4),
            min_depth: Some(0.2),
            max_depth: Some(4.5),
            max_depth_jump: Some(0.05),
            bilateral: true,
            bilateral_radius: Some(2),
            bilateral_sigma_space: Some(1.5),
            bilateral_sigma_depth: Some(0.001),
            bilateral_sigma_depth_z2: Some(0.02),
        };
        let text = all.to_toml().unwrap();
        assert_eq!(ParamOverrides::from_toml(&text).unwrap(), all, "{text}");
        assert_eq!(ParamOverrides::keys().len(), text.lines().count(), "{text}");
        assert_eq!(ParamOverrides::default().to_toml().unwrap().trim(), "");
    }

    /// A batch job's parameter file is read with the same keys and values.
    #[test]
    fn manifest_jobs_write_parameter_files_this_parser_reads() {
        let m = crate::batch::manifest::Manifest::parse(
            Path::new("/m/batch.toml"),
            "[[job]]\nsequence = \"s\"\nprofile = \"assignment\"\ndownsample = 4\n\
             overrides = { icp-dist = 0.08, bilateral = true, icp-level-iters = \"3,2\", \
             min-depth = \"0.2\" }\n",
        )
        .unwrap();
        let text = m.jobs[0].params_toml();
        let o = ParamOverrides::from_toml(&text).unwrap();
        assert_eq!(
            o,
            flags(&[
                "--profile",
                "assignment",
                "--downsample",
                "4",
                "--icp-dist",
                "0.08",
                "--bilateral",
                "--icp-level-iters",
                "3,2",
                "--min-depth",
                "0.2",
            ]),
            "{text}"
        );
    }
}
