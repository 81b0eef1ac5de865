//! Where a sequence's files come from: the one seam between the dataset readers and the
//! files they read. Layout detection, every layout's lister and the frame decoder ask this
//! module (is a path there, a folder's entries, a file's bytes), never `std::fs`, so the same
//! code reads a folder on disk ([`Disk`]: bounded reads of [`crate::io::input`]), files held
//! in memory ([`super::InMemoryFiles`]) or the files a web page was given (`src/web.rs`,
//! which reads each file's bytes from the browser only when a frame needs it).
//!
//! The source in use is the calling thread's *current* one: [`super::open_with`] and
//! [`super::Sequence::load`] make their sequence's source current for the duration of the
//! call ([`with_source`]); outside such a call it is [`Disk`]. (Threading a parameter
//! through every reader would say the same thing in forty signatures.)
//!
//! Not a virtual file system: read-only, whole files, no links or permissions.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fmt::Debug;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::io::input::InputKind;
use crate::{Error, Result};

/// What is at a path (following links).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Entry {
    /// A regular file of this many bytes.
    File(u64),
    /// A folder.
    Folder,
    /// Something else: a device, a FIFO, a socket.
    Other,
}

/// A read-only set of files a sequence is read from.
pub trait DatasetFiles: Debug + Send + Sync {
    /// What is at `path`; a `NotFound` error when nothing is.
    fn entry(&self, path: &Path) -> std::io::Result<Entry>;
    /// Whether anything is at `path` (for [`Disk`]: a link too, even a broken one, see
    /// [`crate::io::input::present`]).
    fn present(&self, path: &Path) -> bool {
        self.entry(path).is_ok()
    }
    /// The paths (`dir` joined with each name) of the entries directly in folder `dir`, in
    /// no particular order; an error when `dir` is not a folder.
    fn list(&self, dir: &Path) -> std::io::Result<Vec<PathBuf>>;
    /// The whole of regular file `path`, within `kind`'s cap ([`InputKind::max_bytes`]).
    fn read(&self, path: &Path, kind: InputKind) -> Result<Vec<u8>>;
    /// The frame whose colour and depth are `rgb` and `depth`, for a source that decodes
    /// frames itself (a recording's messages, `bag.rs`) instead of from image files;
    /// `None` (the default) for a source of files. `depth_k`: the depth images'
    /// intrinsics, whose size the frame must have.
    fn frame(
        &self,
        rgb: &Path,
        depth: &Path,
        depth_k: &crate::geometry::camera::Intrinsics,
    ) -> Option<Result<super::RawFrame>> {
        let _ = (rgb, depth, depth_k);
        None
    }
}

/// The local file system, read with the bounds of [`crate::io::input`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Disk;

impl DatasetFiles for Disk {
    fn entry(&self, path: &Path) -> std::io::Result<Entry> {
        let m = std::fs::metadata(path)?;
        Ok(if m.is_file() {
            Entry::File(m.len())
        } else if m.is_dir() {
            Entry::Folder
        } else {
            Entry::Other
        })
    }
    fn present(&self, path: &Path) -> bool {
        crate::io::input::present(path)
    }
    fn list(&self, dir: &Path) -> std::io::Result<Vec<PathBuf>> {
        std::fs::read_dir(dir)?
            .map(|e| e.map(|e| e.path()))
            .collect()
    }
    fn read(&self, path: &Path, kind: InputKind) -> Result<Vec<u8>> {
        crate::io::input::read_kind(path, kind)
    }
}

/// The file sizes of a set of files known by path (folders are implied by the paths): the
/// folder logic that [`super::InMemoryFiles`] and the web page's file list share.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct FileList {
    sizes: BTreeMap<PathBuf, u64>,
}

impl FileList {
    /// Adds (or replaces) file `path` of `bytes` bytes.
    pub fn insert(&mut self, path: impl Into<PathBuf>, bytes: u64) {
        self.sizes.insert(path.into(), bytes);
    }

    /// Number of files.
    pub fn len(&self) -> usize {
        self.sizes.len()
    }

    /// True without any file.
    pub fn is_empty(&self) -> bool {
        self.sizes.is_empty()
    }

    /// Every file's path and size, sorted by path.
    pub fn files(&self) -> impl Iterator<Item = (&Path, u64)> {
        self.sizes.iter().map(|(p, &n)| (p.as_path(), n))
    }

    /// What is at `path`: a listed file, a folder some listed file is under, or nothing.
    pub fn entry(&self, path: &Path) -> std::io::Result<Entry> {
        if let Some(&n) = self.sizes.get(path) {
            return Ok(Entry::File(n));
        }
        let under = self
            .sizes
            .range(path.to_path_buf()..)
            .next()
            .is_some_and(|(p, _)| p.starts_with(path) && p != path);
        if under {
            Ok(Entry::Folder)
        } else {
            Err(not_found())
        }
    }

    /// The entries directly in folder `dir`.
    pub fn list(&self, dir: &Path) -> std::io::Result<Vec<PathBuf>> {
        if self.entry(dir)? != Entry::Folder {
            return Err(std::io::Error::new(
                std::io::ErrorKind::NotADirectory,
                "not a folder",
            ));
        }
        let mut out: Vec<PathBuf> = Vec::new();
        for (p, _) in self.sizes.range(dir.to_path_buf()..) {
            let Ok(rest) = p.strip_prefix(dir) else { break };
            if let Some(first) = rest.components().next() {
                let child = dir.join(first);
                if out.last() != Some(&child) {
                    out.push(child);
                }
            }
        }
        Ok(out)
    }

    /// Checks that a file of `len` bytes at `path` is within `kind`'s cap.
    pub fn check_size(path: &Path, len: u64, kind: InputKind) -> Result<()> {
        let max = kind.max_bytes()?;
        if len > max {
            return Err(crate::io::input::too_big(path, len, max, kind));
        }
        Ok(())
    }
}

/// Reads one listed file's whole bytes for a [`Listed`] source (which checks sizes).
pub trait ReadFile: Debug + Send + Sync {
    /// The bytes of `path`, one of the list's files.
    fn read_file(&self, path: &Path) -> Result<Vec<u8>>;
}

/// Files known by their paths and sizes ([`FileList`]) whose bytes come from `reader`:
/// held in memory ([`super::InMemoryFiles`]) or asked of a web page when needed
/// (`src/web`). Sizes are checked against the kind's cap before a read (the listed size)
/// and after it (the bytes that came), as [`Disk`] checks a file's.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Listed<R> {
    pub list: FileList,
    pub reader: R,
}

impl<R: ReadFile> DatasetFiles for Listed<R> {
    fn entry(&self, path: &Path) -> std::io::Result<Entry> {
        self.list.entry(path)
    }
    fn list(&self, dir: &Path) -> std::io::Result<Vec<PathBuf>> {
        self.list.list(dir)
    }
    fn read(&self, path: &Path, kind: InputKind) -> Result<Vec<u8>> {
        let Entry::File(len) = self.list.entry(path).map_err(|e| Error::io(path, e))? else {
            return Err(Error::format(path, "is a folder, not a file"));
        };
        FileList::check_size(path, len, kind)?;
        let bytes = self.reader.read_file(path)?;
        FileList::check_size(path, bytes.len() as u64, kind)?;
        Ok(bytes)
    }
}

fn not_found() -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::NotFound,
        "not among the sequence's files",
    )
}

thread_local! {
    /// The source of [`with_source`]'s closure, if one is running on this thread.
    static CURRENT: RefCell<Option<Arc<dyn DatasetFiles>>> = const { RefCell::new(None) };
}

/// Runs `f` with `files` as this thread's current source (the previous one comes back
/// afterwards, also when `f` panics).
pub fn with_source<R>(files: &Arc<dyn DatasetFiles>, f: impl FnOnce() -> R) -> R {
    struct Restore(Option<Arc<dyn DatasetFiles>>);
    impl Drop for Restore {
        fn drop(&mut self) {
            CURRENT.with_borrow_mut(|c| *c = self.0.take());
        }
    }
    let _restore = Restore(CURRENT.with_borrow_mut(|c| c.replace(Arc::clone(files))));
    f()
}

/// The current source: [`with_source`]'s, else [`Disk`].
pub fn current() -> Arc<dyn DatasetFiles> {
    CURRENT
        .with_borrow(|c| c.clone())
        .unwrap_or_else(|| Arc::new(Disk))
}

/// [`DatasetFiles::present`] of the current source.
pub fn present(path: &Path) -> bool {
    current().present(path)
}

/// Whether `path` is a folder in the current source.
pub fn is_dir(path: &Path) -> bool {
    matches!(current().entry(path), Ok(Entry::Folder))
}

/// [`DatasetFiles::list`] of the current source.
pub fn list(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    current().list(dir)
}

/// [`DatasetFiles::read`] of the current source.
pub fn read(path: &Path, kind: InputKind) -> Result<Vec<u8>> {
    current().read(path, kind)
}

/// [`read`] as UTF-8 text; a leading byte-order mark is dropped (as
/// [`crate::io::input::read_kind_string`]).
pub fn read_string(path: &Path, kind: InputKind) -> Result<String> {
    crate::io::input::text_of(path, read(path, kind)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader that must not be asked.
    #[derive(Debug)]
    struct NeverRead;

    impl ReadFile for NeverRead {
        fn read_file(&self, path: &Path) -> Result<Vec<u8>> {
            panic!("{} was read", path.display())
        }
    }

    /// A reader that returns more bytes than the list said.
    #[derive(Debug)]
    struct Grows;

    impl ReadFile for Grows {
        fn read_file(&self, _: &Path) -> Result<Vec<u8>> {
            Ok(vec![0; (crate::io::input::MAX_MATRIX_BYTES + 1) as usize])
        }
    }

    #[test]
    fn listed_sizes_are_checked_before_and_after_the_read() {
        let p = Path::new("s/frame-000000.pose.txt");
        let mut list = FileList::default();
        list.insert(p, crate::io::input::MAX_MATRIX_BYTES + 1);
        let files = Listed {
            list: list.clone(),
            reader: NeverRead,
        };
        let e = files.read(p, InputKind::Matrix).unwrap_err().to_string();
        assert!(e.contains("more than the limit"), "{e}");
        let e = files.read(Path::new("s"), InputKind::Matrix).unwrap_err();
        assert!(e.to_string().contains("is a folder"), "{e}");
        let mut small = FileList::default();
        small.insert(p, 10);
        let files = Listed {
            list: small,
            reader: Grows,
        };
        let e = files.read(p, InputKind::Matrix).unwrap_err().to_string();
        assert!(e.contains("more than the limit"), "{e}");
    }

    #[test]
    fn a_file_list_implies_its_folders() {
        let mut l = FileList::default();
        for p in [
            "s/rgb.txt",
            "s/rgb/1.png",
            "s/rgb/2.png",
            "s/depth/1.png",
            "s2/x",
        ] {
            l.insert(p, 3);
        }
        assert_eq!(l.entry(Path::new("s/rgb.txt")).unwrap(), Entry::File(3));
        assert_eq!(l.entry(Path::new("s/rgb")).unwrap(), Entry::Folder);
        assert_eq!(l.entry(Path::new("s")).unwrap(), Entry::Folder);
        assert!(
            l.entry(Path::new("s/r")).is_err(),
            "a prefix is not a folder"
        );
        assert!(l.entry(Path::new("s/depth.txt")).is_err());
        let mut top = l.list(Path::new("s")).unwrap();
        top.sort();
        let want: Vec<PathBuf> = ["s/depth", "s/rgb", "s/rgb.txt"]
            .iter()
            .map(PathBuf::from)
            .collect();
        assert_eq!(top, want);
        assert!(l.list(Path::new("s/rgb.txt")).is_err());
    }
}
