//! Manifest parsing and expansion: job numbering, grids, ids, refusals.

use super::*;

fn parse(text: &str) -> Result<Manifest> {
    Manifest::parse(Path::new("/m/batch.toml"), text)
}

/// A job that sets no downsampling takes its backends' default: the full frames for the
/// GPU alone, every second pixel wherever the CPU reference runs (both backends of a job
/// run the same frames); a value the manifest sets wins.
#[test]
fn unset_downsampling_is_the_jobs_backends_default() {
    let m = parse(
        r#"
        [[grid]]
        sequence = "s"
        backend = ["gpu", "cpu", "both"]
        [[job]]
        name = "set"
        sequence = "s"
        backend = "gpu"
        downsample = 2
        "#,
    )
    .unwrap();
    let ds: Vec<(&str, u32)> = m
        .jobs
        .iter()
        .map(|j| (j.id.as_str(), j.downsample))
        .collect();
    assert_eq!(ds, [("set", 2), ("s-gpu", 1), ("s-cpu", 2), ("s-both", 2)]);
}

#[test]
fn grid_expands_in_index_order_with_ids_from_varying_values() {
    let m = parse(
        r#"
        output = "out"
        [defaults]
        frames = "1..10"
        backend = "cpu"
        overrides = { icp-huber = 0.02 }
        [[job]]
        name = "first"
        sequence = "a/seq1"
        [[grid]]
        name = "g"
        sequence = ["a/seq1", "/abs/seq2"]
        profile = ["robust", "assignment"]
        overrides = { icp-dist = [0.08, 0.1], bilateral = true }
        "#,
    )
    .unwrap();
    assert_eq!(m.output, Some(PathBuf::from("/m/out")));
    let ids: Vec<&str> = m.jobs.iter().map(|j| j.id.as_str()).collect();
    assert_eq!(
        ids,
        [
            "first",
            "g-seq1-robust-icp-dist=0.08",
            "g-seq1-robust-icp-dist=0.1",
            "g-seq1-assignment-icp-dist=0.08",
            "g-seq1-assignment-icp-dist=0.1",
            "g-seq2-robust-icp-dist=0.08",
            "g-seq2-robust-icp-dist=0.1",
            "g-seq2-assignment-icp-dist=0.08",
            "g-seq2-assignment-icp-dist=0.1",
        ]
    );
    let j = &m.jobs[8];
    assert_eq!(j.sequence, PathBuf::from("/abs/seq2"));
    assert_eq!(
        m.jobs[1].sequence,
        PathBuf::from("/m/a/seq1"),
        "relative to the manifest"
    );
    assert_eq!(j.frames.as_deref(), Some("1..10"), "from [defaults]");
    assert_eq!(j.backends, ["cpu"]);
    assert_eq!(j.downsample, 2, "the CPU reference's default");
    // The grid's overrides join the defaults', sorted by name.
    assert_eq!(
        j.overrides,
        [
            ("bilateral".to_string(), "true".to_string()),
            ("icp-dist".to_string(), "0.1".to_string()),
            ("icp-huber".to_string(), "0.02".to_string()),
        ]
    );
    assert_eq!(m.jobs[0].backends, ["cpu"]);
}

#[test]
fn sequence_paths_are_folded() {
    let m = Manifest::parse(
        Path::new("deploy/manifests/m.toml"),
        "[[job]]\nsequence = \"../../assets/./kt2\"\n[[job]]\nname = \"b\"\nsequence = \"../../../data\"\n",
    )
    .unwrap();
    assert_eq!(m.jobs[0].sequence, PathBuf::from("assets/kt2"));
    assert_eq!(m.jobs[1].sequence, PathBuf::from("../data"));
    assert_eq!(
        lexically_normal(Path::new("/a/../../b")),
        PathBuf::from("/b")
    );
}

#[test]
fn both_backends_by_default() {
    let m = parse("[[job]]\nsequence = \"s\"\n").unwrap();
    assert_eq!(m.jobs[0].backends, ["cpu", "gpu"]);
    assert_eq!(m.jobs[0].profile, "robust");
    assert_eq!(m.output, None);
}

#[test]
fn mistakes_are_errors_that_say_what_to_do() {
    let err = |text: &str| parse(text).unwrap_err().to_string();
    assert!(err("").contains("no jobs"));
    assert!(err("[[job]]\nsequnce = \"s\"\n").contains("unknown field"));
    assert!(err("[[job]]\nsequence = [\"a\", \"b\"]\n").contains("use a [[grid]]"));
    assert!(err("[[job]]\nname = \"x\"\n").contains("no `sequence`"));
    assert!(err("[[job]]\nsequence = \"s\"\nprofile = \"fast\"\n").contains("profile \"fast\""));
    assert!(err("[[job]]\nsequence = \"s\"\nbackend = \"tpu\"\n").contains("cpu, gpu or both"));
    assert!(
        err("[[job]]\nsequence = \"s\"\noverrides = { out = \"x\" }\n")
            .contains("set by the batch")
    );
    assert!(
        err("[[job]]\nsequence = \"s\"\n[[job]]\nsequence = \"s\"\n")
            .contains("give them different")
    );
    assert!(err("[[grid]]\nsequence = \"s\"\nprofile = []\n").contains("empty list"));
    assert!(err("[[job]]\nname = \"../x\"\nsequence = \"s\"\n").contains("folder name"));
    assert!(err("[[job]\n").contains("not a batch manifest"));
}
