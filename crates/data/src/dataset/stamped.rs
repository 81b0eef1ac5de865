//! The frame listing of the TUM-like layouts (TUM RGB-D, ICL-NUIM, ETH3D, Bonn): colour
//! and depth pairs from the association lists (or by stamp, [`tum::associate`]), in the
//! order [`StampOrder`] chooses, with the layout's intrinsics where it has them.

use std::path::{Path, PathBuf};

use super::{bonn, checks, eth3d, frame, icl, tum};
use super::{FrameConventions, FrameRecord, Layout, Listing, StampOrder};
use crate::geometry::camera::Intrinsics;
use crate::{Error, Result};

/// The TUM-like layouts (TUM, ICL-NUIM, ETH3D, Bonn): frames from the association lists,
/// ground truth from one trajectory file.
pub(super) fn listing(
    root: &Path,
    layout: Layout,
    max_time_diff: f64,
    order: StampOrder,
) -> Result<Listing> {
    let mut order_notes = Vec::new();
    // (stamp, rgb, depth) in order of depth stamp.
    let (pairs, gt_file): (Vec<(f64, PathBuf, PathBuf)>, Option<PathBuf>) = match layout {
        Layout::IclNuim => {
            let assoc = icl::read_associations(&root.join("associations.txt"))?;
            let pairs = assoc
                .into_iter()
                .map(|a| (a.stamp, root.join(a.rgb_path), root.join(a.depth_path)))
                .collect();
            (pairs, icl::find_ground_truth(root)?)
        }
        Layout::Eth3d if super::source::present(&root.join("associated.txt")) => {
            let pairs = eth3d::read_associated(&root.join("associated.txt"))?
                .into_iter()
                .map(|a| (a.stamp, root.join(a.rgb_path), root.join(a.depth_path)))
                .collect();
            let gt = root.join("groundtruth.txt");
            (pairs, super::source::present(&gt).then_some(gt))
        }
        _ => {
            let rgb = tum::read_list(&root.join("rgb.txt"))?;
            let depth = tum::read_list(&root.join("depth.txt"))?;
            let rs: Vec<f64> = rgb.iter().map(|e| e.stamp).collect();
            let ds: Vec<f64> = depth.iter().map(|e| e.stamp).collect();
            order_notes.extend(checks::order_note(&root.join("depth.txt"), &ds, order));
            let mut assoc = tum::associate(&ds, &rs, max_time_diff);
            if order == StampOrder::File {
                assoc.sort_by_key(|&(id, _)| id);
            }
            let pairs = assoc
                .into_iter()
                .map(|(id, ir)| (ds[id], root.join(&rgb[ir].path), root.join(&depth[id].path)))
                .collect();
            let gt = root.join("groundtruth.txt");
            (pairs, super::source::present(&gt).then_some(gt))
        }
    };
    if pairs.is_empty() {
        return Err(Error::format(
            root,
            format!(
                "empty sequence: no colour/depth pairs{}",
                if matches!(layout, Layout::Tum | Layout::Bonn | Layout::Eth3d) {
                    format!(" within {max_time_diff} s of each other")
                } else {
                    String::new()
                }
            ),
        ));
    }
    let mut image_size = None;
    let (intrinsics, no_intrinsics) = match layout {
        Layout::IclNuim => (Some(Intrinsics::ICL_NUIM), String::new()),
        Layout::Bonn => (Some(bonn::INTRINSICS), String::new()),
        Layout::Eth3d => {
            // calibration.txt has no image size: the depth images have it.
            let [fx, fy, cx, cy] = eth3d::read_calibration(&root.join(eth3d::CALIBRATION))?;
            let (width, height) = frame::image_size(&pairs[0].2)?;
            image_size = Some((width, height));
            let k = Intrinsics {
                width,
                height,
                fx,
                fy,
                cx,
                cy,
            };
            (Some(k), String::new())
        }
        _ => (
            None,
            format!(
                "{}: TUM RGB-D sequences do not record their intrinsics; pass --intrinsics \
                 (a preset such as fr1, fr2, fr3, or fx,fy,cx,cy) or add a camera.json",
                root.display()
            ),
        ),
    };
    Ok(Listing {
        frames: pairs
            .into_iter()
            .map(|(timestamp, rgb_path, depth_path)| FrameRecord {
                timestamp,
                rgb_path,
                depth_path,
                gt_cam_to_world: None,
            })
            .collect(),
        gt_file,
        intrinsics,
        no_intrinsics,
        image_size,
        depth_scale: None,
        conventions: FrameConventions::default(),
        notes: order_notes,
    })
}
