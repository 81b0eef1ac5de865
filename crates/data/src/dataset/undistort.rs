//! Removing a lens's distortion from a decoded frame, so that the kernels see the pinhole
//! camera of the sequence's intrinsics (they project and back-project through `fx, fy, cx,
//! cy` alone).
//!
//! Each pixel `(u, v)` of the undistorted image is the ray of the pinhole camera through
//! it; the lens shows that ray at [`Distortion::distort`] of its normalised point, a
//! position in the decoded (distorted) image. Depth takes the nearest pixel's reading (a
//! depth is not averaged across an edge: that would invent a surface between two), so a
//! reading keeps its value, which is the distance along the optical axis and does not
//! change with the pixel's position. Colour is interpolated bilinearly. A ray the decoded
//! image does not see gets no depth (0) and black. The same intrinsics and lens give the
//! same map, which is kept for the next frame.

use std::sync::{Arc, Mutex};

use super::frame::bilinear;
use super::RawFrame;
use crate::geometry::camera::{Distortion, Intrinsics};

/// For each pixel of the undistorted image (row-major), where the decoded image sees its
/// ray: pixel coordinates, `None` outside the decoded image (further than half a pixel
/// beyond its outer pixels' centres, where no pixel is nearest).
struct SourceMap {
    camera: (Intrinsics, Distortion),
    at: Vec<Option<(f32, f32)>>,
}

impl SourceMap {
    fn new(k: &Intrinsics, lens: &Distortion) -> SourceMap {
        let (w, h) = (k.width as f32, k.height as f32);
        let mut at = Vec::with_capacity(k.pixels());
        for v in 0..k.height {
            let y = (v as f64 - k.cy as f64) / k.fy as f64;
            for u in 0..k.width {
                let x = (u as f64 - k.cx as f64) / k.fx as f64;
                let (xd, yd) = lens.distort(x, y);
                let ud = (k.fx as f64 * xd + k.cx as f64) as f32;
                let vd = (k.fy as f64 * yd + k.cy as f64) as f32;
                let inside = ud > -0.5 && vd > -0.5 && ud < w - 0.5 && vd < h - 0.5;
                at.push(inside.then_some((ud, vd)));
            }
        }
        SourceMap {
            camera: (*k, *lens),
            at,
        }
    }
}

/// The last map made (a run has one camera; a batch's runs on one thread mostly share it).
static LAST_MAP: Mutex<Option<Arc<SourceMap>>> = Mutex::new(None);

/// The map of `k` and `lens`, made once and kept.
fn source_map(k: &Intrinsics, lens: &Distortion) -> Arc<SourceMap> {
    let mut last = LAST_MAP.lock().unwrap_or_else(|p| p.into_inner());
    match last.as_ref() {
        Some(map) if map.camera == (*k, *lens) => map.clone(),
        _ => {
            let map = Arc::new(SourceMap::new(k, lens));
            *last = Some(map.clone());
            map
        }
    }
}

/// `frame` (decoded at `k`'s size, seen through `lens`) as the pinhole camera `k` sees it.
pub(crate) fn undistort(frame: &RawFrame, k: &Intrinsics, lens: &Distortion) -> RawFrame {
    let map = source_map(k, lens);
    let w = frame.width as usize;
    let mut depth = Vec::with_capacity(map.at.len());
    let mut rgb = Vec::with_capacity(map.at.len());
    for at in &map.at {
        let Some((u, v)) = *at else {
            depth.push(0);
            rgb.push([0; 3]);
            continue;
        };
        depth.push(frame.depth[v.round() as usize * w + u.round() as usize]);
        rgb.push(bilinear(&frame.rgb, w, frame.height as usize, u, v));
    }
    RawFrame {
        width: frame.width,
        height: frame.height,
        depth,
        rgb,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame whose depth and colour encode each pixel's own position.
    fn numbered(k: &Intrinsics) -> RawFrame {
        let (w, h) = (k.width, k.height);
        RawFrame {
            width: w,
            height: h,
            depth: (0..w * h).map(|i| i as u16 + 1).collect(),
            rgb: (0..w * h)
                .map(|i| [(i % w) as u8, (i / w) as u8, 7])
                .collect(),
        }
    }

    #[test]
    fn each_pixel_takes_the_reading_its_ray_shows_through_the_lens() {
        let k = Intrinsics::TUM_FR1.downsampled(4);
        let lens = Distortion::TUM_FR1;
        let frame = numbered(&k);
        let out = undistort(&frame, &k, &lens);
        let mut outside = 0;
        for v in 0..k.height {
            for u in 0..k.width {
                let i = (v * k.width + u) as usize;
                let x = (u as f64 - k.cx as f64) / k.fx as f64;
                let y = (v as f64 - k.cy as f64) / k.fy as f64;
                let (xd, yd) = lens.distort(x, y);
                let (ud, vd) = (
                    k.fx as f64 * xd + k.cx as f64,
                    k.fy as f64 * yd + k.cy as f64,
                );
                if out.depth[i] == 0 {
                    outside += 1;
                    assert_eq!(out.rgb[i], [0; 3]);
                    continue;
                }
                // Depth is the reading of the nearest decoded pixel, unchanged.
                let src = out.depth[i] as u32 - 1;
                let (su, sv) = ((src % k.width) as f64, (src / k.width) as f64);
                assert!((su - ud).abs() <= 0.5 + 1e-3 && (sv - vd).abs() <= 0.5 + 1e-3);
                // Colour interpolates the position: its channels are u and v.
                assert!((out.rgb[i][0] as f64 - ud).abs() <= 1.0, "{u},{v}");
                assert!((out.rgb[i][1] as f64 - vd).abs() <= 1.0, "{u},{v}");
            }
        }
        // freiburg1's barrel distortion pulls the corners' rays outside the decoded image.
        assert!(outside > 0 && outside < k.pixels() / 10, "{outside}");
    }

    #[test]
    fn no_distortion_keeps_every_pixel() {
        let k = Intrinsics::TUM_FR1.downsampled(8);
        let none = Distortion::from_coefficients([0.0; 5]).unwrap();
        assert_eq!(none, None);
        let tiny = Distortion::from_coefficients([1e-9, 0.0, 0.0, 0.0, 0.0])
            .unwrap()
            .unwrap();
        let frame = numbered(&k);
        assert_eq!(undistort(&frame, &k, &tiny), frame);
    }
}
