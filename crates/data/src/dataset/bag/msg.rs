//! The three ROS messages a recording is read for, decoded by hand from their wire bytes:
//! `sensor_msgs/Image`, `sensor_msgs/CompressedImage` and `sensor_msgs/CameraInfo` (up to
//! its `K`), in ROS 1's serialisation (packed little-endian, `.bag`) or ROS 2's CDR (aligned,
//! after a 4-byte encapsulation header; `.mcap` and `.db3`).
//!
//! Bounded: every length is checked against the bytes left before anything is sliced or
//! allocated, and an image's size must agree with its width, height and step. Not a
//! general ROS decoder: other message types are never decoded.

/// How a message's bytes are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wire {
    /// ROS 1: little-endian, no alignment, `Header` starts with a `uint32 seq`.
    Ros1,
    /// ROS 2 CDR (XCDR1): encapsulation header, then fields aligned to their size
    /// relative to the end of that header; byte order from the header.
    Cdr,
}

/// A message's header stamp, seconds.
pub type Stamp = f64;

/// `sensor_msgs/Image`, its pixels still in their encoding.
#[derive(Debug, Clone, PartialEq)]
pub struct Image<'a> {
    pub stamp: Stamp,
    pub height: u32,
    pub width: u32,
    pub encoding: String,
    pub big_endian: bool,
    /// Bytes per row (at least `width` times the encoding's pixel size).
    pub step: u32,
    pub data: &'a [u8],
}

/// `sensor_msgs/CompressedImage`: `format` (e.g. `jpeg`, `png`, `16UC1; png`) and the file's
/// bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct Compressed<'a> {
    pub stamp: Stamp,
    pub format: String,
    pub data: &'a [u8],
}

/// The part of `sensor_msgs/CameraInfo` read: size, distortion and `K` (row-major 3x3).
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    pub height: u32,
    pub width: u32,
    pub distortion_model: String,
    pub d: Vec<f64>,
    pub k: [f64; 9],
}

/// Why a message does not decode, in words (the caller adds the topic and file).
pub type Why = String;

/// A cursor over one message's bytes; every read is checked against what is left.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// Where alignment counts from (after CDR's encapsulation header); `None` for ROS 1.
    align_base: Option<usize>,
    big_endian: bool,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8], wire: Wire) -> Result<Self, Why> {
        match wire {
            Wire::Ros1 => Ok(Reader {
                bytes,
                pos: 0,
                align_base: None,
                big_endian: false,
            }),
            Wire::Cdr => {
                let head = bytes.get(..4).ok_or("shorter than CDR's 4-byte header")?;
                let big_endian = match head[..2] {
                    [0, 0] => true,
                    [0, 1] => false,
                    _ => {
                        return Err(format!(
                            "not plain CDR (encapsulation {:02x}{:02x}; XCDR2 and PL_CDR are \
                             not read)",
                            head[0], head[1]
                        ))
                    }
                };
                Ok(Reader {
                    bytes,
                    pos: 4,
                    align_base: Some(4),
                    big_endian,
                })
            }
        }
    }

    fn align(&mut self, n: usize) -> Result<(), Why> {
        if let Some(base) = self.align_base {
            let rel = self.pos - base;
            let pad = (n - rel % n) % n;
            self.take(pad)?;
        }
        Ok(())
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], Why> {
        let left = self.bytes.len() - self.pos;
        if n > left {
            return Err(format!(
                "cut short: a field needs {n} bytes at offset {} but {left} are left",
                self.pos
            ));
        }
        let out = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    fn u8(&mut self) -> Result<u8, Why> {
        Ok(self.take(1)?[0])
    }

    /// A number of `N` bytes, aligned to `N`, in the message's byte order.
    fn number<const N: usize, T>(
        &mut self,
        from_le: fn([u8; N]) -> T,
        from_be: fn([u8; N]) -> T,
    ) -> Result<T, Why> {
        self.align(N)?;
        let b: [u8; N] = self.take(N)?.try_into().expect("N bytes");
        Ok(if self.big_endian {
            from_be(b)
        } else {
            from_le(b)
        })
    }

    fn u32(&mut self) -> Result<u32, Why> {
        self.number(u32::from_le_bytes, u32::from_be_bytes)
    }

    fn f64(&mut self) -> Result<f64, Why> {
        self.number(f64::from_le_bytes, f64::from_be_bytes)
    }

    /// A length-prefixed byte array (`uint8[]`), borrowed.
    fn bytes(&mut self) -> Result<&'a [u8], Why> {
        let n = self.u32()? as usize;
        self.take(n)
    }

    /// A string: ROS 1 without a terminator, CDR with its NUL counted in the length.
    fn string(&mut self) -> Result<String, Why> {
        let mut raw = self.bytes()?;
        if self.align_base.is_some() {
            match raw.split_last() {
                Some((0, rest)) => raw = rest,
                _ => return Err("a CDR string lacks its terminating NUL".into()),
            }
        }
        std::str::from_utf8(raw)
            .map(str::to_string)
            .map_err(|_| "a string is not UTF-8".into())
    }

    /// `std_msgs/Header`: the stamp in seconds (ROS 1's `seq` and the frame id are skipped).
    fn header(&mut self) -> Result<Stamp, Why> {
        if self.align_base.is_none() {
            self.u32()?; // seq
        }
        let sec = self.u32()?;
        let nsec = self.u32()?;
        self.string()?; // frame_id
        let sec = if self.align_base.is_some() {
            f64::from(sec as i32) // builtin_interfaces/Time.sec is int32
        } else {
            f64::from(sec)
        };
        Ok(sec + f64::from(nsec) * 1e-9)
    }
}

/// Bytes per pixel of an `Image` encoding wgslam reads, `None` for others.
pub fn bytes_per_pixel(encoding: &str) -> Option<u32> {
    Some(match encoding {
        "16UC1" | "mono16" => 2,
        "32FC1" => 4,
        "rgb8" | "bgr8" => 3,
        "rgba8" | "bgra8" => 4,
        "mono8" | "8UC1" => 1,
        _ => return None,
    })
}

/// Decodes a `sensor_msgs/Image` and checks that its data holds `height` rows of `step`
/// bytes, each at least `width` pixels of its encoding.
pub fn image(bytes: &[u8], wire: Wire) -> Result<Image<'_>, Why> {
    let mut r = Reader::new(bytes, wire)?;
    let stamp = r.header()?;
    let height = r.u32()?;
    let width = r.u32()?;
    let encoding = r.string()?;
    let big_endian = r.u8()? != 0;
    let step = r.u32()?;
    let data = r.bytes()?;
    let img = Image {
        stamp,
        height,
        width,
        encoding,
        big_endian,
        step,
        data,
    };
    check_image_size(&img)?;
    Ok(img)
}

/// The checks of [`image`] on sizes: side cap, step against width, data against step.
fn check_image_size(img: &Image) -> Result<(), Why> {
    let cap = super::super::frame::MAX_IMAGE_SIDE_PX;
    if img.width == 0 || img.height == 0 || img.width.max(img.height) > cap {
        return Err(format!(
            "image is {}x{} pixels (at least 1 and at most {cap} on a side)",
            img.width, img.height
        ));
    }
    if let Some(bpp) = bytes_per_pixel(&img.encoding) {
        let row = u64::from(img.width) * u64::from(bpp);
        if u64::from(img.step) < row {
            return Err(format!(
                "step {} is less than a {}-pixel row of {} ({row} bytes)",
                img.step, img.width, img.encoding
            ));
        }
    }
    let need = u64::from(img.step) * u64::from(img.height);
    if img.data.len() as u64 != need {
        return Err(format!(
            "data is {} bytes but height {} x step {} is {need}",
            img.data.len(),
            img.height,
            img.step
        ));
    }
    Ok(())
}

/// Decodes a `sensor_msgs/CompressedImage`.
pub fn compressed(bytes: &[u8], wire: Wire) -> Result<Compressed<'_>, Why> {
    let mut r = Reader::new(bytes, wire)?;
    let stamp = r.header()?;
    let format = r.string()?;
    let data = r.bytes()?;
    Ok(Compressed {
        stamp,
        format,
        data,
    })
}

/// Most distortion coefficients read: rational_polynomial has 8, some drivers write 14.
const MAX_DISTORTION_COEFFS: u32 = 64;

/// Decodes a `sensor_msgs/CameraInfo` up to `K`.
pub fn camera_info(bytes: &[u8], wire: Wire) -> Result<CameraInfo, Why> {
    let mut r = Reader::new(bytes, wire)?;
    r.header()?;
    let height = r.u32()?;
    let width = r.u32()?;
    let distortion_model = r.string()?;
    let n = r.u32()?;
    if n > MAX_DISTORTION_COEFFS {
        return Err(format!(
            "{n} distortion coefficients (at most {MAX_DISTORTION_COEFFS} are read)"
        ));
    }
    let d = (0..n).map(|_| r.f64()).collect::<Result<Vec<_>, _>>()?;
    let mut k = [0.0; 9];
    for v in &mut k {
        *v = r.f64()?;
    }
    Ok(CameraInfo {
        height,
        width,
        distortion_model,
        d,
        k,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2x1 `16UC1` image in CDR, little-endian, written field by field.
    fn cdr_image(data_len: u32) -> Vec<u8> {
        let mut b = vec![0, 1, 0, 0];
        b.extend(5i32.to_le_bytes());
        b.extend(7u32.to_le_bytes());
        b.extend(2u32.to_le_bytes()); // "a\0"
        b.extend(b"a\0");
        b.extend([0, 0]); // align to 4
        b.extend(1u32.to_le_bytes()); // height
        b.extend(2u32.to_le_bytes()); // width
        b.extend(6u32.to_le_bytes());
        b.extend(b"16UC1\0");
        b.push(0); // is_bigendian
        b.push(0); // align
        b.extend(4u32.to_le_bytes()); // step
        b.extend(data_len.to_le_bytes());
        b.extend((0..data_len.min(64)).map(|i| i as u8));
        b
    }

    #[test]
    fn a_cdr_image_decodes_and_a_wrong_size_is_refused() {
        let bytes = cdr_image(4);
        let img = image(&bytes, Wire::Cdr).unwrap();
        assert_eq!((img.width, img.height, img.step), (2, 1, 4));
        assert_eq!(img.encoding, "16UC1");
        assert_eq!(img.stamp, 5.0 + 7e-9);
        assert_eq!(img.data, &[0, 1, 2, 3]);
        let e = image(&cdr_image(3), Wire::Cdr).unwrap_err();
        assert!(e.contains("height 1 x step 4"), "{e}");
        let e = image(&cdr_image(4_000_000_000), Wire::Cdr).unwrap_err();
        assert!(e.contains("cut short"), "{e}");
        for cut in 0..bytes.len() {
            assert!(image(&bytes[..cut], Wire::Cdr).is_err(), "cut at {cut}");
        }
    }
}
