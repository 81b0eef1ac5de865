//! The batch folder as something a batch owns: the marker naming the manifest that made it,
//! the refusal of folders that are someone else's, one lock per job so two processes never
//! run the same job at once, and the removal of a job's earlier outputs that deletes only
//! what a batch wrote.
//!
//! The marker `wgslam-batch.json` holds the canonical path of the manifest. A batch writes
//! into a folder only if the folder is new or empty (but for `slurm-logs`, which
//! `deploy/slurm/submit.sh` makes before the first task), or already holds the marker of
//! the same manifest. The marker is created with a hard link, which fails when the name
//! exists, so array tasks starting together agree on one marker.

use std::fs;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::manifest::BACKENDS;
use crate::io::outputs::{is_temp_of, remove_owned};
use crate::{Error, Result};

/// The record's file name inside a job folder.
pub const RECORD: &str = "job.json";
/// The comparison's file name inside a job folder (jobs that ran both backends).
pub const COMPARISON: &str = "comparison.json";
/// The job's parameter file inside its folder, which each backend's `wgslam run --params`
/// reads.
pub const PARAMS: &str = "params.toml";

/// The marker's file name at the top of a batch folder.
pub const MARKER: &str = "wgslam-batch.json";
/// The folder of job locks (`locks/<id>.lock`).
pub const LOCKS: &str = "locks";
/// The folder of job folders.
pub const JOBS: &str = "jobs";
/// Entries a folder may hold before its first batch: `deploy/slurm/submit.sh` makes the
/// array's log folder before the array starts.
const ALLOWED_BEFORE: [&str; 1] = ["slurm-logs"];

/// What the marker holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Marker {
    /// What this file is, for a person who finds it.
    what: String,
    /// The canonical path of the manifest whose batch folder this is.
    manifest: PathBuf,
}

/// The identity a manifest gives its batch folder: its canonical path.
fn identity(manifest: &Path) -> Result<PathBuf> {
    fs::canonicalize(manifest).map_err(|e| Error::io(manifest, e))
}

/// Whether `out` may hold `manifest`'s batch; `create`: also create the folder and its
/// marker. Errors say why not: the root, a file, a folder of another manifest, a non-empty
/// folder that is not a batch folder, links where the batch's own folders belong.
pub fn claim(out: &Path, manifest: &Path, create: bool) -> Result<()> {
    let id = identity(manifest)?;
    let refuse = |why: String| Error::Batch(format!("--out {}: {why}", out.display()));
    let existing = match fs::metadata(out) {
        Ok(m) if !m.is_dir() => return Err(refuse("is a file, not a folder".into())),
        Ok(_) => true,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
        Err(e) => return Err(Error::io(out, e)),
    };
    if existing {
        let canonical = fs::canonicalize(out).map_err(|e| Error::io(out, e))?;
        if canonical.parent().is_none() {
            return Err(refuse(
                "is the file system's root; a batch needs a folder of its own".into(),
            ));
        }
        match read_marker(out)? {
            Some(m) if m.manifest == id => {}
            Some(m) => {
                return Err(refuse(format!(
                    "is the batch folder of manifest {}, not of {}; give this manifest \
                     another --out (or its own `output`)",
                    m.manifest.display(),
                    id.display()
                )))
            }
            None => {
                let foreign = foreign_top_level(out)?;
                if !foreign.is_empty() {
                    return Err(refuse(format!(
                        "is not empty and not a batch folder (no {MARKER}; it holds {}); \
                         a batch deletes and rewrites what is in its folder, so give a new \
                         or empty folder",
                        foreign.join(", ")
                    )));
                }
            }
        }
        for own in [JOBS, LOCKS] {
            let p = out.join(own);
            if fs::symlink_metadata(&p).is_ok_and(|m| !m.is_dir()) {
                return Err(refuse(format!(
                    "{own} is a link or a file, not a folder a batch made; a batch never \
                     follows links in its folder"
                )));
            }
        }
    }
    if !create {
        return Ok(());
    }
    fs::create_dir_all(out).map_err(|e| Error::write(out, e))?;
    if read_marker(out)?.is_none() {
        write_marker(out, &id)?;
    }
    match read_marker(out)? {
        Some(m) if m.manifest == id => Ok(()),
        _ => Err(refuse(format!(
            "another manifest claimed this folder at the same moment; {MARKER} does not \
             name {}",
            id.display()
        ))),
    }
}

fn read_marker(out: &Path) -> Result<Option<Marker>> {
    let path = out.join(MARKER);
    match fs::symlink_metadata(&path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(&path, e)),
        Ok(m) if !m.is_file() => {
            return Err(Error::format(
                &path,
                "not a batch marker (not a plain file)",
            ))
        }
        Ok(_) => {}
    }
    let text = crate::io::input::read_kind_string(&path, crate::io::input::InputKind::Manifest)?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| Error::format(&path, format!("not a batch marker: {e}")))
}

/// Writes the marker unless one exists: a complete temporary file hard-linked to the name
/// (the link fails if the name exists, so of two tasks only one marker wins).
fn write_marker(out: &Path, id: &Path) -> Result<()> {
    let path = out.join(MARKER);
    let tmp = crate::io::atomic::temp_path(&path)?;
    let m = Marker {
        what: "wgslam batch folder: the manifest that made it".into(),
        manifest: id.to_path_buf(),
    };
    let text = serde_json::to_string_pretty(&m).expect("plain struct") + "\n";
    fs::write(&tmp, text).map_err(|e| Error::write(&tmp, e))?;
    let linked = fs::hard_link(&tmp, &path);
    let _ = fs::remove_file(&tmp);
    match linked {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        Err(e) => Err(Error::write(&path, e)),
    }
}

/// The entries at the top of `out` that a batch did not write and may not ignore.
fn foreign_top_level(out: &Path) -> Result<Vec<String>> {
    let mut v = Vec::new();
    for entry in fs::read_dir(out).map_err(|e| Error::io(out, e))? {
        let entry = entry.map_err(|e| Error::io(out, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let allowed = ALLOWED_BEFORE.contains(&name.as_str())
            || (name.starts_with('.') && is_temp_of(&name, &[MARKER]));
        if !allowed {
            v.push(name);
        }
    }
    v.sort();
    v.truncate(5);
    Ok(v)
}

/// Whether `rel` (relative to a job folder) is something a batch job writes: its parameter
/// file, record, comparison, logs, and per backend the run's outputs and their staging
/// folders ([`crate::tools::run::OUTPUT_FILES`]).
pub fn job_owns(rel: &Path, is_dir: bool) -> bool {
    let parts: Vec<&str> = match rel.iter().map(|c| c.to_str()).collect::<Option<Vec<_>>>() {
        Some(p) => p,
        None => return false,
    };
    let logs: Vec<String> = BACKENDS.iter().map(|b| format!("{b}.log")).collect();
    let logs: Vec<&str> = logs.iter().map(String::as_str).collect();
    let files: Vec<&str> = [PARAMS, RECORD, COMPARISON]
        .into_iter()
        .chain(logs.iter().copied())
        .collect();
    let run_folder =
        |name: &str| BACKENDS.contains(&name) || BACKENDS.iter().any(|b| is_staging_of(name, b));
    match parts.as_slice() {
        [name] if is_dir => run_folder(name),
        [name] => files.contains(name) || is_temp_of(name, &files),
        [folder, name] if !is_dir && run_folder(folder) => {
            let outs = crate::tools::run::OUTPUT_FILES;
            outs.contains(name) || is_temp_of(name, &outs)
        }
        _ => false,
    }
}

/// `.<name>.tmp-<pid>-<n>` or its `.old` twin: an [`crate::io::outputs::OutputSet`]'s
/// staging folder for `name`.
fn is_staging_of(entry: &str, name: &str) -> bool {
    is_temp_of(entry, &[name])
}

/// Removes job folder `dir` (`jobs/<id>`) with what a batch wrote in it; refuses, deleting
/// none of them, entries it did not write and links in place of its folders.
pub fn remove_job_dir(dir: &Path) -> Result<()> {
    remove_owned(dir, &job_owns)
        .map_err(|e| Error::Batch(format!("cannot start the job afresh: {e}")))
}

/// A job's lock, held while the process runs the job; released when dropped (or when the
/// process dies: the kernel drops `flock` locks with the file).
#[derive(Debug)]
pub struct JobLock {
    _file: fs::File,
}

/// Takes job `id`'s lock in `out/locks/`, or says which process holds it.
pub fn lock_job(out: &Path, id: &str) -> Result<JobLock> {
    let dir = out.join(LOCKS);
    fs::create_dir_all(&dir).map_err(|e| Error::write(&dir, e))?;
    let path = dir.join(format!("{id}.lock"));
    let file = open_no_follow(&path)?;
    if !try_lock_exclusive(&file).map_err(|e| Error::io(&path, e))? {
        return Err(Error::Batch(format!(
            "job {id} is being run by another `wgslam batch` on {} (it holds {}); two \
             batches on one folder would delete each other's outputs: wait for it, or give \
             this one another --out",
            out.display(),
            path.display()
        )));
    }
    Ok(JobLock { _file: file })
}

#[cfg(unix)]
fn open_no_follow(path: &Path) -> Result<fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .custom_flags(libc::O_NOFOLLOW)
        .open(path)
        .map_err(|e| Error::write(path, e))
}

#[cfg(not(unix))]
fn open_no_follow(path: &Path) -> Result<fs::File> {
    fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(path)
        .map_err(|e| Error::write(path, e))
}

/// `flock(LOCK_EX | LOCK_NB)`: `Ok(false)` when another open file holds the lock.
#[cfg(unix)]
fn try_lock_exclusive(file: &fs::File) -> std::io::Result<bool> {
    use std::os::unix::io::AsRawFd;
    // SAFETY: flock on a file descriptor this `File` owns and keeps open; no memory is
    // passed.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if rc == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    if e.raw_os_error() == Some(libc::EWOULDBLOCK) {
        Ok(false)
    } else {
        Err(e)
    }
}

/// Without `flock` no lock is taken (the marker still keeps manifests apart).
#[cfg(not(unix))]
fn try_lock_exclusive(_file: &fs::File) -> std::io::Result<bool> {
    Ok(true)
}
