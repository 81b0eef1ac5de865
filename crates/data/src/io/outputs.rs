//! Output folders: deleting only what wgslam wrote, and writing a set of outputs so that it
//! is complete or absent as a set.
//!
//! [`remove_owned`] never follows a symbolic link (a link is removed as a link, or left and
//! reported when it is not one of ours) and removes only entries an ownership rule accepts;
//! anything else stays and is named in the error. [`OutputSet`] stages a command's outputs
//! in a fresh folder beside the target and moves them into place with renames, so an
//! interrupted or failed command leaves the old set or the new set, never a mix.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::{Error, Result};

/// Distinguishes staging folders of the same process.
static STAGING_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Whether `name` is a temporary file of [`crate::io::write_atomic`] for one of `known`
/// (`.<name>.tmp-<pid>-<n>`).
pub fn is_temp_of(name: &str, known: &[&str]) -> bool {
    name.strip_prefix('.')
        .and_then(|rest| rest.split_once(".tmp-"))
        .is_some_and(|(base, _)| known.contains(&base))
}

/// Removes `dir` and its entries when `owned(relative_path, is_dir)` accepts every one of
/// them, recursing into accepted folders; an absent `dir` is fine. Symbolic links are never
/// followed: an accepted link is unlinked (its target untouched), `dir` itself being a link
/// is an error. Entries not accepted are left in place, with their folders, and named in
/// the error, so a file a user put there is never deleted.
pub fn remove_owned(dir: &Path, owned: &dyn Fn(&Path, bool) -> bool) -> Result<()> {
    match fs::symlink_metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(dir, e)),
        Ok(m) if m.file_type().is_symlink() => {
            return Err(Error::Argument(format!(
                "{} is a symbolic link; wgslam never deletes through links: remove it yourself",
                dir.display()
            )))
        }
        Ok(m) if !m.is_dir() => {
            return Err(Error::Argument(format!(
                "{} is not a folder; wgslam did not write it: move it away",
                dir.display()
            )))
        }
        Ok(_) => {}
    }
    let mut foreign = Vec::new();
    remove_tree(dir, Path::new(""), owned, &mut foreign)?;
    if foreign.is_empty() {
        return Ok(());
    }
    let shown: Vec<String> = foreign
        .iter()
        .take(5)
        .map(|p| p.display().to_string())
        .collect();
    Err(Error::Argument(format!(
        "{} holds {} entr{} wgslam did not write ({}{}); nothing of those was deleted: \
         move them away or choose another folder",
        dir.display(),
        foreign.len(),
        if foreign.len() == 1 { "y" } else { "ies" },
        shown.join(", "),
        if foreign.len() > 5 { ", ..." } else { "" }
    )))
}

fn remove_tree(
    dir: &Path,
    rel: &Path,
    owned: &dyn Fn(&Path, bool) -> bool,
    foreign: &mut Vec<PathBuf>,
) -> Result<()> {
    let before = foreign.len();
    for entry in fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let path = entry.path();
        let rel_path = rel.join(entry.file_name());
        let kind = entry.file_type().map_err(|e| Error::io(&path, e))?;
        if kind.is_dir() && owned(&rel_path, true) {
            remove_tree(&path, &rel_path, owned, foreign)?;
        } else if !kind.is_dir() && owned(&rel_path, false) {
            fs::remove_file(&path).map_err(|e| Error::write(&path, e))?;
        } else {
            foreign.push(rel_path);
        }
    }
    if foreign.len() == before {
        fs::remove_dir(dir).map_err(|e| Error::write(dir, e))?;
    }
    Ok(())
}

/// A set of output files staged in a fresh folder beside the target folder and moved into
/// it by [`OutputSet::commit`]; dropped without a commit, the staging folder is removed.
///
/// The target must be absent, an empty folder, or a folder holding only files of the same
/// set (an earlier run's): a folder with anything else is refused by [`OutputSet::begin`]
/// before any work, as is a target that is a file. The commit renames the old folder aside,
/// the staging folder into its place and then deletes the old one, so at every moment the
/// target holds the old set, the new set or nothing.
#[derive(Debug)]
pub struct OutputSet {
    target: PathBuf,
    staging: PathBuf,
    /// Where the old set goes during the commit, beside the staging folder.
    old: PathBuf,
    names: Vec<String>,
    committed: bool,
}

impl OutputSet {
    /// Checks `target` for the set whose file names are `names` (temporary files of
    /// [`crate::io::write_atomic`] for them count as the set's too) and makes the staging
    /// folder `.<target name>.tmp-<pid>-<n>` beside it.
    pub fn begin(target: &Path, names: &[&str]) -> Result<OutputSet> {
        let names: Vec<String> = names.iter().map(|n| n.to_string()).collect();
        let file_name = target
            .file_name()
            .filter(|n| *n != "." && *n != "..")
            .ok_or_else(|| {
                Error::Argument(format!(
                    "output folder {} has no name of its own (give e.g. {}/out)",
                    target.display(),
                    target.display()
                ))
            })?;
        match fs::metadata(target) {
            Ok(m) if !m.is_dir() => {
                return Err(Error::Argument(format!(
                    "--out {} is a file, not a folder",
                    target.display()
                )))
            }
            Ok(_) => {
                let foreign = foreign_entries(target, &names)?;
                if !foreign.is_empty() {
                    return Err(Error::Argument(format!(
                        "--out {} holds files this command did not write ({}); its outputs \
                         replace the folder's as a set, so give an empty or new folder",
                        target.display(),
                        foreign.join(", ")
                    )));
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(target, e)),
        }
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        fs::create_dir_all(&parent).map_err(|e| Error::write(&parent, e))?;
        remove_stale_staging(&parent, &file_name.to_string_lossy(), &names);
        let n = STAGING_COUNTER.fetch_add(1, Ordering::Relaxed);
        let mut staging_name = std::ffi::OsString::from(".");
        staging_name.push(file_name);
        staging_name.push(format!(".tmp-{}-{n}", std::process::id()));
        let staging = parent.join(&staging_name);
        staging_name.push("-old");
        let old = parent.join(staging_name);
        fs::create_dir(&staging).map_err(|e| Error::write(&staging, e))?;
        Ok(OutputSet {
            target: target.to_path_buf(),
            staging,
            old,
            names,
            committed: false,
        })
    }

    /// The folder to write the outputs into (the staging folder).
    pub fn dir(&self) -> &Path {
        &self.staging
    }

    /// The folder the outputs end up in.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Moves the staged set into the target folder, replacing an earlier set there.
    pub fn commit(mut self) -> Result<()> {
        let names: Vec<&str> = self.names.iter().map(String::as_str).collect();
        let owned = |rel: &Path, is_dir: bool| {
            !is_dir
                && rel
                    .to_str()
                    .is_some_and(|n| names.contains(&n) || is_temp_of(n, &names))
        };
        let old = match fs::symlink_metadata(&self.target) {
            Ok(m) if m.is_dir() && is_empty_dir(&self.target) => {
                // An empty folder: the rename below replaces it in one step.
                None
            }
            Ok(_) => {
                fs::rename(&self.target, &self.old).map_err(|e| Error::write(&self.target, e))?;
                Some(self.old.clone())
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(Error::io(&self.target, e)),
        };
        if let Err(e) = fs::rename(&self.staging, &self.target) {
            if let Some(old) = &old {
                let _ = fs::rename(old, &self.target);
            }
            return Err(Error::write(&self.target, e));
        }
        self.committed = true;
        if let Some(old) = old {
            remove_owned(&old, &owned)?;
        }
        Ok(())
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        if !self.committed {
            // Everything in the staging folder was written by this process.
            let _ = remove_owned(&self.staging, &|_, _| true);
        }
    }
}

/// Removes the staging folders (and the old sets moved aside) for target `name` in `parent`
/// that a process no longer alive on this machine left (killed, or stopped by Ctrl-C,
/// before it could clean up); only the set's files are deleted. Best effort, Linux only
/// (a process is alive when `/proc/<pid>` exists).
fn remove_stale_staging(parent: &Path, name: &str, names: &[String]) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = fs::read_dir(parent) else {
        return;
    };
    let prefix = format!(".{name}.tmp-");
    let known: Vec<&str> = names.iter().map(String::as_str).collect();
    for entry in entries.flatten() {
        let entry_name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = entry_name
            .strip_prefix(&prefix)
            .and_then(|rest| rest.split('-').next())
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid == std::process::id() || Path::new("/proc").join(pid.to_string()).exists() {
            continue;
        }
        let _ = remove_owned(&entry.path(), &|rel: &Path, is_dir: bool| {
            !is_dir
                && rel
                    .to_str()
                    .is_some_and(|n| known.contains(&n) || is_temp_of(n, &known))
        });
    }
}

/// The entries of `dir` that are not files of the set `names` (nor their temporary files).
fn foreign_entries(dir: &Path, names: &[String]) -> Result<Vec<String>> {
    let known: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut out = Vec::new();
    for entry in fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let is_file = entry.file_type().map(|t| t.is_file()).unwrap_or(false);
        if !(is_file && (known.contains(&name.as_str()) || is_temp_of(&name, &known))) {
            out.push(name);
        }
    }
    out.sort();
    Ok(out)
}

fn is_empty_dir(dir: &Path) -> bool {
    fs::read_dir(dir).is_ok_and(|mut d| d.next().is_none())
}
