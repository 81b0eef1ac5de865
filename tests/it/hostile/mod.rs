//! Hostile inputs and faults (issue 27), as the cases were found: batch output folders that
//! are not the batch's, a crafted `batch.json` against the report, runs that must leave
//! their outputs complete or absent as a set, readers fed declared sizes they cannot hold,
//! silently wrong results and unclear messages; and round 2 (issue 35): every reader
//! bounded, numbers validated where they enter, an honest verdict when nothing tracks.
//! Each test names the case it reproduces.

use crate::common;

mod batch_folders;
mod bounded;
mod messages;
mod numbers;
mod outputs;
mod readers;
mod report;
mod round3;
mod wrong_results;

pub(super) use std::path::{Path, PathBuf};
pub(super) use std::process::{Child, Command};

pub(super) use common::cli::{ok, text, wgslam, wgslam_env};
pub(super) use common::harness::{gpu, plain};

pub(super) fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `cp -r src dst`.
pub(super) fn copy_dir(src: &Path, dst: &Path) {
    let ok = Command::new("cp")
        .arg("-r")
        .arg(src)
        .arg(dst)
        .status()
        .unwrap();
    assert!(ok.success(), "cp -r {} {}", src.display(), dst.display());
}

/// A copy of the bundled sequence in `dir/name`, for damaging.
pub(super) fn copy_bundled(dir: &Path, name: &str) -> PathBuf {
    let seq = dir.join(name);
    copy_dir(&common::bundled_icl(), &seq);
    seq
}

/// `wgslam run SEQ` over frames 1..3 at 160x120 on the CPU, with `extra`.
pub(super) fn run_small(seq: &Path, extra: &[&str]) -> std::process::Output {
    let mut a = vec![
        "run",
        s(seq),
        "--frames",
        "1..3",
        "--downsample",
        "4",
        "--backend",
        "cpu",
    ];
    a.extend_from_slice(extra);
    wgslam(&a)
}

/// A one-job CPU manifest over 2 bundled frames at 160x120, job `name`, into `output`.
pub(super) fn small_manifest(dir: &Path, file: &str, name: &str, output: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(file);
    std::fs::write(
        &path,
        format!(
            "output = \"{output}\"\n[defaults]\nframes = \"1..2\"\ndownsample = 4\n\
             backend = \"cpu\"\n[[job]]\nname = \"{name}\"\nsequence = \"{}\"\n",
            common::bundled_icl().display()
        ),
    )
    .unwrap();
    path
}

/// `wgslam run` over the bundled frames 1..`last` at 160x120 on the CPU into `out`.
pub(super) fn run_args(last: u32, out: &Path) -> Vec<String> {
    [
        "run",
        s(&common::bundled_icl()),
        "--frames",
        &format!("1..{last}"),
        "--downsample",
        "4",
        "--backend",
        "cpu",
        "--out",
        s(out),
    ]
    .iter()
    .map(|a| a.to_string())
    .collect()
}

/// [`run_args`] with `more` after them, which must fail with exit code 1; what the run said.
pub(super) fn run_fails(last: u32, out: &Path, more: &[&str]) -> String {
    let mut args = run_args(last, out);
    args.extend(more.iter().map(|m| m.to_string()));
    let o = wgslam(&args);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    text(&o)
}

/// Every hostile-input test, by topic.
pub fn tests() -> Vec<common::harness::Test> {
    let mut v = batch_folders::tests();
    for more in [
        report::tests(),
        outputs::tests(),
        readers::tests(),
        wrong_results::tests(),
        messages::tests(),
        bounded::tests(),
        numbers::tests(),
        round3::tests(),
    ] {
        v.extend(more);
    }
    v
}
