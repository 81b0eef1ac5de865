//! A recording's image messages turned into a [`RawFrame`]'s pixels: depth from `16UC1`
//! (millimetres, kept as they are) or `32FC1` (metres, rounded to the sequence's depth
//! scale), colour from raw `rgb8`/`bgr8`/`rgba8`/`bgra8`/`mono8` or a JPEG/PNG
//! `CompressedImage`.
//!
//! Not a resampler: colour must have the depth image's size.

use super::msg::{self, Wire};

/// Why a message's pixels cannot be used, in words.
type Why = String;

/// The depth image's pixels as raw `u16` at `scale` units per metre: `16UC1` as it is;
/// `32FC1` metres times `scale`, rounded, with NaN, infinities, zero and negatives (no
/// reading) and values beyond 65535 units as 0.
pub fn depth_scaled(img: &msg::Image, scale: Option<f32>) -> Result<Vec<u16>, Why> {
    let (w, step) = (img.width as usize, img.step as usize);
    let mut out = Vec::with_capacity(w * img.height as usize);
    let rows = img.data.chunks_exact(step.max(1));
    match img.encoding.as_str() {
        "16UC1" => {
            for row in rows {
                out.extend(row[..2 * w].chunks_exact(2).map(|b| {
                    let b = [b[0], b[1]];
                    if img.big_endian {
                        u16::from_be_bytes(b)
                    } else {
                        u16::from_le_bytes(b)
                    }
                }));
            }
        }
        "32FC1" => {
            let scale = scale.ok_or("32FC1 depth needs a depth scale")?;
            for row in rows {
                out.extend(row[..4 * w].chunks_exact(4).map(|b| {
                    let b = [b[0], b[1], b[2], b[3]];
                    let m = if img.big_endian {
                        f32::from_be_bytes(b)
                    } else {
                        f32::from_le_bytes(b)
                    };
                    metres_to_raw(m, scale)
                }));
            }
        }
        other => {
            return Err(format!(
                "depth encoding {other:?} is not read (16UC1 millimetres or 32FC1 metres are)"
            ))
        }
    }
    Ok(out)
}

/// One `32FC1` depth value (metres) as raw units: 0 for no reading or out of range.
pub fn metres_to_raw(m: f32, scale: f32) -> u16 {
    let v = (f64::from(m) * f64::from(scale)).round();
    if v.is_finite() && v > 0.0 && v <= f64::from(u16::MAX) {
        v as u16
    } else {
        0
    }
}

/// An uncompressed colour image as RGB pixels.
pub fn color(img: &msg::Image) -> Result<Vec<[u8; 3]>, Why> {
    let (w, step) = (img.width as usize, img.step as usize);
    let bpp = msg::bytes_per_pixel(&img.encoding).unwrap_or(0) as usize;
    let pick: fn(&[u8]) -> [u8; 3] = match img.encoding.as_str() {
        "rgb8" | "rgba8" => |p| [p[0], p[1], p[2]],
        "bgr8" | "bgra8" => |p| [p[2], p[1], p[0]],
        "mono8" | "8UC1" => |p| [p[0]; 3],
        other => {
            return Err(format!(
                "colour encoding {other:?} is not read (rgb8, bgr8, rgba8, bgra8, mono8 are)"
            ))
        }
    };
    let mut out = Vec::with_capacity(w * img.height as usize);
    for row in img.data.chunks_exact(step.max(1)) {
        out.extend(row[..bpp * w].chunks_exact(bpp).map(pick));
    }
    Ok(out)
}

/// A JPEG or PNG `CompressedImage` decoded to RGB: `(width, height, pixels)`.
pub fn compressed_color(c: &msg::Compressed) -> Result<(u32, u32, Vec<[u8; 3]>), Why> {
    if c.format.contains("compressedDepth") {
        return Err("compressedDepth images are not read as colour".into());
    }
    let path = std::path::Path::new("message");
    crate::dataset::frame::check_jpeg_end(c.data, path, "colour").map_err(|e| e.to_string())?;
    let mut reader = image::ImageReader::new(std::io::Cursor::new(c.data))
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    let side = crate::dataset::frame::MAX_IMAGE_SIDE_PX;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(side);
    limits.max_image_height = Some(side);
    reader.limits(limits);
    let img = reader
        .decode()
        .map_err(|e| format!("cannot decode the {:?} image: {e}", c.format))?;
    let img = match img {
        image::DynamicImage::ImageLuma8(g) => {
            image::DynamicImage::ImageRgb8(image::DynamicImage::ImageLuma8(g).to_rgb8())
        }
        other => other,
    };
    crate::dataset::frame::rgb_of(img, path).map_err(|e| e.to_string())
}

/// Colour from either message type, as RGB of `(width, height)`.
pub fn any_color(
    bytes: &[u8],
    wire: Wire,
    compressed: bool,
) -> Result<(u32, u32, Vec<[u8; 3]>), Why> {
    if compressed {
        compressed_color(&msg::compressed(bytes, wire)?)
    } else {
        let img = msg::image(bytes, wire)?;
        Ok((img.width, img.height, color(&img)?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_metres_round_to_raw_units_and_no_reading_is_zero() {
        assert_eq!(metres_to_raw(1.0, 5000.0), 5000);
        assert_eq!(metres_to_raw(0.0012, 1000.0), 1);
        assert_eq!(metres_to_raw(f32::NAN, 5000.0), 0);
        assert_eq!(metres_to_raw(-1.0, 5000.0), 0);
        assert_eq!(metres_to_raw(14.0, 5000.0), 0, "beyond 65535 units");
        // Millimetre depth stored as float metres comes back exactly at either scale.
        for mm in [1u16, 999, 4095, 13107] {
            let m = f32::from(mm) / 1000.0;
            assert_eq!(metres_to_raw(m, 1000.0), mm);
            assert_eq!(u32::from(metres_to_raw(m, 5000.0)), 5 * u32::from(mm));
        }
    }
}
