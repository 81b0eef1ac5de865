//! Hostile inputs: Messages that say what is wrong; a closed pipe ends the output quietly.

use super::*;

// ---- 6. messages -----------------------------------------------------------------------

fn messages_say_what_is_wrong() {
    let dir = common::temp_dir("hostile-messages");
    let seq = copy_bundled(&dir, "seq");
    let run = |extra: &[&str]| run_small(&seq, extra);
    // A ground-truth path that is a folder, or a loop of links, was silently ignored.
    let o = run(&["--gt", s(&dir), "--out", s(&dir.join("o1"))]);
    assert!(text(&o).contains("is a folder"), "{}", text(&o));
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(dir.join("loop-b"), dir.join("loop-a")).unwrap();
        std::os::unix::fs::symlink(dir.join("loop-a"), dir.join("loop-b")).unwrap();
        let o = run(&["--gt", s(&dir.join("loop-a")), "--out", s(&dir.join("o2"))]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains("loop-a"), "{}", text(&o));
    }
    // `--max-time-diff 0` with identical stamps pairs them ("no pairs within 0 s").
    let out = dir.join("o3");
    ok(run(&["--max-time-diff", "0", "--out", s(&out)]));
    let metrics = std::fs::read_to_string(out.join("metrics.json")).unwrap();
    assert!(metrics.contains("ate_rmse_aligned_m"), "no ATE: {metrics}");
    // ICL-NUIM stamps near 1e15 ran the whole sequence and failed at the end.
    for name in ["associations.txt", "livingRoom2.gt.freiburg"] {
        let p = seq.join(name);
        let shifted: String = std::fs::read_to_string(&p)
            .unwrap()
            .lines()
            .map(|l| {
                let mut f: Vec<String> = l.split_whitespace().map(String::from).collect();
                for k in [0, 2] {
                    if k < f.len() && (k == 0 || name == "associations.txt") {
                        f[k] =
                            (1_000_000_000_000_000u64 + f[k].parse::<u64>().unwrap()).to_string();
                    }
                }
                f.join(" ") + "\n"
            })
            .collect();
        std::fs::write(&p, shifted).unwrap();
    }
    ok(run(&["--out", s(&dir.join("o4"))]));
    // An image entry that is a folder "does not exist".
    let rgb = seq.join("rgb/2.png");
    std::fs::remove_file(&rgb).unwrap();
    std::fs::create_dir(&rgb).unwrap();
    let o = run(&["--out", s(&dir.join("o5"))]);
    assert!(
        text(&o).contains("is a folder, not an image file"),
        "{}",
        text(&o)
    );
    // Manifests: a value of the wrong type, a NUL in a job name.
    let m = dir.join("m.toml");
    std::fs::write(
        &m,
        "output = \"o\"\n[defaults]\ndownsample = \"two\"\n[[job]]\nsequence = \"s\"\n",
    )
    .unwrap();
    let o = wgslam(&["batch", "list", s(&m)]);
    assert!(!text(&o).contains("untagged enum"), "{}", text(&o));
    assert!(
        text(&o).contains("downsample: a whole number"),
        "{}",
        text(&o)
    );
    std::fs::write(
        &m,
        "output = \"o\"\n[[job]]\nname = \"a\\u0000b\"\nsequence = \"s\"\n",
    )
    .unwrap();
    let o = wgslam(&["batch", "list", s(&m)]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("control character"), "{}", text(&o));
}

fn a_closed_pipe_ends_the_output_quietly() {
    // `batch list | head -1` panicked on the broken pipe.
    let m = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("deploy/manifests/proof.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_wgslam"))
        .args(["batch", "list", s(&m)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_ne!(o.status.code(), Some(101), "{err}");
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain("messages_say_what_is_wrong", messages_say_what_is_wrong),
        plain(
            "a_closed_pipe_ends_the_output_quietly",
            a_closed_pipe_ends_the_output_quietly,
        ),
    ]
}
