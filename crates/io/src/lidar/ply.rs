//! 3-D point clouds as PLY files (Turk 1994, the Stanford polygon format): ASCII and binary
//! little/big endian, `vertex` elements with `x y z` of any scalar type, an optional intensity
//! (`intensity` or CloudCompare's `scalar_intensity`) and any other scalar properties, which are
//! skipped. Plain, `.xz` or `.gz` ([`open_data_file`](crate::open_data_file)).
//!
//! ```
//! use chronomap_io::ply::{PlyFormat, decode_ply, encode_ply};
//! use chronomap_registration::Cloud;
//!
//! let cloud = Cloud::new(vec![[1.0, 2.0, 3.0], [-0.5, 0.25, 8.0]], Some(vec![7.0, 9.0]))?;
//! let bytes = encode_ply(&cloud, PlyFormat::BinaryLittleEndian);
//! assert_eq!(decode_ply("cloud.ply", &bytes[..])?, cloud);
//!
//! let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
//!             property float z\nend_header\n1 2 oops\n";
//! let err = decode_ply("bad.ply", text.as_bytes()).unwrap_err();
//! assert_eq!(err.to_string(), r#"bad.ply: line 8 (vertex 0), property z: "oops" is not a number"#);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Bounds: at most [`MAX_VERTICES`] vertices and [`MAX_ELEMENT_COUNT`] items per other
//! element, a header of at most [`MAX_HEADER_BYTES`], ASCII lines of at most
//! [`MAX_LINE_BYTES`]; memory grows with the data actually read, never with a count announced
//! in the header. In a plain (uncompressed) file the counts are also checked against the bytes
//! that follow the header before any item is read: an element announcing more items than those
//! bytes can hold is refused at its header line. A device such as `/dev/zero` is refused before
//! reading.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use chronomap_registration::{Cloud, MAX_POINTS};

/// The most vertices a PLY file may have (10⁸, [`MAX_POINTS`] of a cloud).
pub const MAX_VERTICES: u64 = MAX_POINTS as u64;
/// The most items of any other element (skipped, but counted).
pub const MAX_ELEMENT_COUNT: u64 = 100_000_000;
/// The longest header (bytes, `ply` to `end_header` included).
pub const MAX_HEADER_BYTES: usize = 64 * 1024;
/// The longest ASCII body line (bytes).
pub const MAX_LINE_BYTES: usize = 64 * 1024;
/// The most entries of a list property in an element that is skipped.
const MAX_LIST_LEN: u64 = 1 << 16;

/// What is wrong with a PLY file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlyErrorKind {
    /// Opening or reading failed.
    #[error("cannot {action}: {message}")]
    Io {
        /// `open` or `read`.
        action: &'static str,
        /// The system's message.
        message: String,
    },
    /// A header line is malformed or unsupported.
    #[error("line {line}: {reason}")]
    Header {
        /// 1-based header line.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// More vertices than the caller takes ([`read_ply_at_most`]), found in the header.
    #[error("line {line}: element vertex: {count} vertices, at most {max} are read here")]
    TooManyVertices {
        /// 1-based header line of the vertex element.
        line: usize,
        /// The vertices it announces.
        count: u64,
        /// The caller's bound.
        max: u64,
    },
    /// The file ends inside the data.
    #[error("{element} {index}, property {property}: the file ends here (truncated)")]
    Truncated {
        /// The element being read.
        element: String,
        /// Its 0-based item.
        index: u64,
        /// The property.
        property: String,
    },
    /// An ASCII value is not a number, or a number is not finite.
    #[error("{}, property {property}: {reason}", where_in_body(*line, *vertex))]
    Value {
        /// 1-based line of the file (0 in binary files and where no line applies).
        line: usize,
        /// 0-based vertex.
        vertex: u64,
        /// The property.
        property: String,
        /// What is wrong.
        reason: String,
    },
}

/// `line L (vertex V)` in text, `vertex V` in binary bodies.
fn where_in_body(line: usize, vertex: u64) -> String {
    if line == 0 {
        format!("vertex {vertex}")
    } else {
        format!("line {line} (vertex {vertex})")
    }
}

/// A PLY error: the file and what is wrong where.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {kind}")]
pub struct PlyError {
    /// The file as given.
    pub file: String,
    /// What and where.
    pub kind: PlyErrorKind,
}

/// Encoding of a PLY body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyFormat {
    /// Text, one vertex a line.
    Ascii,
    /// Binary, little endian.
    BinaryLittleEndian,
    /// Binary, big endian.
    BinaryBigEndian,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
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

    fn decode(self, b: &[u8], big: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().expect("sized slice");
                f64::from(if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                })
            }};
        }
        match self {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => num!(i16, 2),
            Scalar::U16 => num!(u16, 2),
            Scalar::I32 => num!(i32, 4),
            Scalar::U32 => num!(u32, 4),
            Scalar::F32 => num!(f32, 4),
            Scalar::F64 => num!(f64, 8),
        }
    }
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    scalar: Scalar,
    /// The count type of a list property.
    list: Option<Scalar>,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
    /// Its header line.
    line: usize,
}

impl Element {
    /// The fewest bytes one item takes: its scalars (a list's count alone) in binary, one
    /// digit and one separator per property in ASCII.
    fn min_item_bytes(&self, format: PlyFormat) -> u64 {
        match format {
            PlyFormat::Ascii => (2 * self.properties.len() as u64).max(1),
            _ => self
                .properties
                .iter()
                .map(|p| p.list.unwrap_or(p.scalar).size() as u64)
                .sum(),
        }
    }
}

struct Header {
    format: PlyFormat,
    elements: Vec<Element>,
    lines: usize,
    /// Bytes from `ply` to the end of `end_header`'s line.
    bytes: usize,
}

/// Reads the PLY file `path` (plain, `.xz` or `.gz`) as a cloud.
pub fn read_ply(path: impl AsRef<Path>) -> Result<Cloud<3>, PlyError> {
    read_ply_at_most(path, MAX_VERTICES)
}

/// [`read_ply`] for a caller that takes at most `max_vertices` points: a header announcing
/// more is refused ([`PlyErrorKind::TooManyVertices`]) before any vertex is read.
pub fn read_ply_at_most(path: impl AsRef<Path>, max_vertices: u64) -> Result<Cloud<3>, PlyError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let file = crate::bounded::open_stream(path).map_err(|e| PlyError {
        file: name.clone(),
        kind: PlyErrorKind::Io {
            action: "open",
            message: e.to_string(),
        },
    })?;
    // The size of a plain regular file bounds what its header may announce.
    let compressed = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("xz") || e.eq_ignore_ascii_case("gz"));
    let size = file
        .metadata()
        .ok()
        .filter(|m| m.is_file() && !compressed)
        .map(|m| m.len());
    decode(
        &name,
        crate::decompressing_reader(&path.to_string_lossy(), file),
        size,
        max_vertices,
    )
}

/// Reads a PLY cloud from `reader`; `name` is the file name the errors give.
pub fn decode_ply(name: &str, reader: impl Read) -> Result<Cloud<3>, PlyError> {
    decode(name, reader, None, MAX_VERTICES)
}

/// Reads a PLY cloud of `size` bytes in all, if known, and at most `max_vertices` vertices
/// from `reader`.
fn decode(
    name: &str,
    reader: impl Read,
    size: Option<u64>,
    max_vertices: u64,
) -> Result<Cloud<3>, PlyError> {
    let fail = |kind| PlyError {
        file: name.to_string(),
        kind,
    };
    let mut reader = BufReader::new(reader);
    let header = read_header(&mut reader).map_err(fail)?;
    if let Some(vertex) = header.elements.iter().find(|e| e.name == "vertex")
        && vertex.count > max_vertices
    {
        return Err(fail(PlyErrorKind::TooManyVertices {
            line: vertex.line,
            count: vertex.count,
            max: max_vertices,
        }));
    }
    if let Some(size) = size {
        check_counts(&header, size.saturating_sub(header.bytes as u64)).map_err(fail)?;
    }
    read_body(&mut reader, &header).map_err(fail)
}

/// Every element's count against the `left` bytes after the header: the items cannot take
/// fewer than [`Element::min_item_bytes`] each.
fn check_counts(header: &Header, left: u64) -> Result<(), PlyErrorKind> {
    let mut need = 0u64;
    for element in &header.elements {
        let each = element.min_item_bytes(header.format);
        need = need.saturating_add(element.count.saturating_mul(each));
        if need > left {
            return Err(PlyErrorKind::Header {
                line: element.line,
                reason: format!(
                    "element {}: {} items of at least {each} bytes each do not fit in the \
                     {left} bytes after end_header (a wrong count, or a truncated file)",
                    element.name, element.count
                ),
            });
        }
    }
    Ok(())
}

fn io_error(e: std::io::Error) -> PlyErrorKind {
    PlyErrorKind::Io {
        action: "read",
        message: e.to_string(),
    }
}

fn read_header(reader: &mut impl BufRead) -> Result<Header, PlyErrorKind> {
    let mut used = 0usize;
    let mut line_no = 0usize;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut buf = Vec::new();
    loop {
        buf.clear();
        let budget = (MAX_HEADER_BYTES - used) as u64;
        let n = reader
            .by_ref()
            .take(budget)
            .read_until(b'\n', &mut buf)
            .map_err(io_error)?;
        line_no += 1;
        let header = |reason: String| PlyErrorKind::Header {
            line: line_no,
            reason,
        };
        used += n;
        if n == 0 {
            return Err(header("the file ends before end_header".into()));
        }
        if buf.last() != Some(&b'\n') {
            if used >= MAX_HEADER_BYTES {
                return Err(header(format!(
                    "no end_header in the first {MAX_HEADER_BYTES} bytes"
                )));
            }
            return Err(header("the file ends before end_header".into()));
        }
        let Ok(text) = std::str::from_utf8(&buf) else {
            return Err(header("not text (is this a PLY file?)".into()));
        };
        let words: Vec<&str> = text.split_ascii_whitespace().collect();
        if line_no == 1 {
            if words != ["ply"] {
                return Err(header(
                    "the first line is not \"ply\" (not a PLY file)".into(),
                ));
            }
            continue;
        }
        match words.as_slice() {
            [] => {}
            ["comment" | "obj_info", ..] => {}
            ["format", f, version] => {
                if *version != "1.0" {
                    return Err(header(format!(
                        "format version {version} (only 1.0 is known)"
                    )));
                }
                format = Some(match *f {
                    "ascii" => PlyFormat::Ascii,
                    "binary_little_endian" => PlyFormat::BinaryLittleEndian,
                    "binary_big_endian" => PlyFormat::BinaryBigEndian,
                    other => return Err(header(format!("unknown format \"{other}\""))),
                });
            }
            ["element", name, count] => {
                let count: u64 = count.parse().map_err(|_| {
                    header(format!(
                        "element {name}: count \"{count}\" is not a whole number"
                    ))
                })?;
                let limit = if *name == "vertex" {
                    MAX_VERTICES
                } else {
                    MAX_ELEMENT_COUNT
                };
                if count > limit {
                    return Err(header(format!(
                        "element {name}: {count} items, at most {limit} are read"
                    )));
                }
                if *name == "vertex" && elements.iter().any(|e| e.name == "vertex") {
                    return Err(header("a second vertex element".into()));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                    line: line_no,
                });
            }
            ["property", "list", count_type, item_type, name] => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| header("a property before any element".into()))?;
                if element.name == "vertex" {
                    return Err(header(format!(
                        "property {name}: list properties in the vertex element are not supported"
                    )));
                }
                let (Some(c), Some(s)) = (Scalar::parse(count_type), Scalar::parse(item_type))
                else {
                    return Err(header(format!(
                        "property {name}: unknown list type \"{count_type} {item_type}\""
                    )));
                };
                if matches!(c, Scalar::F32 | Scalar::F64) {
                    return Err(header(format!(
                        "property {name}: a list count must be an integer type"
                    )));
                }
                element.properties.push(Property {
                    name: name.to_string(),
                    scalar: s,
                    list: Some(c),
                });
            }
            ["property", ty, name] => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| header("a property before any element".into()))?;
                let scalar = Scalar::parse(ty)
                    .ok_or_else(|| header(format!("property {name}: unknown type \"{ty}\"")))?;
                if element.properties.iter().any(|p| p.name == *name) {
                    return Err(header(format!(
                        "property {name} appears twice in element {}",
                        element.name
                    )));
                }
                element.properties.push(Property {
                    name: name.to_string(),
                    scalar,
                    list: None,
                });
            }
            ["end_header"] => break,
            _ => return Err(header(format!("cannot read \"{}\"", text.trim_end()))),
        }
    }
    let format = format.ok_or_else(|| PlyErrorKind::Header {
        line: line_no,
        reason: "no format line".into(),
    })?;
    let Some(vertex) = elements.iter().find(|e| e.name == "vertex") else {
        return Err(PlyErrorKind::Header {
            line: line_no,
            reason: "no vertex element".into(),
        });
    };
    for axis in ["x", "y", "z"] {
        if !vertex.properties.iter().any(|p| p.name == axis) {
            return Err(PlyErrorKind::Header {
                line: line_no,
                reason: format!("the vertex element has no property {axis}"),
            });
        }
    }
    Ok(Header {
        format,
        elements,
        lines: line_no,
        bytes: used,
    })
}

/// Positions of x, y, z and the intensity among the vertex properties.
fn vertex_slots(vertex: &Element) -> ([usize; 3], Option<usize>) {
    let at = |n: &str| vertex.properties.iter().position(|p| p.name == n);
    let xyz = [at("x"), at("y"), at("z")].map(|s| s.expect("checked in the header"));
    (xyz, at("intensity").or_else(|| at("scalar_intensity")))
}

fn read_body(reader: &mut impl BufRead, header: &Header) -> Result<Cloud<3>, PlyErrorKind> {
    let mut line = header.lines;
    let mut points = Vec::new();
    let mut intensity = Vec::new();
    for element in &header.elements {
        if element.name != "vertex" {
            skip_element(reader, element, header.format, &mut line)?;
            continue;
        }
        let (xyz, slot_i) = vertex_slots(element);
        let reserve = element.count.min(1 << 20) as usize;
        points.reserve(reserve);
        if slot_i.is_some() {
            intensity.reserve(reserve);
        }
        let mut values = vec![0.0; element.properties.len()];
        for index in 0..element.count {
            match header.format {
                PlyFormat::Ascii => {
                    line += 1;
                    let text = read_line(reader, element, index)?;
                    let mut words = text.split_ascii_whitespace();
                    for (p, v) in element.properties.iter().zip(values.iter_mut()) {
                        let value_error = |reason: String| PlyErrorKind::Value {
                            line,
                            vertex: index,
                            property: p.name.clone(),
                            reason,
                        };
                        let word = words.next().ok_or_else(|| value_error("missing".into()))?;
                        *v = word
                            .parse()
                            .map_err(|_| value_error(format!("\"{word}\" is not a number")))?;
                    }
                    if let Some(extra) = words.next() {
                        return Err(PlyErrorKind::Value {
                            line,
                            vertex: index,
                            property: "(end of line)".into(),
                            reason: format!("\"{extra}\" after the last property"),
                        });
                    }
                }
                PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
                    let big = header.format == PlyFormat::BinaryBigEndian;
                    let mut b = [0u8; 8];
                    for (p, v) in element.properties.iter().zip(values.iter_mut()) {
                        read_exact(reader, &mut b[..p.scalar.size()], element, index, &p.name)?;
                        *v = p.scalar.decode(&b, big);
                    }
                }
            }
            for slot in xyz.into_iter().chain(slot_i) {
                if !values[slot].is_finite() {
                    return Err(PlyErrorKind::Value {
                        line: if header.format == PlyFormat::Ascii {
                            line
                        } else {
                            0
                        },
                        vertex: index,
                        property: element.properties[slot].name.clone(),
                        reason: format!("{} is not finite", values[slot]),
                    });
                }
            }
            points.push(xyz.map(|s| values[s]));
            if let Some(s) = slot_i {
                intensity.push(values[s]);
            }
        }
        break;
    }
    let has_intensity = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .is_some_and(|e| vertex_slots(e).1.is_some());
    Cloud::new(points, has_intensity.then_some(intensity)).map_err(|e| PlyErrorKind::Value {
        line: 0,
        vertex: 0,
        property: "vertex".into(),
        reason: e.to_string(),
    })
}

fn read_exact(
    reader: &mut impl Read,
    buf: &mut [u8],
    element: &Element,
    index: u64,
    property: &str,
) -> Result<(), PlyErrorKind> {
    reader.read_exact(buf).map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            PlyErrorKind::Truncated {
                element: element.name.clone(),
                index,
                property: property.to_string(),
            }
        } else {
            io_error(e)
        }
    })
}

/// One ASCII line (without its end), at most [`MAX_LINE_BYTES`].
fn read_line(
    reader: &mut impl BufRead,
    element: &Element,
    index: u64,
) -> Result<String, PlyErrorKind> {
    let mut buf = Vec::new();
    let n = reader
        .by_ref()
        .take(MAX_LINE_BYTES as u64 + 1)
        .read_until(b'\n', &mut buf)
        .map_err(io_error)?;
    let first = element.properties.first().map_or("", |p| p.name.as_str());
    if n == 0 {
        return Err(PlyErrorKind::Truncated {
            element: element.name.clone(),
            index,
            property: first.to_string(),
        });
    }
    if n > MAX_LINE_BYTES {
        return Err(PlyErrorKind::Value {
            line: 0,
            vertex: index,
            property: first.to_string(),
            reason: format!("a line longer than {MAX_LINE_BYTES} bytes"),
        });
    }
    String::from_utf8(buf).map_err(|_| PlyErrorKind::Value {
        line: 0,
        vertex: index,
        property: first.to_string(),
        reason: "not text".into(),
    })
}

/// Reads past the items of an element that is not the vertex element.
fn skip_element(
    reader: &mut impl BufRead,
    element: &Element,
    format: PlyFormat,
    line: &mut usize,
) -> Result<(), PlyErrorKind> {
    let big = format == PlyFormat::BinaryBigEndian;
    for index in 0..element.count {
        if format == PlyFormat::Ascii {
            *line += 1;
            read_line(reader, element, index)?;
            continue;
        }
        let mut b = [0u8; 8];
        for p in &element.properties {
            let items = match p.list {
                Some(count_type) => {
                    read_exact(reader, &mut b[..count_type.size()], element, index, &p.name)?;
                    let n = count_type.decode(&b, big);
                    if !(0.0..=MAX_LIST_LEN as f64).contains(&n) {
                        return Err(PlyErrorKind::Value {
                            line: 0,
                            vertex: index,
                            property: p.name.clone(),
                            reason: format!("list of {n} entries in element {}", element.name),
                        });
                    }
                    n as u64
                }
                None => 1,
            };
            for _ in 0..items {
                read_exact(reader, &mut b[..p.scalar.size()], element, index, &p.name)?;
            }
        }
    }
    Ok(())
}

/// Encodes a cloud as PLY: `double` x, y, z and, if the cloud has them, `double intensity`.
pub fn encode_ply(cloud: &Cloud<3>, format: PlyFormat) -> Vec<u8> {
    let name = match format {
        PlyFormat::Ascii => "ascii",
        PlyFormat::BinaryLittleEndian => "binary_little_endian",
        PlyFormat::BinaryBigEndian => "binary_big_endian",
    };
    let mut out = format!(
        "ply\nformat {name} 1.0\ncomment chronomap\nelement vertex {}\n",
        cloud.len()
    );
    out.push_str("property double x\nproperty double y\nproperty double z\n");
    if cloud.intensity().is_some() {
        out.push_str("property double intensity\n");
    }
    out.push_str("end_header\n");
    let mut bytes = out.into_bytes();
    for (i, p) in cloud.points().iter().enumerate() {
        let mut values = p.to_vec();
        values.extend(cloud.intensity().map(|v| v[i]));
        match format {
            PlyFormat::Ascii => {
                let words: Vec<String> = values.iter().map(|v| format!("{v:?}")).collect();
                bytes.extend_from_slice(words.join(" ").as_bytes());
                bytes.push(b'\n');
            }
            PlyFormat::BinaryLittleEndian => values
                .iter()
                .for_each(|v| bytes.extend_from_slice(&v.to_le_bytes())),
            PlyFormat::BinaryBigEndian => values
                .iter()
                .for_each(|v| bytes.extend_from_slice(&v.to_be_bytes())),
        }
    }
    bytes
}

/// Writes a cloud as PLY to `path`, atomically ([`encode_ply`]).
pub fn write_ply(
    path: impl AsRef<Path>,
    cloud: &Cloud<3>,
    format: PlyFormat,
) -> Result<(), PlyError> {
    let path = path.as_ref();
    crate::atomic::write_atomically(path, &encode_ply(cloud, format)).map_err(|f| PlyError {
        file: path.display().to_string(),
        kind: PlyErrorKind::Io {
            action: f.action,
            message: f.io.to_string(),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n";

    fn err(bytes: &[u8]) -> String {
        decode_ply("t.ply", bytes).unwrap_err().to_string()
    }

    #[test]
    fn every_format_round_trips() {
        let cloud = Cloud::new(
            vec![[1.5, -2.0, 1e-3], [0.1, 0.2, 0.3]],
            Some(vec![5.0, 250.0]),
        )
        .unwrap();
        for format in [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ] {
            assert_eq!(
                decode_ply("t.ply", &encode_ply(&cloud, format)[..]).unwrap(),
                cloud
            );
        }
        let bare = Cloud::from_points(vec![[1.0, 2.0, 3.0]]).unwrap();
        let back = decode_ply("t.ply", &encode_ply(&bare, PlyFormat::Ascii)[..]).unwrap();
        assert_eq!(back.intensity(), None);
    }

    #[test]
    fn other_properties_and_elements_are_skipped() {
        // Big endian: uchar r, short x, float y, double z, int intensity; a face element with a
        // list first.
        let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement face 1\nproperty list uchar int vertex_indices\n\
element vertex 1\nproperty uchar r\nproperty short x\nproperty float y\nproperty double z\nproperty int intensity\nend_header\n"
            .to_vec();
        bytes.push(2);
        bytes.extend_from_slice(&7i32.to_be_bytes());
        bytes.extend_from_slice(&8i32.to_be_bytes());
        bytes.push(200);
        bytes.extend_from_slice(&(-3i16).to_be_bytes());
        bytes.extend_from_slice(&0.5f32.to_be_bytes());
        bytes.extend_from_slice(&2.25f64.to_be_bytes());
        bytes.extend_from_slice(&42i32.to_be_bytes());
        let cloud = decode_ply("t.ply", &bytes[..]).unwrap();
        assert_eq!(cloud.points(), &[[-3.0, 0.5, 2.25]]);
        assert_eq!(cloud.intensity(), Some(&[42.0][..]));
    }

    #[test]
    fn damaged_headers_name_the_line() {
        assert_eq!(
            err(b"PLY\n"),
            "t.ply: line 1: the first line is not \"ply\" (not a PLY file)"
        );
        assert_eq!(
            err(b"ply\nformat ascii 1.0\n"),
            "t.ply: line 3: the file ends before end_header"
        );
        let e = err(b"ply\nformat ascii 1.0\nelement vertex 100000001\n");
        assert_eq!(
            e,
            "t.ply: line 3: element vertex: 100000001 items, at most 100000000 are read"
        );
        let e = err(format!("{HEAD}property list uchar int idx\nend_header\n").as_bytes());
        assert!(
            e.starts_with("t.ply: line 7: property idx: list properties in the vertex element"),
            "{e}"
        );
        let e = err(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n");
        assert_eq!(e, "t.ply: line 6: the vertex element has no property z");
        let e = err(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty half x\n");
        assert_eq!(e, "t.ply: line 4: property x: unknown type \"half\"");
        let mut long = b"ply\n".to_vec();
        long.extend(
            std::iter::repeat_n(b"comment padding padding padding\n".as_slice(), 3000).flatten(),
        );
        assert!(err(&long).contains("no end_header in the first 65536 bytes"));
    }

    #[test]
    fn damaged_bodies_name_the_vertex_and_property() {
        let e = err(format!("{HEAD}end_header\n1 2 3\n4 5\n").as_bytes());
        assert_eq!(e, "t.ply: line 9 (vertex 1), property z: missing");
        let e = err(format!("{HEAD}end_header\n1 2 3\n").as_bytes());
        assert_eq!(
            e,
            "t.ply: vertex 1, property x: the file ends here (truncated)"
        );
        let e = err(format!("{HEAD}end_header\n1 2 3\n4 5 nan\n").as_bytes());
        assert_eq!(e, "t.ply: line 9 (vertex 1), property z: NaN is not finite");
        let cloud = Cloud::from_points(vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]).unwrap();
        let bytes = encode_ply(&cloud, PlyFormat::BinaryLittleEndian);
        let e = err(&bytes[..bytes.len() - 12]);
        assert_eq!(
            e,
            "t.ply: vertex 1, property y: the file ends here (truncated)"
        );
    }

    #[test]
    fn reads_the_bundled_lidar_scans_and_their_damaged_copies() {
        let path = chronomap_testutil::data_path("registration_small_gicp/source.ply.xz");
        let cloud = read_ply(&path).unwrap();
        assert_eq!(cloud.len(), 69_792);
        // First and last vertex and intensity, as float32 in the file.
        assert_eq!(
            cloud.points()[0],
            [
                0.004045109264552593,
                2.5751945972442627,
                -1.5272173881530762
            ]
        );
        assert_eq!(
            cloud.points()[69_791],
            [-0.004093721974641085, 1.804250717163086, 0.3399392366409302]
        );
        let intensity = cloud.intensity().unwrap();
        assert_eq!((intensity[0], intensity[69_791]), (70.0, 36.0));
        let target = read_ply(chronomap_testutil::data_path(
            "registration_small_gicp/target.ply.xz",
        ))
        .unwrap();
        assert_eq!(target.len(), 69_088);

        let mut bytes = Vec::new();
        crate::open_data_file(&path)
            .unwrap()
            .read_to_end(&mut bytes)
            .unwrap();
        let body = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        // Cut inside vertex 1000's z (bytes 8..12 of its 16).
        let e = err(&bytes[..body + 1000 * 16 + 9]);
        assert_eq!(
            e,
            "t.ply: vertex 1000, property z: the file ends here (truncated)"
        );
        // Announce one vertex more than there is.
        let text = String::from_utf8_lossy(&bytes[..body]).replace("vertex 69792", "vertex 69793");
        let mut longer = text.into_bytes();
        longer.extend_from_slice(&bytes[body..]);
        let e = err(&longer);
        assert_eq!(
            e,
            "t.ply: vertex 69792, property x: the file ends here (truncated)"
        );
        // A NaN in vertex 5's y.
        let mut nan = bytes.clone();
        nan[body + 5 * 16 + 4..body + 5 * 16 + 8].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(err(&nan), "t.ply: vertex 5, property y: NaN is not finite");
    }

    #[test]
    fn counts_beyond_the_bytes_of_a_plain_file_are_refused_before_reading() {
        // A 2-vertex binary cloud whose header announces 10^8 vertices (1.2 GB of float x, y, z):
        // refused at the element's line from the file's size, before reading a vertex.
        let cloud = Cloud::from_points(vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]).unwrap();
        let bytes = encode_ply(&cloud, PlyFormat::BinaryLittleEndian);
        let text = String::from_utf8_lossy(&bytes).into_owned();
        let body = text.find("end_header\n").unwrap() + 11;
        let mut lying = text[..body]
            .replace("element vertex 2", "element vertex 100000000")
            .into_bytes();
        lying.extend_from_slice(&bytes[body..]);
        let dir = std::env::temp_dir().join(format!("ply_counts_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("lying.ply");
        std::fs::write(&path, &lying).unwrap();
        let e = read_ply(&path).unwrap_err();
        assert_eq!(
            e.kind.to_string(),
            "line 4: element vertex: 100000000 items of at least 24 bytes each do not fit in the \
             48 bytes after end_header (a wrong count, or a truncated file)"
        );
        // As bytes (no size known) the same file reads until it ends.
        assert_eq!(
            decode_ply("t.ply", &lying[..])
                .unwrap_err()
                .kind
                .to_string(),
            "vertex 2, property x: the file ends here (truncated)"
        );
        // ASCII: 3 lines of at least "x y z\n" (6 bytes) do not fit in 10 bytes.
        std::fs::write(
            &path,
            format!("{HEAD}end_header\n1 2 3\n4 5 6\n").replace("vertex 2", "vertex 3"),
        )
        .unwrap();
        let e = read_ply(&path).unwrap_err().to_string();
        assert!(e.ends_with("line 3: element vertex: 3 items of at least 6 bytes each do not fit in the 12 bytes after end_header (a wrong count, or a truncated file)"), "{e}");
        // The exact count is read.
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(read_ply(&path).unwrap(), cloud);
        // A caller's own bound is checked from the header, before the bytes and the vertices.
        assert_eq!(read_ply_at_most(&path, 2).unwrap(), cloud);
        assert_eq!(
            read_ply_at_most(&path, 1).unwrap_err().kind,
            PlyErrorKind::TooManyVertices {
                line: 4,
                count: 2,
                max: 1
            }
        );
        std::fs::write(&path, &lying).unwrap();
        assert_eq!(
            read_ply_at_most(&path, 10_000_000)
                .unwrap_err()
                .kind
                .to_string(),
            "line 4: element vertex: 100000000 vertices, at most 10000000 are read here"
        );
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn devices_are_refused() {
        #[cfg(unix)]
        {
            let e = read_ply("/dev/zero").unwrap_err().to_string();
            assert!(
                e.starts_with("/dev/zero: cannot open: it is not a regular file"),
                "{e}"
            );
        }
    }
}
