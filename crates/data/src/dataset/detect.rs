//! Which layout a folder is in: each layout's telltale files, tried in a fixed order, and
//! for a folder that fits none, an error listing every layout tried and what the closest
//! one lacks.

use std::path::Path;

use super::numbered;
use super::source::present;
use super::{replica, scannet, seven_scenes, Layout};
use crate::{Error, Result};

/// One layout's telltale files in `root`: `(what, present)` for each.
fn telltales(layout: Layout, root: &Path) -> Vec<(String, bool)> {
    let file = |name: &str| (name.to_string(), super::source::present(&root.join(name)));
    match layout {
        Layout::Eth3d => vec![
            file("calibration.txt"),
            (
                "associated.txt (or rgb.txt and depth.txt)".into(),
                present(&root.join("associated.txt"))
                    || (present(&root.join("rgb.txt")) && present(&root.join("depth.txt"))),
            ),
        ],
        Layout::Bonn => vec![
            file("rgb.txt"),
            file("depth.txt"),
            (
                "a folder name starting with rgbd_bonn_".into(),
                super::bonn::is_bonn_name(root),
            ),
        ],
        Layout::Tum => vec![file("rgb.txt"), file("depth.txt")],
        Layout::IclNuim => vec![file("associations.txt")],
        Layout::SevenScenes => vec![
            (
                format!(
                    "{} files (here or in a seq-NN folder)",
                    seven_scenes::DEPTH.describe()
                ),
                seven_scenes::has_depth_frames(root),
            ),
            (
                format!(
                    "{} or {} files",
                    seven_scenes::COLOR_JPG.describe(),
                    seven_scenes::COLOR_PNG.describe()
                ),
                seven_scenes::has_color_frames(root),
            ),
        ],
        Layout::ScanNet => vec![
            (
                format!("depth/{}", scannet::DEPTH.describe()),
                numbered::any(&root.join("depth"), scannet::DEPTH),
            ),
            (
                format!("color/{}", scannet::COLOR.describe()),
                numbered::any(&root.join("color"), scannet::COLOR),
            ),
        ],
        Layout::Replica => vec![
            (
                format!("results/{}", replica::DEPTH.describe()),
                numbered::any(&root.join("results"), replica::DEPTH),
            ),
            (
                format!("results/{}", replica::COLOR.describe()),
                numbered::any(&root.join("results"), replica::COLOR),
            ),
        ],
        // Recordings are files (or a ROS 2 bag's folder), recognised before detection.
        Layout::Ros1Bag | Layout::Ros2Bag | Layout::Mcap => Vec::new(),
    }
}

/// Why `root` cannot be a dataset folder, in words: missing, a loop of symbolic links, a
/// link to nothing, or not a folder.
fn check_root(root: &Path) -> Result<()> {
    let why = match super::source::current().entry(root) {
        Ok(super::source::Entry::Folder) => return Ok(()),
        Ok(_) => "is not a folder (a dataset is a folder of frame lists and images)",
        Err(e) if is_link_loop(&e) => {
            "is a loop of symbolic links (following them leads back to a link): give the \
             dataset folder's real path"
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound && super::source::present(root) => {
            "is a symbolic link to nothing (its target does not exist)"
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(Error::io(
                root,
                std::io::Error::new(e.kind(), "dataset directory does not exist"),
            ))
        }
        Err(e) => return Err(Error::io(root, e)),
    };
    Err(Error::format(root, why))
}

/// Whether `e` says a path's symbolic links loop (`ELOOP`).
fn is_link_loop(e: &std::io::Error) -> bool {
    #[cfg(unix)]
    {
        e.raw_os_error() == Some(libc::ELOOP)
    }
    #[cfg(not(unix))]
    {
        let _ = e;
        false
    }
}

/// The layout of `root`: the first of [`Layout::DETECTION_ORDER`] whose telltale files are
/// all there. A folder that fits none is an error listing the layouts tried and, for the
/// one with the most telltales present, what is missing.
pub fn detect(root: &Path) -> Result<Layout> {
    check_root(root)?;
    let mut closest: Option<(usize, Layout, Vec<String>)> = None;
    let mut tried = Vec::new();
    for layout in Layout::DETECTION_ORDER {
        let t = telltales(layout, root);
        if t.iter().all(|(_, present)| *present) {
            return Ok(layout);
        }
        let present = t.iter().filter(|(_, p)| *p).count();
        let missing: Vec<String> = t
            .iter()
            .filter(|(_, p)| !*p)
            .map(|(w, _)| w.clone())
            .collect();
        tried.push(format!(
            "{} ({})",
            layout.name(),
            t.iter()
                .map(|(w, _)| w.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ));
        if present > 0 && closest.as_ref().is_none_or(|(best, _, _)| present > *best) {
            closest = Some((present, layout, missing));
        }
    }
    let verdict = match closest {
        Some((_, layout, missing)) => format!(
            "the closest is {}, which lacks {}",
            layout.name(),
            missing.join(" and ")
        ),
        None => "no file of any of them is here".to_string(),
    };
    let icl_like =
        super::source::is_dir(&root.join("depth")) && super::source::is_dir(&root.join("rgb"));
    let verdict = if icl_like && !present(&root.join("associations.txt")) {
        format!(
            "{verdict}; with depth/ and rgb/ folders this looks like ICL-NUIM, which needs \
             associations.txt (`<i> depth/<i>.png <i> rgb/<i>.png`, a line per frame)"
        )
    } else {
        verdict
    };
    Err(Error::format(
        root,
        format!(
            "not a dataset in any layout wgslam reads; tried {}; {verdict}",
            tried.join("; ")
        ),
    ))
}
