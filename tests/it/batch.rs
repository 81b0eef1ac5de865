//! `wgslam batch` as a user runs it: manifests in, job folders, summaries and report out;
//! resuming, failing jobs, interruption, shards and scheduler indices, and `batch diff`.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use common::cli::{ok, text, wgslam_env as wgslam};
use common::harness::{gpu, plain, shared};

/// Writes `body` as `dir/batch.toml` with `output = "out"`; returns the manifest path.
fn manifest(dir: &Path, body: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("batch.toml");
    std::fs::write(&path, format!("output = \"out\"\n{body}")).unwrap();
    path
}

/// A `[[job]]` table named `name` over `seq` with more `fields` (TOML lines).
fn one_job(name: &str, seq: &Path, fields: &str) -> String {
    format!(
        "[[job]]\nname = \"{name}\"\nsequence = \"{}\"\n{fields}",
        seq.display()
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn summary(out: &Path) -> serde_json::Value {
    common::read_json(out.join("summary.json"))
}

/// The batch of manifest `m` run again, uninterrupted, into `whole`: `batch diff` finds
/// its three jobs' numbers equal to those in `out`.
fn same_numbers_as_a_whole_batch(m: &Path, out: &Path, whole: &Path) {
    succeeds(&["batch", s(m), "--out", s(whole)]);
    let said = succeeds(&["batch", "diff", s(out), s(whole)]);
    assert!(said.contains("equal: 3 jobs"), "{said}");
}

/// Runs `wgslam ARGS`, asserts that it succeeded, and returns what it printed.
fn succeeds(args: &[&str]) -> String {
    text(&ok(wgslam(args, &[])))
}

/// Asserts that `output` says `jobs` jobs were skipped as already complete.
fn assert_skipped(output: &str, jobs: usize) {
    let skipped = output.matches("outputs complete, skipped").count();
    assert_eq!(skipped, jobs, "{output}");
}

/// Three short CPU jobs over the bundled frames (a grid of two profiles and a named job).
fn cpu_grid(frames: &str) -> String {
    let seq = common::bundled_icl();
    format!(
        "[defaults]\nframes = \"{frames}\"\ndownsample = 4\nbackend = \"cpu\"\n\
         [[job]]\nname = \"named\"\nsequence = \"{}\"\noverrides = {{ icp-dist = 0.08 }}\n\
         [[grid]]\nname = \"g\"\nsequence = \"{}\"\nprofile = [\"robust\", \"assignment\"]\n",
        seq.display(),
        seq.display()
    )
}

/// ATE bound for 4 bundled frames at 160x120 against the ground truth: both profiles
/// track these noise-free frames to well under a millimetre (measured 0.13-0.18 mm).
const SHORT_RUN_ATE_MAX_MM: f64 = 1.0;

fn runs_resumes_and_reports() {
    let dir = common::temp_dir("batch-basic");
    let m = manifest(&dir, &cpu_grid("1..4"));
    let out = dir.join("out");
    ok(wgslam(&["batch", s(&m)], &[]));
    let sum = summary(&out);
    assert_eq!(
        (sum["jobs"].as_u64(), sum["ok"].as_u64()),
        (Some(3), Some(3)),
        "{sum}"
    );
    let ids: Vec<&str> = sum["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, ["named", "g-robust", "g-assignment"]);
    for r in sum["rows"].as_array().unwrap() {
        let cpu = &r["record"]["runs"]["cpu"];
        assert_eq!(cpu["frames"], 4);
        let ate = cpu["ate_rmse_mm"].as_f64().unwrap();
        assert!(ate < SHORT_RUN_ATE_MAX_MM, "{}: ATE {ate} mm", r["id"]);
    }
    // The named job's override reached its run.
    let metrics: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("jobs/named/cpu/metrics.json")).unwrap(),
    )
    .unwrap();
    assert!(
        (metrics["params"]["icp"]["dist_m"].as_f64().unwrap() - 0.08).abs() < 1e-6,
        "{metrics}"
    );
    // ...through the job's parameter file, which `wgslam run --params` reads.
    let params = std::fs::read_to_string(out.join("jobs/named/params.toml")).unwrap();
    assert!(params.contains("icp-dist = 0.08"), "{params}");
    let csv = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    assert_eq!(csv.lines().count(), 4, "{csv}");
    assert!(csv.lines().nth(1).unwrap().starts_with("0,named,ok,"));
    // The report is self-contained: pictures inline, nothing fetched.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("data:image/png;base64,"));
    for bad in ["src=\"http", "href=\"http", "<script", "<link"] {
        assert!(!html.contains(bad), "report.html has {bad}");
    }
    // A re-run skips every complete job and leaves its record alone.
    let record = out.join("jobs/g-robust/job.json");
    let before = std::fs::read_to_string(&record).unwrap();
    assert_skipped(&succeeds(&["batch", s(&m)]), 3);
    assert_eq!(std::fs::read_to_string(&record).unwrap(), before);
    // A changed job runs again; the others are still skipped.
    std::fs::write(
        &m,
        std::fs::read_to_string(&m).unwrap().replace("0.08", "0.09"),
    )
    .unwrap();
    assert_skipped(&succeeds(&["batch", s(&m)]), 2);
}

fn a_failing_job_is_recorded_and_the_batch_goes_on() {
    let dir = common::temp_dir("batch-fail");
    let body = cpu_grid("1..2") + &one_job("missing", Path::new("no/such/sequence"), "");
    let m = manifest(&dir, &body);
    let sum = one_job_fails(&m, &dir.join("out"), &["1 of 4 jobs failed: missing"], 3);
    // [[job]] tables come first, in file order, then the grid.
    let row = &sum["rows"][1];
    assert_eq!(row["id"], "missing");
    assert_eq!(row["status"], "failed");
    let err = row["record"]["error"].as_str().unwrap();
    assert!(
        err.contains("no/such/sequence"),
        "the run's own error is quoted: {err}"
    );
    let csv = std::fs::read_to_string(dir.join("out/summary.csv")).unwrap();
    assert!(
        csv.lines().nth(2).unwrap().starts_with("1,missing,failed,"),
        "{csv}"
    );
}

/// Runs the batch of manifest `m`, which must fail one job and say each of `says`, with
/// `ok` jobs done; its summary (in `out`).
fn one_job_fails(m: &Path, out: &Path, says: &[&str], ok: u64) -> serde_json::Value {
    let o = wgslam(&["batch", s(m)], &[]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    for said in says {
        assert!(text(&o).contains(said), "{said:?} not in {}", text(&o));
    }
    let sum = summary(out);
    assert_eq!(
        (sum["ok"].as_u64(), sum["failed"].as_u64()),
        (Some(ok), Some(1))
    );
    sum
}

fn manifest_mistakes_fail_before_any_job() {
    // A typo in every job's parameters fails before any job runs, naming the job.
    let dir = common::temp_dir("batch-typo");
    let body = cpu_grid("1..2").replace("icp-dist", "icp-dits");
    let only_named = &body[..body.find("[[grid]]").unwrap()];
    let m = manifest(&dir, only_named);
    let o = wgslam(&["batch", s(&m)], &[]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("job \"named\"") && text(&o).contains("icp-dits"),
        "{}",
        text(&o)
    );
    assert!(!dir.join("out").exists(), "nothing may run");
    // In one job of three it fails that job only (issue 46): the others run and the
    // summary is written.
    let dir = common::temp_dir("batch-typo-one");
    let m = manifest(&dir, &body);
    let says = ["job \"named\"", "1 of 3 jobs failed: named"];
    one_job_fails(&m, &dir.join("out"), &says, 2);
    let o = wgslam(&["batch", s(&dir.join("absent.toml"))], &[]);
    assert!(!o.status.success());
    assert!(text(&o).contains("absent.toml"), "{}", text(&o));
}

fn shards_and_scheduler_indices_split_the_jobs() {
    let dir = common::temp_dir("batch-shards");
    let m = manifest(&dir, &cpu_grid("1..2"));
    let out = dir.join("out");
    // Slurm's array index picks one job; the summary lists the others as pending.
    let o = ok(wgslam(&["batch", s(&m)], &[("SLURM_ARRAY_TASK_ID", "1")]));
    assert!(
        text(&o).contains("1 of 3 jobs (index 1 of 3, from SLURM_ARRAY_TASK_ID"),
        "{}",
        text(&o)
    );
    assert!(
        !out.join("summary.json").exists(),
        "an array task leaves the summary to collect"
    );
    ok(wgslam(&["batch", "collect", s(&out)], &[]));
    let sum = summary(&out);
    assert_eq!(
        (sum["ok"].as_u64(), sum["pending"].as_u64()),
        (Some(1), Some(2))
    );
    assert_eq!(sum["rows"][1]["status"], "ok");
    // A Kubernetes index and a shard flag fill in the rest (job 1 is already complete).
    ok(wgslam(&["batch", s(&m)], &[("JOB_COMPLETION_INDEX", "2")]));
    let o = ok(wgslam(&["batch", s(&m), "--shard", "0/2"], &[]));
    assert!(
        text(&o).contains("job 2 g-assignment: outputs complete, skipped"),
        "{}",
        text(&o)
    );
    ok(wgslam(&["batch", "collect", s(&out)], &[]));
    assert_eq!(summary(&out)["ok"].as_u64(), Some(3));
    // An index past the last job is a mis-sized array, not a silent success.
    let o = wgslam(&["batch", s(&m)], &[("SLURM_ARRAY_TASK_ID", "3")]);
    assert!(!o.status.success());
    assert!(text(&o).contains("picks no job"), "{}", text(&o));
}

/// How long the interrupted batch may take to reach its second job.
const FIRST_JOB_TIMEOUT: Duration = Duration::from_secs(120);

/// Runs `wgslam batch ARGS`, waits until `started` (a job's log) exists, sends SIGTERM and
/// checks the batch exits 130, as an interrupted batch must. `which`: the job `started`
/// belongs to, for the timeout's message.
fn sigterm_batch_once_started(args: &[&str], started: &Path, which: &str) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_wgslam"))
        .arg("batch")
        .args(args)
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !started.exists() {
        assert!(
            start.elapsed() < FIRST_JOB_TIMEOUT,
            "the batch did not reach its {which} job"
        );
        assert!(child.try_wait().unwrap().is_none(), "the batch ended early");
        std::thread::sleep(Duration::from_millis(20));
    }
    let kill = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "interrupted batches exit 130");
}

fn sigterm_half_way_then_resume_equals_an_uninterrupted_run() {
    let dir = common::temp_dir("batch-kill");
    let m = manifest(&dir, &cpu_grid("1..12"));
    let out = dir.join("out");
    // Wait until the first job is complete and the second has started, then SIGTERM.
    sigterm_batch_once_started(&[s(&m)], &out.join("jobs/g-robust/cpu.log"), "second");
    assert!(
        out.join("jobs/named/job.json").is_file(),
        "the finished job keeps its record"
    );
    assert!(
        !out.join("jobs/g-robust/job.json").exists(),
        "the stopped job must not look complete"
    );
    assert!(!out.join("jobs/g-assignment").exists());
    // Resume: the finished job is skipped, the rest run.
    assert_skipped(&succeeds(&["batch", s(&m)]), 1);
    // The same numbers as an uninterrupted batch.
    same_numbers_as_a_whole_batch(&m, &out, &dir.join("whole"));
    // ...and diff does see a changed number.
    let mut sum = summary(&out);
    sum["rows"][2]["record"]["runs"]["cpu"]["map_points"] = serde_json::json!(1);
    let edited = dir.join("edited.json");
    std::fs::write(&edited, sum.to_string()).unwrap();
    let o = wgslam(&["batch", "diff", s(&edited), s(&dir.join("whole"))], &[]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("differs: g-assignment"), "{}", text(&o));
}

/// GPU vs CPU over 4 bundled frames end to end: each backend tracks on its own, so the
/// bound is `wgslam compare --free`'s per-frame pose tolerance.
const BOTH_POSE_MAX_MM: f64 = wgslam::tools::compare::tolerance::POSE_MAX_MM;

fn both_backends_write_the_gpu_vs_cpu_comparison() {
    let dir = common::temp_dir("batch-both");
    let seq = common::bundled_icl();
    let m = manifest(
        &dir,
        &one_job("both", &seq, "frames = \"1..4\"\ndownsample = 4\n"),
    );
    ok(wgslam(&["batch", s(&m)], &[]));
    let out = dir.join("out/jobs/both");
    for f in ["cpu/map.ply", "gpu/map.ply", "comparison.json", "job.json"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let row = &summary(&dir.join("out"))["rows"][0];
    let c = &row["record"]["gpu_vs_cpu"];
    assert_eq!(c["poses"], 4);
    assert!(c["pose_max_mm"].as_f64().unwrap() < BOTH_POSE_MAX_MM, "{c}");
    assert_eq!(row["record"]["runs"]["gpu"]["frames"], 4);
    let html = std::fs::read_to_string(dir.join("out/report.html")).unwrap();
    assert!(
        html.contains("gpu trajectory.png"),
        "both backends' pictures"
    );
}

/// Four short jobs over the bundled frames, GPU and CPU, different ranges and settings;
/// the manifest asks for them all at once.
fn mixed_jobs() -> String {
    let seq = common::bundled_icl();
    format!(
        "concurrent = 4\n\
         [defaults]\nframes = \"1..4\"\ndownsample = 4\n\
         [[job]]\nname = \"both\"\nsequence = \"{seq}\"\n\
         [[job]]\nname = \"gpu-later\"\nsequence = \"{seq}\"\nframes = \"3..7\"\nbackend = \"gpu\"\n\
         [[job]]\nname = \"gpu-assignment\"\nsequence = \"{seq}\"\nbackend = \"gpu\"\nprofile = \"assignment\"\n\
         [[job]]\nname = \"cpu-icp\"\nsequence = \"{seq}\"\nbackend = \"cpu\"\noverrides = {{ icp-dist = 0.08 }}\n",
        seq = seq.display()
    )
}

/// The outputs that must be byte-identical whichever way the jobs ran.
const IDENTICAL_OUTPUTS: [&str; 2] = ["trajectory.tum", "map.ply"];

fn concurrent_jobs_equal_one_at_a_time() {
    let dir = common::temp_dir("batch-concurrent");
    let m = manifest(&dir, &mixed_jobs());
    // The manifest's `concurrent = 4`: the four jobs at once, in this process.
    let (at_once, one_by_one) = (dir.join("at-once"), dir.join("one-by-one"));
    let o = ok(wgslam(&["batch", s(&m), "--out", s(&at_once)], &[]));
    assert!(
        text(&o).contains("up to 4 at once in this process"),
        "{}",
        text(&o)
    );
    // The flag wins over the key: one job at a time, each run a child process.
    let o = ok(wgslam(
        &["batch", s(&m), "--out", s(&one_by_one), "--concurrent", "1"],
        &[],
    ));
    assert!(!text(&o).contains("at once"), "{}", text(&o));
    let jobs = [
        ("both", "cpu"),
        ("both", "gpu"),
        ("gpu-later", "gpu"),
        ("gpu-assignment", "gpu"),
        ("cpu-icp", "cpu"),
    ];
    for (job, backend) in jobs {
        for f in IDENTICAL_OUTPUTS {
            let rel = format!("jobs/{job}/{backend}/{f}");
            let (a, b) = (at_once.join(&rel), one_by_one.join(&rel));
            let (a, b) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
            assert!(!a.is_empty(), "{rel} is empty");
            assert!(a == b, "{rel} differs between --concurrent 4 and 1");
        }
        // An in-process run's log holds what `wgslam run` prints.
        let log =
            std::fs::read_to_string(at_once.join(format!("jobs/{job}/{backend}.log"))).unwrap();
        assert!(log.contains("wrote "), "{job} {backend}.log: {log}");
    }
    let o = ok(wgslam(&["batch", "diff", s(&at_once), s(&one_by_one)], &[]));
    assert!(text(&o).contains("equal: 4 jobs"), "{}", text(&o));
    // Resuming with several at once skips what is complete.
    assert_skipped(&succeeds(&["batch", s(&m), "--out", s(&at_once)]), 4);
}

fn sigterm_stops_concurrent_jobs_then_resume_completes() {
    let dir = common::temp_dir("batch-kill-concurrent");
    let m = manifest(&dir, &cpu_grid("1..12"));
    let out = dir.join("out");
    // The third job starts when one of the first two is done: SIGTERM while it runs.
    sigterm_batch_once_started(
        &[s(&m), "--concurrent", "2"],
        &out.join("jobs/g-assignment/cpu.log"),
        "third",
    );
    assert!(
        !out.join("jobs/g-assignment/job.json").exists(),
        "the stopped job must not look complete"
    );
    assert!(
        !out.join("jobs/g-assignment/cpu/map.ply").exists(),
        "a stopped run writes no outputs"
    );
    // Resume with several at once: the rest run, and the numbers are an uninterrupted
    // batch's.
    let o = ok(wgslam(&["batch", s(&m), "--concurrent", "2"], &[]));
    assert!(
        text(&o).contains("g-assignment: ok in"),
        "the stopped job runs again: {}",
        text(&o)
    );
    same_numbers_as_a_whole_batch(&m, &out, &dir.join("whole"));
}

/// The full noisy sequence: the batch's numbers are the run's, on the real ground truth.
const NOISY_ATE_MAX_MM: f64 = 15.0;

fn noisy_sequence_job_tracks_against_ground_truth(data: &Path) {
    let dir = common::temp_dir("batch-noisy");
    let seq = common::shared_icl_noisy(data);
    let m = manifest(
        &dir,
        &one_job(
            "noisy",
            &seq,
            "frames = \"1..40\"\ndownsample = 4\nbackend = \"cpu\"\n",
        ),
    );
    ok(wgslam(&["batch", s(&m)], &[]));
    let ate = summary(&dir.join("out"))["rows"][0]["record"]["runs"]["cpu"]["ate_rmse_mm"]
        .as_f64()
        .unwrap();
    assert!(ate < NOISY_ATE_MAX_MM, "ATE {ate} mm");
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain("runs_resumes_and_reports", runs_resumes_and_reports),
        plain(
            "a_failing_job_is_recorded_and_the_batch_goes_on",
            a_failing_job_is_recorded_and_the_batch_goes_on,
        ),
        plain(
            "manifest_mistakes_fail_before_any_job",
            manifest_mistakes_fail_before_any_job,
        ),
        plain(
            "shards_and_scheduler_indices_split_the_jobs",
            shards_and_scheduler_indices_split_the_jobs,
        ),
        plain(
            "sigterm_half_way_then_resume_equals_an_uninterrupted_run",
            sigterm_half_way_then_resume_equals_an_uninterrupted_run,
        ),
        plain(
            "sigterm_stops_concurrent_jobs_then_resume_completes",
            sigterm_stops_concurrent_jobs_then_resume_completes,
        ),
        gpu("both_backends_write_the_gpu_vs_cpu_comparison", |_ctx| {
            both_backends_write_the_gpu_vs_cpu_comparison()
        }),
        gpu("concurrent_jobs_equal_one_at_a_time", |_ctx| {
            concurrent_jobs_equal_one_at_a_time()
        }),
        shared(
            "noisy_sequence_job_tracks_against_ground_truth",
            noisy_sequence_job_tracks_against_ground_truth,
        ),
    ]
}
