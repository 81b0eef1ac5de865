//! ScanNet as its SensReader exports a scan: `color/N.jpg` (1296x968 in ScanNet v2),
//! `depth/N.png` (16-bit millimetres, 640x480), `pose/N.txt` (4x4 camera-to-world, metres;
//! all `-inf` where ScanNet's reconstruction lost the camera) and
//! `intrinsic/intrinsic_depth.txt`, `intrinsic/intrinsic_color.txt` (4x4, K upper-left).
//! File numbers have no zero padding and are ordered as numbers. A frame's stamp is its
//! number.
//!
//! Colour at another size than depth is resampled onto the depth image through the two
//! intrinsics ([`super::frame::resample_color`]); ScanNet's exports treat the two cameras
//! as sharing their pose (`extrinsic_*.txt` are identities), and so does wgslam.

use std::path::Path;

use super::matrix_file::{read_k, read_pose};
use super::numbered::{self, Pattern};
use super::{FrameConventions, FrameRecord, Listing};
use crate::geometry::camera::Intrinsics;
use crate::{Error, Result};

/// Refuses colour images that cannot be the camera `k` describes: its principal point
/// outside them (1x1 colour images under ScanNet's 1296x968 intrinsics were resampled into
/// an all-black colour, silently).
fn check_color_fits(k: &Intrinsics, k_path: &Path, first_rgb: &Path) -> Result<()> {
    let (w, h) = (k.width as f32, k.height as f32);
    if (0.0..=w).contains(&k.cx) && (0.0..=h).contains(&k.cy) {
        return Ok(());
    }
    Err(Error::format(
        first_rgb,
        format!(
            "colour image is {}x{}, but the colour intrinsics in {} put the principal point \
             at ({}, {}), outside it: these are not the images those intrinsics describe \
             (ScanNet's colour is 1296x968); use the sequence's own colour images",
            k.width,
            k.height,
            k_path.display(),
            k.cx,
            k.cy
        ),
    ))
}

/// `depth/N.png`.
pub const DEPTH: Pattern = Pattern::new("", ".png");
/// `color/N.jpg`.
pub const COLOR: Pattern = Pattern::new("", ".jpg");
/// `pose/N.txt`.
pub const POSE: Pattern = Pattern::new("", ".txt");
/// Millimetres.
pub const DEPTH_SCALE: f32 = 1000.0;

/// Lists the frames of `root` with their poses and reads both intrinsics files.
pub fn list(root: &Path) -> Result<Listing> {
    let depth = numbered::list(&root.join("depth"), DEPTH)?;
    let color = numbered::list(&root.join("color"), COLOR)?;
    let pairs = numbered::pair(&depth, &color, DEPTH, COLOR)?;
    let poses = numbered::list(&root.join("pose"), POSE)?;
    let mut notes = Vec::new();
    let mut frames = Vec::with_capacity(pairs.len());
    let mut failed = Vec::new();
    for (n, rgb_path, depth_path) in pairs {
        let gt = match poses.get(&n) {
            Some(p) => {
                let gt = read_pose(p)?;
                if gt.is_none() {
                    failed.push(n);
                }
                gt
            }
            None => None,
        };
        frames.push(FrameRecord {
            timestamp: n as f64,
            rgb_path,
            depth_path,
            gt_cam_to_world: gt,
        });
    }
    let without_file = frames.len()
        - frames
            .iter()
            .filter(|f| poses.contains_key(&(f.timestamp as u64)))
            .count();
    if poses.is_empty() {
        notes.push(format!(
            "no pose/N.txt files in {}: no ground truth",
            root.display()
        ));
    } else if without_file > 0 {
        notes.push(format!(
            "{without_file} of {} frames have no pose/N.txt: no ground truth for them",
            frames.len()
        ));
    }
    if !failed.is_empty() {
        notes.push(format!(
            "{} pose file(s) are -inf (ScanNet lost the camera there; first: pose/{}.txt): no \
             ground truth for those frames",
            failed.len(),
            failed[0]
        ));
    }
    let first = frames
        .first()
        .ok_or_else(|| Error::format(root.join("depth"), "no frames"))?;
    let depth_size = super::frame::image_size(&first.depth_path)?;
    let color_size = super::frame::image_size(&first.rgb_path)?;

    let depth_k_path = root.join("intrinsic/intrinsic_depth.txt");
    let depth_k = if super::source::present(&depth_k_path) {
        Some(Intrinsics::from_floats(read_k(&depth_k_path)?, depth_size))
    } else {
        None
    };
    let color_k_path = root.join("intrinsic/intrinsic_color.txt");
    let color_intrinsics = if super::source::present(&color_k_path) {
        let k = Intrinsics::from_floats(read_k(&color_k_path)?, color_size);
        check_color_fits(&k, &color_k_path, &first.rgb_path)?;
        Some(k)
    } else if color_size != depth_size {
        return Err(Error::io(
            &color_k_path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!(
                    "colour images are {}x{} and depth images {}x{}: the colour intrinsics \
                     are needed to map colour onto depth",
                    color_size.0, color_size.1, depth_size.0, depth_size.1
                ),
            ),
        ));
    } else {
        None
    };
    Ok(Listing {
        frames,
        gt_file: None,
        intrinsics: depth_k,
        no_intrinsics: format!(
            "{} is missing: ScanNet's depth intrinsics are needed",
            depth_k_path.display()
        ),
        image_size: Some(depth_size),
        depth_scale: Some(DEPTH_SCALE),
        conventions: FrameConventions {
            invalid_depth_raw: None,
            color_intrinsics,
            distortion: None,
        },
        notes,
    })
}
