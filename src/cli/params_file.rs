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
use crate::batch::manifest::{insert_dotted, option_value};
use crate::slam::params::{Key, SlamParams, KEY_SECTIONS};
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

    /// Parses a parameter file's text: a TOML table of options with the value forms of
    /// [`option_value`] (a number, string, boolean, or a list for `icp-level-iters`), and
    /// of sections ([`KEY_SECTIONS`]: `[icp]`, `[fusion.unstable_removal]`) whose values
    /// are set by [`SlamParams`] key (`dist_m = 0.08` in `[icp]` is `icp.dist_m`), TOML
    /// typed as the field is.
    pub fn from_toml(text: &str) -> std::result::Result<ParamOverrides, String> {
        let table: toml::Table =
            toml::from_str(text).map_err(|e| format!("not a parameter file (TOML): {e}"))?;
        let mut pairs = Vec::new();
        let mut section_keys = Vec::new();
        for (key, value) in &table {
            if let Some(section) = value.as_table() {
                if !KEY_SECTIONS.contains(&key.as_str()) {
                    return Err(format!(
                        "`{key}` is not a section; the sections are: {}",
                        KEY_SECTIONS.join(", ")
                    ));
                }
                flatten(key, section, &mut section_keys);
                continue;
            }
            let v = option_value(value).ok_or_else(|| {
                format!("`{key}`: want a number, string, boolean or a list of them, not {value}")
            })?;
            pairs.push((key.as_str(), v));
        }
        for (key, value) in &section_keys {
            SlamParams::check_key(key, value).map_err(|e| match e {
                Error::Argument(why) => why,
                other => other.to_string(),
            })?;
        }
        let options = ParamOverrides::from_pairs(pairs.iter().map(|(k, v)| (*k, v.as_str())))?;
        Ok(ParamOverrides {
            section_keys,
            ..options
        })
    }

    /// Reads the parameter file `path`; its errors name the file.
    pub fn read(path: &Path) -> Result<ParamOverrides> {
        let text = crate::io::input::read_kind_string(path, crate::io::input::InputKind::Settings)?;
        ParamOverrides::from_toml(&text).map_err(|why| Error::format(path, why))
    }

    /// These overrides as a parameter file that [`ParamOverrides::from_toml`] reads back
    /// as `self` (the unset ones left out; the sections' keys in sections, a key set twice
    /// once with its last value).
    pub fn to_toml(&self) -> Result<String> {
        let encode = |e| Error::encode("the parameter file", e);
        let mut t = toml::Table::try_from(self).map_err(encode)?;
        for (key, value) in &self.section_keys {
            insert_dotted(&mut t, key, value.clone());
        }
        toml::to_string(&t).map_err(encode)
    }
}

/// The values of a section table, by key (`prefix.name`), nested tables as deeper keys.
fn flatten(prefix: &str, table: &toml::Table, out: &mut Vec<Key>) {
    for (name, value) in table {
        let key = format!("{prefix}.{name}");
        match value.as_table() {
            Some(inner) => flatten(&key, inner, out),
            None => out.push((key, value.clone())),
        }
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
    use crate::geometry::camera::Intrinsics;
    use crate::slam::params::{BilateralSettings, PoseSource, Profile, SlamParams, ValidParams};
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

    fn params(o: &ParamOverrides) -> ValidParams {
        o.slam_params(PoseSource::Track).unwrap()
    }

    /// A `--bilateral-*` setting tunes the robust profile's filter without `--bilateral`
    /// (it was once dropped there without a word), and is refused, naming the flag and
    /// the fix, for the assignment profile, which runs no filter.
    #[test]
    fn bilateral_settings_apply_where_the_filter_runs_and_are_refused_elsewhere() {
        let robust = params(&flags(&["--bilateral-radius", "2"]));
        assert_eq!(robust.bilateral.map(|b| b.radius_px), Some(2));
        let from_file = ParamOverrides::from_toml("bilateral-sigma-space = 2.5").unwrap();
        let sigma = params(&from_file).bilateral.map(|b| b.sigma_space_px);
        assert_eq!(sigma, Some(2.5));
        let why = flags(&["--profile", "assignment", "--bilateral-radius", "2"])
            .slam_params(PoseSource::Track)
            .unwrap_err()
            .to_string();
        assert!(
            why.contains("--bilateral-radius") && why.contains("add --bilateral"),
            "{why}"
        );
        let on = flags(&[
            "--profile",
            "assignment",
            "--bilateral",
            "--bilateral-radius",
            "2",
        ]);
        assert_eq!(params(&on).bilateral.map(|b| b.radius_px), Some(2));
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
        let robust = crate::slam::params::defaults::ROBUST_FUSE_DIST_M;
        let same = ParamOverrides::from_toml(&format!("fuse-dist = {robust}")).unwrap();
        assert_eq!(params(&same), ValidParams::default());
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
            ("[icpp]\nx = 1", "`icpp` is not a section"),
            ("[icp]\ndits_m = 0.1", "`icp.dits_m`"),
            ("[icp]\ndist_m = \"far\"", "`icp.dist_m`"),
            (
                "[fusion]\nassociation = \"nearest\"",
                "`fusion.association`",
            ),
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

    /// A value for every option, each other than the assignment profile's (the robust
    /// profile's for `profile`). The tests below fail on an option missing here, so a new
    /// option comes with its check.
    const OPTION_VALUES: [(&str, &str); 47] = [
        ("gt", "a/gt.txt"),
        ("camera", "fr1"),
        ("intrinsics", "500,500,319.5,239.5"),
        ("depth-scale", "1000"),
        ("max-time-diff", "0.03"),
        ("stamp-order", "file"),
        ("depth-topic", "/camera/depth"),
        ("color-topic", "/camera/rgb"),
        ("profile", "assignment"),
        ("downsample", "4"),
        ("icp-dist", "0.08"),
        ("icp-angle", "25"),
        ("icp-full-res-angle", "35"),
        ("icp-retry-angle", "40"),
        ("icp-huber", "0.015"),
        ("tracking", "rgbd"),
        ("photometric-weight", "0.5"),
        ("photometric-levels", "0,1"),
        ("icp-level-iters", "6,3"),
        ("icp-noise-weight", "true"),
        ("icp-min-increment", "1e-5"),
        ("icp-degenerate-ratio", "1e-3"),
        ("tracking-health", "false"),
        ("health-min-inliers", "0.25"),
        ("health-max-residual-ratio", "5"),
        ("relocalise", "false"),
        ("loop-closure", "on"),
        ("pyramid-radius", "2"),
        ("pyramid-depth-gate-z2", "0.1"),
        ("fuse-dist", "0.012345679"),
        ("fuse-dist-confident", "0.0234"),
        ("fuse-angle", "33.3"),
        ("fuse-association", "best-candidate"),
        ("confidence-sigma", "0.7"),
        ("prune-scale", "0.4"),
        ("stable-weight", "12.5"),
        ("unstable-max-age", "9"),
        ("removal-every", "4"),
        ("min-depth", "0.2"),
        ("max-depth", "4.5"),
        ("max-depth-jump", "0.05"),
        ("bilateral", "true"),
        ("bilateral-radius", "2"),
        ("bilateral-sigma-space", "1.5"),
        ("bilateral-sigma-depth", "0.001"),
        ("bilateral-sigma-depth-z2", "0.02"),
        ("bilateral-filter-points", "true"),
    ];

    /// `--flag=value`, or `--flag` for a switch.
    fn arg(flag: &str, value: &str) -> String {
        let switch = ParamOverrides::command()
            .get_arguments()
            .any(|a| a.get_long() == Some(flag) && matches!(a.get_action(), ArgAction::SetTrue));
        match switch {
            true => format!("--{flag}"),
            false => format!("--{flag}={value}"),
        }
    }

    /// Each option, as a flag, a parameter file's key and a manifest's override, reaches
    /// what it sets: the [`SlamParams`] value of its key (other than the profile's), the
    /// profile, or the sequence's options. A forgotten line cannot ignore an option.
    #[test]
    fn every_option_reaches_the_parameters() {
        let names: Vec<String> = OPTION_VALUES.iter().map(|(f, _)| f.to_string()).collect();
        assert_eq!(
            ParamOverrides::keys(),
            names,
            "OPTION_VALUES lists every option"
        );
        let assignment = SlamParams::profile(Profile::Assignment);
        for (flag, value) in OPTION_VALUES {
            // The assignment profile under each (`profile` itself over the robust default),
            // `--bilateral` under its settings (the assignment profile refuses them without
            // it), and a two-level schedule under `--photometric-levels` (a level must exist).
            let mut args = vec![arg(flag, value)];
            let mut file = format!("{flag} = {value:?}\n");
            if flag != "profile" {
                args.push("--profile=assignment".into());
                file.push_str("profile = \"assignment\"\n");
            }
            // The photometric keys take effect only with RGB-D tracking (and are refused
            // without it).
            let companions: &[&str] = match flag {
                f if f.starts_with("bilateral-") => &["bilateral = true"],
                "photometric-levels" => &["icp-level-iters = \"6,3\"", "tracking = \"rgbd\""],
                "photometric-weight" => &["tracking = \"rgbd\""],
                _ => &[],
            };
            for companion in companions {
                let (k, v) = companion.split_once(" = ").expect("key = value");
                args.push(arg(k, v.trim_matches('"')));
                file.push_str(&format!("{companion}\n"));
            }
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let o = flags(&args);
            assert_eq!(ParamOverrides::from_toml(&file).unwrap(), o, "{file}");
            if !crate::batch::manifest::RESERVED_OPTIONS.contains(&flag) {
                let m = crate::batch::manifest::Manifest::parse(
                    Path::new("/m/batch.toml"),
                    &format!(
                        "[[job]]\nsequence = \"s\"\nprofile = \"assignment\"\n\
                         overrides = {{ {flag} = {value:?}{} }}\n",
                        companions
                            .iter()
                            .map(|c| format!(", {c}"))
                            .collect::<String>()
                    ),
                )
                .unwrap();
                let job = ParamOverrides::from_toml(&m.jobs[0].params_toml()).unwrap();
                // The job's parameter file also holds its `downsample` field.
                let expected = ParamOverrides {
                    downsample: Some(2),
                    ..o.clone()
                };
                assert_eq!(job, expected, "{flag} in a manifest");
            }
            let entry = o.options().into_iter().find(|e| e.flag == flag).unwrap();
            let p = params(&o);
            let s = o.sequence_options(&p).unwrap();
            match entry.key {
                Some(key) => {
                    let got = p.get_key(key);
                    assert_eq!(got, entry.value, "--{flag} {value} sets `{key}`");
                    assert_ne!(got, assignment.get_key(key), "--{flag} {value}");
                }
                None => {
                    let reached = match flag {
                        "gt" => s.gt_path == Some("a/gt.txt".into()),
                        "camera" => s.intrinsics == Intrinsics::preset("fr1"),
                        "intrinsics" => s.intrinsics.is_some_and(|k| k.fx == 500.0),
                        "max-time-diff" => s.max_time_diff == 0.03,
                        "stamp-order" => s.stamp_order == crate::dataset::StampOrder::File,
                        "depth-topic" => s.depth_topic.as_deref() == Some("/camera/depth"),
                        "color-topic" => s.color_topic.as_deref() == Some("/camera/rgb"),
                        "profile" => p.profile == Profile::Assignment,
                        _ => false,
                    };
                    assert!(reached, "--{flag} {value} reaches nothing");
                }
            }
        }
    }

    /// The raw depth scale has one home, the key `input.depth_scale`: a file's
    /// `[input] depth_scale` reaches the sequence's options as the top-level `depth-scale`
    /// and the flag do (it was once accepted and silently replaced by the dataset's), in
    /// the order flag, then top-level file key, then section; unset, the dataset decides.
    #[test]
    fn depth_scale_has_one_home_and_one_order() {
        let scale = |o: &ParamOverrides| o.sequence_options(&params(o)).unwrap().depth_scale;
        let section = ParamOverrides::from_toml("[input]\ndepth_scale = 1000\n").unwrap();
        assert_eq!(scale(&section), Some(1000.0), "[input] depth_scale");
        assert_eq!(params(&section).input.depth_scale, 1000.0);
        let both =
            ParamOverrides::from_toml("depth-scale = 2000\n[input]\ndepth_scale = 1000\n").unwrap();
        assert_eq!(
            scale(&both),
            Some(2000.0),
            "the top-level key over the section"
        );
        let flag = flags(&["--depth-scale=4000"]).over(both);
        assert_eq!(scale(&flag), Some(4000.0), "the flag over the file");
        assert_eq!(scale(&ParamOverrides::default()), None, "the dataset's own");
        let zero = ParamOverrides::from_toml("[input]\ndepth_scale = 0\n");
        let refused = zero.map(|o| {
            o.slam_params(PoseSource::Track)
                .and_then(|p| o.sequence_options(&p))
                .map(|_| ())
        });
        assert!(
            !matches!(refused, Ok(Ok(()))),
            "a zero depth scale is refused, by the file's check or the parameters' validation"
        );
    }

    /// Sections set values by key, options (the file's and the command line's) win over
    /// them, and a written file reads back with its sections.
    #[test]
    fn sections_set_values_by_key() {
        let o = ParamOverrides::from_toml(
            "icp-dist = 0.09\n[icp]\ndist_m = 0.08\nnormal_deg = 25\n[icp.pyramid]\n\
             radius_px = 2\n[loop_closure]\nmin_gap_frames = 90\n\
             [fusion.unstable_removal]\nenabled = false\n",
        )
        .unwrap();
        let p = params(&o);
        assert_eq!(p.icp.dist_m, 0.09, "the option wins");
        assert_eq!(p.icp.normal_deg, 25.0);
        assert_eq!(p.icp.pyramid.radius_px, 2);
        assert_eq!(p.loop_closure.map(|l| l.min_gap_frames), Some(90));
        assert_eq!(p.fusion.unstable_removal, None);
        let text = o.to_toml().unwrap();
        assert_eq!(ParamOverrides::from_toml(&text).unwrap(), o, "{text}");
        let merged = flags(&["--icp-angle", "30"]).over(o);
        assert_eq!(params(&merged).icp.normal_deg, 30.0, "the flag wins");
        assert_eq!(params(&merged).icp.pyramid.radius_px, 2, "from the file");
    }

    /// docs/params-file.md lists every option and the `SlamParams` key it sets.
    #[test]
    fn the_page_lists_every_option_and_its_key() {
        let page = include_str!("../../docs/params-file.md");
        for o in ParamOverrides::default().options() {
            assert!(page.contains(&format!("`{}`", o.flag)), "{}", o.flag);
            if let Some(key) = o.key {
                assert!(page.contains(&format!("`{key}`")), "{key}");
            }
        }
    }

    /// Every option written by `to_toml` reads back as the same value: the serde names are
    /// the clap names.
    #[test]
    fn written_files_read_back() {
        let args: Vec<String> = OPTION_VALUES
            .iter()
            .map(|(flag, value)| arg(flag, value))
            .collect();
        let all = flags(&args.iter().map(String::as_str).collect::<Vec<_>>());
        let text = all.to_toml().unwrap();
        assert_eq!(ParamOverrides::from_toml(&text).unwrap(), all, "{text}");
        assert_eq!(ParamOverrides::keys().len(), text.lines().count(), "{text}");
        assert_eq!(ParamOverrides::default().to_toml().unwrap().trim(), "");
    }

    /// A manifest's override by section key, in either form, reaches the parameters
    /// through the job's parameter file; a grid over one varies it.
    #[test]
    fn manifest_overrides_by_section_key_reach_the_parameters() {
        let m = crate::batch::manifest::Manifest::parse(
            Path::new("/m/batch.toml"),
            "[[grid]]\nname = \"g\"\nsequence = \"s\"\n\
             overrides = { icp = { stop_chi2 = [3, 7.5], pyramid = { radius_px = 2 } }, \
             \"loop_closure.enabled\" = false, icp-dist = 0.08 }\n",
        )
        .unwrap();
        let ids: Vec<&str> = m.jobs.iter().map(|j| j.id.as_str()).collect();
        assert_eq!(ids, ["g-icp.stop_chi2=3", "g-icp.stop_chi2=7.5"]);
        for (job, chi2) in m.jobs.iter().zip([3.0, 7.5]) {
            let text = job.params_toml();
            let p = params(&ParamOverrides::from_toml(&text).unwrap());
            assert_eq!(p.icp.stop_chi2, chi2, "{text}");
            assert_eq!(p.icp.pyramid.radius_px, 2, "{text}");
            assert_eq!(p.icp.dist_m, 0.08, "{text}");
            assert!(p.loop_closure.is_none(), "{text}");
        }
        let err = |overrides: &str| {
            let text = format!("[[job]]\nsequence = \"s\"\noverrides = {{ {overrides} }}\n");
            crate::batch::manifest::Manifest::parse(Path::new("/m/b.toml"), &text)
                .unwrap_err()
                .to_string()
        };
        assert!(err("icq = { dist_m = 1 }").contains("not a section"));
        assert!(err("icp = { dist_m = 1 }, \"icp.dist_m\" = 2").contains("set twice"));
        assert!(err("\"input.downsample\" = 4").contains("job field"));
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
