//! CDR, the serialisation of ROS 2 messages (OMG DDS-XTypes "XCDR1", plain, as every ROS 2
//! middleware writes it and rosbag2 stores it), decoded by a [`Schema`] into a [`Value`] that
//! borrows the bytes.
//!
//! ```
//! use chronomap_rosbag::cdr::{decode, Value};
//! use chronomap_rosbag::msgdef::Schema;
//!
//! // std_msgs/msg/Bool `true`, as rclpy's serialize_message writes it (with 3 padding bytes).
//! let schema = Schema::parse("std_msgs/msg/Bool", "bool data\n")?;
//! let value = decode(&schema, &[0x00, 0x01, 0x00, 0x00, 0x01, 0x55, 0x00, 0x00])?;
//! assert_eq!(value.get("data"), Some(&Value::Bool(true)));
//!
//! // A length that runs past the end is an error naming the field.
//! let schema = Schema::parse("std_msgs/msg/String", "string data\n")?;
//! let err = decode(&schema, &[0, 1, 0, 0, 0xff, 0xff, 0xff, 0x7f, b'a', 0]).unwrap_err();
//! assert_eq!(err.to_string(), "field `data`: a string of 2147483647 bytes at byte 4 runs past the end of the message (10 bytes)");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Encoding
//! A 4-byte encapsulation header (`00 00` big-endian or `00 01` little-endian CDR, then two
//! option bytes), then the fields in order, each primitive aligned to its size (at most 8)
//! relative to the first byte after the header. Strings are a `uint32` length counting a
//! terminating NUL, then the bytes; sequences a `uint32` count, then the elements; fixed
//! arrays just the elements. A message type without fields is one byte on the wire.
//! Parameter-list and XCDR2 encapsulations (which ROS 2 does not use for topics) and `wstring`
//! fields are refused with an error saying so.
//!
//! Nothing here trusts a length: every count is checked against the bytes that remain before
//! anything is allocated, and the values one message decodes to are counted against a budget
//! ([`VALUES_PER_BYTE`] a byte of the message, at most [`MAX_VALUES`]) before each is
//! allocated, so a damaged or hostile message cannot make the decoder hold more than a small
//! multiple of its own size: without the budget, a definition of single-byte messages nested
//! [`MAX_DEPTH`](crate::msgdef::MAX_DEPTH) deep decodes each byte to 64 values (kilobytes).

use std::borrow::Cow;
use std::fmt;

use thiserror::Error;

use crate::msgdef::{Arity, FieldType, MessageDef, Primitive, Schema};

/// A decoded value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value<'a> {
    /// `bool`.
    Bool(bool),
    /// `int8` … `int64` (alone; arrays of `int8` are [`Value::Bytes`]).
    Int(i64),
    /// `uint8` … `uint64`, `byte`, `char` (alone).
    UInt(u64),
    /// `float32`.
    F32(f32),
    /// `float64`.
    F64(f64),
    /// `string` (invalid UTF-8 is replaced, as `String::from_utf8_lossy` does).
    String(Cow<'a, str>),
    /// An array or sequence of `uint8`, `byte`, `char` or `int8`: the bytes as they are.
    Bytes(&'a [u8]),
    /// Any other array or sequence.
    Array(Vec<Value<'a>>),
    /// A message.
    Struct(Struct<'a>),
}

/// A decoded message: its type and its field values in wire order.
#[derive(Clone, Debug, PartialEq)]
pub struct Struct<'a> {
    /// The type.
    pub def: &'a MessageDef,
    /// One value per field of `def`.
    pub fields: Vec<Value<'a>>,
}

impl<'a> Value<'a> {
    /// The field `name` of a message value.
    pub fn get(&self, name: &str) -> Option<&Value<'a>> {
        match self {
            Value::Struct(s) => s.def.field_index(name).map(|i| &s.fields[i]),
            _ => None,
        }
    }

    /// The value at a dotted path of field names (`info.origin.position.x`).
    pub fn path(&self, path: &str) -> Option<&Value<'a>> {
        path.split('.').try_fold(self, |v, name| v.get(name))
    }

    /// A number as `f64` (integers converted, `bool` as 0 or 1).
    pub fn as_f64(&self) -> Option<f64> {
        match *self {
            Value::Bool(b) => Some(f64::from(u8::from(b))),
            Value::Int(i) => Some(i as f64),
            Value::UInt(u) => Some(u as f64),
            Value::F32(x) => Some(f64::from(x)),
            Value::F64(x) => Some(x),
            _ => None,
        }
    }

    /// An integer, signed or unsigned, if it fits `i64`.
    pub fn as_i64(&self) -> Option<i64> {
        match *self {
            Value::Int(i) => Some(i),
            Value::UInt(u) => i64::try_from(u).ok(),
            _ => None,
        }
    }

    /// A string.
    pub fn as_str(&self) -> Option<&str> {
        match self {
            Value::String(s) => Some(s),
            _ => None,
        }
    }

    /// The elements of an array (not of a byte array).
    pub fn as_array(&self) -> Option<&[Value<'a>]> {
        match self {
            Value::Array(a) => Some(a),
            _ => None,
        }
    }

    /// The bytes of a byte array.
    pub fn as_bytes(&self) -> Option<&'a [u8]> {
        match self {
            Value::Bytes(b) => Some(b),
            _ => None,
        }
    }

    /// A short name of the kind of value, for error messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Value::Bool(_) => "a bool",
            Value::Int(_) => "a signed integer",
            Value::UInt(_) => "an unsigned integer",
            Value::F32(_) => "a float32",
            Value::F64(_) => "a float64",
            Value::String(_) => "a string",
            Value::Bytes(_) => "a byte array",
            Value::Array(_) => "an array",
            Value::Struct(_) => "a message",
        }
    }
}

/// Why bytes could not be decoded: where (the field path) and what.
#[derive(Debug, Error, PartialEq)]
pub struct CdrError {
    /// Field names from the message down to the field that failed (array indices as
    /// `[i]`); empty for the header.
    pub path: Vec<String>,
    /// What is wrong.
    pub problem: String,
}

impl fmt::Display for CdrError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if !self.path.is_empty() {
            write!(f, "field `")?;
            for (i, part) in self.path.iter().enumerate() {
                if i > 0 && !part.starts_with('[') {
                    write!(f, ".")?;
                }
                write!(f, "{part}")?;
            }
            write!(f, "`: ")?;
        }
        write!(f, "{}", self.problem)
    }
}

impl CdrError {
    fn new(problem: String) -> Self {
        CdrError {
            path: Vec::new(),
            problem,
        }
    }

    /// Adds an outer path element (the error travels outwards).
    fn within(mut self, part: impl Into<String>) -> Self {
        self.path.insert(0, part.into());
        self
    }
}

/// Values one message may decode to per byte of it (header included): every value — a
/// message, a field, an element — counts once. A sequence of messages of one `bool` takes 2 a
/// byte; every message chronomap learns from takes less than 1 (`std_msgs/Bool`: 2 values in 8
/// bytes, `geometry_msgs/Pose`: 10 in 56).
pub const VALUES_PER_BYTE: usize = 2;

/// Most values one message may decode to, however large (each takes about 40 bytes, so at most
/// about 1 GiB): the ranges and intensities of a scan of 8 million beams. Byte arrays
/// (`uint8[]`, `int8[]`: map cells, point clouds) are one value, whatever their length.
pub const MAX_VALUES: usize = 1 << 24;

/// Most trailing bytes a message may have after its last field: the padding to a multiple of
/// 4 bytes that ROS 2 middlewares add (rclpy's `std_msgs/Bool` is 4 + 1 + 3 bytes). More is a
/// message that does not match its definition.
const MAX_TRAILING: usize = 3;

/// Decodes one CDR message (with its encapsulation header) of `schema`'s root type.
///
/// # Errors
/// A [`CdrError`] naming the field: an unknown encapsulation, a length or count that runs past
/// the end, a bound exceeded, a `bool` that is not 0 or 1, more than 3 bytes left over (the
/// data do not match the schema).
pub fn decode<'a>(schema: &'a Schema, data: &'a [u8]) -> Result<Value<'a>, CdrError> {
    if data.len() < 4 {
        return Err(CdrError::new(format!(
            "{} bytes are too short for a CDR message (the header alone has 4)",
            data.len()
        )));
    }
    let little = match (data[0], data[1]) {
        (0, 0) => false,
        (0, 1) => true,
        (0, 2) | (0, 3) => {
            return Err(CdrError::new(
                "parameter-list CDR (PL_CDR) is not supported: ROS 2 topics use plain CDR".into(),
            ));
        }
        (a, b) => {
            return Err(CdrError::new(format!(
                "encapsulation {a:02x} {b:02x} is not plain CDR (00 00 or 00 01){}",
                if (6..=11).contains(&b) && a == 0 {
                    ": XCDR2 is not supported"
                } else {
                    ""
                }
            )));
        }
    };
    let mut reader = Reader {
        data: &data[4..],
        pos: 0,
        little,
        total: data.len(),
        budget: data.len().saturating_mul(VALUES_PER_BYTE).min(MAX_VALUES),
    };
    reader.spend(1)?;
    let value = reader.message(schema, 0)?;
    let left = reader.data.len() - reader.pos;
    if left > MAX_TRAILING {
        return Err(CdrError::new(format!(
            "{left} bytes are left after the last field: the data do not match the definition"
        )));
    }
    Ok(value)
}

/// A cursor over the bytes after the encapsulation header.
struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    little: bool,
    /// The size of the whole message, header included, for error messages.
    total: usize,
    /// Values that may still be decoded ([`VALUES_PER_BYTE`], [`MAX_VALUES`]).
    budget: usize,
}

impl<'a> Reader<'a> {
    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// The offset in the whole message (header included).
    fn offset(&self) -> usize {
        self.pos + 4
    }

    fn align(&mut self, size: usize) -> Result<(), CdrError> {
        let padded = self.pos.div_ceil(size) * size;
        if padded > self.data.len() {
            return Err(self.past_end(size));
        }
        self.pos = padded;
        Ok(())
    }

    /// Takes `n` values from the budget, before room for them is allocated.
    fn spend(&mut self, n: usize) -> Result<(), CdrError> {
        if n > self.budget {
            return Err(CdrError::new(format!(
                "at byte {} the message decodes to more values than its {} bytes allow \
                 ({VALUES_PER_BYTE} a byte, at most {MAX_VALUES}): the definition nests or \
                 repeats more than the data can hold",
                self.offset(),
                self.total
            )));
        }
        self.budget -= n;
        Ok(())
    }

    fn past_end(&self, wanted: usize) -> CdrError {
        CdrError::new(format!(
            "{wanted} more bytes at byte {} run past the end of the message ({} bytes)",
            self.offset(),
            self.total
        ))
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], CdrError> {
        if n > self.remaining() {
            return Err(self.past_end(n));
        }
        let bytes = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(bytes)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], CdrError> {
        self.align(N)?;
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(N)?);
        if self.little != cfg!(target_endian = "little") {
            out.reverse();
        }
        Ok(out)
    }

    fn u32(&mut self) -> Result<u32, CdrError> {
        Ok(u32::from_ne_bytes(self.array::<4>()?))
    }

    fn primitive(&mut self, p: Primitive) -> Result<Value<'a>, CdrError> {
        Ok(match p {
            Primitive::Bool => {
                let b = self.take(1)?[0];
                match b {
                    0 => Value::Bool(false),
                    1 => Value::Bool(true),
                    _ => {
                        return Err(CdrError::new(format!(
                            "byte {} is {b}, not a bool (0 or 1)",
                            self.offset() - 1
                        )));
                    }
                }
            }
            Primitive::U8 | Primitive::Char => Value::UInt(u64::from(self.take(1)?[0])),
            Primitive::I8 => Value::Int(i64::from(self.take(1)?[0] as i8)),
            Primitive::I16 => Value::Int(i64::from(i16::from_ne_bytes(self.array()?))),
            Primitive::U16 => Value::UInt(u64::from(u16::from_ne_bytes(self.array()?))),
            Primitive::I32 => Value::Int(i64::from(i32::from_ne_bytes(self.array()?))),
            Primitive::U32 => Value::UInt(u64::from(u32::from_ne_bytes(self.array()?))),
            Primitive::I64 => Value::Int(i64::from_ne_bytes(self.array()?)),
            Primitive::U64 => Value::UInt(u64::from_ne_bytes(self.array()?)),
            Primitive::F32 => Value::F32(f32::from_ne_bytes(self.array()?)),
            Primitive::F64 => Value::F64(f64::from_ne_bytes(self.array()?)),
        })
    }

    fn string(&mut self, bound: Option<u32>) -> Result<Value<'a>, CdrError> {
        let at = self.offset();
        let len = self.u32()? as usize;
        if len > self.remaining() {
            return Err(CdrError::new(format!(
                "a string of {len} bytes at byte {at} runs past the end of the message ({} bytes)",
                self.total
            )));
        }
        let bytes = self.take(len)?;
        // The length counts a terminating NUL; a writer that omits it for "" writes 0.
        let text = match bytes.split_last() {
            Some((0, text)) => text,
            Some(_) => {
                return Err(CdrError::new(format!(
                    "the string at byte {at} does not end with a NUL byte"
                )));
            }
            None => &[],
        };
        if let Some(bound) = bound
            && text.len() > bound as usize
        {
            return Err(CdrError::new(format!(
                "a string of {} bytes is longer than its bound {bound}",
                text.len()
            )));
        }
        Ok(Value::String(String::from_utf8_lossy(text)))
    }

    /// One element of type `ty`.
    fn element(&mut self, schema: &'a Schema, ty: FieldType) -> Result<Value<'a>, CdrError> {
        match ty {
            FieldType::Primitive(p) => self.primitive(p),
            FieldType::String(bound) => self.string(bound),
            FieldType::WString(_) => Err(CdrError::new(
                "wstring fields are not supported (no ROS 2 message chronomap reads has one)"
                    .into(),
            )),
            FieldType::Message(index) => self.message(schema, index),
        }
    }

    fn message(&mut self, schema: &'a Schema, index: usize) -> Result<Value<'a>, CdrError> {
        let def = schema.get(index);
        if def.fields.is_empty() {
            // An empty type is one placeholder byte on the wire.
            self.take(1)?;
        }
        self.spend(def.fields.len())?;
        let mut fields = Vec::with_capacity(def.fields.len());
        for field in &def.fields {
            let value = match field.arity {
                Arity::Single => self.element(schema, field.ty),
                Arity::Fixed(n) => self.elements(schema, field.ty, n as usize),
                Arity::Sequence | Arity::Bounded(_) => {
                    let at = self.offset();
                    let n = self.u32();
                    n.and_then(|n| {
                        if let Arity::Bounded(bound) = field.arity
                            && n > bound
                        {
                            return Err(CdrError::new(format!(
                                "a sequence of {n} elements at byte {at} is longer than its bound {bound}"
                            )));
                        }
                        self.elements(schema, field.ty, n as usize)
                    })
                }
            };
            fields.push(value.map_err(|e| e.within(field.name.clone()))?);
        }
        Ok(Value::Struct(Struct { def, fields }))
    }

    /// `n` elements of type `ty`.
    fn elements(
        &mut self,
        schema: &'a Schema,
        ty: FieldType,
        n: usize,
    ) -> Result<Value<'a>, CdrError> {
        // Every element takes at least this many bytes: checked before allocating.
        let least = match ty {
            FieldType::Primitive(p) => p.size(),
            FieldType::String(_) | FieldType::WString(_) => 4,
            FieldType::Message(_) => 1,
        };
        let at = self.offset();
        if n.saturating_mul(least) > self.remaining() {
            return Err(CdrError::new(format!(
                "{n} elements at byte {at} need at least {} bytes, but the message ({} bytes) has {} left",
                n.saturating_mul(least),
                self.total,
                self.remaining()
            )));
        }
        match ty {
            FieldType::Primitive(Primitive::U8 | Primitive::Char | Primitive::I8) => {
                Ok(Value::Bytes(self.take(n)?))
            }
            _ => {
                self.spend(n)?;
                let mut values = Vec::with_capacity(n);
                for i in 0..n {
                    values.push(
                        self.element(schema, ty)
                            .map_err(|e| e.within(format!("[{i}]")))?,
                    );
                }
                Ok(Value::Array(values))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(s: &str) -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    const SEP: &str =
        "================================================================================";

    fn header_types() -> String {
        format!(
            "{SEP}\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
             {SEP}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
        )
    }

    #[test]
    fn laser_scan_serialised_by_rclpy() {
        // rclpy 9.1.2 (Kilted): LaserScan with frame_id "l" and ranges [1, 2]; the two bytes
        // after "l\0" are uninitialised padding, as real middlewares leave them.
        let text = format!(
            "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\n\
             float32 angle_increment\nfloat32 time_increment\nfloat32 scan_time\n\
             float32 range_min\nfloat32 range_max\nfloat32[] ranges\nfloat32[] intensities\n{}",
            header_types()
        );
        let schema = Schema::parse("sensor_msgs/msg/LaserScan", &text).unwrap();
        let bytes = hex(
            "000100000000000000000000020000006c0013de00000000000000000000000000000000000000000000000000000000020000000000803f0000004000000000",
        );
        let scan = decode(&schema, &bytes).unwrap();
        assert_eq!(scan.path("header.frame_id").unwrap().as_str(), Some("l"));
        let ranges: Vec<f64> = scan
            .get("ranges")
            .unwrap()
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(ranges, [1.0, 2.0]);
        assert_eq!(
            scan.get("intensities").unwrap().as_array().unwrap().len(),
            0
        );
    }

    #[test]
    fn occupancy_grid_serialised_by_rclpy() {
        // rclpy: OccupancyGrid frame "map", 2 × 1, data [0, 100] (see the Python snippet in
        // tests/ros2/); map_load_time 0, resolution 0, origin at 0 with w = 1.
        let bytes = hex(
            "000100000000000000000000040000006d617000000000000000000000000000020000000100000070949945000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000f03f020000000064",
        );
        let text = format!(
            "std_msgs/Header header\nMapMetaData info\nint8[] data\n{SEP}\nMSG: nav_msgs/MapMetaData\n\
             builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\n\
             geometry_msgs/Pose origin\n{SEP}\nMSG: geometry_msgs/Pose\ngeometry_msgs/Point position\n\
             geometry_msgs/Quaternion orientation\n{SEP}\nMSG: geometry_msgs/Point\nfloat64 x\n\
             float64 y\nfloat64 z\n{SEP}\nMSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\n\
             float64 z 0\nfloat64 w 1\n{}",
            header_types()
        );
        let schema = Schema::parse("nav_msgs/msg/OccupancyGrid", &text).unwrap();
        let grid = decode(&schema, &bytes).unwrap();
        assert_eq!(grid.path("header.frame_id").unwrap().as_str(), Some("map"));
        assert_eq!(grid.path("info.width"), Some(&Value::UInt(2)));
        assert_eq!(grid.path("info.height"), Some(&Value::UInt(1)));
        assert_eq!(
            grid.path("info.origin.orientation.w"),
            Some(&Value::F64(1.0))
        );
        assert_eq!(grid.get("data").unwrap().as_bytes(), Some(&[0u8, 100][..]));
    }

    #[test]
    fn big_endian_and_bounds() {
        let schema = Schema::parse("a/B", "uint16 x\nint32[<=2] few\nstring<=3 s\n").unwrap();
        // x = 258 (big-endian), few = [-1], s = "ab".
        let bytes = hex("0000000001020000" /* x + pad */);
        let mut all = bytes.clone();
        all.extend(hex("00000001ffffffff0000000361620000"));
        let v = decode(&schema, &all).unwrap();
        assert_eq!(v.get("x"), Some(&Value::UInt(258)));
        assert_eq!(v.get("few").unwrap().as_array().unwrap(), &[Value::Int(-1)]);
        assert_eq!(v.get("s").unwrap().as_str(), Some("ab"));
        // A sequence over its bound.
        let mut over = bytes.clone();
        over.extend(hex("00000003ffffffffffffffffffffffff"));
        let err = decode(&schema, &over).unwrap_err();
        assert_eq!(err.path, ["few"]);
        assert!(err.problem.contains("longer than its bound 2"), "{err}");
    }

    #[test]
    fn hostile_counts_fail_before_allocating() {
        let schema = Schema::parse("a/B", "float64[] xs\n").unwrap();
        let err = decode(&schema, &hex("00010000ffffffff")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "field `xs`: 4294967295 elements at byte 8 need at least 34359738360 bytes, but the message (8 bytes) has 0 left"
        );
        let err = decode(&schema, &hex("0001")).unwrap_err();
        assert!(err.problem.contains("too short"), "{err}");
        let err = decode(&schema, &hex("00020000")).unwrap_err();
        assert!(err.problem.contains("PL_CDR"), "{err}");
        let err = decode(&schema, &hex("00070000")).unwrap_err();
        assert!(err.problem.contains("XCDR2"), "{err}");
    }

    /// `n` message types nested one in the next, the innermost holding `leaf`.
    fn nested(n: usize, leaf: &str) -> String {
        let mut text = String::from("N1 x\n");
        for i in 1..n {
            text.push_str(&format!("{SEP}\nMSG: a/N{i}\nN{} x\n", i + 1));
        }
        text.push_str(&format!("{SEP}\nMSG: a/N{n}\n{leaf}\n"));
        text
    }

    #[test]
    fn values_are_counted_against_the_bytes_of_the_message() {
        // A sequence of messages of one bool: 2 values a byte, the most the budget allows.
        let schema = Schema::parse(
            "a/B",
            &format!("Flag[] flags\n{SEP}\nMSG: a/Flag\nbool b\n"),
        )
        .unwrap();
        let mut bytes = hex("0001000000100000");
        bytes.extend([1u8; 4096]);
        let value = decode(&schema, &bytes).unwrap();
        assert_eq!(value.get("flags").unwrap().as_array().unwrap().len(), 4096);
        // One level more (3 values a byte) is refused at the first element over the budget:
        // 4104 bytes allow 8208 values; the root, its field and the 4096 elements take 4098,
        // each element's two inner fields 2 more, so elements 0 to 2054 fit and element 2055
        // (at byte 4 + 4 + 2055) is refused.
        let text =
            format!("Flag[] flags\n{SEP}\nMSG: a/Flag\nInner i\n{SEP}\nMSG: a/Inner\nbool b\n");
        let schema = Schema::parse("a/B", &text).unwrap();
        let err = decode(&schema, &bytes).unwrap_err();
        assert_eq!(
            err.to_string(),
            "field `flags[2055]`: at byte 2063 the message decodes to more values than its 4104 \
             bytes allow (2 a byte, at most 16777216): the definition nests or repeats more than \
             the data can hold"
        );
        // 60 levels of messages around one bool: 61 values from 1 byte, refused at once.
        let schema = Schema::parse("a/B", &nested(60, "bool b")).unwrap();
        let err = decode(&schema, &hex("0001000001")).unwrap_err();
        assert!(
            err.problem.contains("more values than its 5 bytes allow"),
            "{err}"
        );
        assert_eq!(err.path.len(), 9, "{err}"); // 10 values: the root and 9 levels
        // A few levels fit: std_msgs/Bool-like wrappers of real messages decode.
        let schema = Schema::parse("a/B", &nested(3, "bool b")).unwrap();
        assert!(decode(&schema, &hex("000100000100")).is_ok());
    }

    #[test]
    fn nested_errors_name_the_path_and_leftovers_are_mismatches() {
        let text = format!("Header[] headers\n{}", header_types());
        let schema = Schema::parse("a/B", &text).unwrap();
        // Two headers; the second string has no NUL.
        let bytes =
            hex("0001000002000000010000000200000002000000610000000300000004000000030000006263640a");
        let err = decode(&schema, &bytes).unwrap_err();
        assert_eq!(
            err.to_string(),
            "field `headers[1].frame_id`: the string at byte 32 does not end with a NUL byte"
        );
        let schema = Schema::parse("std_msgs/msg/Bool", "bool data\n").unwrap();
        let err = decode(&schema, &hex("000100000100000000000000000000")).unwrap_err();
        assert!(err.problem.contains("10 bytes are left"), "{err}");
        let err = decode(&schema, &hex("0001000002")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "field `data`: byte 4 is 2, not a bool (0 or 1)"
        );
        // An empty message is one byte on the wire (rclpy: std_msgs/Empty is 00 01 00 00 00).
        let schema = Schema::parse("std_msgs/msg/Empty", "").unwrap();
        assert!(decode(&schema, &hex("0001000000000000")).is_ok());
    }
}
