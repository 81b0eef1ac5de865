//! `wgslam batch collect`: one row per job from whatever has finished (`summary.json`,
//! `summary.csv`), and `wgslam batch diff`: two batches' numbers side by side.
//!
//! The batch folder's `batch.json` (the expanded job list, written when a batch starts)
//! says which jobs to expect; a job without a record is `pending`. `diff` compares what
//! does not depend on the machine's load: status, frames, map size, lost frames, ATE, RPE
//! and the GPU-vs-CPU differences, exactly (the runs are deterministic: same inputs, same
//! binary, same numbers), and ignores times and memory.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::folder::RECORD;
use super::job::{JobRecord, JobStatus};
use super::manifest::{JobSpec, Manifest};
use crate::io::atomic::write_atomic;
use crate::tools::run::RunNumbers;
use crate::{Error, Result};

/// The expanded job list a batch folder was started with.
pub const PLAN: &str = "batch.json";

/// What `batch.json` holds.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Plan {
    /// The manifest it was expanded from.
    pub manifest: PathBuf,
    pub jobs: Vec<JobSpec>,
}

/// Writes `batch.json` into `out` (every shard writes the same, atomically).
pub fn write_plan(out: &Path, manifest: &Manifest) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::write(out, e))?;
    crate::tools::run::write_json(
        &out.join(PLAN),
        &Plan {
            manifest: manifest.path.clone(),
            jobs: manifest.jobs.clone(),
        },
    )
}

/// One row of the summary: a job and, when it finished, its record.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Row {
    pub index: usize,
    pub id: String,
    /// `ok`, `lost` (ran to the end, but a backend's run ended lost or never tracked:
    /// health `LOST`), `failed` or `pending` (no record yet, or a record for another spec).
    pub status: String,
    pub spec: JobSpec,
    pub record: Option<JobRecord>,
}

/// What `summary.json` holds.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Summary {
    pub jobs: usize,
    pub ok: usize,
    /// Jobs that ran but whose tracking ended lost (status `lost`).
    #[serde(default)]
    pub lost: usize,
    pub failed: usize,
    pub pending: usize,
    pub rows: Vec<Row>,
}

/// Reads the batch folder `out`: the plan's jobs with their records. Every job of
/// `batch.json` is checked as the manifest's were ([`JobSpec::validate`]): an id that is not
/// a plain folder name (`../x`), an unknown backend or profile is an error, never a path
/// or a string passed on to the report.
pub fn collect(out: &Path) -> Result<Summary> {
    let plan_path = out.join(PLAN);
    let text =
        match crate::io::input::read_kind_string(&plan_path, crate::io::input::InputKind::Manifest)
        {
            Err(Error::Io { path, source }) => {
                let why = format!("{source} (not a batch folder: no {PLAN})");
                return Err(Error::io(&path, std::io::Error::new(source.kind(), why)));
            }
            other => other?,
        };
    let plan: Plan = serde_json::from_str(&text)
        .map_err(|e| Error::format(&plan_path, format!("unreadable: {e}")))?;
    let mut seen = std::collections::BTreeSet::new();
    for (index, spec) in plan.jobs.iter().enumerate() {
        let bad = |why: String| {
            Error::format(
                &plan_path,
                format!(
                    "job {index} ({:?}): {why}; this batch.json was not written by wgslam as it \
                     is, so nothing is collected from it",
                    spec.id
                ),
            )
        };
        spec.validate().map_err(bad)?;
        if !seen.insert(spec.id.as_str()) {
            return Err(bad("a second job with this id".into()));
        }
    }
    let mut rows = Vec::new();
    for (index, spec) in plan.jobs.into_iter().enumerate() {
        let path = out.join("jobs").join(&spec.id).join(RECORD);
        let record =
            match crate::io::input::read_kind_string(&path, crate::io::input::InputKind::List) {
                Ok(t) => {
                    let r: JobRecord = serde_json::from_str(&t)
                        .map_err(|e| Error::format(&path, format!("unreadable job record: {e}")))?;
                    (r.spec == spec).then_some(r)
                }
                Err(_) => None,
            };
        let lost = |r: &JobRecord| r.runs.values().any(|n| n.health == "LOST");
        let status = match record.as_ref() {
            Some(r) if r.status == JobStatus::Failed => "failed",
            Some(r) if lost(r) => "lost",
            Some(_) => "ok",
            None => "pending",
        };
        rows.push(Row {
            index,
            id: spec.id.clone(),
            status: status.into(),
            spec,
            record,
        });
    }
    let count = |s: &str| rows.iter().filter(|r| r.status == s).count();
    Ok(Summary {
        jobs: rows.len(),
        ok: count("ok"),
        lost: count("lost"),
        failed: count("failed"),
        pending: count("pending"),
        rows,
    })
}

/// The CSV columns, one per number: the job's fields, then each backend's numbers, then
/// the GPU-vs-CPU differences (empty where a job has no such value).
const CSV_HEADER: &str = "index,id,status,sequence,frames,downsample,profile,backends,overrides,\
cpu_frames,cpu_ate_mm,cpu_rpe_mm,cpu_rpe_deg,cpu_ms_per_frame,cpu_peak_mib,cpu_map_points,cpu_lost,\
cpu_relocalised,cpu_health,\
gpu_frames,gpu_ate_mm,gpu_rpe_mm,gpu_rpe_deg,gpu_ms_per_frame,gpu_peak_mib,gpu_map_points,gpu_lost,\
gpu_relocalised,gpu_health,\
gpu_vs_cpu_pose_max_mm,gpu_vs_cpu_pose_max_deg,gpu_vs_cpu_map_unmatched,wall_s,error";

/// Writes `summary.json` and `summary.csv` into `out`, each completely or not at all.
pub fn write(out: &Path, s: &Summary) -> Result<()> {
    crate::tools::run::write_json(&out.join("summary.json"), s)?;
    let path = out.join("summary.csv");
    write_atomic(&path, |w| {
        writeln!(w, "{CSV_HEADER}").map_err(|e| Error::write(&path, e))?;
        for r in &s.rows {
            writeln!(w, "{}", csv_line(r)).map_err(|e| Error::write(&path, e))?;
        }
        Ok(())
    })
}

fn csv_line(r: &Row) -> String {
    let opt = |x: Option<f64>| x.map(|v| format!("{v}")).unwrap_or_default();
    let spec = &r.spec;
    let overrides: Vec<String> = spec
        .overrides
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    let mut f = vec![
        r.index.to_string(),
        r.id.clone(),
        r.status.clone(),
        spec.sequence.display().to_string(),
        spec.frames.clone().unwrap_or_default(),
        spec.downsample.to_string(),
        spec.profile.clone(),
        spec.backends.join("+"),
        overrides.join(" "),
    ];
    for b in ["cpu", "gpu"] {
        let n: Option<&RunNumbers> = r.record.as_ref().and_then(|rec| rec.runs.get(b));
        f.extend([
            n.map(|n| n.frames.to_string()).unwrap_or_default(),
            opt(n.and_then(|n| n.ate_rmse_mm)),
            opt(n.and_then(|n| n.rpe_trans_rmse_mm)),
            opt(n.and_then(|n| n.rpe_rot_rmse_deg)),
            opt(n.map(|n| n.time_per_frame_median_ms)),
            opt(n.and_then(|n| n.peak_memory_mib)),
            n.map(|n| n.map_points.to_string()).unwrap_or_default(),
            n.map(|n| n.lost_frames.to_string()).unwrap_or_default(),
            n.map(|n| n.relocalised_frames.to_string())
                .unwrap_or_default(),
            n.map(|n| n.health.clone()).unwrap_or_default(),
        ]);
    }
    let c = r.record.as_ref().and_then(|rec| rec.gpu_vs_cpu.as_ref());
    f.extend([
        opt(c.map(|c| c.pose_max_mm)),
        opt(c.map(|c| c.pose_max_deg)),
        opt(c.map(|c| c.map_unmatched_fraction)),
        opt(r.record.as_ref().map(|rec| rec.wall_s)),
        r.record
            .as_ref()
            .and_then(|rec| rec.error.clone())
            .unwrap_or_default(),
    ]);
    f.iter().map(|x| csv_field(x)).collect::<Vec<_>>().join(",")
}

/// RFC 4180 quoting: fields with commas, quotes or line breaks in double quotes.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Reads a summary from a batch folder (collecting it) or a `summary.json` file.
pub fn load(path: &Path) -> Result<Summary> {
    if path.is_dir() {
        return collect(path);
    }
    let text = crate::io::input::read_kind_string(path, crate::io::input::InputKind::Manifest)?;
    serde_json::from_str(&text).map_err(|e| Error::format(path, format!("not a summary.json: {e}")))
}

/// A backend's numbers that must be equal between two runs of the same job (not its
/// times or memory).
#[derive(Debug, PartialEq)]
struct RunFacts<'a> {
    backend: &'a str,
    frames: u64,
    map_points: u64,
    lost_frames: u64,
    relocalised_frames: u64,
    health: &'a str,
    ate_rmse_mm: Option<f64>,
    rpe_trans_rmse_mm: Option<f64>,
    rpe_rot_rmse_deg: Option<f64>,
}

/// The numbers of a row that must be equal between two runs of the same job.
#[derive(Debug, PartialEq)]
struct Deterministic<'a> {
    status: &'a str,
    runs: Vec<RunFacts<'a>>,
    gpu_vs_cpu: Option<&'a super::gpu_vs_cpu::GpuVsCpu>,
}

fn deterministic(r: &Row) -> Deterministic<'_> {
    let runs = r
        .record
        .iter()
        .flat_map(|rec| rec.runs.iter())
        .map(|(b, n)| RunFacts {
            backend: b,
            frames: n.frames,
            map_points: n.map_points,
            lost_frames: n.lost_frames,
            relocalised_frames: n.relocalised_frames,
            health: &n.health,
            ate_rmse_mm: n.ate_rmse_mm,
            rpe_trans_rmse_mm: n.rpe_trans_rmse_mm,
            rpe_rot_rmse_deg: n.rpe_rot_rmse_deg,
        })
        .collect();
    Deterministic {
        status: &r.status,
        runs,
        gpu_vs_cpu: r.record.as_ref().and_then(|rec| rec.gpu_vs_cpu.as_ref()),
    }
}

/// The differences between two summaries, one line each (empty: equal). Jobs are matched
/// by id; a job in one only is a difference.
pub fn diff(a: &Summary, b: &Summary) -> Vec<String> {
    let mut out = Vec::new();
    for ra in &a.rows {
        match b.rows.iter().find(|rb| rb.id == ra.id) {
            None => out.push(format!("{}: only in the first", ra.id)),
            Some(rb) => {
                if ra.spec != rb.spec {
                    out.push(format!("{}: different job specs", ra.id));
                }
                let (da, db) = (deterministic(ra), deterministic(rb));
                if da != db {
                    out.push(format!("{}: {da:?}\n    vs {db:?}", ra.id));
                }
            }
        }
    }
    for rb in &b.rows {
        if !a.rows.iter().any(|ra| ra.id == rb.id) {
            out.push(format!("{}: only in the second", rb.id));
        }
    }
    out
}
