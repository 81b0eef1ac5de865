//! Which of a manifest's jobs this process runs: all, one index, or a shard.
//!
//! Precedence: `--shard I/N`, then `--index I`, then the schedulers' own variables
//! (`SLURM_ARRAY_TASK_ID`, then Kubernetes Indexed Jobs' `JOB_COMPLETION_INDEX`), then all
//! jobs. With an index from a variable, the shard count comes from `SLURM_ARRAY_TASK_COUNT`
//! or `WGSLAM_SHARD_COUNT` when set (array smaller than the job list: task I runs jobs I,
//! I+N, ...), else each index is one job.

use crate::{Error, Result};

/// The jobs picked: indices `i` with `i % count == index`, or every job.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Selection {
    All,
    Shard { index: usize, count: usize },
}

impl Selection {
    /// Whether job `i` is picked.
    pub fn picks(&self, i: usize) -> bool {
        match *self {
            Selection::All => true,
            Selection::Shard { index, count } => i % count == index,
        }
    }

    /// Checks the selection against a manifest of `jobs` jobs: an index past the last job
    /// is a mis-sized array, an error rather than a silent no-op.
    pub fn check(&self, jobs: usize) -> Result<()> {
        if let Selection::Shard { index, count } = *self {
            if index >= jobs.min(count) {
                return Err(Error::Argument(format!(
                    "job index {index} (of {count} shards) picks no job: the manifest has {jobs} \
                     jobs, so indices run 0..={}; size the array with `wgslam batch list`",
                    jobs.min(count) - 1
                )));
            }
        }
        Ok(())
    }
}

/// Where a selection came from, for the log line that says which jobs run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Chosen {
    pub selection: Selection,
    pub source: String,
}

/// Parses `I/N`.
pub fn parse_shard(s: &str) -> Result<Selection> {
    let bad = || Error::Argument(format!("--shard {s:?}: want I/N with 0 <= I < N, e.g. 0/4"));
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (index, count): (usize, usize) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if count == 0 || index >= count {
        return Err(bad());
    }
    Ok(Selection::Shard { index, count })
}

/// The selection from the flags, else from `env` (a lookup such as `std::env::var`), for a
/// manifest of `jobs` jobs.
pub fn choose(
    shard: Option<&str>,
    index: Option<usize>,
    jobs: usize,
    env: impl Fn(&str) -> Option<String>,
) -> Result<Chosen> {
    if let Some(s) = shard {
        return Ok(Chosen {
            selection: parse_shard(s)?,
            source: "--shard".into(),
        });
    }
    let number = |var: &str| -> Result<Option<usize>> {
        match env(var) {
            None => Ok(None),
            Some(v) => v.trim().parse().map(Some).map_err(|_| {
                Error::Argument(format!("{var}={v:?} is not a job index (a whole number)"))
            }),
        }
    };
    let (index, source) = match index {
        Some(i) => (i, "--index".to_string()),
        None => match (
            number("SLURM_ARRAY_TASK_ID")?,
            number("JOB_COMPLETION_INDEX")?,
        ) {
            (Some(i), _) => (i, "SLURM_ARRAY_TASK_ID".into()),
            (None, Some(i)) => (i, "JOB_COMPLETION_INDEX".into()),
            (None, None) => {
                return Ok(Chosen {
                    selection: Selection::All,
                    source: "no index given".into(),
                })
            }
        },
    };
    let (count, count_source) = match (
        number("SLURM_ARRAY_TASK_COUNT")?.filter(|_| source == "SLURM_ARRAY_TASK_ID"),
        number("WGSLAM_SHARD_COUNT")?,
    ) {
        (Some(n), _) => (n, " of SLURM_ARRAY_TASK_COUNT"),
        (None, Some(n)) => (n, " of WGSLAM_SHARD_COUNT"),
        (None, None) => (jobs, ", one job per index"),
    };
    if count == 0 {
        return Err(Error::Argument("the shard count is 0".into()));
    }
    Ok(Chosen {
        selection: Selection::Shard { index, count },
        source: format!("{source}{count_source}"),
    })
}
