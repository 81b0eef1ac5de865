//! Headless pictures of point clouds: the fused map seen from a virtual camera (colour,
//! normals, weight or depth), and before/after overlays of two ICP point clouds.
//!
//! Surfels are drawn as small discs (a fixed world radius projected, clamped to a few
//! pixels) into a 64-bit depth|index map (`render_splat`), then each pixel is shaded from
//! its winning surfel (`render_resolve`), in the order of the render plan
//! (`plan::render`). The CPU twins in `crates/core/src/cpu/render_*.rs` run here, through
//! the twins' engine by their registry rows; the GPU pass lives in [`gpu`]. This module
//! knows cameras, views and images, not files other than the PNG it is asked to write;
//! trajectory plots are in `crate::render::plot`.
//!
//! Submodules: `view` (what a pixel shows, image sizes), `framing` (virtual cameras
//! that frame a cloud), `overlay` (ICP before/after pictures), `outputs` (the pictures
//! a run writes), [`orbit`] (an interactive viewer's camera), [`gpu`] (the GPU pass; its parameter
//! struct is `crate::layout::render`).
//!
//! Virtual cameras use the pinhole model of [`Intrinsics`] with `fy > 0` (x right, y down,
//! z ahead); a dataset camera with negative `fy` can be passed as is to render what it saw.

pub(crate) mod framing;
pub mod gpu;
pub mod orbit;
pub mod outputs;
pub(crate) mod overlay;
pub mod plot;
pub(crate) mod view;

pub use framing::{
    default_camera, framing_camera, framing_intrinsics, look_rotation, robust_bounds,
    trajectory_view_hint, DEFAULT_ELEVATION_DEG, FRAMING_FOV_DEG, FRAMING_MARGIN,
    FRAMING_OUTLIER_FRACTION,
};
pub use overlay::{overlay_camera, overlay_cloud, render_overlay, SOURCE_RGB, TARGET_RGB};
pub use view::{check_size, parse_size, View, DEFAULT_SIZE, MAX_PIXELS, MAX_SIDE_PX};

use std::path::Path;

use glam::{DMat4, DVec3};
use image::RgbImage;

use crate::cpu::binding::Pool;
use crate::geometry::camera::Intrinsics;
use crate::geometry::se3;
use crate::layout::map::SurfelMap;
use crate::layout::render::RenderParams;
use crate::layout::{gpu_mat4, Camera};
use crate::{Error, Result};
use wgslam_core::cpu_backend::run_call;
use wgslam_core::plan::{self, RenderCall};

/// A point cloud to draw: positions and whichever attributes it has. All arrays have one
/// entry per point; positions and normals are world frame (`w` ignored), colours RGB 0..255.
#[derive(Debug, Clone, Copy)]
pub struct Cloud<'a> {
    pub positions: &'a [[f32; 4]],
    pub normals: Option<&'a [[f32; 4]]>,
    pub colors: Option<&'a [[f32; 4]]>,
    pub weights: Option<&'a [f32]>,
}

/// The whole fused map as a [`Cloud`] (all attributes present): positions, normals and
/// colours borrowed from the map's packed arrays (their `w` holds the weight and the last
/// frame, which the renderer ignores), the weights copied out of `position_weight`'s `w`
/// because the render kernels take them as an array of their own.
#[derive(Debug, Clone)]
pub struct MapCloud<'a> {
    map: &'a SurfelMap,
    weights: Vec<f32>,
}

impl<'a> MapCloud<'a> {
    /// Splits the weights out of `map`.
    pub fn new(map: &'a SurfelMap) -> MapCloud<'a> {
        map.assert_consistent();
        let weights = (0..map.len()).map(|i| map.weight(i)).collect();
        MapCloud { map, weights }
    }

    /// The cloud to draw.
    pub fn cloud(&self) -> Cloud<'_> {
        Cloud {
            positions: &self.map.position_weight,
            normals: Some(bytemuck::cast_slice(&self.map.normal_frame)),
            colors: Some(&self.map.color),
            weights: Some(&self.weights),
        }
    }
}

impl<'a> Cloud<'a> {
    /// Checks that every present attribute has one entry per point.
    pub fn check(&self) -> Result<()> {
        let n = self.positions.len();
        let bad = |what: &str, len: usize| {
            Error::Argument(format!("{what} has {len} entries for {n} points"))
        };
        if let Some(a) = self.normals.filter(|a| a.len() != n) {
            return Err(bad("normals", a.len()));
        }
        if let Some(a) = self.colors.filter(|a| a.len() != n) {
            return Err(bad("colors", a.len()));
        }
        if let Some(a) = self.weights.filter(|a| a.len() != n) {
            return Err(bad("weights", a.len()));
        }
        if n > u32::MAX as usize {
            return Err(Error::Capacity(format!(
                "{n} points do not fit 32-bit indices"
            )));
        }
        Ok(())
    }

    /// The view actually drawn for `wanted`: itself when the cloud has the attribute, else
    /// the depth view, with a sentence saying what is missing.
    pub fn usable_view(&self, wanted: View) -> (View, Option<String>) {
        let missing = match wanted {
            View::Color if self.colors.is_none() => Some("colours"),
            View::Normals if self.normals.is_none() => Some("normals"),
            View::Weight if self.weights.is_none() => Some("weights"),
            _ => None,
        };
        match missing {
            Some(what) => (
                View::Depth,
                Some(format!(
                    "the cloud has no {what}: drawing the {} view as a depth view instead",
                    wanted.name()
                )),
            ),
            None => (wanted, None),
        }
    }
}

/// A virtual camera: pose and pinhole intrinsics (the image size is `intrinsics.width` x
/// `intrinsics.height`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderCamera {
    /// Camera to world (metres).
    pub t_cam_to_world: DMat4,
    pub intrinsics: Intrinsics,
}

/// Drawing settings shared by every view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    /// World radius of one splat, metres.
    pub splat_radius_m: f32,
    /// Pixel radius bounds of one splat.
    pub min_radius_px: f32,
    pub max_radius_px: f32,
    /// Hide surfels whose normal faces away from the camera (needs normals; lets a
    /// viewpoint outside a room see in through its walls).
    pub cull_backfaces: bool,
    /// Depth range drawn, metres; `far_m = None` fits the cloud.
    pub near_m: f32,
    pub far_m: Option<f32>,
    /// Empty pixels, RGB.
    pub background: [u8; 3],
    /// Gap filling in `render_resolve` (see [`RenderParams::fill_gap_px`]); 0 turns it off.
    pub fill_gap_px: u32,
}

/// Default of [`RenderSettings::fill_gap_px`], pixels. Surfaces the input camera saw at a
/// grazing angle (a sofa seat, a floor, the tops of armrests) hold rows of surfels several
/// centimetres apart, which an elevated framing view shows as empty stripes between rows:
/// measured on the bundled frames' map at 960x720, the stripes are 1-5 pixels tall
/// (`tests/it/render/renderer.rs`, `gap_fill_closes_the_stripes`). Real holes of the map
/// (unseen surface) are wider and stay open.
pub const DEFAULT_FILL_GAP_PX: u32 = 6;

/// Largest [`RenderSettings::fill_gap_px`]: each empty pixel looks this far in four
/// directions, so the resolve pass's work grows with it; wider gaps are holes of the map.
pub const MAX_FILL_GAP_PX: u32 = 64;

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            splat_radius_m: 0.01,
            min_radius_px: 0.75,
            max_radius_px: 6.0,
            cull_backfaces: true,
            near_m: 0.05,
            far_m: None,
            background: [255, 255, 255],
            fill_gap_px: DEFAULT_FILL_GAP_PX,
        }
    }
}

/// The parameters of one render of `cloud` from `camera` (validated).
pub fn render_params(
    cloud: &Cloud,
    camera: &RenderCamera,
    view: View,
    settings: &RenderSettings,
) -> Result<RenderParams> {
    cloud.check()?;
    let k = &camera.intrinsics;
    check_size(k.width, k.height)?;
    if settings.fill_gap_px > MAX_FILL_GAP_PX {
        return Err(Error::Argument(format!(
            "gap filling of {} pixels is more than {MAX_FILL_GAP_PX}",
            settings.fill_gap_px
        )));
    }
    let (view, _) = cloud.usable_view(view);
    let t_world_to_cam = se3::inverse_rigid(&camera.t_cam_to_world);
    // Without a far plane the depth range is fitted to the cloud, so that the depth view's
    // ramp spans what is visible.
    let (near_m, far_m) = match settings.far_m {
        Some(f) => (settings.near_m, f),
        None => fit_depth_range(cloud.positions, &t_world_to_cam, settings.near_m),
    };
    if !(near_m > 0.0 && far_m > near_m) {
        return Err(Error::Argument(format!(
            "depth range ({near_m}, {far_m}] m is empty"
        )));
    }
    let weight_max = cloud
        .weights
        .map(|w| {
            w.iter()
                .copied()
                .filter(|x| x.is_finite())
                .fold(0.0f32, f32::max)
        })
        .unwrap_or(0.0);
    let bg = settings.background;
    Ok(RenderParams {
        t_world_to_cam: gpu_mat4(&t_world_to_cam),
        camera: Camera::new(k),
        surfel_count: cloud.positions.len() as u32,
        view: view.code(),
        splat_radius_m: settings.splat_radius_m,
        min_radius_px: settings.min_radius_px,
        max_radius_px: settings.max_radius_px.max(settings.min_radius_px),
        cull_backfaces: (settings.cull_backfaces && cloud.normals.is_some()) as u32,
        near_m,
        far_m,
        weight_max: if weight_max > 0.0 { weight_max } else { 1.0 },
        background: crate::layout::pack_rgba8(bg),
        fill_gap_px: settings.fill_gap_px,
        _pad0: 0,
    })
}

/// `(near, far)` camera depths (metres) just around every finite point in front of
/// `min_near_m`; `near` never below `min_near_m`, `far` at least just past it.
fn fit_depth_range(positions: &[[f32; 4]], t_world_to_cam: &DMat4, min_near_m: f32) -> (f32, f32) {
    let min_near = min_near_m as f64;
    let (lo, hi) = positions
        .iter()
        .map(|p| {
            let q = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            t_world_to_cam.transform_point3(q).z
        })
        .filter(|z| z.is_finite() && *z > min_near)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), z| {
            (lo.min(z), hi.max(z))
        });
    if hi <= 0.0 {
        // Nothing in front of the camera: any valid range draws nothing.
        return (min_near_m, min_near_m * 2.0);
    }
    // Margins so that the extreme points stay inside (near, far] after f32 rounding.
    ((lo * 0.99).max(min_near) as f32, (hi * 1.01) as f32)
}

/// Unpacks `r | g << 8 | b << 16 | a << 24` pixels into an RGB image.
pub fn rgba_to_image(width: u32, height: u32, rgba: &[u32]) -> RgbImage {
    assert_eq!(rgba.len(), width as usize * height as usize, "pixel count");
    let mut bytes = Vec::with_capacity(rgba.len() * 3);
    for &p in rgba {
        bytes.extend_from_slice(&[p as u8, (p >> 8) as u8, (p >> 16) as u8]);
    }
    RgbImage::from_raw(width, height, bytes).expect("buffer size matches the image size")
}

/// The CPU twins' index map and packed pixels for `params` (unused attributes may be
/// empty): the render plan (`plan::render`) through the twins' engine
/// (`cpu_backend::run_call`), over a pool named as the GPU pass's.
pub fn render_cpu_raw(params: &RenderParams, cloud: &Cloud) -> (Vec<u64>, Vec<u32>) {
    let n = params.camera.width as usize * params.camera.height as usize;
    let mut index_map = vec![0u64; n];
    let mut rgba = vec![0u32; n];
    for call in plan::render() {
        if call == RenderCall::ClearIndexMap {
            index_map.fill(0);
            continue;
        }
        let mut pool = Pool::new();
        pool.uniform("render", params);
        pool.read("positions", cloud.positions);
        pool.read("normals", cloud.normals.unwrap_or(&[]));
        pool.read("colors", cloud.colors.unwrap_or(&[]));
        pool.read("weights", cloud.weights.unwrap_or(&[]));
        pool.write("index_map", &mut index_map);
        pool.write("out_rgba", &mut rgba);
        run_call(call, pool);
    }
    (index_map, rgba)
}

/// Renders `cloud` from `camera` on the CPU. A view whose attribute the cloud lacks is drawn
/// as a depth view (see [`Cloud::usable_view`]).
pub fn render_cpu(
    cloud: &Cloud,
    camera: &RenderCamera,
    view: View,
    settings: &RenderSettings,
) -> Result<RgbImage> {
    let params = render_params(cloud, camera, view, settings)?;
    let (_, rgba) = render_cpu_raw(&params, cloud);
    Ok(rgba_to_image(
        params.camera.width,
        params.camera.height,
        &rgba,
    ))
}

/// Which implementation draws: the CPU twins, or the GPU pass on a borrowed context
/// (`wgslam render --backend`; `wgslam run` draws its pictures with the CPU twins).
#[derive(Debug, Clone, Copy)]
pub enum RenderBackend<'a> {
    Cpu,
    Gpu {
        ctx: &'a crate::gpu::GpuContext,
        kernels: &'a gpu::GpuRenderer,
    },
}

impl RenderBackend<'_> {
    /// `cpu` or `gpu`.
    pub fn name(&self) -> &'static str {
        match self {
            RenderBackend::Cpu => "cpu",
            RenderBackend::Gpu { .. } => "gpu",
        }
    }

    /// Renders `cloud` from `camera` (see [`render_cpu`]; both backends draw the same
    /// picture up to rounding at splat borders).
    pub fn render(
        &self,
        cloud: &Cloud,
        camera: &RenderCamera,
        view: View,
        settings: &RenderSettings,
    ) -> Result<RgbImage> {
        match self {
            RenderBackend::Cpu => render_cpu(cloud, camera, view, settings),
            RenderBackend::Gpu { ctx, kernels } => {
                kernels.render(ctx, cloud, camera, view, settings)
            }
        }
    }
}

/// Writes `image` as a PNG at `path`, completely or not at all (`io::atomic`).
pub fn write_png(path: &Path, image: &RgbImage) -> Result<()> {
    let mut png = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| Error::format(path, format!("PNG encoding failed: {e}")))?;
    crate::io::atomic::write_atomic(path, |w| {
        w.write_all(&png).map_err(|e| Error::write(path, e))
    })
}
