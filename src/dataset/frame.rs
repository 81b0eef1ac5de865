//! One RGB-D frame decoded from its two PNG files, full resolution, row-major.
//!
//! Decoding only: no depth scaling, filtering or downsampling (depth stays raw `u16`).

use std::path::Path;

use image::{DynamicImage, ImageReader};

use crate::{Error, Result};

/// One frame as decoded from disk, full resolution, row-major (`index = v * width + u`).
#[derive(Debug, Clone, PartialEq)]
pub struct RawFrame {
    pub width: u32,
    pub height: u32,
    /// Raw depth, `width * height` values; metres = value / depth scale; 0 = invalid.
    pub depth: Vec<u16>,
    /// 8-bit RGB, `width * height` pixels.
    pub rgb: Vec<[u8; 3]>,
}

impl RawFrame {
    /// Number of pixels with a depth reading (non-zero).
    pub fn valid_depth_pixels(&self) -> usize {
        self.depth.iter().filter(|&&d| d != 0).count()
    }
}

fn decode(path: &Path, role: &str) -> Result<DynamicImage> {
    if !path.is_file() {
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("{role} image does not exist"),
            ),
        ));
    }
    let reader = ImageReader::open(path).map_err(|e| Error::io(path, e))?;
    let reader = reader
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    reader.decode().map_err(|e| Error::Image {
        path: path.to_path_buf(),
        what: format!("cannot decode {role} PNG (unreadable or truncated): {e}"),
    })
}

/// Human name of a decoded image's pixel format, for error messages.
fn describe(img: &DynamicImage) -> String {
    let c = img.color();
    format!(
        "{:?} ({} channel(s), {} bits per channel)",
        c,
        c.channel_count(),
        c.bits_per_pixel() / c.channel_count() as u16
    )
}

/// Decodes a depth PNG, which must be 16-bit single channel.
pub fn load_depth(path: &Path) -> Result<(u32, u32, Vec<u16>)> {
    match decode(path, "depth")? {
        DynamicImage::ImageLuma16(img) => {
            let (w, h) = img.dimensions();
            Ok((w, h, img.into_raw()))
        }
        other => Err(Error::Image {
            path: path.to_path_buf(),
            what: format!(
                "depth must be a 16-bit single-channel PNG, found {}",
                describe(&other)
            ),
        }),
    }
}

/// Decodes a colour PNG, which must be 8-bit RGB or RGBA (alpha is dropped).
pub fn load_rgb(path: &Path) -> Result<(u32, u32, Vec<[u8; 3]>)> {
    match decode(path, "colour")? {
        DynamicImage::ImageRgb8(img) => {
            let (w, h) = img.dimensions();
            let px = img.pixels().map(|p| p.0).collect();
            Ok((w, h, px))
        }
        DynamicImage::ImageRgba8(img) => {
            let (w, h) = img.dimensions();
            let px = img.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect();
            Ok((w, h, px))
        }
        other => Err(Error::Image {
            path: path.to_path_buf(),
            what: format!(
                "colour must be an 8-bit RGB or RGBA PNG, found {}",
                describe(&other)
            ),
        }),
    }
}

/// Decodes both images of a frame and checks their sizes against each other and against
/// the expected `(width, height)` of the intrinsics.
pub fn load_frame(rgb_path: &Path, depth_path: &Path, expected: (u32, u32)) -> Result<RawFrame> {
    let (dw, dh, depth) = load_depth(depth_path)?;
    let (cw, ch, rgb) = load_rgb(rgb_path)?;
    if (dw, dh) != (cw, ch) {
        return Err(Error::Image {
            path: rgb_path.to_path_buf(),
            what: format!(
                "colour image is {cw}x{ch} but its depth image {} is {dw}x{dh}",
                depth_path.display()
            ),
        });
    }
    if (dw, dh) != expected {
        return Err(Error::Image {
            path: depth_path.to_path_buf(),
            what: format!(
                "image is {dw}x{dh} but the intrinsics are for {}x{}",
                expected.0, expected.1
            ),
        });
    }
    Ok(RawFrame {
        width: dw,
        height: dh,
        depth,
        rgb,
    })
}
