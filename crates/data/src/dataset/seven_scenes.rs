//! The frame-file layout of Microsoft 7-Scenes, 3DMatch and the tsdf-fusion demos:
//! `frame-NNNNNN.depth.png` (16-bit millimetres; 0 and 65535 mean no reading),
//! `frame-NNNNNN.color.jpg` or `.color.png`, `frame-NNNNNN.pose.txt` (4x4 camera-to-world,
//! row-major, metres) and, in 3DMatch and the demos, `camera-intrinsics.txt` (3x3 K of the
//! depth camera).
//!
//! The official 7-Scenes release keeps each recording in a `seq-NN/` folder and ships no
//! intrinsics file: a scene folder with one `seq-NN/` opens that sequence, one with several
//! asks for one of them, and without `camera-intrinsics.txt` (here or in the scene folder
//! above a `seq-NN/`) the 7-Scenes Kinect's published intrinsics are used, with a note.
//! Frames have no timestamps (recorded at 30 Hz): a frame's stamp is its number.

use std::path::{Path, PathBuf};

use super::matrix_file::{read_k, read_pose};
use super::numbered::{self, Pattern};
use super::{FrameConventions, FrameRecord, Listing};
use crate::geometry::camera::Intrinsics;
use crate::{Error, Result};

/// Depth images, the files that make a folder a sequence of this layout.
pub const DEPTH: Pattern = Pattern::new("frame-", ".depth.png");
/// JPEG colour (7-Scenes as the tsdf-fusion demo ships it).
pub const COLOR_JPG: Pattern = Pattern::new("frame-", ".color.jpg");
/// PNG colour (official 7-Scenes, 3DMatch).
pub const COLOR_PNG: Pattern = Pattern::new("frame-", ".color.png");
/// Per-frame ground truth.
pub const POSE: Pattern = Pattern::new("frame-", ".pose.txt");
/// The intrinsics file of 3DMatch and the tsdf-fusion demos.
pub const INTRINSICS_FILE: &str = "camera-intrinsics.txt";
/// Millimetres.
pub const DEPTH_SCALE: f32 = 1000.0;
/// The official 7-Scenes release marks missing depth with 65535 as well as 0.
pub const INVALID_DEPTH_RAW: u16 = 65535;
/// The 7-Scenes Kinect's intrinsics as the dataset's page gives them (fx = fy = 585,
/// principal point at the image centre), for a release without `camera-intrinsics.txt`.
pub const SEVEN_SCENES_K: [f32; 4] = [585.0, 585.0, 320.0, 240.0];

/// Whether `path`'s name starts with `seq-` (a 7-Scenes sequence folder's).
fn is_seq_folder(path: &Path) -> bool {
    path.file_name()
        .is_some_and(|n| n.to_string_lossy().starts_with("seq-"))
}

/// The `seq-NN` folders of `root` that hold depth frames, sorted.
fn sequence_folders(root: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = super::source::list(root)
        .into_iter()
        .flatten()
        .filter(|p| is_seq_folder(p))
        .filter(|p| numbered::any(p, DEPTH))
        .collect();
    found.sort();
    found
}

/// True when `root`, or a `seq-NN` folder in it, holds `frame-N.depth.png` files.
pub fn has_depth_frames(root: &Path) -> bool {
    numbered::any(root, DEPTH) || !sequence_folders(root).is_empty()
}

/// True when `root`, or a `seq-NN` folder in it, holds colour frames.
pub fn has_color_frames(root: &Path) -> bool {
    let here = |d: &Path| numbered::any(d, COLOR_JPG) || numbered::any(d, COLOR_PNG);
    here(root)
        || super::source::list(root)
            .into_iter()
            .flatten()
            .any(|p| is_seq_folder(&p) && here(&p))
}

/// The folder whose frames to read: `root` itself, or its only `seq-NN` folder.
fn frame_folder(root: &Path) -> Result<PathBuf> {
    if numbered::any(root, DEPTH) {
        return Ok(root.to_path_buf());
    }
    let mut seqs = sequence_folders(root);
    match seqs.len() {
        1 => Ok(seqs.pop().expect("one folder")),
        0 => Err(Error::format(
            root,
            format!("no {} files here or in a seq-NN folder", DEPTH.describe()),
        )),
        _ => Err(Error::format(
            root,
            format!(
                "holds {} recordings ({}); pass one of them, e.g. {}",
                seqs.len(),
                seqs.iter()
                    .map(|p| p.file_name().unwrap_or_default().to_string_lossy())
                    .collect::<Vec<_>>()
                    .join(", "),
                seqs[0].display()
            ),
        )),
    }
}

/// Lists the frames of `root` with their per-frame poses, and reads the intrinsics file.
pub fn list(root: &Path) -> Result<Listing> {
    let dir = frame_folder(root)?;
    let depth = numbered::list(&dir, DEPTH)?;
    let jpg = numbered::list(&dir, COLOR_JPG)?;
    let png = numbered::list(&dir, COLOR_PNG)?;
    let (color, color_pattern) = match (jpg.is_empty(), png.is_empty()) {
        (false, true) => (jpg, COLOR_JPG),
        (true, _) => (png, COLOR_PNG),
        (false, false) => {
            return Err(Error::format(
                &dir,
                format!(
                    "holds both {} and {} colour images; keep one kind",
                    COLOR_JPG.describe(),
                    COLOR_PNG.describe()
                ),
            ))
        }
    };
    let pairs = numbered::pair(&depth, &color, DEPTH, color_pattern)?;
    let poses = numbered::list(&dir, POSE)?;
    let mut notes = Vec::new();
    let mut frames = Vec::with_capacity(pairs.len());
    let (mut no_file, mut not_finite) = (0usize, 0usize);
    for (n, rgb_path, depth_path) in pairs {
        let gt = if let Some(pose_path) = poses.get(&n) {
            let gt = read_pose(pose_path)?;
            not_finite += usize::from(gt.is_none());
            gt
        } else {
            no_file += 1;
            None
        };
        frames.push(FrameRecord {
            timestamp: n as f64,
            rgb_path,
            depth_path,
            gt_cam_to_world: gt,
        });
    }
    if no_file > 0 && no_file < frames.len() {
        notes.push(format!(
            "{no_file} of {} frames have no frame-NNNNNN.pose.txt: no ground truth for them",
            frames.len()
        ));
    }
    if not_finite > 0 {
        notes.push(format!(
            "{not_finite} pose file(s) hold non-finite numbers (a failed pose): no ground truth \
             for those frames"
        ));
    }

    // Beside the frames, or in the scene folder above a seq-NN folder.
    let k_path = [dir.join(INTRINSICS_FILE), root.join(INTRINSICS_FILE)]
        .into_iter()
        .find(|p| super::source::present(p));
    let k = match &k_path {
        Some(p) => read_k(p)?,
        None => {
            notes.push(format!(
                "no {INTRINSICS_FILE} in {}: using the 7-Scenes Kinect's fx = fy = 585, \
                 cx = 320, cy = 240 (--intrinsics overrides)",
                dir.display()
            ));
            SEVEN_SCENES_K
        }
    };
    let first_depth = &frames
        .first()
        .ok_or_else(|| Error::format(&dir, "no frames"))?
        .depth_path;
    let (width, height) = super::frame::image_size(first_depth)?;
    Ok(Listing {
        frames,
        gt_file: None,
        intrinsics: Some(Intrinsics::from_floats(k, (width, height))),
        no_intrinsics: String::new(),
        image_size: Some((width, height)),
        depth_scale: Some(DEPTH_SCALE),
        conventions: FrameConventions {
            invalid_depth_raw: Some(INVALID_DEPTH_RAW),
            color_intrinsics: None,
            distortion: None,
        },
        notes,
    })
}
