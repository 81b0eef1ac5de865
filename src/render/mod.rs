//! Headless pictures of point clouds: the fused map seen from a virtual camera (colour,
//! normals, weight or depth), and before/after overlays of two ICP point clouds.
//!
//! Surfels are drawn as small discs (a fixed world radius projected, clamped to a few
//! pixels) into a 64-bit depth|index map (`render_splat`), then each pixel is shaded from
//! its winning surfel (`render_resolve`). The CPU twins in `src/cpu/render_*.rs` run here;
//! the GPU pass lives in [`gpu`]. This module knows cameras, views and images, not files
//! other than the PNG it is asked to write; trajectory plots are in `crate::plot`.
//!
//! Virtual cameras use the pinhole model of [`Intrinsics`] with `fy > 0` (x right, y down,
//! z ahead); a dataset camera with negative `fy` can be passed as is to render what it saw.

pub mod gpu;
pub mod layout;
pub mod outputs;

use std::path::Path;

use glam::{DMat3, DMat4, DVec3};
use image::RgbImage;

use crate::camera::Intrinsics;
use crate::cpu::render_resolve::render_resolve;
use crate::cpu::render_splat::render_splat;
use crate::layout::gpu_mat4;
use crate::map::SurfelMap;
use crate::se3;
use crate::{Error, Result};
use layout::{RenderParams, VIEW_COLOR, VIEW_DEPTH, VIEW_NORMALS, VIEW_WEIGHT};

/// Largest accepted image side, pixels.
pub const MAX_SIDE_PX: u32 = 16384;
/// Largest accepted image for the CPU renderer, pixels (the index map is 8 bytes a pixel,
/// so 64 Mpx is 512 MiB; the GPU is further bounded by its storage-binding limit).
pub const MAX_PIXELS: u64 = 1 << 26;
/// Default image size of the renders `wgslam run` writes, pixels.
pub const DEFAULT_SIZE: (u32, u32) = (960, 720);
/// Horizontal field of view of framing cameras, degrees.
pub const FRAMING_FOV_DEG: f64 = 60.0;
/// Elevation of the default viewpoint above the horizontal, degrees.
pub const DEFAULT_ELEVATION_DEG: f64 = 35.0;
/// Fraction of points ignored at each end of every axis when framing (stray surfels far
/// from the scene would otherwise shrink it to a dot).
pub const FRAMING_OUTLIER_FRACTION: f64 = 0.005;
/// Extra distance of a framing camera, as a fraction of the framed extent (a border).
pub const FRAMING_MARGIN: f64 = 0.08;
/// Colour of the source cloud in overlays (orange), RGB.
pub const SOURCE_RGB: [u8; 3] = [245, 130, 32];
/// Colour of the target cloud in overlays (blue), RGB.
pub const TARGET_RGB: [u8; 3] = [40, 110, 230];

/// What a pixel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum View {
    /// The surfel colour.
    Color,
    /// The world-frame normal as RGB, `(n + 1) / 2`.
    Normals,
    /// The fused weight, dark blue (low) to yellow (the map's largest).
    Weight,
    /// The camera depth, yellow (near) to dark blue (far).
    Depth,
}

impl View {
    /// The `RenderParams::view` code.
    pub fn code(self) -> u32 {
        match self {
            View::Color => VIEW_COLOR,
            View::Normals => VIEW_NORMALS,
            View::Weight => VIEW_WEIGHT,
            View::Depth => VIEW_DEPTH,
        }
    }

    /// Lower-case name, as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            View::Color => "color",
            View::Normals => "normals",
            View::Weight => "weight",
            View::Depth => "depth",
        }
    }

    /// Parses `color`/`colour`, `normals`, `weight`, `depth`.
    pub fn parse(s: &str) -> Result<View> {
        match s.to_ascii_lowercase().as_str() {
            "color" | "colour" | "rgb" => Ok(View::Color),
            "normals" | "normal" => Ok(View::Normals),
            "weight" | "weights" => Ok(View::Weight),
            "depth" => Ok(View::Depth),
            _ => Err(Error::Argument(format!(
                "unknown view `{s}` (expected color, normals, weight or depth)"
            ))),
        }
    }
}

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
}

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
        }
    }
}

/// Checks an image size against [`MAX_SIDE_PX`] and [`MAX_PIXELS`].
pub fn check_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::Argument(format!(
            "image size {width}x{height} is empty"
        )));
    }
    if width > MAX_SIDE_PX || height > MAX_SIDE_PX {
        return Err(Error::Argument(format!(
            "image size {width}x{height} exceeds {MAX_SIDE_PX} pixels per side"
        )));
    }
    if width as u64 * height as u64 > MAX_PIXELS {
        return Err(Error::Argument(format!(
            "image size {width}x{height} exceeds {MAX_PIXELS} pixels"
        )));
    }
    Ok(())
}

/// Parses `WxH` (e.g. `960x720`) and checks it with [`check_size`].
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let bad = || {
        Error::Argument(format!(
            "image size `{s}` is not WIDTHxHEIGHT (e.g. 960x720)"
        ))
    };
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    check_size(w, h)?;
    Ok((w, h))
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
        fx: k.fx,
        fy: k.fy,
        cx: k.cx,
        cy: k.cy,
        width: k.width,
        height: k.height,
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

/// The CPU twins' index map and packed pixels for `params` (unused attributes may be empty).
pub fn render_cpu_raw(params: &RenderParams, cloud: &Cloud) -> (Vec<u64>, Vec<u32>) {
    let n = params.width as usize * params.height as usize;
    let mut index_map = vec![0u64; n];
    render_splat(
        params,
        cloud.positions,
        cloud.normals.unwrap_or(&[]),
        &mut index_map,
    );
    let mut rgba = vec![0u32; n];
    render_resolve(
        params,
        &index_map,
        cloud.normals.unwrap_or(&[]),
        cloud.colors.unwrap_or(&[]),
        cloud.weights.unwrap_or(&[]),
        &mut rgba,
    );
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
    Ok(rgba_to_image(params.width, params.height, &rgba))
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

/// Intrinsics of a framing camera: `width` x `height`, [`FRAMING_FOV_DEG`] horizontally,
/// square pixels, `fy` negative when `fy_negative` (see [`look_rotation`]).
pub fn framing_intrinsics(width: u32, height: u32, fy_negative: bool) -> Intrinsics {
    let f = 0.5 * width as f64 / (0.5 * FRAMING_FOV_DEG.to_radians()).tan();
    Intrinsics {
        width,
        height,
        fx: f as f32,
        fy: if fy_negative { -f as f32 } else { f as f32 },
        cx: (width as f32 - 1.0) * 0.5,
        cy: (height as f32 - 1.0) * 0.5,
    }
}

/// Camera-to-world rotation of a camera looking along `forward` (camera z) with `up` up in
/// the image and x to the right. With `fy > 0` image up is camera -y; with `fy < 0` (the
/// ICL-NUIM convention) it is +y. Datasets differ in handedness, so a virtual camera takes
/// the sign of its dataset's `fy`: the other sign would show the scene mirrored.
/// `None` when the two directions are parallel or not finite.
pub fn look_rotation(forward: DVec3, up: DVec3, fy_negative: bool) -> Option<DMat3> {
    let z = forward.try_normalize()?;
    let up_ortho = (up - z * up.dot(z)).try_normalize()?;
    let y = if fy_negative { up_ortho } else { -up_ortho };
    let x = y.cross(z);
    Some(DMat3::from_cols(x, y, z))
}

/// Robust axis-aligned bounds of the finite points: the [`FRAMING_OUTLIER_FRACTION`] and
/// `1 - FRAMING_OUTLIER_FRACTION` quantiles per axis. `None` without finite points.
pub fn robust_bounds(positions: &[[f32; 4]]) -> Option<(DVec3, DVec3)> {
    let mut axes: [Vec<f32>; 3] = Default::default();
    for p in positions {
        if p[0].is_finite() && p[1].is_finite() && p[2].is_finite() {
            for (a, axis) in axes.iter_mut().enumerate() {
                axis.push(p[a]);
            }
        }
    }
    let n = axes[0].len();
    if n == 0 {
        return None;
    }
    let lo_i = ((n - 1) as f64 * FRAMING_OUTLIER_FRACTION).floor() as usize;
    let hi_i = ((n - 1) as f64 * (1.0 - FRAMING_OUTLIER_FRACTION)).ceil() as usize;
    let mut lo = [0.0f64; 3];
    let mut hi = [0.0f64; 3];
    for (a, axis) in axes.iter_mut().enumerate() {
        lo[a] = *axis.select_nth_unstable_by(lo_i, f32::total_cmp).1 as f64;
        hi[a] = *axis.select_nth_unstable_by(hi_i, f32::total_cmp).1 as f64;
    }
    Some((DVec3::from(lo), DVec3::from(hi)))
}

/// A camera of `width` x `height` looking along `forward` (with `up` up in the image) that
/// frames the robust bounds of `positions` (taken in the view's own axes): centred on them,
/// and as close as it can be while each point inside them stays in the picture. `fy_negative`:
/// the sign convention of the data's camera (see [`look_rotation`]).
pub fn framing_camera(
    positions: &[[f32; 4]],
    width: u32,
    height: u32,
    forward: DVec3,
    up: DVec3,
    fy_negative: bool,
) -> Result<RenderCamera> {
    check_size(width, height)?;
    let rot = look_rotation(forward, up, fy_negative)
        .ok_or_else(|| Error::Argument("view direction and up direction are parallel".into()))?;
    let k = framing_intrinsics(width, height, fy_negative);
    // Work in view-aligned coordinates (q = Rᵀ p: x right, y along the image's vertical, z
    // ahead), where framing is a 2-D fit.
    let rot_t = rot.transpose();
    let view_pts: Vec<[f32; 4]> = positions
        .iter()
        .map(|p| {
            let q = rot_t * DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            [q.x as f32, q.y as f32, q.z as f32, 1.0]
        })
        .collect();
    let (lo, hi) = robust_bounds(&view_pts)
        .ok_or_else(|| Error::Argument("the cloud has no finite point to frame".into()))?;
    let (cx, cy) = ((lo.x + hi.x) * 0.5, (lo.y + hi.y) * 0.5);
    let tan_x = 0.5 * width as f64 / k.fx as f64;
    let tan_y = 0.5 * height as f64 / k.fy.abs() as f64;
    // The camera sits on the line through (cx, cy) along z, as far forward as it can while
    // every point inside the robust bounds stays in the picture.
    let inside = |q: &DVec3| q.cmpge(lo).all() && q.cmple(hi).all();
    let z_cam = view_pts
        .iter()
        .map(|q| DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64))
        .filter(inside)
        .map(|q| q.z - ((q.x - cx).abs() / tan_x).max((q.y - cy).abs() / tan_y))
        .fold(f64::INFINITY, f64::min);
    // A small margin around the picture, and never closer than 5 cm to the nearest point.
    let margin = FRAMING_MARGIN * (hi - lo).max_element().max(0.05);
    let z_cam = z_cam.min(lo.z - 0.05) - margin;
    let eye = rot * DVec3::new(cx, cy, z_cam);
    Ok(RenderCamera {
        t_cam_to_world: se3::from_rt(rot, eye),
        intrinsics: k,
    })
}

/// The default viewpoint on a map: looking down at [`DEFAULT_ELEVATION_DEG`] with `up` as
/// the world's up direction, along `heading` (a horizontal direction; any direction is
/// projected onto the horizontal plane), framing the whole map. `fy_negative`: the sign
/// convention of the data's camera (see [`look_rotation`]).
pub fn default_camera(
    positions: &[[f32; 4]],
    width: u32,
    height: u32,
    up: DVec3,
    heading: DVec3,
    fy_negative: bool,
) -> Result<RenderCamera> {
    let up = up
        .try_normalize()
        .ok_or_else(|| Error::Argument("the up direction is zero".into()))?;
    let mut h = heading - up * heading.dot(up);
    if h.length() < 1e-9 {
        // Any horizontal direction will do; pick one from the world axes.
        h = up.any_orthonormal_vector();
    }
    let h = h.normalize();
    let e = DEFAULT_ELEVATION_DEG.to_radians();
    let forward = h * e.cos() - up * e.sin();
    framing_camera(positions, width, height, forward, up, fy_negative)
}

/// Up and heading of a trajectory's cameras (`t_cam_to_world` with the dataset intrinsics'
/// sign of `fy`): the mean image-up direction and the mean viewing direction, for
/// [`default_camera`]. `None` for an empty trajectory or when the means cancel out.
pub fn trajectory_view_hint(poses: &[DMat4], fy: f32) -> Option<(DVec3, DVec3)> {
    // Image up is camera -y when fy > 0 (v grows downwards), +y when fy < 0.
    let up_cam = if fy < 0.0 { DVec3::Y } else { DVec3::NEG_Y };
    let mut up = DVec3::ZERO;
    let mut fwd = DVec3::ZERO;
    for t in poses {
        up += t.transform_vector3(up_cam);
        fwd += t.transform_vector3(DVec3::Z);
    }
    Some((up.try_normalize()?, fwd.try_normalize()?))
}

/// Renders the before/after picture of two clouds: `target_pts` as they are and
/// `source_pts` moved by `t_source_to_target`, in [`TARGET_RGB`] and [`SOURCE_RGB`], from
/// `camera` (positions in the target frame, metres; `w` ignored). No back-face culling.
pub fn render_overlay(
    source_pts: &[[f32; 4]],
    target_pts: &[[f32; 4]],
    t_source_to_target: &DMat4,
    camera: &RenderCamera,
    settings: &RenderSettings,
) -> Result<RgbImage> {
    let (positions, colors) = overlay_cloud(source_pts, target_pts, t_source_to_target);
    let cloud = Cloud {
        positions: &positions,
        normals: None,
        colors: Some(&colors),
        weights: None,
    };
    render_cpu(&cloud, camera, View::Color, settings)
}

/// The merged overlay cloud: target points first, then the moved source points, with their
/// colours. Entries with `w <= 0` (invalid vertex-map pixels) are skipped.
pub fn overlay_cloud(
    source_pts: &[[f32; 4]],
    target_pts: &[[f32; 4]],
    t_source_to_target: &DMat4,
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
    let t = gpu_mat4(t_source_to_target);
    let mut positions = Vec::with_capacity(source_pts.len() + target_pts.len());
    let mut colors = Vec::with_capacity(positions.capacity());
    let rgb = |c: [u8; 3]| [c[0] as f32, c[1] as f32, c[2] as f32, 255.0];
    for p in target_pts.iter().filter(|p| p[3] > 0.0) {
        positions.push([p[0], p[1], p[2], 1.0]);
        colors.push(rgb(TARGET_RGB));
    }
    for p in source_pts.iter().filter(|p| p[3] > 0.0) {
        let q = crate::cpu::transform_point(&t, crate::cpu::xyz(*p));
        positions.push([q.x, q.y, q.z, 1.0]);
        colors.push(rgb(SOURCE_RGB));
    }
    (positions, colors)
}

/// A camera framing both clouds of an overlay (target frame), looking along `forward` with
/// `up` up. For an RGB-D pair, `forward = +z`, `up = -y` (or `+y` with `fy_negative` when
/// the dataset's `fy` is negative) shows them roughly as the target camera saw them.
pub fn overlay_camera(
    source_pts: &[[f32; 4]],
    target_pts: &[[f32; 4]],
    t_source_to_target: &DMat4,
    size: (u32, u32),
    forward: DVec3,
    up: DVec3,
    fy_negative: bool,
) -> Result<RenderCamera> {
    let (positions, _) = overlay_cloud(source_pts, target_pts, t_source_to_target);
    framing_camera(&positions, size.0, size.1, forward, up, fy_negative)
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
