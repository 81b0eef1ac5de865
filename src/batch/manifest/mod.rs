//! Batch manifests: a TOML file of jobs and grids, expanded into a numbered job list.
//!
//! ```toml
//! output = "batch-out"            # the batch folder, relative to this file's folder
//! concurrent = 4                  # jobs at once in one process (`batch --concurrent` wins)
//! [defaults]                      # every job's values unless the job sets its own
//! frames = "1..60"                # as `wgslam run --frames` (absent: the run's default)
//! downsample = 2                  # absent: 1 for a GPU-only job, 2 where the CPU runs
//! profile = "robust"              # robust | assignment
//! backend = "both"                # cpu | gpu | both (both adds the GPU-vs-CPU comparison)
//! [defaults.overrides]            # parameters: the keys of a `--params` file (docs/params-file.md)
//! icp-dist = 0.1
//! icp = { stop_chi2 = 6 }         # a key by section (or "icp.stop_chi2" = 6; `sections`)
//!
//! [[job]]                         # one job
//! name = "bundled"                # its id (default: made from its values)
//! sequence = "assets/icl_living_room_kt2"
//!
//! [[grid]]                        # every combination of its list values is a job
//! name = "icl"
//! sequence = ["data/kt2", "data/kt2_noisy"]
//! profile = ["robust", "assignment"]
//! overrides = { icp-dist = [0.08, 0.1] }
//! ```
//!
//! Jobs are numbered from 0: the `[[job]]` tables in file order, then each `[[grid]]`'s
//! combinations (sequence, frames, downsample, profile, backend, then the overrides by
//! name, the last varying fastest). The numbers are what `--index`, `--shard` and the
//! schedulers' array indices pick. Relative sequence paths are taken from the manifest's
//! folder, so a manifest means the same jobs wherever it is run from.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{Error, Result};

mod ids;
mod sections;
use ids::{all_axes, generated_id, id_problem};
pub use sections::insert_dotted;

/// One expanded job: what `wgslam run` is asked to do, once per backend.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobSpec {
    /// Unique within the manifest; the job's folder name.
    pub id: String,
    /// Sequence folder (relative paths already joined to the manifest's folder).
    pub sequence: PathBuf,
    /// `--frames` value, or `None` for the run's default range.
    pub frames: Option<String>,
    /// `--downsample` value: the manifest's, or where it sets none the default of the
    /// job's backends (`crate::slam::params::resolution`: 1 for the GPU alone, else 2).
    pub downsample: u32,
    /// `--profile` value: `robust` or `assignment`.
    pub profile: String,
    /// Backends to run, each into its own subfolder: `["cpu"]`, `["gpu"]` or both.
    pub backends: Vec<String>,
    /// Further parameters, `(key, value)` in the command-line form, sorted by key: the keys
    /// of a parameter file (`wgslam run --params`, docs/params-file.md), written with the
    /// profile and downsampling into the job's [`JobSpec::params_toml`].
    pub overrides: Vec<(String, String)>,
}

/// A parsed manifest: where its outputs go by default and its jobs in index order.
#[derive(Debug, Clone)]
pub struct Manifest {
    /// The manifest file.
    pub path: PathBuf,
    /// Its `output` key (joined to its folder), if any.
    pub output: Option<PathBuf>,
    /// Its `concurrent` key: jobs run at once in one process (`batch --concurrent`).
    pub concurrent: Option<usize>,
    pub jobs: Vec<JobSpec>,
}

/// Options the batch sets itself for every job; an override may not set them.
pub const RESERVED_OPTIONS: [&str; 6] =
    ["frames", "downsample", "profile", "backend", "out", "poses"];

/// Backend names a job may ask for.
pub const BACKENDS: [&str; 2] = ["cpu", "gpu"];
/// Profile names (those of `wgslam run --profile`).
const PROFILES: [&str; 2] = ["robust", "assignment"];

/// Defaults of values neither the job nor `[defaults]` sets (those of `wgslam run`,
/// but for the backend: a batch checks the GPU against the CPU unless told otherwise;
/// the downsampling's is its backends', at `resolve`).
const DEFAULT_PROFILE: &str = "robust";
const DEFAULT_BACKEND: &str = "both";

/// A scalar or a list of scalars (a grid axis). `Many` first: an untagged enum takes the
/// first variant that fits, and a list fits a `toml::Value` too.
#[derive(Debug, Clone, Deserialize)]
#[serde(
    untagged,
    expecting = "a value of this field's type (downsample: a whole number; sequence, frames, \
                 profile, backend: a string), or in a [[grid]] a list of them"
)]
enum OneOrMany<T> {
    Many(Vec<T>),
    One(T),
}

impl<T: Clone> OneOrMany<T> {
    fn len(&self) -> usize {
        match self {
            OneOrMany::One(_) => 1,
            OneOrMany::Many(v) => v.len(),
        }
    }

    fn values(&self) -> Vec<T> {
        match self {
            OneOrMany::One(v) => vec![v.clone()],
            OneOrMany::Many(v) => v.clone(),
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileToml {
    output: Option<PathBuf>,
    concurrent: Option<usize>,
    #[serde(default)]
    defaults: Fields,
    #[serde(default)]
    job: Vec<Fields>,
    #[serde(default)]
    grid: Vec<Fields>,
}

/// The fields of a `[[job]]`, `[[grid]]` or `[defaults]` table; lists only in a grid.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct Fields {
    name: Option<String>,
    sequence: Option<OneOrMany<PathBuf>>,
    frames: Option<OneOrMany<String>>,
    downsample: Option<OneOrMany<u32>>,
    profile: Option<OneOrMany<String>>,
    backend: Option<OneOrMany<String>>,
    #[serde(default)]
    overrides: BTreeMap<String, OneOrMany<toml::Value>>,
}

impl Fields {
    /// Each field's number of values, by axis name (`override:NAME` for overrides).
    fn axis_lengths(&self) -> Vec<(String, usize)> {
        let mut v: Vec<(String, usize)> = [
            ("sequence", self.sequence.as_ref().map(OneOrMany::len)),
            ("frames", self.frames.as_ref().map(OneOrMany::len)),
            ("downsample", self.downsample.as_ref().map(OneOrMany::len)),
            ("profile", self.profile.as_ref().map(OneOrMany::len)),
            ("backend", self.backend.as_ref().map(OneOrMany::len)),
        ]
        .into_iter()
        .filter_map(|(k, l)| l.map(|l| (k.to_string(), l)))
        .collect();
        v.extend(
            self.overrides
                .iter()
                .map(|(k, a)| (format!("override:{k}"), a.len())),
        );
        v
    }
}

/// One job's values before validation, every field resolved against `[defaults]`.
#[derive(Debug, Clone)]
struct Combination {
    sequence: Option<PathBuf>,
    frames: Option<String>,
    downsample: Option<u32>,
    profile: String,
    backend: String,
    overrides: BTreeMap<String, toml::Value>,
}

impl Manifest {
    /// Reads and expands `path`; every error names the manifest and, where it can, the job.
    pub fn read(path: &Path) -> Result<Manifest> {
        let text = crate::io::input::read_kind_string(path, crate::io::input::InputKind::Manifest)?;
        Manifest::parse(path, &text)
    }

    /// Parses manifest `text` as if read from `path` (relative paths join its folder).
    pub fn parse(path: &Path, text: &str) -> Result<Manifest> {
        let mut file: FileToml = toml::from_str(text)
            .map_err(|e| Error::format(path, format!("not a batch manifest: {e}")))?;
        sections::flatten_file(path, &mut file)?;
        let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
        let max_jobs = crate::io::input::max_jobs()?;
        let total = file.grid.iter().fold(file.job.len() as u64, |total, g| {
            let n = g
                .axis_lengths()
                .iter()
                .try_fold(1u64, |a, (_, l)| a.checked_mul(*l as u64))
                .unwrap_or(u64::MAX);
            total.saturating_add(n)
        });
        if total > max_jobs {
            return Err(Error::format(
                path,
                format!(
                    "the manifest makes {total} jobs, more than the limit of {max_jobs} \
                     (WGSLAM_MAX_JOBS raises it); split it into several manifests"
                ),
            ));
        }
        let d = &file.defaults;
        single_valued(path, "[defaults]", d)?;
        if d.name.is_some() {
            return Err(Error::format(
                path,
                "[defaults] cannot set a name: names are per job",
            ));
        }
        let base = Combination {
            sequence: None,
            frames: None,
            downsample: None,
            profile: DEFAULT_PROFILE.into(),
            backend: DEFAULT_BACKEND.into(),
            overrides: BTreeMap::new(),
        };
        let base = expand(&base, d).remove(0);
        let mut jobs = Vec::new();
        for (k, j) in file.job.iter().enumerate() {
            let origin = format!("[[job]] number {}", k + 1);
            single_valued(path, &origin, j)?;
            let c = expand(&base, j).remove(0);
            let id = match &j.name {
                Some(n) => n.clone(),
                None => generated_id(None, &c, &all_axes(&c)),
            };
            jobs.push(resolve(path, &dir, &id, &c, &origin)?);
        }
        for (k, g) in file.grid.iter().enumerate() {
            let origin = format!("[[grid]] number {}", k + 1);
            let lengths = g.axis_lengths();
            if let Some((axis, _)) = lengths.iter().find(|(_, n)| *n == 0) {
                return Err(Error::format(
                    path,
                    format!("{origin}: `{axis}` is an empty list"),
                ));
            }
            let varying = lengths
                .into_iter()
                .filter(|(_, n)| *n > 1)
                .map(|(a, _)| a)
                .collect();
            for c in expand(&base, g) {
                let id = generated_id(g.name.as_deref(), &c, &varying);
                jobs.push(resolve(path, &dir, &id, &c, &origin)?);
            }
        }
        if jobs.is_empty() {
            return Err(Error::format(
                path,
                "no jobs: add a [[job]] or a [[grid]] table",
            ));
        }
        let mut seen = BTreeSet::new();
        for j in &jobs {
            if !seen.insert(j.id.as_str()) {
                return Err(Error::format(
                    path,
                    format!(
                        "two jobs have the id {:?}: give them different `name`s",
                        j.id
                    ),
                ));
            }
        }
        Ok(Manifest {
            path: path.to_path_buf(),
            output: file.output.map(|o| dir.join(o)),
            concurrent: file.concurrent,
            jobs,
        })
    }
}

/// Lists belong in a `[[grid]]`: a `[[job]]` or `[defaults]` with one is an error.
fn single_valued(path: &Path, origin: &str, t: &Fields) -> Result<()> {
    match t.axis_lengths().into_iter().find(|(_, n)| *n != 1) {
        Some((axis, _)) => Err(Error::format(
            path,
            format!("{origin}: `{axis}` is a list; lists make a grid, use a [[grid]] table"),
        )),
        None => Ok(()),
    }
}

/// Every combination of a table's values over `base`, in index order (the last field
/// varying fastest); one combination for a table without lists.
fn expand(base: &Combination, t: &Fields) -> Vec<Combination> {
    fn axis<T: Clone>(
        combos: Vec<Combination>,
        values: Option<&OneOrMany<T>>,
        set: impl Fn(&mut Combination, T),
    ) -> Vec<Combination> {
        let Some(values) = values else {
            return combos;
        };
        let mut out = Vec::new();
        for c in combos {
            for v in values.values() {
                let mut c = c.clone();
                set(&mut c, v);
                out.push(c);
            }
        }
        out
    }
    let mut out = vec![base.clone()];
    out = axis(out, t.sequence.as_ref(), |c, v| c.sequence = Some(v));
    out = axis(out, t.frames.as_ref(), |c, v| c.frames = Some(v));
    out = axis(out, t.downsample.as_ref(), |c, v| c.downsample = Some(v));
    out = axis(out, t.profile.as_ref(), |c, v| c.profile = v);
    out = axis(out, t.backend.as_ref(), |c, v| c.backend = v);
    for (name, values) in &t.overrides {
        out = axis(out, Some(values), |c, v| {
            c.overrides.insert(name.clone(), v);
        });
    }
    out
}

/// `path` with `.` dropped and `x/..` folded, without touching the file system (the
/// sequence may exist only on the cluster's nodes); a leading `..` stays.
fn lexically_normal(path: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => match out.components().next_back() {
                Some(Component::Normal(_)) => {
                    out.pop();
                }
                Some(Component::RootDir) | Some(Component::Prefix(_)) => {}
                _ => out.push(".."),
            },
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// A TOML value as the command-line value it stands for: a scalar as written, a list of
/// scalars joined by commas (`[10, 5, 4]` is `10,5,4`, as `--icp-level-iters 10,5,4`);
/// `None` for tables, nested lists and dates. The value forms of manifest overrides and of
/// parameter files (`wgslam run --params`, docs/params-file.md) both.
pub fn option_value(v: &toml::Value) -> Option<String> {
    match v {
        toml::Value::String(s) => Some(s.clone()),
        toml::Value::Integer(i) => Some(i.to_string()),
        toml::Value::Float(f) => Some(f.to_string()),
        toml::Value::Boolean(b) => Some(b.to_string()),
        toml::Value::Array(items) => items
            .iter()
            .map(|item| match item {
                toml::Value::Array(_) => None,
                scalar => option_value(scalar),
            })
            .collect::<Option<Vec<_>>>()
            .map(|parts| parts.join(",")),
        _ => None,
    }
}

/// The TOML value whose [`option_value`] is `s`: a boolean, integer or float when `s` reads
/// back as exactly that, else a string (so a parameter file written from command-line
/// values gives the same values back).
pub fn toml_value(s: &str) -> toml::Value {
    let typed = if let Ok(b) = s.parse::<bool>() {
        Some(toml::Value::Boolean(b))
    } else if let Ok(i) = s.parse::<i64>() {
        Some(toml::Value::Integer(i))
    } else if let Ok(f) = s.parse::<f64>() {
        Some(toml::Value::Float(f)).filter(|_| f.is_finite())
    } else {
        None
    };
    typed
        .filter(|v| option_value(v).as_deref() == Some(s))
        .unwrap_or_else(|| toml::Value::String(s.to_string()))
}

impl JobSpec {
    /// The job's parameter file (`wgslam run --params`, docs/params-file.md): its profile,
    /// downsampling and overrides, keys sorted. `wgslam batch` writes it into the job's
    /// folder and checks every job's before the first runs.
    pub fn params_toml(&self) -> String {
        let mut t = toml::Table::new();
        t.insert("profile".into(), toml::Value::String(self.profile.clone()));
        t.insert(
            "downsample".into(),
            toml::Value::Integer(self.downsample.into()),
        );
        for (k, v) in &self.overrides {
            insert_dotted(&mut t, k, toml_value(v));
        }
        format!(
            "# wgslam parameters of batch job {:?} (written by `wgslam batch`)\n{}",
            self.id,
            toml::to_string(&t).expect("a table of scalars is TOML")
        )
    }
}

impl JobSpec {
    /// Checks a job read back from a batch folder (`batch.json`) as the manifest's reader
    /// checked it when it was written: its id a plain folder name, a known profile, one or
    /// both known backends, downsampling of at least 1, no reserved override. A batch
    /// folder is only files; nothing read from it is trusted further than that.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if let Some(why) = id_problem(&self.id) {
            return Err(why);
        }
        if !PROFILES.contains(&self.profile.as_str()) {
            return Err(format!(
                "profile {:?}: want one of {PROFILES:?}",
                self.profile
            ));
        }
        let known = self.backends.iter().all(|b| BACKENDS.contains(&b.as_str()));
        let distinct = self.backends.first() != self.backends.get(1);
        if self.backends.is_empty() || self.backends.len() > 2 || !known || !distinct {
            return Err(format!(
                "backends {:?}: want [\"cpu\"], [\"gpu\"] or both",
                self.backends
            ));
        }
        if self.downsample == 0 {
            return Err("downsample must be at least 1".into());
        }
        if let Some(f) = &self.frames {
            crate::dataset::parse_range(f).map_err(|e| format!("frames: {e}"))?;
        }
        if let Some((k, _)) = self
            .overrides
            .iter()
            .find(|(k, _)| RESERVED_OPTIONS.contains(&k.as_str()))
        {
            return Err(format!("override {k:?} is set by the batch"));
        }
        Ok(())
    }
}

/// Checks a combination's values and makes its [`JobSpec`].
fn resolve(path: &Path, dir: &Path, id: &str, c: &Combination, origin: &str) -> Result<JobSpec> {
    let bad = |what: String| Error::format(path, format!("{origin} ({id:?}): {what}"));
    if let Some(why) = id_problem(id) {
        return Err(bad(why));
    }
    let Some(sequence) = &c.sequence else {
        return Err(bad(
            "no `sequence` (set it in the job or in [defaults])".into()
        ));
    };
    if !PROFILES.contains(&c.profile.as_str()) {
        return Err(bad(format!(
            "profile {:?}: want one of {PROFILES:?}",
            c.profile
        )));
    }
    let backends: Vec<String> = match c.backend.as_str() {
        "both" => BACKENDS.iter().map(|b| b.to_string()).collect(),
        b if BACKENDS.contains(&b) => vec![b.to_string()],
        b => return Err(bad(format!("backend {b:?}: want cpu, gpu or both"))),
    };
    let names: Vec<&str> = backends.iter().map(String::as_str).collect();
    let downsample = c
        .downsample
        .unwrap_or_else(|| crate::slam::params::resolution::default_downsample(&names).0);
    if downsample == 0 {
        return Err(bad("downsample must be at least 1".into()));
    }
    if let Some(f) = &c.frames {
        crate::dataset::parse_range(f).map_err(|e| bad(format!("frames: {e}")))?;
    }
    let mut overrides = Vec::new();
    for (k, v) in &c.overrides {
        if RESERVED_OPTIONS.contains(&k.as_str()) {
            return Err(bad(format!(
                "override {k:?} is a job field or set by the batch; set it as a field, not an override"
            )));
        }
        let value = option_value(v).ok_or_else(|| {
            bad(format!(
                "override {k:?}: want a string, number, boolean or a list of them"
            ))
        })?;
        overrides.push((k.clone(), value));
    }
    Ok(JobSpec {
        id: id.to_string(),
        sequence: lexically_normal(&dir.join(sequence)),
        frames: c.frames.clone(),
        downsample,
        profile: c.profile.clone(),
        backends,
        overrides,
    })
}

#[cfg(test)]
mod tests;
