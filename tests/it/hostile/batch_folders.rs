//! Hostile inputs: `batch --out`: a batch never deletes what it did not write, and its locks hold.

use super::*;

// ---- 1. batch --out: never delete what the batch did not write -----------------------

fn batch_refuses_a_folder_with_files_it_did_not_write() {
    let dir = common::temp_dir("hostile-foreign");
    let out = dir.join("out");
    std::fs::create_dir_all(out.join("jobs/myjob")).unwrap();
    std::fs::write(out.join("jobs/myjob/thesis.tex"), "my thesis").unwrap();
    std::fs::write(out.join("summary.csv"), "my numbers").unwrap();
    let m = small_manifest(&dir, "m.toml", "myjob", "out");
    let said = batch(&m, false);
    assert!(said.contains("not a batch folder"), "{}", said);
    still_holds(&out.join("jobs/myjob/thesis.tex"), "my thesis");
    still_holds(&out.join("summary.csv"), "my numbers");
    assert!(!out.join("batch.json").exists());
}

fn batch_job_folder_keeps_a_file_it_did_not_write() {
    // The batch's own folder, but a user dropped a file into a job's folder: the job is
    // not started afresh (that would delete it), the file stays.
    let dir = common::temp_dir("hostile-jobfile");
    let m = small_manifest(&dir, "m.toml", "myjob", "out");
    batch(&m, true);
    let job = dir.join("out/jobs/myjob");
    std::fs::remove_file(job.join("job.json")).unwrap();
    std::fs::write(job.join("thesis.tex"), "my thesis").unwrap();
    std::fs::write(job.join("cpu/notes.txt"), "notes").unwrap();
    let said = batch(&m, false);
    assert!(
        said.contains("thesis.tex") && said.contains("did not write"),
        "{}",
        said
    );
    still_holds(&job.join("thesis.tex"), "my thesis");
    still_holds(&job.join("cpu/notes.txt"), "notes");
}

#[cfg(unix)]
fn batch_never_deletes_through_a_link() {
    let dir = common::temp_dir("hostile-link");
    let m = small_manifest(&dir, "m.toml", "myjob", "out");
    batch(&m, true);
    let elsewhere = dir.join("elsewhere");
    std::fs::create_dir_all(elsewhere.join("myjob")).unwrap();
    std::fs::write(elsewhere.join("myjob/precious.txt"), "keep").unwrap();
    let out = dir.join("out");
    std::fs::rename(out.join("jobs"), dir.join("old-jobs")).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out.join("jobs")).unwrap();
    let said = batch(&m, false);
    assert!(said.contains("link"), "{}", said);
    still_holds(&elsewhere.join("myjob/precious.txt"), "keep");
    // A link in place of a job's folder is not followed either.
    std::fs::remove_file(out.join("jobs")).unwrap();
    std::fs::create_dir(out.join("jobs")).unwrap();
    std::os::unix::fs::symlink(elsewhere.join("myjob"), out.join("jobs/myjob")).unwrap();
    batch(&m, false);
    still_holds(&elsewhere.join("myjob/precious.txt"), "keep");
}

fn two_manifests_cannot_share_a_folder() {
    let dir = common::temp_dir("hostile-two-manifests");
    let a = small_manifest(&dir, "a.toml", "job-a", "out");
    let b = small_manifest(&dir, "b.toml", "job-b", "out");
    batch(&a, true);
    let said = batch(&b, false);
    assert!(
        said.contains("batch folder of manifest") && said.contains("a.toml"),
        "{}",
        said
    );
    assert!(dir.join("out/jobs/job-a/job.json").is_file());
    assert!(!dir.join("out/jobs/job-b").exists());
    // The same manifest again resumes (skips its finished job).
    let said = batch(&a, true);
    assert!(said.contains("skipped"), "{}", said);
}

fn batch_refuses_the_root_and_a_file() {
    let dir = common::temp_dir("hostile-root");
    let m = small_manifest(&dir, "m.toml", "j", "out");
    let o = wgslam(&["batch", s(&m), "--out", "/"]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("root"), "{}", text(&o));
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let o = wgslam(&["batch", s(&m), "--out", s(&file)]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("is a file"), "{}", text(&o));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}

/// Holds `path`'s flock(2) lock in a child `flock` process until [`release`]; returns once
/// the lock is held.
fn hold_lock(path: &Path) -> Child {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    // -o: the lock stays with flock(1) itself, not with `cat`; `cat` ends when its stdin
    // closes, and flock with it, freeing the lock.
    let child = Command::new("flock")
        .arg("-o")
        .arg(path)
        .arg("cat")
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::null())
        .spawn()
        .expect("flock(1) from util-linux");
    for _ in 0..200 {
        let free = Command::new("flock")
            .args(["-n"])
            .arg(path)
            .arg("true")
            .status()
            .unwrap()
            .success();
        if !free {
            return child;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    release(child);
    panic!("flock never took {}", path.display());
}

/// Ends a [`hold_lock`] holder and waits for it.
fn release(mut child: Child) {
    drop(child.stdin.take());
    let _ = child.wait();
}

fn a_second_batch_on_a_running_job_is_refused_by_its_lock() {
    let dir = common::temp_dir("hostile-lock");
    let m = small_manifest(&dir, "m.toml", "myjob", "out");
    batch(&m, true);
    std::fs::remove_file(dir.join("out/jobs/myjob/job.json")).unwrap();
    let holder = hold_lock(&dir.join("out/locks/myjob.lock"));
    let o = wgslam(&["batch", s(&m)]);
    release(holder);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("being run by another"), "{}", text(&o));
    assert!(
        dir.join("out/jobs/myjob/cpu/map.ply").is_file(),
        "the other batch's job folder was touched"
    );
    let o = wgslam(&["batch", s(&m)]);
    assert!(o.status.success(), "lock released: {}", text(&o));
}

pub fn tests() -> Vec<common::harness::Test> {
    #[allow(unused_mut)]
    let mut v = vec![
        plain(
            "batch_refuses_a_folder_with_files_it_did_not_write",
            batch_refuses_a_folder_with_files_it_did_not_write,
        ),
        plain(
            "batch_job_folder_keeps_a_file_it_did_not_write",
            batch_job_folder_keeps_a_file_it_did_not_write,
        ),
        plain(
            "two_manifests_cannot_share_a_folder",
            two_manifests_cannot_share_a_folder,
        ),
        plain(
            "batch_refuses_the_root_and_a_file",
            batch_refuses_the_root_and_a_file,
        ),
        plain(
            "a_second_batch_on_a_running_job_is_refused_by_its_lock",
            a_second_batch_on_a_running_job_is_refused_by_its_lock,
        ),
    ];
    #[cfg(unix)]
    v.push(plain(
        "batch_never_deletes_through_a_link",
        batch_never_deletes_through_a_link,
    ));
    v
}

/// Runs `wgslam batch MANIFEST`, asserts whether it `succeeds`, and returns what it said.
fn batch(manifest: &Path, succeeds: bool) -> String {
    let o = wgslam(&["batch", s(manifest)]);
    assert_eq!(o.status.success(), succeeds, "{}", text(&o));
    text(&o)
}

/// `path` still holds exactly `contents` (a file the batch did not write).
fn still_holds(path: &Path, contents: &str) {
    let now = std::fs::read_to_string(path).unwrap();
    assert_eq!(now, contents, "{} changed", path.display());
}
