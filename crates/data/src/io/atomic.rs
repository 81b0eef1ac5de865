//! All-or-nothing file writes: a temp file in the target's directory, fsync, then rename.
//!
//! Not a lock: two processes writing the same path race, and the last rename wins.

use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::{Error, Result};

/// Distinguishes temp files of concurrent writes from the same process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `path` completely or not at all.
///
/// `fill` writes the whole contents into a buffered writer on a temp file next to `path`
/// (same directory, so the final rename is atomic on one file system). On success the temp
/// file is flushed, fsynced and renamed over `path`; on any error (from `fill` or from the
/// file system) the temp file is removed and `path` is left as it was.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    let tmp = temp_path(path)?;
    let result = write_and_rename(path, &tmp, fill);
    if result.is_err() {
        // Best effort: the temp file may not exist if creating it failed.
        let _ = fs::remove_file(&tmp);
    }
    result
}

fn write_and_rename<F>(path: &Path, tmp: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    let file = File::create(tmp).map_err(|e| Error::write(tmp, e))?;
    let mut w = BufWriter::new(file);
    fill(&mut w)?;
    {
        // Closed at the end of this block, before the rename. (A block, not `drop`: on
        // wasm32, where files do not exist, `File` has no destructor and clippy objects.)
        let file = w
            .into_inner()
            .map_err(|e| Error::write(tmp, e.into_error()))?;
        file.sync_all().map_err(|e| Error::write(tmp, e))?;
    }
    fs::rename(tmp, path).map_err(|e| Error::write(path, e))?;
    Ok(())
}

/// `<dir>/.<name>.tmp-<pid>-<n>` next to `path`.
pub fn temp_path(path: &Path) -> Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| {
        Error::Argument(format!("output path {} has no file name", path.display()))
    })?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}-{}", std::process::id(), n));
    Ok(dir.join(tmp_name))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The folder `d` holds one entry (the written file, no temp file), and is removed.
    fn only_the_file_is_left(d: &Path) {
        assert_eq!(fs::read_dir(d).unwrap().count(), 1, "temp file left behind");
        fs::remove_dir_all(d).unwrap();
    }

    /// A fresh empty directory; each test removes it when it passes.
    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("wgslam-atomic-{}-{}", std::process::id(), name));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn writes_whole_file() {
        let d = scratch("ok");
        let p = d.join("out.txt");
        write_atomic(&p, |w| {
            w.write_all(b"hello")
                .map_err(|e| Error::write("out.txt", e))
        })
        .unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"hello");
        only_the_file_is_left(&d);
    }

    #[test]
    fn error_keeps_old_file_and_removes_temp() {
        let d = scratch("err");
        let p = d.join("out.txt");
        fs::write(&p, b"old").unwrap();
        let r = write_atomic(&p, |w| {
            w.write_all(b"partial").unwrap();
            Err(Error::Argument("fail on purpose".into()))
        });
        assert!(r.is_err());
        assert_eq!(fs::read(&p).unwrap(), b"old");
        only_the_file_is_left(&d);
    }

    #[test]
    fn missing_directory_is_an_io_error() {
        let d = scratch("missing");
        let p = d.join("no/such/dir/out.txt");
        let r = write_atomic(&p, |_| Ok(()));
        assert!(matches!(r, Err(Error::Write { .. })), "{r:?}");
        fs::remove_dir_all(&d).unwrap();
    }
}
