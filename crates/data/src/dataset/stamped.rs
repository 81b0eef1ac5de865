//! The frame listing of the TUM-like layouts (TUM RGB-D, ICL-NUIM, ETH3D, Bonn): colour
//! and depth pairs from the association lists (or by stamp, [`tum::associate`]), in the
//! order [`StampOrder`] chooses, with the layout's intrinsics where it has them.

use std::path::{Path, PathBuf};

use super::{bonn, checks, eth3d, frame, icl, tum};
use super::{FrameConventions, FrameRecord, Layout, Listing, SequenceOptions, StampOrder};
use crate::geometry::camera::Intrinsics;
use crate::{Error, Result};

/// The TUM-like layouts (TUM, ICL-NUIM, ETH3D, Bonn): frames from the association lists,
/// ground truth from one trajectory file.
pub(super) fn listing(root: &Path, layout: Layout, opts: &SequenceOptions) -> Result<Listing> {
    let max_time_diff = opts.max_time_diff;
    let mut order_notes = Vec::new();
    let (pairs, gt_file) = frame_pairs(root, layout, opts, &mut order_notes)?;
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
    let LayoutIntrinsics {
        intrinsics,
        no_intrinsics,
        image_size,
    } = layout_intrinsics(root, layout, &pairs[0].2)?;
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

/// `(stamp, rgb path, depth path)` of one frame.
type FramePair = (f64, PathBuf, PathBuf);

/// `pairs` (one association list's, in its lines' order) in the order `opts.stamp_order`
/// chooses: sorted by stamp (stable), or as listed; a note in `order_notes` when the
/// list's stamps go backwards, as a TUM depth list's get.
fn in_order(
    list: &Path,
    mut pairs: Vec<FramePair>,
    opts: &SequenceOptions,
    order_notes: &mut Vec<String>,
) -> Vec<FramePair> {
    let stamps: Vec<f64> = pairs.iter().map(|p| p.0).collect();
    order_notes.extend(checks::order_note(
        list,
        &stamps,
        opts.stamp_order,
        opts.interface,
    ));
    if opts.stamp_order == StampOrder::Time {
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    pairs
}

/// `(stamp, rgb, depth)` of every frame, in order of depth stamp (or of the depth list with
/// [`StampOrder::File`]), and the ground-truth file when there is one. A note on a list
/// out of stamp order goes to `order_notes`.
fn frame_pairs(
    root: &Path,
    layout: Layout,
    opts: &SequenceOptions,
    order_notes: &mut Vec<String>,
) -> Result<(Vec<FramePair>, Option<PathBuf>)> {
    let (max_time_diff, order) = (opts.max_time_diff, opts.stamp_order);
    Ok(match layout {
        Layout::IclNuim => {
            let list = root.join("associations.txt");
            let pairs = icl::read_associations(&list)?
                .into_iter()
                .map(|a| (a.stamp, root.join(a.rgb_path), root.join(a.depth_path)))
                .collect();
            let pairs = in_order(&list, pairs, opts, order_notes);
            (pairs, icl::find_ground_truth(root)?)
        }
        Layout::Eth3d if super::source::present(&root.join("associated.txt")) => {
            let list = root.join("associated.txt");
            let pairs = eth3d::read_associated(&list)?
                .into_iter()
                .map(|a| (a.stamp, root.join(a.rgb_path), root.join(a.depth_path)))
                .collect();
            let pairs = in_order(&list, pairs, opts, order_notes);
            let gt = root.join("groundtruth.txt");
            (pairs, super::source::present(&gt).then_some(gt))
        }
        _ => {
            let rgb = tum::read_list(&root.join("rgb.txt"))?;
            let depth = tum::read_list(&root.join("depth.txt"))?;
            let rs: Vec<f64> = rgb.iter().map(|e| e.stamp).collect();
            let ds: Vec<f64> = depth.iter().map(|e| e.stamp).collect();
            order_notes.extend(checks::order_note(
                &root.join("depth.txt"),
                &ds,
                order,
                opts.interface,
            ));
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
    })
}

/// What a layout says of its camera: see [`Listing`]'s fields of the same names.
struct LayoutIntrinsics {
    intrinsics: Option<Intrinsics>,
    no_intrinsics: String,
    image_size: Option<(u32, u32)>,
}

/// The layout's intrinsics where it has them (ETH3D's from calibration.txt, with the image
/// size read from `first_depth`), else why not; and the image size when read here.
fn layout_intrinsics(root: &Path, layout: Layout, first_depth: &Path) -> Result<LayoutIntrinsics> {
    let (intrinsics, no_intrinsics, image_size) = match layout {
        Layout::IclNuim => (Some(Intrinsics::ICL_NUIM), String::new(), None),
        Layout::Bonn => (Some(bonn::INTRINSICS), String::new(), None),
        Layout::Eth3d => {
            // calibration.txt has no image size: the depth images have it.
            let floats = eth3d::read_calibration(&root.join(eth3d::CALIBRATION))?;
            let size = frame::image_size(first_depth)?;
            let k = Intrinsics::from_floats(floats, size);
            (Some(k), String::new(), Some(size))
        }
        _ => (
            None,
            format!(
                "{}: TUM RGB-D sequences do not record their intrinsics",
                root.display()
            ),
            None,
        ),
    };
    Ok(LayoutIntrinsics {
        intrinsics,
        no_intrinsics,
        image_size,
    })
}
