//! One RGB-D frame decoded from its two image files (16-bit PNG depth; PNG or JPEG colour),
//! at the depth image's full resolution, row-major.
//!
//! Decoding, the layout's "no reading" depth value set to 0, and colour from a camera of
//! another size resampled onto the depth image (the lens's distortion is removed after,
//! by `Sequence::load`); no depth scaling, filtering or downsampling (depth stays raw
//! `u16`).

use std::path::Path;

use image::{DynamicImage, ImageReader};

use super::source::Entry;
use super::FrameConventions;
use crate::geometry::camera::Intrinsics;
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

/// Checks that image `path` is a regular file: a missing one "does not exist", a folder
/// or a device says what it is instead.
pub(crate) fn check_image_file(path: &Path, what: &str) -> Result<()> {
    let why = match super::source::current().entry(path) {
        Ok(Entry::File(_)) => return Ok(()),
        Ok(Entry::Folder) => format!("{what} is a folder, not an image file"),
        Ok(Entry::Other) => format!("{what} is not a regular file (a device, a FIFO or a socket)"),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => format!("{what} does not exist"),
        Err(e) => return Err(Error::io(path, e)),
    };
    Err(Error::io(
        path,
        std::io::Error::new(std::io::ErrorKind::InvalidInput, why),
    ))
}

/// Largest accepted image width or height, pixels: 4x the widest depth or colour camera
/// these layouts come from (4K colour); a header claiming more is corrupt or hostile, and
/// decoding it would allocate gigabytes per frame.
pub const MAX_IMAGE_SIDE_PX: u32 = 16_384;

fn decode(path: &Path, role: &str) -> Result<DynamicImage> {
    check_image_file(path, &format!("{role} image"))?;
    let bytes = super::source::read(path, crate::io::input::InputKind::Image)?;
    check_jpeg_end(&bytes, path, role)?;
    let mut reader = ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE_PX);
    limits.max_image_height = Some(MAX_IMAGE_SIDE_PX);
    reader.limits(limits);
    reader.decode().map_err(|e| Error::Image {
        path: path.to_path_buf(),
        what: format!("cannot decode {role} image (unreadable or truncated): {e}"),
    })
}

/// How far from a JPEG's end its end-of-image marker may sit, bytes: some writers pad
/// after it; a file cut short has none in its tail (entropy-coded data never holds
/// `FF D9`, the encoder stuffs every `FF` with `00`).
const JPEG_END_WINDOW_BYTES: usize = 1024;

/// A JPEG (`FF D8` first) must end with its end-of-image marker (`FF D9`): the decoder
/// fills a truncated one with grey without an error (a file cut to a third decoded).
pub(crate) fn check_jpeg_end(bytes: &[u8], path: &Path, role: &str) -> Result<()> {
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return Ok(());
    }
    let tail = &bytes[bytes.len().saturating_sub(JPEG_END_WINDOW_BYTES)..];
    if tail.windows(2).any(|w| w == [0xFF, 0xD9]) {
        return Ok(());
    }
    Err(Error::Image {
        path: path.to_path_buf(),
        what: format!("{role} image is a JPEG cut short (no end-of-image marker)"),
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
    depth_of(decode(path, "depth")?, path)
}

/// A decoded depth image's pixels; `path` names it in errors.
fn depth_of(img: DynamicImage, path: &Path) -> Result<(u32, u32, Vec<u16>)> {
    match img {
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

/// Width and height of an image from its header, without decoding it.
pub fn image_size(path: &Path) -> Result<(u32, u32)> {
    check_image_file(path, "image")?;
    // The whole file: a page's files come whole, and one image per sequence is read so.
    let bytes = super::source::read(path, crate::io::input::InputKind::Image)?;
    let (w, h) = ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?
        .into_dimensions()
        .map_err(|e| Error::Image {
            path: path.to_path_buf(),
            what: format!("cannot read the image's size: {e}"),
        })?;
    if w.max(h) > MAX_IMAGE_SIDE_PX {
        return Err(Error::Image {
            path: path.to_path_buf(),
            what: format!("is {w}x{h} pixels, more than {MAX_IMAGE_SIDE_PX} on a side"),
        });
    }
    Ok((w, h))
}

/// A decoded colour image's pixels, which must be 8-bit RGB or RGBA (alpha is dropped);
/// `path` names it in errors.
pub(crate) fn rgb_of(img: DynamicImage, path: &Path) -> Result<(u32, u32, Vec<[u8; 3]>)> {
    match img {
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
                "colour must be an 8-bit RGB or RGBA image (PNG or JPEG), found {}",
                describe(&other)
            ),
        }),
    }
}

/// Colour of a camera with intrinsics `color_k` (an image of `color_k.width` x
/// `color_k.height`) seen at each pixel of a depth image with intrinsics `depth_k`,
/// assuming both cameras share their optical centre and axes (ScanNet's exports): each
/// depth pixel's ray is projected into the colour image and sampled bilinearly; rays that
/// leave the colour image get black.
pub fn resample_color(rgb: &[[u8; 3]], color_k: &Intrinsics, depth_k: &Intrinsics) -> Vec<[u8; 3]> {
    let (cw, ch) = (color_k.width as usize, color_k.height as usize);
    let mut out = Vec::with_capacity(depth_k.pixels());
    for v in 0..depth_k.height {
        let y = (v as f32 - depth_k.cy) / depth_k.fy;
        let vc = color_k.fy * y + color_k.cy;
        for u in 0..depth_k.width {
            let x = (u as f32 - depth_k.cx) / depth_k.fx;
            let uc = color_k.fx * x + color_k.cx;
            if !(uc >= 0.0 && vc >= 0.0 && uc <= (cw - 1) as f32 && vc <= (ch - 1) as f32) {
                out.push([0; 3]);
                continue;
            }
            out.push(bilinear(rgb, cw, ch, uc, vc));
        }
    }
    out
}

/// The colour at `(u, v)` (within half a pixel of the `w` x `h` image's pixel centres;
/// clamped onto them) interpolated from its four pixels.
pub(crate) fn bilinear(rgb: &[[u8; 3]], w: usize, h: usize, u: f32, v: f32) -> [u8; 3] {
    let (u, v) = (u.clamp(0.0, (w - 1) as f32), v.clamp(0.0, (h - 1) as f32));
    let (u0, v0) = (u.floor() as usize, v.floor() as usize);
    let (u1, v1) = ((u0 + 1).min(w - 1), (v0 + 1).min(h - 1));
    let (a, b) = (u - u0 as f32, v - v0 as f32);
    let px = |uu: usize, vv: usize| rgb[vv * w + uu];
    let mut c = [0u8; 3];
    for (i, ci) in c.iter_mut().enumerate() {
        let top = (1.0 - a) * px(u0, v0)[i] as f32 + a * px(u1, v0)[i] as f32;
        let bottom = (1.0 - a) * px(u0, v1)[i] as f32 + a * px(u1, v1)[i] as f32;
        *ci = ((1.0 - b) * top + b * bottom).round() as u8;
    }
    c
}

/// Decodes both images of a frame and checks their sizes against each other and against
/// the depth intrinsics `depth_k`; applies the layout's `conventions` (its "no reading"
/// depth value becomes 0; colour from a camera with its own intrinsics is resampled onto
/// the depth image). The images are read from the current source ([`super::source`]).
pub(crate) fn load_frame(
    rgb_path: &Path,
    depth_path: &Path,
    depth_k: &Intrinsics,
    conventions: &FrameConventions,
) -> Result<RawFrame> {
    let expected = (depth_k.width, depth_k.height);
    let (dw, dh, mut depth) = depth_of(decode(depth_path, "depth")?, depth_path)?;
    if let Some(invalid) = conventions.invalid_depth_raw {
        depth
            .iter_mut()
            .filter(|d| **d == invalid)
            .for_each(|d| *d = 0);
    }
    let (cw, ch, mut rgb) = rgb_of(decode(rgb_path, "colour")?, rgb_path)?;
    if (dw, dh) != expected {
        return Err(Error::Image {
            path: depth_path.to_path_buf(),
            what: format!(
                "image is {dw}x{dh} but the intrinsics are for {}x{}",
                expected.0, expected.1
            ),
        });
    }
    match &conventions.color_intrinsics {
        Some(color_k) => {
            if (cw, ch) != (color_k.width, color_k.height) {
                return Err(Error::Image {
                    path: rgb_path.to_path_buf(),
                    what: format!(
                        "colour image is {cw}x{ch} but the colour intrinsics are for {}x{}",
                        color_k.width, color_k.height
                    ),
                });
            }
            rgb = resample_color(&rgb, color_k, depth_k);
        }
        None if (dw, dh) != (cw, ch) => {
            return Err(Error::Image {
                path: rgb_path.to_path_buf(),
                what: format!(
                    "colour image is {cw}x{ch} but its depth image {} is {dw}x{dh} (and the \
                     layout gives no colour intrinsics to map one onto the other)",
                    depth_path.display()
                ),
            });
        }
        None => {}
    }
    Ok(RawFrame {
        width: dw,
        height: dh,
        depth,
        rgb,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resampling_a_double_size_colour_camera_picks_the_matching_pixels() {
        let depth_k = Intrinsics {
            width: 4,
            height: 2,
            fx: 2.0,
            fy: 2.0,
            cx: 1.5,
            cy: 0.5,
        };
        // The same field of view at twice the size: depth pixel (u, v) is colour pixel
        // (2u + 0.5, 2v + 0.5), halfway between four colour pixels.
        let color_k = Intrinsics {
            width: 8,
            height: 4,
            fx: 4.0,
            fy: 4.0,
            cx: 3.5,
            cy: 1.5,
        };
        let rgb: Vec<[u8; 3]> = (0..32)
            .map(|i| [(i % 8 * 10) as u8, (i / 8 * 10) as u8, 7])
            .collect();
        let out = resample_color(&rgb, &color_k, &depth_k);
        assert_eq!(out.len(), 8);
        assert_eq!(out[0], [5, 5, 7]);
        assert_eq!(out[4 + 3], [65, 25, 7]);
    }
}
