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

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn flags_then_slurm_then_kubernetes_then_all() {
        let shard = |i, n| Selection::Shard { index: i, count: n };
        let pick = |s: Option<&str>, i: Option<usize>, vars: &[(&str, &str)]| {
            choose(s, i, 8, env(vars)).unwrap().selection
        };
        assert_eq!(pick(None, None, &[]), Selection::All);
        assert_eq!(
            pick(Some("1/3"), Some(5), &[("SLURM_ARRAY_TASK_ID", "2")]),
            shard(1, 3)
        );
        assert_eq!(
            pick(None, Some(5), &[("SLURM_ARRAY_TASK_ID", "2")]),
            shard(5, 8)
        );
        assert_eq!(
            pick(None, None, &[("SLURM_ARRAY_TASK_ID", "2")]),
            shard(2, 8)
        );
        assert_eq!(
            pick(
                None,
                None,
                &[
                    ("SLURM_ARRAY_TASK_ID", "2"),
                    ("SLURM_ARRAY_TASK_COUNT", "4")
                ]
            ),
            shard(2, 4)
        );
        assert_eq!(
            pick(None, None, &[("JOB_COMPLETION_INDEX", "7")]),
            shard(7, 8)
        );
        assert_eq!(
            pick(
                None,
                None,
                &[("JOB_COMPLETION_INDEX", "1"), ("WGSLAM_SHARD_COUNT", "2")]
            ),
            shard(1, 2)
        );
        // Slurm's count does not apply to a Kubernetes index.
        assert_eq!(
            pick(
                None,
                None,
                &[
                    ("JOB_COMPLETION_INDEX", "1"),
                    ("SLURM_ARRAY_TASK_COUNT", "2")
                ]
            ),
            shard(1, 8)
        );
    }

    #[test]
    fn shards_cover_every_job_once() {
        let n = 4;
        for job in 0..11 {
            let owners = (0..n)
                .filter(|&i| Selection::Shard { index: i, count: n }.picks(job))
                .count();
            assert_eq!(owners, 1);
        }
    }

    #[test]
    fn bad_indices_are_errors() {
        assert!(parse_shard("3/3").is_err());
        assert!(parse_shard("1").is_err());
        assert!(parse_shard("a/2").is_err());
        assert!(parse_shard("0/0").is_err());
        assert!(choose(None, None, 8, env(&[("SLURM_ARRAY_TASK_ID", "x")])).is_err());
        let past = Selection::Shard { index: 8, count: 8 };
        assert!(past.check(8).unwrap_err().to_string().contains("0..=7"));
        assert!(Selection::Shard { index: 2, count: 4 }.check(8).is_ok());
        assert!(Selection::Shard {
            index: 3,
            count: 10
        }
        .check(3)
        .is_err());
    }
}
