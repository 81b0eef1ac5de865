//! A sequence whose files are in memory instead of on disk: [`open_in_memory`] reads a
//! dataset folder's files held as bytes through the same layout detection, listers, parsers
//! and decoders as [`super::open`] (every layout; see [`super::source`]).
//!
//! Not a cache: every file is held whole until the sequence goes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::source::{Listed, ReadFile};
use super::{open_with, Sequence, SequenceOptions};
use crate::{Error, Result};

/// A dataset folder's files held in memory, by path (the sequence's root joined with the
/// path inside the folder, as [`super::FrameRecord`]'s paths are).
pub type InMemoryFiles = Listed<HeldBytes>;

/// The bytes of an [`InMemoryFiles`], by path.
#[derive(Default, Clone, PartialEq)]
pub struct HeldBytes(BTreeMap<PathBuf, Vec<u8>>);

impl std::fmt::Debug for HeldBytes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let bytes: usize = self.0.values().map(Vec::len).sum();
        write!(f, "HeldBytes({} files, {bytes} bytes)", self.0.len())
    }
}

impl ReadFile for HeldBytes {
    fn read_file(&self, path: &Path) -> Result<Vec<u8>> {
        let bytes = self.0.get(path).ok_or_else(|| {
            Error::io(
                path,
                std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "not among the sequence's in-memory files",
                ),
            )
        })?;
        Ok(bytes.clone())
    }
}

impl InMemoryFiles {
    /// Adds (or replaces) file `path` with its contents.
    pub fn insert(&mut self, path: impl Into<PathBuf>, bytes: Vec<u8>) {
        let path = path.into();
        self.list.insert(path.clone(), bytes.len() as u64);
        self.reader.0.insert(path, bytes);
    }

    /// The contents of file `path`, if held.
    pub fn get(&self, path: &Path) -> Option<&[u8]> {
        self.reader.0.get(path).map(Vec::as_slice)
    }

    /// Number of files held.
    pub fn len(&self) -> usize {
        self.list.len()
    }

    /// True when no file is held.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }
}

/// Opens the sequence whose files under `root` are in `files`, as [`super::open`] opens a
/// folder (any layout it reads), associating by stamp within `max_time_diff`. Images are
/// decoded by [`Sequence::load`].
pub fn open_in_memory(root: &Path, files: InMemoryFiles, max_time_diff: f64) -> Result<Sequence> {
    let opts = SequenceOptions {
        max_time_diff,
        ..SequenceOptions::default()
    };
    open_with(Arc::new(files), root, &opts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::{open, SequenceOptions, DEFAULT_MAX_TIME_DIFF};

    /// Every file under `dir`, keyed by its path as `dir.join(relative)`.
    fn read_folder(dir: &Path, files: &mut InMemoryFiles) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                read_folder(&path, files);
            } else {
                files.insert(path.clone(), std::fs::read(&path).unwrap());
            }
        }
    }

    #[test]
    fn the_bundled_frames_in_memory_open_and_decode_as_from_disk() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/icl_living_room_kt2");
        let on_disk = open(&root, &SequenceOptions::default()).unwrap();
        let mut files = InMemoryFiles::default();
        read_folder(&root, &mut files);
        let in_memory = open_in_memory(&root, files, DEFAULT_MAX_TIME_DIFF).unwrap();
        assert_eq!(in_memory.frames, on_disk.frames);
        assert_eq!(in_memory.intrinsics, on_disk.intrinsics);
        assert_eq!(in_memory.depth_scale, on_disk.depth_scale);
        assert_eq!(in_memory.layout, on_disk.layout);
        assert_eq!(
            in_memory.default_first_frame(),
            1,
            "ICL frame 0 has no ground truth"
        );
        for i in [0, on_disk.len() - 1] {
            assert_eq!(
                in_memory.load(i).unwrap(),
                on_disk.load(i).unwrap(),
                "frame {i}"
            );
        }
    }

    #[test]
    fn a_missing_image_is_named() {
        let root = Path::new("seq");
        let mut files = InMemoryFiles::default();
        files.insert(
            root.join("associations.txt"),
            b"0 depth/0.png 0 rgb/0.png\n".to_vec(),
        );
        files.insert(
            root.join("camera.json"),
            br#"{"width": 4, "height": 2, "fx": 2, "fy": 2, "cx": 1.5, "cy": 0.5}"#.to_vec(),
        );
        files.insert(root.join("depth/0.png"), Vec::new());
        let e = open_in_memory(root, files, DEFAULT_MAX_TIME_DIFF).unwrap_err();
        assert!(e.to_string().contains("rgb/0.png"), "{e}");
    }
}
