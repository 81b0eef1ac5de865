//! What a render shows and how big it may be: the [`View`] (colour, normals, weight,
//! depth) and image sizes (parsing `WxH`, the limits every renderer checks).

use crate::layout::render::{VIEW_COLOR, VIEW_DEPTH, VIEW_NORMALS, VIEW_WEIGHT};
use crate::{Error, Result};

/// Largest accepted image side, pixels.
pub const MAX_SIDE_PX: u32 = 16384;
/// Largest accepted image for the CPU renderer, pixels (the index map is 8 bytes a pixel,
/// so 64 Mpx is 512 MiB; the GPU is further bounded by its storage-binding limit).
pub const MAX_PIXELS: u64 = 1 << 26;
/// Default image size of the renders `wgslam run` writes, pixels.
pub const DEFAULT_SIZE: (u32, u32) = (960, 720);

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
