//! PLY point clouds: writes the surfel map as binary little-endian PLY, and reads
//! vertex-only clouds (ASCII or binary little-endian, any property order and scalar types).
//!
//! Not a mesh library: faces and other elements are skipped, never returned. Big-endian
//! PLY is rejected with a clear message.

use std::io::Write;
use std::path::Path;

use crate::io::atomic::write_atomic;
use crate::layout::map::SurfelMap;
use crate::{Error, Result};

/// Header of the files [`write_surfel_map`] writes, after the `element vertex N` line.
const SURFEL_PROPERTIES: &str = "property float x\nproperty float y\nproperty float z\n\
property float nx\nproperty float ny\nproperty float nz\n\
property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float weight\n";

/// Writes `map` as a binary little-endian PLY (atomically): one vertex per surfel with
/// `float x y z` (world frame, metres), `float nx ny nz` (unit normal), `uchar red green
/// blue` (rounded and clamped from the map's 0..255 floats) and `float weight`.
pub fn write_surfel_map(path: &Path, map: &SurfelMap) -> Result<()> {
    write_atomic(path, |w: &mut dyn Write| write_surfel_map_to(w, path, map))
}

/// The bytes of [`write_surfel_map`] into any writer (the browser build's downloads fill a
/// `Vec<u8>`); `path` names the file in errors.
pub fn write_surfel_map_to(w: &mut dyn Write, path: &Path, map: &SurfelMap) -> Result<()> {
    map.assert_consistent();
    let io = |e| Error::write(path, e);
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment wgslam surfel map (world frame, metres)\n\
         element vertex {}\n{SURFEL_PROPERTIES}end_header\n",
        map.len()
    )
    .map_err(io)?;
    // 31 bytes per vertex; one buffer per chunk keeps the writes large.
    let mut buf = Vec::with_capacity(31 * 4096);
    for i in 0..map.len() {
        let (p, n, c) = (map.position(i), map.normal(i), map.color(i));
        for v in [p[0], p[1], p[2], n[0], n[1], n[2]] {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        for v in [c[0], c[1], c[2]] {
            buf.push(v.round().clamp(0.0, 255.0) as u8);
        }
        buf.extend_from_slice(&map.weight(i).to_le_bytes());
        if buf.len() >= 31 * 4096 {
            w.write_all(&buf).map_err(io)?;
            buf.clear();
        }
    }
    w.write_all(&buf).map_err(io)?;
    Ok(())
}

/// A point cloud read from a PLY file: one entry per vertex in every present array.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlyCloud {
    /// `x y z` as stored (metres for files wgslam writes).
    pub positions: Vec<[f32; 3]>,
    /// `nx ny nz` when all three are present.
    pub normals: Option<Vec<[f32; 3]>>,
    /// `red green blue` when all three are present; integer types are taken as 0..255
    /// (16-bit divided by 257), float types as 0..1.
    pub colors: Option<Vec<[u8; 3]>>,
    /// `weight` when present.
    pub weights: Option<Vec<f32>>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Little-endian value at the start of `b` (`b.len() >= self.size()`).
    fn read_le(self, b: &[u8]) -> f64 {
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(b[..8].try_into().expect("8 bytes")),
        }
    }
}

#[derive(Debug, Clone)]
enum Property {
    Scalar { name: String, ty: Scalar },
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    BinaryLe,
}

/// Parses the header; returns the format, elements and the byte offset of the body.
fn parse_header(path: &Path, bytes: &[u8]) -> Result<(Format, Vec<Element>, usize)> {
    if !bytes.starts_with(b"ply\n") && !bytes.starts_with(b"ply\r\n") {
        return Err(Error::format(
            path,
            "not a PLY file (does not start with `ply`)",
        ));
    }
    let mut pos = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut lineno = 0;
    loop {
        let Some(nl) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(Error::format(path, "PLY header has no `end_header` line"));
        };
        let line = String::from_utf8_lossy(&bytes[pos..pos + nl])
            .trim()
            .to_string();
        pos += nl + 1;
        lineno += 1;
        let f: Vec<&str> = line.split_whitespace().collect();
        let bad = |what: &str| Error::parse(path, lineno, format!("{what}: {line:?}"));
        match f.first().copied() {
            Some("ply") if lineno == 1 => {}
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                format = Some(match f.get(1).copied() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::BinaryLe,
                    Some("binary_big_endian") => {
                        return Err(bad("big-endian PLY is not supported; convert it to \
                             binary_little_endian or ascii"))
                    }
                    _ => return Err(bad("unknown PLY format")),
                })
            }
            Some("element") => {
                let (Some(name), Some(count), 3) = (f.get(1), f.get(2), f.len()) else {
                    return Err(bad("expected `element <name> <count>`"));
                };
                let count = count
                    .parse()
                    .map_err(|_| bad("element count is not a whole number"))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| bad("property before any element"))?;
                let prop = if f.get(1) == Some(&"list") {
                    let (Some(c), Some(i), 5) = (f.get(2), f.get(3), f.len()) else {
                        return Err(bad(
                            "expected `property list <count type> <item type> <name>`",
                        ));
                    };
                    let count = Scalar::parse(c).ok_or_else(|| bad("unknown list count type"))?;
                    if count.is_float() {
                        return Err(bad("list count type must be an integer"));
                    }
                    let item = Scalar::parse(i).ok_or_else(|| bad("unknown list item type"))?;
                    Property::List { count, item }
                } else {
                    let (Some(t), Some(name), 3) = (f.get(1), f.get(2), f.len()) else {
                        return Err(bad("expected `property <type> <name>`"));
                    };
                    let ty = Scalar::parse(t).ok_or_else(|| bad("unknown property type"))?;
                    Property::Scalar {
                        name: name.to_string(),
                        ty,
                    }
                };
                el.props.push(prop);
            }
            Some("end_header") => break,
            Some(_) => return Err(bad("unknown PLY header line")),
        }
    }
    let format = format.ok_or_else(|| Error::format(path, "PLY header has no `format` line"))?;
    Ok((format, elements, pos))
}

/// Column indices of the vertex properties we return.
struct Columns {
    xyz: [usize; 3],
    normal: Option<[usize; 3]>,
    color: Option<[usize; 3]>,
    weight: Option<usize>,
}

fn columns(path: &Path, vertex: &Element) -> Result<(Columns, Vec<Scalar>)> {
    let mut types = Vec::new();
    let mut names = Vec::new();
    for p in &vertex.props {
        match p {
            Property::Scalar { name, ty } => {
                names.push(name.as_str());
                types.push(*ty);
            }
            Property::List { .. } => {
                return Err(Error::format(
                    path,
                    "list properties on the vertex element are not supported",
                ))
            }
        }
    }
    let find = |n: &str| names.iter().position(|&x| x == n);
    let find3 = |a: [&str; 3]| Some([find(a[0])?, find(a[1])?, find(a[2])?]);
    let xyz = find3(["x", "y", "z"]).ok_or_else(|| {
        Error::format(
            path,
            format!(
                "vertex element has no x, y and z properties (has: {})",
                names.join(" ")
            ),
        )
    })?;
    let cols = Columns {
        xyz,
        normal: find3(["nx", "ny", "nz"]),
        color: find3(["red", "green", "blue"])
            .or_else(|| find3(["diffuse_red", "diffuse_green", "diffuse_blue"])),
        weight: find("weight"),
    };
    Ok((cols, types))
}

fn to_color(v: f64, ty: Scalar) -> u8 {
    let v = match ty {
        Scalar::F32 | Scalar::F64 => v * 255.0,
        Scalar::U16 | Scalar::I16 => v / 257.0,
        _ => v,
    };
    v.round().clamp(0.0, 255.0) as u8
}

/// Reads the vertices of a PLY file (ASCII or binary little-endian). Elements before the
/// vertex element are skipped (including list properties), elements after it are ignored.
/// Errors: not a PLY, big-endian, bad header line (with line number), no vertex element or
/// no `x y z`, truncated body (byte offset in binary files, line in ASCII ones).
pub fn read_ply(path: &Path) -> Result<PlyCloud> {
    let bytes = crate::io::input::read_input(path)?;
    let (format, elements, body) = parse_header(path, &bytes)?;
    let vi = elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| Error::format(path, "PLY file has no `vertex` element"))?;
    let (cols, types) = columns(path, &elements[vi])?;
    let n = elements[vi].count;
    // Every value takes at least one byte of the body (two in ASCII): reserve no more than
    // the file can hold, whatever the header declares.
    let mut rows: Vec<f64> = Vec::with_capacity(
        n.saturating_mul(types.len())
            .min(bytes.len().saturating_sub(body)),
    );
    match format {
        Format::BinaryLe => {
            let pos = skip_binary_elements(path, &bytes, body, &elements[..vi])?;
            read_binary_vertices(path, &bytes, pos, n, &types, &mut rows)?;
        }
        Format::Ascii => {
            read_ascii_vertices(path, &bytes, body, &elements[..vi], n, &types, &mut rows)?;
        }
    }
    Ok(cloud_from_rows(&rows, n, &cols, &types))
}

/// Bytes of a PLY file [`ply_read_bytes`] reads to find its header: a header is tens of
/// lines (a few hundred bytes); 64 KiB leaves room for long comments.
pub const HEADER_PROBE_BYTES: u64 = 64 << 10;

/// Bytes of memory [`read_ply`] needs for `path`, from its header alone: the file itself,
/// every vertex value as an `f64` while parsing, and 32 bytes a vertex for the cloud it
/// returns. `None` when no header ends within [`HEADER_PROBE_BYTES`] (then [`read_ply`]
/// gives the error). Lets a caller refuse a file too large to hold before reading it.
pub fn ply_read_bytes(path: &Path) -> Result<Option<u64>> {
    use std::io::Read;
    let (file, len) = crate::io::input::open_kind(path, crate::io::input::InputKind::Cloud)?;
    let mut head = Vec::new();
    file.take(HEADER_PROBE_BYTES)
        .read_to_end(&mut head)
        .map_err(|e| Error::io(path, e))?;
    let Ok((_, elements, _)) = parse_header(path, &head) else {
        return Ok(None);
    };
    let Some(vertex) = elements.iter().find(|e| e.name == "vertex") else {
        return Ok(None);
    };
    let values = (vertex.count as u64).saturating_mul(vertex.props.len() as u64);
    Ok(Some(
        len.saturating_add(values.saturating_mul(8))
            .saturating_add((vertex.count as u64).saturating_mul(32)),
    ))
}

/// The error for a binary body that ends before byte offset `at`, which `what` needs.
fn truncated_error(path: &Path, file_len: usize, at: usize, what: &str) -> Error {
    Error::format(
        path,
        format!("truncated PLY body: {what} needs bytes up to offset {at}, file has {file_len}"),
    )
}

/// Skips the binary records of `elements` (those before the vertex element) from byte
/// offset `pos`; returns the offset just after them.
fn skip_binary_elements(
    path: &Path,
    bytes: &[u8],
    mut pos: usize,
    elements: &[Element],
) -> Result<usize> {
    let truncated = |at: usize, what: &str| truncated_error(path, bytes.len(), at, what);
    for el in elements {
        // Scalar properties only: a fixed record size, skipped in one step.
        let fixed: Option<usize> = el
            .props
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => Some(ty.size()),
                Property::List { .. } => None,
            })
            .sum();
        if let Some(row) = fixed {
            pos = el
                .count
                .checked_mul(row)
                .and_then(|b| b.checked_add(pos))
                .filter(|&end| end <= bytes.len())
                .ok_or_else(|| {
                    Error::format(
                        path,
                        format!(
                            "truncated PLY body: {} `{}` records of {row} bytes from \
                             byte offset {pos} do not fit in the file's {} bytes",
                            el.count,
                            el.name,
                            bytes.len()
                        ),
                    )
                })?;
            continue;
        }
        for _ in 0..el.count {
            // Each record takes at least a byte: the loop ends with the file.
            if pos > bytes.len() {
                return Err(truncated(pos, &format!("element {}", el.name)));
            }
            for p in &el.props {
                match p {
                    Property::Scalar { ty, .. } => pos += ty.size(),
                    Property::List { count, item } => {
                        let end = pos + count.size();
                        let b = bytes
                            .get(pos..end)
                            .ok_or_else(|| truncated(end, &format!("element {}", el.name)))?;
                        let k = count.read_le(b);
                        if k < 0.0 {
                            return Err(Error::format(
                                path,
                                format!("negative list length at byte offset {pos}"),
                            ));
                        }
                        pos = (k as usize)
                            .checked_mul(item.size())
                            .and_then(|b| b.checked_add(end))
                            .unwrap_or(usize::MAX);
                    }
                }
            }
        }
        if pos > bytes.len() {
            return Err(truncated(pos, &format!("element {}", el.name)));
        }
    }
    Ok(pos)
}

/// Appends the `n` binary vertex records from byte offset `pos` to `rows`, one f64 per
/// property of `types`.
fn read_binary_vertices(
    path: &Path,
    bytes: &[u8],
    pos: usize,
    n: usize,
    types: &[Scalar],
    rows: &mut Vec<f64>,
) -> Result<()> {
    let truncated = |at: usize, what: &str| truncated_error(path, bytes.len(), at, what);
    let stride: usize = types.iter().map(|t| t.size()).sum();
    let end = n
        .checked_mul(stride)
        .and_then(|b| b.checked_add(pos))
        .unwrap_or(usize::MAX);
    if end > bytes.len() {
        return Err(truncated(end, &format!("{n} vertices of {stride} bytes")));
    }
    for v in 0..n {
        let mut at = pos + v * stride;
        for ty in types {
            rows.push(ty.read_le(&bytes[at..]));
            at += ty.size();
        }
    }
    Ok(())
}

/// Appends the `n` ASCII vertex lines to `rows`, one f64 per property of `types`, after
/// skipping the lines of `before` (the elements before the vertex element). The body
/// starts at byte `body`; errors name the line in the file.
fn read_ascii_vertices(
    path: &Path,
    bytes: &[u8],
    body: usize,
    before: &[Element],
    n: usize,
    types: &[Scalar],
    rows: &mut Vec<f64>,
) -> Result<()> {
    let text = std::str::from_utf8(&bytes[body..])
        .map_err(|_| Error::format(path, "ASCII PLY body is not valid UTF-8"))?;
    let header_lines = bytes[..body].iter().filter(|&&b| b == b'\n').count();
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (header_lines + i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty());
    let skip = before.iter().fold(0usize, |a, e| a.saturating_add(e.count));
    for _ in 0..skip {
        lines.next().ok_or_else(|| {
            Error::format(path, "truncated PLY body: ends before the vertex element")
        })?;
    }
    for v in 0..n {
        let (lineno, line) = lines.next().ok_or_else(|| {
            Error::format(
                path,
                format!("truncated PLY body: {n} vertices declared, only {v} found"),
            )
        })?;
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() != types.len() {
            return Err(Error::parse(
                path,
                lineno,
                format!(
                    "expected {} values per vertex, found {}",
                    types.len(),
                    f.len()
                ),
            ));
        }
        for s in f {
            let x: f64 = s
                .parse()
                .map_err(|_| Error::parse(path, lineno, format!("{s:?} is not a number")))?;
            rows.push(x);
        }
    }
    Ok(())
}

/// The cloud from the vertex table `rows` (`n` rows of `types.len()` values): positions,
/// and normals, colours (as 8-bit) and weights where `cols` finds them.
fn cloud_from_rows(rows: &[f64], n: usize, cols: &Columns, types: &[Scalar]) -> PlyCloud {
    let m = types.len();
    let get3 = |r: usize, c: [usize; 3]| {
        [
            rows[r * m + c[0]] as f32,
            rows[r * m + c[1]] as f32,
            rows[r * m + c[2]] as f32,
        ]
    };
    PlyCloud {
        positions: (0..n).map(|r| get3(r, cols.xyz)).collect(),
        normals: cols.normal.map(|c| (0..n).map(|r| get3(r, c)).collect()),
        colors: cols.color.map(|c| {
            (0..n)
                .map(|r| [0, 1, 2].map(|k| to_color(rows[r * m + c[k]], types[c[k]])))
                .collect()
        }),
        weights: cols
            .weight
            .map(|c| (0..n).map(|r| rows[r * m + c] as f32).collect()),
    }
}
