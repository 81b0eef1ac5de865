//! `wgslam batch`: many runs from one manifest, resumable, shardable across a scheduler's
//! array tasks, merged into one report.
//!
//! | module | what |
//! |---|---|
//! | [`manifest`] | the TOML manifest and its expansion into numbered [`manifest::JobSpec`]s |
//! | [`select`] | which jobs this process runs: `--index`, `--shard I/N`, Slurm / Kubernetes variables |
//! | [`folder`] | the batch folder's marker, job locks, deleting only what a batch wrote |
//! | [`job`] | one job: `wgslam run` per backend in a child process (or in this one), its record `job.json` |
//! | [`in_process`] | `--concurrent N`: N jobs at once on threads, one shared GPU device |
//! | [`gpu_vs_cpu`] | the GPU run's trajectory and map against the CPU run's, from their output files |
//! | [`interrupt`] | Ctrl-C / SIGTERM: stop the job in flight, leave it looking unfinished |
//! | [`summary`] | `collect`: `summary.csv`, `summary.json`; `diff` of two batches' numbers |
//! | [`report`] | the self-contained `report.html` |
//!
//! A batch folder holds `batch.json` (the expanded job list), `jobs/<id>/` per job
//! (`params.toml`, the parameter file each backend's run reads; one subfolder of run
//! outputs per backend, `<backend>.log`, `comparison.json` with both backends, and
//! `job.json`, written last and atomically: a job is complete exactly when its `job.json`
//! says `ok` for the same spec), and the summaries.

pub mod folder;
pub mod gpu_vs_cpu;
pub mod in_process;
pub mod interrupt;
pub mod job;
pub mod manifest;
pub mod report;
pub mod select;
pub mod summary;
