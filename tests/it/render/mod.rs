//! Renderer tests: ground truth against the bundled real frames, determinism, the depth
//! test's key order, overlays, trajectory plots, bad input, and (with a GPU) GPU-vs-CPU
//! parity. Set `WGSLAM_RENDER_OUT=DIR` to keep the pictures for a look. The CPU renderer's
//! tests are in `renderer`, the commands' in `command`, the GPU's in `gpu`; this module
//! holds the bundled map and the helpers they share.

mod command;
mod gaps;
mod gpu;
mod renderer;

use crate::common;

use std::path::{Path, PathBuf};

use common::frames::{load_frame, load_gt, Frame};
use glam::{DMat4, DVec3};
use wgslam::cpu::binding::Binding;
use wgslam::cpu::depth_to_vertex::depth_to_vertex;
use wgslam::cpu::vertex_to_normal::vertex_to_normal;
use wgslam::geometry::camera::Intrinsics;
use wgslam::layout::map::SurfelMap;
use wgslam::layout::{Camera, NormalParams, PreprocessParams};
use wgslam::render;

/// Ground-truth poses (`t_cam_to_world`) of the bundled frames that have one, in frame
/// order (frame 0 has none, so `[0]` is frame 1).
fn gt_poses(root: &Path) -> Vec<(usize, DMat4)> {
    load_gt(root)
        .into_iter()
        .enumerate()
        .filter_map(|(i, t)| Some((i, t?)))
        .collect()
}

/// Intrinsics, then camera-frame vertex, normal and colour maps (row-major `[f32; 4]`).
type Maps = (Intrinsics, Vec<[f32; 4]>, Vec<[f32; 4]>, Vec<[f32; 4]>);

/// Camera-frame vertex, normal and colour maps of frame `i`, downsampled by `stride`.
fn frame_maps(root: &Path, i: usize, stride: u32) -> Maps {
    let k = Intrinsics::ICL_NUIM.downsampled(stride);
    let Frame { depth, rgba } = load_frame(root, i);
    let pp = PreprocessParams {
        camera: Camera::new(&k),
        raw_width: 640,
        raw_height: 480,
        stride,
        depth_scale: 5000.0,
        min_depth_m: 0.1,
        max_depth_m: 10.0,
        _pad0: 0,
        _pad1: 0,
    };
    let n = k.pixels();
    let (mut vmap, mut cmap, mut nmap) = (
        vec![[0.0f32; 4]; n],
        vec![[0.0f32; 4]; n],
        vec![[0.0f32; 4]; n],
    );
    depth_to_vertex(&mut [
        Binding::of(&pp),
        Binding::read(&depth),
        Binding::read(&rgba),
        Binding::write(&mut vmap),
        Binding::write(&mut cmap),
    ]);
    let np = NormalParams {
        width: k.width,
        height: k.height,
        max_depth_jump_m: 0.1,
        _pad: 0,
    };
    vertex_to_normal(&mut [
        Binding::of(&np),
        Binding::read(&vmap),
        Binding::write(&mut nmap),
        Binding::read(&vmap),
    ]);
    (k, vmap, nmap, cmap)
}

/// A surfel map from the bundled frames `frames` at their ground-truth poses (no fusion:
/// every pixel with a normal becomes a surfel; weight = position in `frames` + 1).
fn bundled_map(frames: &[usize], stride: u32) -> SurfelMap {
    let root = common::bundled_icl();
    let gt = gt_poses(&root);
    let mut map = SurfelMap::default();
    for (fi, &i) in frames.iter().enumerate() {
        let t = gt.iter().find(|(j, _)| *j == i).expect("gt pose").1;
        let (_, vmap, nmap, cmap) = frame_maps(&root, i, stride);
        for pix in 0..vmap.len() {
            if vmap[pix][3] > 0.0 && nmap[pix][3] > 0.0 {
                let p = t.transform_point3(DVec3::new(
                    vmap[pix][0] as f64,
                    vmap[pix][1] as f64,
                    vmap[pix][2] as f64,
                ));
                let n = t.transform_vector3(DVec3::new(
                    nmap[pix][0] as f64,
                    nmap[pix][1] as f64,
                    nmap[pix][2] as f64,
                ));
                map.push(
                    p.as_vec3().to_array(),
                    n.as_vec3().to_array(),
                    [cmap[pix][0], cmap[pix][1], cmap[pix][2]],
                    (fi + 1) as f32,
                    i as u32,
                );
            }
        }
    }
    map
}

/// Where to keep pictures, when asked.
fn out_dir() -> Option<PathBuf> {
    std::env::var_os("WGSLAM_RENDER_OUT").map(PathBuf::from)
}

fn keep(name: &str, img: &image::RgbImage) {
    if let Some(d) = out_dir() {
        std::fs::create_dir_all(&d).unwrap();
        render::write_png(&d.join(name), img).unwrap();
    }
}

/// Fraction of pixels that differ from `bg`.
fn coverage(img: &image::RgbImage, bg: [u8; 3]) -> f64 {
    img.pixels().filter(|p| p.0 != bg).count() as f64 / (img.width() * img.height()) as f64
}

pub fn tests() -> Vec<common::harness::Test> {
    [
        renderer::tests(),
        command::tests(),
        gpu::tests(),
        gaps::tests(),
    ]
    .into_iter()
    .flatten()
    .collect()
}
