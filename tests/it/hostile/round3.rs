//! Hostile inputs, round 3 (issue 46): one batch job's failure stays that job's, the last
//! oddities get a note or an error in the words of the interface they reach.

use super::*;

/// A copy of the bundled sequence in `dir/name` whose depth images all read 0 (nothing
/// can track).
fn zero_depth_copy(dir: &Path, name: &str) -> PathBuf {
    let seq = copy_bundled(dir, name);
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
    let s = common::read_json(out.join("summary.json"));
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
    vec![
        plain(
            "one_jobs_input_never_stops_the_batch",
            one_jobs_input_never_stops_the_batch,
        ),
        plain(
            "missing_intrinsics_name_each_interfaces_control",
            missing_intrinsics_name_each_interfaces_control,
        ),
        plain(
            "reversed_association_lists_are_noted_and_ordered_as_asked",
            reversed_association_lists_are_noted_and_ordered_as_asked,
        ),
        plain(
            "repeated_ground_truth_stamps_are_noted",
            repeated_ground_truth_stamps_are_noted,
        ),
        plain(
            "photometric_options_need_rgbd_tracking",
            photometric_options_need_rgbd_tracking,
        ),
        plain("a_link_loop_dataset_says_so", a_link_loop_dataset_says_so),
        plain(
            "tiny_scannet_colour_is_refused",
            tiny_scannet_colour_is_refused,
        ),
    ]
}

/// `wgslam run SEQ` over frames 1..3 at 160x120 on the CPU into `dir/out`, with `extra`.
fn run_on(seq: &Path, dir: &Path, extra: &[&str]) -> std::process::Output {
    let out = dir.join("out");
    let mut a = vec!["--out", s(&out)];
    a.extend_from_slice(extra);
    run_small(seq, &a)
}

/// A TUM folder without intrinsics was told "pass `--intrinsics` (a preset such as
/// fr1...)", which `--intrinsics fr1` refuses; the flag is `--camera fr1`, Python's
/// keyword `params={"camera": "fr1"}`, and the page has neither.
fn missing_intrinsics_name_each_interfaces_control() {
    let dir = common::temp_dir("hostile-round3-intrinsics");
    let tum = dir.join("tum");
    let icl = common::bundled_icl();
    std::fs::create_dir_all(&tum).unwrap();
    for sub in ["rgb", "depth"] {
        copy_dir(&icl.join(sub), &tum.join(sub));
    }
    for (list, sub) in [("rgb.txt", "rgb"), ("depth.txt", "depth")] {
        let lines: String = (0..4)
            .map(|i| format!("{:.6} {sub}/{i}.png\n", 1.0 + i as f64 * 0.033))
            .collect();
        std::fs::write(tum.join(list), lines).unwrap();
    }
    let o = run_on(&tum, &dir, &[]);
    let said = text(&o);
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert!(
        said.contains("pass --camera fr1, fr2 or fr3") && !said.contains("a preset such as"),
        "{said}"
    );
    ok(run_on(&tum, &dir, &["--camera", "fr1"]));
    let python = wgslam::cli::embed::open_sequence(Some(&tum), "").unwrap_err();
    assert!(
        python
            .to_string()
            .contains(r#"pass params={"camera": "fr1"}"#),
        "{python}"
    );
    let page = wgslam::dataset::open(
        &tum,
        &wgslam::dataset::SequenceOptions {
            interface: wgslam::dataset::Interface::Page,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        page.to_string()
            .contains("choose the camera on the page (fr1")
            && page.to_string().contains("add a camera.json")
            && !page.to_string().contains("--"),
        "{page}"
    );
}

/// Reversed ICL-NUIM (and ETH3D) frame lists were played in file order without the note
/// TUM lists get, and `--stamp-order` was ignored there.
fn reversed_association_lists_are_noted_and_ordered_as_asked() {
    let dir = common::temp_dir("hostile-round3-order");
    let seq = copy_bundled(&dir, "rev");
    let list = seq.join("associations.txt");
    let lines: Vec<String> = std::fs::read_to_string(&list)
        .unwrap()
        .lines()
        .rev()
        .map(String::from)
        .collect();
    std::fs::write(&list, lines.join("\n") + "\n").unwrap();
    // Runs `seq` with `extra`, which must succeed with the note `note`: what it said, and
    // the trajectory's first stamp.
    let first_stamp = |seq: &Path, note: &str, extra: &[&str]| {
        let o = run_on(seq, &dir, extra);
        let said = text(&o);
        assert!(o.status.success() && said.contains(note), "{said}");
        let traj = std::fs::read_to_string(dir.join("out/trajectory.tum")).unwrap();
        let stamp = traj.lines().find(|l| !l.starts_with('#')).unwrap();
        (said, stamp.split_whitespace().next().unwrap().to_string())
    };
    let note = "associations.txt: stamps go backwards";
    let (said, stamp) = first_stamp(&seq, note, &[]);
    assert!(said.contains("pass --stamp-order file"), "{said}");
    assert_eq!(stamp, "1", "time order: frame 1 is stamp 1");
    let (_, stamp) = first_stamp(&seq, note, &["--stamp-order", "file"]);
    assert_eq!(stamp, "22", "file order: frame 1 is the list's second line");
    // ETH3D's associated.txt, reversed: the same note and the same choice.
    let eth3d = dir.join("eth3d");
    std::fs::create_dir_all(&eth3d).unwrap();
    for sub in ["rgb", "depth"] {
        copy_dir(&seq.join(sub), &eth3d.join(sub));
    }
    let k = wgslam::geometry::camera::Intrinsics::ICL_NUIM;
    let calibration = format!("{} {} {} {}\n", k.fx, k.fy, k.cx, k.cy);
    std::fs::write(eth3d.join("calibration.txt"), calibration).unwrap();
    let assoc: String = (0..6)
        .rev()
        .map(|i| format!("{i}.0 rgb/{i}.png {i}.0 depth/{i}.png\n"))
        .collect();
    std::fs::write(eth3d.join("associated.txt"), assoc).unwrap();
    let note = "associated.txt: stamps go backwards 5 time(s)";
    assert_eq!(first_stamp(&eth3d, note, &[]).1, "1");
    assert_eq!(first_stamp(&eth3d, note, &["--stamp-order", "file"]).1, "4");
}

/// A ground truth with a repeated stamp was accepted by `run` and `eval` without a note.
fn repeated_ground_truth_stamps_are_noted() {
    let dir = common::temp_dir("hostile-round3-gt-repeat");
    let seq = copy_bundled(&dir, "seq");
    let gt = seq.join("livingRoom2.gt.freiburg");
    let mut lines: Vec<String> = std::fs::read_to_string(&gt)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    lines.insert(5, lines[5].clone());
    std::fs::write(&gt, lines.join("\n") + "\n").unwrap();
    let o = run_on(&seq, &dir, &[]);
    let note = "1 pose(s) repeat the stamp of the pose before";
    assert!(
        o.status.success() && text(&o).contains(note),
        "{}",
        text(&o)
    );
    let est = dir.join("out/trajectory.tum");
    for reference in [gt.as_path(), seq.as_path()] {
        let o = wgslam(&["eval", s(&est), s(reference)]);
        assert!(
            o.status.success() && text(&o).contains(note),
            "{}",
            text(&o)
        );
    }
}

/// `--photometric-weight` was accepted without `--tracking rgbd`, where it does nothing.
fn photometric_options_need_rgbd_tracking() {
    let dir = common::temp_dir("hostile-round3-photometric");
    let bundled = common::bundled_icl();
    let o = run_on(&bundled, &dir, &["--photometric-weight", "0.5"]);
    let said = text(&o);
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert!(
        said.contains("(--photometric-weight) does nothing unless `icp.tracking` (--tracking)"),
        "{said}"
    );
    ok(run_on(
        &bundled,
        &dir,
        &["--photometric-weight", "0.5", "--tracking", "rgbd"],
    ));
}

/// A dataset path that is a loop of symbolic links was reported as "does not exist".
#[cfg(unix)]
fn a_link_loop_dataset_says_so() {
    let dir = common::temp_dir("hostile-round3-loop");
    std::os::unix::fs::symlink(dir.join("b"), dir.join("a")).unwrap();
    std::os::unix::fs::symlink(dir.join("a"), dir.join("b")).unwrap();
    std::os::unix::fs::symlink(dir.join("nowhere"), dir.join("broken")).unwrap();
    let o = run_on(&dir.join("a"), &dir, &[]);
    assert!(
        text(&o).contains("is a loop of symbolic links"),
        "{}",
        text(&o)
    );
    let o = run_on(&dir.join("broken"), &dir, &[]);
    assert!(
        text(&o).contains("is a symbolic link to nothing"),
        "{}",
        text(&o)
    );
}

#[cfg(not(unix))]
fn a_link_loop_dataset_says_so() {}

/// ScanNet colour images of 1x1 pixels became an all-black colour, with exit 0 and no
/// warning: colour images the colour intrinsics cannot describe are refused. And
/// `--stamp-order file` on a layout of numbered frames is refused, not ignored.
fn tiny_scannet_colour_is_refused() {
    let dir = common::temp_dir("hostile-round3-scannet");
    let seq = dir.join("scene");
    for sub in ["color", "depth", "pose", "intrinsic"] {
        std::fs::create_dir_all(seq.join(sub)).unwrap();
    }
    let k4 = |fx: f32, fy: f32, cx: f32, cy: f32| {
        format!("{fx} 0 {cx} 0\n0 {fy} {cy} 0\n0 0 1 0\n0 0 0 1\n")
    };
    for i in 0..4 {
        std::fs::copy(
            common::bundled_icl().join(format!("depth/{i}.png")),
            seq.join(format!("depth/{i}.png")),
        )
        .unwrap();
        image::RgbImage::new(1, 1)
            .save(seq.join(format!("color/{i}.jpg")))
            .unwrap();
        std::fs::write(seq.join(format!("pose/{i}.txt")), k4(1.0, 1.0, 0.0, 0.0)).unwrap();
    }
    let write = |name: &str, text: String| std::fs::write(seq.join("intrinsic").join(name), text);
    write("intrinsic_depth.txt", k4(481.2, 480.0, 319.5, 239.5)).unwrap();
    write("intrinsic_color.txt", k4(1170.2, 1170.2, 647.8, 483.8)).unwrap();
    let o = run_on(&seq, &dir, &[]);
    let said = text(&o);
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert!(
        said.contains("colour image is 1x1") && said.contains("outside it"),
        "{said}"
    );
    // `--stamp-order` was silently ignored where frames are numbered files.
    let o = run_on(&seq, &dir, &["--stamp-order", "file"]);
    assert!(
        text(&o).contains("--stamp-order file: ") && text(&o).contains("leave it out"),
        "{}",
        text(&o)
    );
}
