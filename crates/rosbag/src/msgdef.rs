//! ROS 2 message definitions (`.msg` text, the `ros2msg` schema encoding of rosbag2 MCAP
//! files), parsed into a [`Schema`] the CDR decoder walks.
//!
//! A rosbag2 schema is the definition of the message type followed by the definitions of every
//! type it uses, each after a line of `=` and a `MSG: pkg/Type` line:
//!
//! ```
//! use chronomap_rosbag::msgdef::{Schema, FieldType};
//!
//! let text = "std_msgs/Header header\nbool data  # the state\n\
//!             ================================================================================\n\
//!             MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
//!             ================================================================================\n\
//!             MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
//! let schema = Schema::parse("door_msgs/msg/Stamped", text)?;
//! let root = schema.root();
//! assert_eq!(root.name, "door_msgs/msg/Stamped");
//! assert_eq!(root.fields[1].name, "data");
//! assert!(matches!(root.fields[0].ty, FieldType::Message(_)));
//!
//! // Every referenced type must be defined; the error says which field needs it.
//! let err = Schema::parse("a/msg/B", "geometry_msgs/Point p\n").unwrap_err();
//! assert_eq!(err.to_string(), "a/msg/B:1, field `p`: type geometry_msgs/Point is not defined in the schema");
//! # Ok::<(), chronomap_rosbag::msgdef::SchemaError>(())
//! ```
//!
//! # Grammar
//! One field per line, `TYPE NAME [DEFAULT]`; `#` starts a comment; `TYPE NAME=VALUE` is a
//! constant (not part of the serialised message, skipped). `TYPE` is a primitive (`bool`,
//! `byte`, `char`, `int8` … `uint64`, `float32`, `float64`), `string` or `wstring` (optionally
//! bounded, `string<=10`), or a message type `pkg/Type`, `pkg/msg/Type` or `Type` (a type of
//! the same package; `Header` alone is `std_msgs/Header`, as in ROS). An array suffix `[]`,
//! `[N]` or `[<=N]` makes a sequence, a fixed array or a bounded sequence. Type names are
//! stored as `pkg/msg/Type`.
//!
//! Hostile schemas are refused: a type that contains itself (which could never be decoded),
//! types nested deeper than [`MAX_DEPTH`], more than [`MAX_FIELDS`] fields in all (counted while
//! parsing, duplicates found with a hash set: time linear in the text), or fixed arrays of no
//! elements (which take no bytes, so a sequence of them could be decoded without end).

use std::collections::{HashMap, HashSet};
use std::fmt;

use thiserror::Error;

/// Deepest nesting of message types a schema may have.
pub const MAX_DEPTH: usize = 64;

/// Most fields a schema may define, over all its types.
pub const MAX_FIELDS: usize = 100_000;

/// A primitive ROS 2 type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Primitive {
    /// `bool`: one byte, 0 or 1.
    Bool,
    /// `byte` (an octet) and `uint8`.
    U8,
    /// `char` in ROS 2 is an unsigned byte too; kept apart to name it in errors.
    Char,
    /// `int8`.
    I8,
    /// `int16`.
    I16,
    /// `uint16`.
    U16,
    /// `int32`.
    I32,
    /// `uint32`.
    U32,
    /// `int64`.
    I64,
    /// `uint64`.
    U64,
    /// `float32`.
    F32,
    /// `float64`.
    F64,
}

impl Primitive {
    /// The primitive of a `.msg` type name.
    pub fn from_name(name: &str) -> Option<Primitive> {
        Some(match name {
            "bool" => Primitive::Bool,
            "byte" | "uint8" => Primitive::U8,
            "char" => Primitive::Char,
            "int8" => Primitive::I8,
            "int16" => Primitive::I16,
            "uint16" => Primitive::U16,
            "int32" => Primitive::I32,
            "uint32" => Primitive::U32,
            "int64" => Primitive::I64,
            "uint64" => Primitive::U64,
            "float32" => Primitive::F32,
            "float64" => Primitive::F64,
            _ => return None,
        })
    }

    /// Size in bytes, which is also its CDR alignment.
    pub fn size(self) -> usize {
        match self {
            Primitive::Bool | Primitive::U8 | Primitive::Char | Primitive::I8 => 1,
            Primitive::I16 | Primitive::U16 => 2,
            Primitive::I32 | Primitive::U32 | Primitive::F32 => 4,
            Primitive::I64 | Primitive::U64 | Primitive::F64 => 8,
        }
    }

    /// The `.msg` name.
    pub fn name(self) -> &'static str {
        match self {
            Primitive::Bool => "bool",
            Primitive::U8 => "uint8",
            Primitive::Char => "char",
            Primitive::I8 => "int8",
            Primitive::I16 => "int16",
            Primitive::U16 => "uint16",
            Primitive::I32 => "int32",
            Primitive::U32 => "uint32",
            Primitive::I64 => "int64",
            Primitive::U64 => "uint64",
            Primitive::F32 => "float32",
            Primitive::F64 => "float64",
        }
    }
}

/// The element type of a field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldType {
    /// A primitive.
    Primitive(Primitive),
    /// A string, with its bound if it has one.
    String(Option<u32>),
    /// A wide string (decoded as UTF-16 code units).
    WString(Option<u32>),
    /// A message type: an index into [`Schema::types`].
    Message(usize),
}

/// Whether a field is one value or several.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arity {
    /// One value.
    Single,
    /// `T[N]`: exactly `N` values, no length on the wire.
    Fixed(u32),
    /// `T[]`: a length, then the values.
    Sequence,
    /// `T[<=N]`: a length of at most `N`, then the values.
    Bounded(u32),
}

/// One field of a message type.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldDef {
    /// Its name.
    pub name: String,
    /// Its element type.
    pub ty: FieldType,
    /// One value or several.
    pub arity: Arity,
}

/// One message type: its name (`pkg/msg/Type`) and fields in wire order.
#[derive(Clone, Debug, PartialEq)]
pub struct MessageDef {
    /// `pkg/msg/Type`.
    pub name: String,
    /// The fields, in the order they are serialised.
    pub fields: Vec<FieldDef>,
}

impl MessageDef {
    /// The index of the field called `name`.
    pub fn field_index(&self, name: &str) -> Option<usize> {
        self.fields.iter().position(|f| f.name == name)
    }
}

/// A message type and every type it uses, ready to decode messages.
#[derive(Clone, Debug, PartialEq)]
pub struct Schema {
    types: Vec<MessageDef>,
}

/// Why a schema could not be used.
#[derive(Debug, Error, PartialEq)]
pub struct SchemaError {
    /// The type whose definition is wrong (`pkg/msg/Type`).
    pub message_type: String,
    /// The 1-based line within that type's definition, if the problem is on one line.
    pub line: Option<usize>,
    /// The field the problem is about, if any.
    pub field: Option<String>,
    /// What is wrong.
    pub problem: String,
}

impl fmt::Display for SchemaError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.message_type)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ", field `{field}`")?;
        }
        write!(f, ": {}", self.problem)
    }
}

/// `pkg/msg/Type` for `pkg/Type` or `pkg/msg/Type`; `None` for anything else.
pub fn canonical_type_name(name: &str) -> Option<String> {
    let parts: Vec<&str> = name.split('/').collect();
    let ok = |s: &str| !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    match parts.as_slice() {
        [pkg, ty] if ok(pkg) && ok(ty) => Some(format!("{pkg}/msg/{ty}")),
        [pkg, "msg", ty] if ok(pkg) && ok(ty) => Some(format!("{pkg}/msg/{ty}")),
        _ => None,
    }
}

/// A field as written, before its message type is resolved.
struct RawField {
    name: String,
    base: RawBase,
    arity: Arity,
    line: usize,
}

enum RawBase {
    Resolved(FieldType),
    Named(String),
}

impl Schema {
    /// Parses a rosbag2 `ros2msg` schema of `type_name` (`pkg/msg/Type` or `pkg/Type`).
    ///
    /// # Errors
    /// A [`SchemaError`] naming the type, line and field: a line that is not a field, a type
    /// that is not defined, a type that contains itself, too deep or too many fields.
    pub fn parse(type_name: &str, text: &str) -> Result<Schema, SchemaError> {
        let root_name = canonical_type_name(type_name).ok_or_else(|| SchemaError {
            message_type: type_name.to_string(),
            line: None,
            field: None,
            problem: "not a message type name (expected pkg/msg/Type)".into(),
        })?;
        let sections = split_sections(&root_name, text)?;
        let mut names: HashMap<String, usize> = HashMap::new();
        for (i, (name, _)) in sections.iter().enumerate() {
            // The first definition of a name wins, as in rosbag2's own readers.
            names.entry(name.clone()).or_insert(i);
        }
        let mut budget = MAX_FIELDS;
        let mut raw_types = Vec::with_capacity(sections.len());
        for (name, body) in &sections {
            // The limit applies while a type is parsed, so that no more than MAX_FIELDS + 1
            // fields are ever looked at.
            let fields = parse_fields(name, body, budget).ok_or_else(|| SchemaError {
                message_type: root_name.clone(),
                line: None,
                field: None,
                problem: format!("more than {MAX_FIELDS} fields in all"),
            })??;
            budget -= fields.len();
            raw_types.push((name.clone(), fields));
        }
        let mut types = Vec::with_capacity(raw_types.len());
        for (name, fields) in raw_types {
            let package = name.split('/').next().unwrap_or_default().to_string();
            let mut resolved = Vec::with_capacity(fields.len());
            for field in fields {
                let ty = match field.base {
                    RawBase::Resolved(ty) => ty,
                    RawBase::Named(ref ty_name) => {
                        let target = resolve_name(&package, ty_name);
                        let index = target.as_ref().and_then(|t| names.get(t)).copied();
                        match index {
                            Some(i) => FieldType::Message(i),
                            None => {
                                return Err(SchemaError {
                                    message_type: name.clone(),
                                    line: Some(field.line),
                                    field: Some(field.name.clone()),
                                    problem: format!("type {ty_name} is not defined in the schema"),
                                });
                            }
                        }
                    }
                };
                resolved.push(FieldDef {
                    name: field.name,
                    ty,
                    arity: field.arity,
                });
            }
            types.push(MessageDef {
                name,
                fields: resolved,
            });
        }
        let schema = Schema { types };
        schema.check_nesting()?;
        Ok(schema)
    }

    /// The message type the schema describes.
    pub fn root(&self) -> &MessageDef {
        &self.types[0]
    }

    /// Every type, the root first; [`FieldType::Message`] indexes into this.
    pub fn types(&self) -> &[MessageDef] {
        &self.types
    }

    /// The type at `index`.
    pub fn get(&self, index: usize) -> &MessageDef {
        &self.types[index]
    }

    /// Refuses types that contain themselves and nesting deeper than [`MAX_DEPTH`] (a
    /// depth-first walk from the root with an explicit stack).
    fn check_nesting(&self) -> Result<(), SchemaError> {
        // Depth of the deepest chain below each type, computed once per type.
        #[derive(Clone, Copy, PartialEq)]
        enum State {
            New,
            Open,
            Done(usize),
        }
        let mut state = vec![State::New; self.types.len()];
        let mut stack: Vec<(usize, usize)> = vec![(0, 0)];
        state[0] = State::Open;
        while let Some(&mut (ty, ref mut next)) = stack.last_mut() {
            let fields = &self.types[ty].fields;
            if *next < fields.len() {
                let field = &fields[*next];
                *next += 1;
                if let FieldType::Message(child) = field.ty {
                    match state[child] {
                        State::Open => {
                            return Err(SchemaError {
                                message_type: self.types[ty].name.clone(),
                                line: None,
                                field: Some(field.name.clone()),
                                problem: format!(
                                    "type {} contains itself (it could never be decoded)",
                                    self.types[child].name
                                ),
                            });
                        }
                        State::New => {
                            if stack.len() >= MAX_DEPTH {
                                return Err(SchemaError {
                                    message_type: self.types[0].name.clone(),
                                    line: None,
                                    field: Some(field.name.clone()),
                                    problem: format!("types are nested more than {MAX_DEPTH} deep"),
                                });
                            }
                            state[child] = State::Open;
                            stack.push((child, 0));
                        }
                        State::Done(_) => {}
                    }
                }
            } else {
                let depth = fields
                    .iter()
                    .filter_map(|f| match f.ty {
                        FieldType::Message(c) => match state[c] {
                            State::Done(d) => Some(d + 1),
                            _ => None,
                        },
                        _ => None,
                    })
                    .max()
                    .unwrap_or(0);
                if depth > MAX_DEPTH {
                    return Err(SchemaError {
                        message_type: self.types[0].name.clone(),
                        line: None,
                        field: None,
                        problem: format!("types are nested more than {MAX_DEPTH} deep"),
                    });
                }
                state[ty] = State::Done(depth);
                stack.pop();
            }
        }
        Ok(())
    }
}

/// The canonical name a field's type refers to from a type of `package`.
fn resolve_name(package: &str, name: &str) -> Option<String> {
    if name.contains('/') {
        canonical_type_name(name)
    } else if name == "Header" {
        Some("std_msgs/msg/Header".into())
    } else {
        canonical_type_name(&format!("{package}/{name}"))
    }
}

/// Splits a schema into `(pkg/msg/Type, body)` sections, the root first.
fn split_sections<'t>(
    root: &str,
    text: &'t str,
) -> Result<Vec<(String, Vec<&'t str>)>, SchemaError> {
    let mut sections: Vec<(String, Vec<&str>)> = vec![(root.to_string(), Vec::new())];
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let trimmed = line.trim();
        if trimmed.len() >= 3 && trimmed.bytes().all(|b| b == b'=') {
            // A separator; the next non-empty line names the type.
            let header = loop {
                match lines.next() {
                    Some(l) if l.trim().is_empty() => continue,
                    Some(l) => break l.trim(),
                    None => break "",
                }
            };
            let Some(name) = header.strip_prefix("MSG:") else {
                return Err(SchemaError {
                    message_type: root.to_string(),
                    line: None,
                    field: None,
                    problem: format!(
                        "expected `MSG: pkg/Type` after a separator line, found {:?}",
                        excerpt(header)
                    ),
                });
            };
            let name = name.trim();
            let canonical = canonical_type_name(name).ok_or_else(|| SchemaError {
                message_type: root.to_string(),
                line: None,
                field: None,
                problem: format!("`MSG: {}` does not name a message type", excerpt(name)),
            })?;
            sections.push((canonical, Vec::new()));
        } else if let Some(last) = sections.last_mut() {
            last.1.push(line);
        }
    }
    Ok(sections)
}

/// At most 40 characters of `s`, for error messages.
fn excerpt(s: &str) -> String {
    let mut out: String = s.chars().take(40).collect();
    if out.len() < s.len() {
        out.push('…');
    }
    out
}

/// Parses the field lines of one type; `None` once it has more than `budget` fields.
fn parse_fields(
    name: &str,
    body: &[&str],
    budget: usize,
) -> Option<Result<Vec<RawField>, SchemaError>> {
    let mut fields: Vec<RawField> = Vec::new();
    // Field names seen, for duplicates in constant time each.
    let mut seen: HashSet<&str> = HashSet::new();
    for (i, raw) in body.iter().enumerate() {
        let line = i + 1;
        let error = |field: Option<&str>, problem: String| SchemaError {
            message_type: name.to_string(),
            line: Some(line),
            field: field.map(str::to_string),
            problem,
        };
        let code = raw.trim();
        if code.is_empty() || code.starts_with('#') {
            continue;
        }
        let mut parts = code.splitn(2, char::is_whitespace);
        let ty = parts.next().unwrap_or_default();
        let rest = parts.next().unwrap_or_default().trim_start();
        let field_name: String = rest
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect();
        let after = rest[field_name.len()..].trim_start();
        if after.starts_with('=') {
            continue; // a constant
        }
        if field_name.is_empty() {
            return Some(Err(error(
                None,
                format!("expected `TYPE NAME`, found {:?}", excerpt(code)),
            )));
        }
        if !field_name.starts_with(|c: char| c.is_ascii_alphabetic()) {
            return Some(Err(error(
                Some(&field_name),
                "a field name must start with a letter".into(),
            )));
        }
        if fields.len() == budget {
            return None;
        }
        let (base, arity) = match parse_type(ty) {
            Ok(parsed) => parsed,
            Err(problem) => return Some(Err(error(Some(&field_name), problem))),
        };
        if !seen.insert(&rest[..field_name.len()]) {
            return Some(Err(error(
                Some(&field_name),
                "the field is defined twice".into(),
            )));
        }
        fields.push(RawField {
            name: field_name,
            base,
            arity,
            line,
        });
    }
    Some(Ok(fields))
}

/// Parses `TYPE` with its array suffix.
fn parse_type(ty: &str) -> Result<(RawBase, Arity), String> {
    let (base, arity) = match ty.find('[') {
        None => (ty, Arity::Single),
        Some(open) => {
            let Some(inner) = ty[open + 1..].strip_suffix(']') else {
                return Err(format!("array type {:?} has no closing `]`", excerpt(ty)));
            };
            let arity = if inner.is_empty() {
                Arity::Sequence
            } else if let Some(bound) = inner.strip_prefix("<=") {
                Arity::Bounded(parse_bound(bound, ty)?)
            } else {
                match parse_bound(inner, ty)? {
                    // Elements that take no bytes on the wire could be decoded without end.
                    0 => return Err(format!("array type {:?} has no elements", excerpt(ty))),
                    n => Arity::Fixed(n),
                }
            };
            (&ty[..open], arity)
        }
    };
    let base = if let Some(p) = Primitive::from_name(base) {
        RawBase::Resolved(FieldType::Primitive(p))
    } else if base == "string" || base.starts_with("string<=") {
        let bound = base
            .strip_prefix("string<=")
            .map(|b| parse_bound(b, ty))
            .transpose()?;
        RawBase::Resolved(FieldType::String(bound))
    } else if base == "wstring" || base.starts_with("wstring<=") {
        let bound = base
            .strip_prefix("wstring<=")
            .map(|b| parse_bound(b, ty))
            .transpose()?;
        RawBase::Resolved(FieldType::WString(bound))
    } else if base == "time" || base == "duration" {
        // ROS 1 built-ins, named by ROS 2 as builtin_interfaces types.
        let name = if base == "time" { "Time" } else { "Duration" };
        RawBase::Named(format!("builtin_interfaces/{name}"))
    } else if !base.is_empty()
        && base
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '/')
    {
        RawBase::Named(base.to_string())
    } else {
        return Err(format!("{:?} is not a type", excerpt(ty)));
    };
    Ok((base, arity))
}

fn parse_bound(text: &str, ty: &str) -> Result<u32, String> {
    text.parse::<u32>()
        .map_err(|_| format!("array or string bound in {:?} is not a number", excerpt(ty)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SEP: &str =
        "================================================================================";

    #[test]
    fn laser_scan_of_the_malaga_bag() {
        // The schema text rosbags wrote into data/malaga_laser_2006's bag.
        let text = format!(
            "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n\
             float32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\n\
             float32[] ranges\nfloat32[] intensities\n{SEP}\nMSG: std_msgs/Header\n\
             builtin_interfaces/Time stamp\nstring frame_id\n{SEP}\nMSG: builtin_interfaces/Time\n\
             int32 sec\nuint32 nanosec\n"
        );
        let schema = Schema::parse("sensor_msgs/msg/LaserScan", &text).unwrap();
        assert_eq!(schema.types().len(), 3);
        let root = schema.root();
        assert_eq!(root.fields.len(), 10);
        assert_eq!(root.fields[8].name, "ranges");
        assert_eq!(root.fields[8].arity, Arity::Sequence);
        assert_eq!(root.fields[8].ty, FieldType::Primitive(Primitive::F32));
        assert_eq!(schema.get(1).name, "std_msgs/msg/Header");
        assert_eq!(
            schema.get(2).fields[1].ty,
            FieldType::Primitive(Primitive::U32)
        );
    }

    #[test]
    fn constants_defaults_comments_bounds_and_local_types() {
        let text = format!(
            "# a comment\nuint8 KEEPOUT=0   # constant\nstring NAME = \"a # b\"\n\
             uint8 type\nstring<=8 label \"x\"\nint32[3] fixed [1, 2, 3]\nfloat64[<=4] few\n\
             Inner inner  # same package\nHeader header\n{SEP}\nMSG: pkg/Inner\nbyte b\n\
             {SEP}\nMSG: std_msgs/msg/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
             {SEP}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
        );
        let schema = Schema::parse("pkg/Outer", &text).unwrap();
        let names: Vec<&str> = schema
            .root()
            .fields
            .iter()
            .map(|f| f.name.as_str())
            .collect();
        assert_eq!(names, ["type", "label", "fixed", "few", "inner", "header"]);
        let f = &schema.root().fields;
        assert_eq!(f[1].ty, FieldType::String(Some(8)));
        assert_eq!(f[2].arity, Arity::Fixed(3));
        assert_eq!(f[3].arity, Arity::Bounded(4));
        assert_eq!(f[4].ty, FieldType::Message(1));
        assert_eq!(f[5].ty, FieldType::Message(2));
        assert_eq!(schema.root().name, "pkg/msg/Outer");
    }

    #[test]
    fn bad_schemas_name_the_type_line_and_field() {
        let err = Schema::parse("a/B", "int32 x\nfloat33 y\n").unwrap_err();
        assert_eq!(
            err.to_string(),
            "a/msg/B:2, field `y`: type float33 is not defined in the schema"
        );
        let err = Schema::parse("a/B", "int32 x\nint32\n").unwrap_err();
        assert_eq!(
            err.to_string(),
            "a/msg/B:2: expected `TYPE NAME`, found \"int32\""
        );
        let err = Schema::parse("a/B", "int32[ x\n").unwrap_err();
        assert_eq!(
            err.to_string(),
            "a/msg/B:1, field `x`: array type \"int32[\" has no closing `]`"
        );
        let err = Schema::parse("a/B", "int32 x\nint64 x\n").unwrap_err();
        assert_eq!(err.line, Some(2));
        let err = Schema::parse("not a type", "int32 x\n").unwrap_err();
        assert!(err.to_string().contains("not a message type name"), "{err}");
        let err = Schema::parse("a/B", &format!("int32 x\n{SEP}\nnonsense\n")).unwrap_err();
        assert!(
            err.to_string().contains("expected `MSG: pkg/Type`"),
            "{err}"
        );
    }

    #[test]
    fn types_that_contain_themselves_are_refused() {
        let text = format!("C c\n{SEP}\nMSG: a/C\nD d\n{SEP}\nMSG: a/D\nC c\n");
        let err = Schema::parse("a/B", &text).unwrap_err();
        assert!(err.to_string().contains("contains itself"), "{err}");
        // A type used twice is not a cycle.
        let text = format!("C one\nC two\nD d\n{SEP}\nMSG: a/C\nint8 x\n{SEP}\nMSG: a/D\nC c\n");
        assert!(Schema::parse("a/B", &text).is_ok());
    }

    #[test]
    fn deep_nesting_is_refused_without_recursion() {
        let mut text = String::from("T0 next\n");
        for i in 0..200 {
            text.push_str(&format!("{SEP}\nMSG: a/T{i}\nT{} next\n", i + 1));
        }
        text.push_str(&format!("{SEP}\nMSG: a/T200\nint8 leaf\n"));
        let err = Schema::parse("a/Root", &text).unwrap_err();
        assert!(
            err.to_string().contains("nested more than 64 deep"),
            "{err}"
        );
    }
}
