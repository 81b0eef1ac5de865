//! A sequence whose files are in memory instead of on disk: the browser build (`src/web`)
//! has no file system, so the page hands over its copies of a dataset folder's files and
//! [`open_in_memory`] reads them with the same parsers and decoders as [`super::open`].
//!
//! Only the layout the page ships is read: ICL-NUIM (`associations.txt` and one
//! `*.gt.freiburg`) with a `camera.json`. No layout detection; no writing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::{icl, parse_camera_json, tum, FrameConventions, FrameRecord, Layout, Sequence};
use crate::geometry::camera::Intrinsics;
use crate::io::trajectory::parse_tum;
use crate::{Error, Result};

/// A dataset folder's files held in memory, by path (the sequence's root joined with the
/// path inside the folder, as [`FrameRecord`]'s paths are).
#[derive(Default, Clone, PartialEq)]
pub struct InMemoryFiles {
    files: BTreeMap<PathBuf, Vec<u8>>,
}

impl std::fmt::Debug for InMemoryFiles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let bytes: usize = self.files.values().map(Vec::len).sum();
        write!(
            f,
            "InMemoryFiles({} files, {bytes} bytes)",
            self.files.len()
        )
    }
}

impl InMemoryFiles {
    /// Adds (or replaces) file `path` with its contents.
    pub fn insert(&mut self, path: impl Into<PathBuf>, bytes: Vec<u8>) {
        self.files.insert(path.into(), bytes);
    }

    /// The contents of file `path`, if held.
    pub fn get(&self, path: &Path) -> Option<&[u8]> {
        self.files.get(path).map(Vec::as_slice)
    }

    /// Number of files held.
    pub fn len(&self) -> usize {
        self.files.len()
    }

    /// True when no file is held.
    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }

    fn text(&self, path: &Path) -> Result<&str> {
        let bytes = self.get(path).ok_or_else(|| {
            Error::io(
                path,
                std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "not among the sequence's in-memory files",
                ),
            )
        })?;
        std::str::from_utf8(bytes).map_err(|e| Error::format(path, format!("not UTF-8: {e}")))
    }
}

/// Opens the ICL-NUIM sequence whose files under `root` are in `files`: frames from
/// `root/associations.txt`, intrinsics and depth scale from `root/camera.json`, ground
/// truth from the one `*.gt.freiburg` file directly in `root`, associated to frames by
/// stamp within `max_time_diff` as [`super::open`] does. Every listed image must be held;
/// images are decoded by [`Sequence::load`].
pub fn open_in_memory(root: &Path, files: InMemoryFiles, max_time_diff: f64) -> Result<Sequence> {
    let assoc_path = root.join("associations.txt");
    let assoc = icl::parse_associations(&assoc_path, files.text(&assoc_path)?)?;
    if assoc.is_empty() {
        return Err(Error::format(root, "empty sequence: no colour/depth pairs"));
    }
    let camera_path = root.join("camera.json");
    let cam = parse_camera_json(&camera_path, files.text(&camera_path)?)?;
    let intrinsics = Intrinsics {
        width: cam.width,
        height: cam.height,
        fx: cam.fx,
        fy: cam.fy,
        cx: cam.cx,
        cy: cam.cy,
    };
    let depth_scale = cam.depth_scale.unwrap_or(super::DEFAULT_DEPTH_SCALE);
    let mut frames = Vec::with_capacity(assoc.len());
    for a in assoc {
        let (rgb_path, depth_path) = (root.join(a.rgb_path), root.join(a.depth_path));
        for p in [&rgb_path, &depth_path] {
            if files.get(p).is_none() {
                return Err(Error::format(
                    p,
                    "image listed by associations.txt is not among the in-memory files",
                ));
            }
        }
        frames.push(FrameRecord {
            timestamp: a.stamp,
            rgb_path,
            depth_path,
            gt_cam_to_world: None,
        });
    }
    let gt_files: Vec<&PathBuf> = files
        .files
        .keys()
        .filter(|p| p.parent() == Some(root))
        .filter(|p| p.to_string_lossy().ends_with(".gt.freiburg"))
        .collect();
    if gt_files.len() > 1 {
        return Err(Error::format(root, "several ground-truth files"));
    }
    if let Some(path) = gt_files.first() {
        let mut gt = parse_tum(path, files.text(path)?)?;
        gt.sort_by(|a, b| a.0.total_cmp(&b.0));
        let gt_stamps: Vec<f64> = gt.iter().map(|g| g.0).collect();
        for f in &mut frames {
            f.gt_cam_to_world =
                tum::nearest_within(&gt_stamps, f.timestamp, max_time_diff).map(|k| gt[k].1);
        }
    }
    Ok(Sequence {
        root: root.to_path_buf(),
        layout: Layout::IclNuim,
        intrinsics,
        depth_scale,
        frames,
        conventions: FrameConventions::default(),
        notes: Vec::new(),
        files: Some(Arc::new(files)),
    })
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
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/icl_living_room_kt2");
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
