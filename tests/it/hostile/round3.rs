//! Hostile inputs, round 3 (issue 46): one batch job's failure stays that job's, the last
//! oddities get a note or an error in the words of the interface they reach.

use super::*;

/// A copy of the bundled sequence in `dir/name` whose depth images all read 0 (nothing
/// can track).
fn zero_depth_copy(dir: &Path, name: &str) -> PathBuf {
    let seq = dir.join(name);
    let ok = Command::new("cp")
        .arg("-r")
        .arg(common::bundled_icl())
        .arg(&seq)
        .status()
        .unwrap();
    assert!(ok.success());
    for e in std::fs::read_dir(seq.join("depth")).unwrap() {
        let p = e.unwrap().path();
        let (w, h) = image::image_dimensions(&p).unwrap();
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(w, h)
            .save(&p)
            .unwrap();
    }
    seq
}

/// The statuses of `summary.json` in `out`, in job order.
fn statuses(out: &Path) -> Vec<String> {
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    s["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["status"].as_str().unwrap().to_string())
        .collect()
}

/// A NUL byte in one job's sequence path aborted the whole batch ("cannot read ...: nul
/// byte found") and the jobs after it never ran; a typo in one job's overrides refused the
/// whole batch; a run that tracked nothing showed `ok` in the table. Now each is that
/// job's status, in a batch of child processes and with `--concurrent`.
fn one_jobs_input_never_stops_the_batch() {
    let dir = common::temp_dir("hostile-round3-batch");
    let zero = zero_depth_copy(&dir, "zero");
    let good = common::bundled_icl();
    let m = dir.join("m.toml");
    std::fs::write(
        &m,
        format!(
            "[defaults]\nframes = \"1..2\"\ndownsample = 4\nbackend = \"cpu\"\n\
             [[job]]\nname = \"nul\"\nsequence = \"{}/a\\u0000b\"\n\
             [[job]]\nname = \"typo\"\nsequence = \"{}\"\noverrides = {{ \"icp-dits\" = 3 }}\n\
             [[job]]\nname = \"zero\"\nsequence = \"{}\"\n\
             [[job]]\nname = \"good\"\nsequence = \"{}\"\n",
            dir.display(),
            good.display(),
            zero.display(),
            good.display()
        ),
    )
    .unwrap();
    for concurrent in ["1", "2"] {
        let out = dir.join(format!("out{concurrent}"));
        let o = wgslam(&["batch", s(&m), "--out", s(&out), "--concurrent", concurrent]);
        let said = text(&o);
        assert_eq!(o.status.code(), Some(1), "{said}");
        assert!(said.contains("2 of 4 jobs failed: nul, typo"), "{said}");
        assert!(said.contains("1 ok, 1 lost, 2 failed"), "{said}");
        assert!(
            said.contains("icp-dits") && said.contains("the others run"),
            "{said}"
        );
        assert_eq!(statuses(&out), ["failed", "failed", "lost", "ok"], "{said}");
        let nul_job = std::fs::read_to_string(out.join("jobs/nul/job.json")).unwrap();
        assert!(
            nul_job.contains("NUL") || nul_job.contains("nul byte"),
            "{nul_job}"
        );
    }
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![plain(
        "one_jobs_input_never_stops_the_batch",
        one_jobs_input_never_stops_the_batch,
    )]
}
