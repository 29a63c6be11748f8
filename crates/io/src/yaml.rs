//! The YAML reader shared by the map_server files ([`crate::navmap`]) and the topological maps
//! ([`crate::topo_files`]): one value type with the line of every part, one serde visitor
//! that builds it from [serde-saphyr](https://docs.rs/serde-saphyr) (YAML 1.2), and the
//! parser's errors in file terms.

use std::fmt;

use serde::de::{Deserialize, Deserializer, MapAccess, SeqAccess, Visitor};
use serde_saphyr::Spanned;

/// A YAML value with the locations of its parts.
#[derive(Debug)]
pub(crate) enum Yaml {
    Null,
    Bool(bool),
    Int(i128),
    Float(f64),
    Str(String),
    Seq(Vec<Spanned<Yaml>>),
    /// Entries in file order; a key that is not a string is held as its text.
    Map(Vec<(String, Spanned<Yaml>)>),
}

#[cfg(feature = "navmap")]
impl Yaml {
    /// The value with the items of a sequence written out (`[1, 2, "x"]`); [`Yaml`]'s
    /// `Display` writes `[...]` for them.
    pub(crate) fn listed(&self) -> Listed<'_> {
        Listed(self)
    }
}

impl<'de> Deserialize<'de> for Yaml {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct YamlVisitor;
        impl<'de> Visitor<'de> for YamlVisitor {
            type Value = Yaml;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("any YAML value")
            }
            fn visit_bool<E>(self, v: bool) -> Result<Yaml, E> {
                Ok(Yaml::Bool(v))
            }
            fn visit_i64<E>(self, v: i64) -> Result<Yaml, E> {
                Ok(Yaml::Int(v.into()))
            }
            fn visit_u64<E>(self, v: u64) -> Result<Yaml, E> {
                Ok(Yaml::Int(v.into()))
            }
            fn visit_i128<E>(self, v: i128) -> Result<Yaml, E> {
                Ok(Yaml::Int(v))
            }
            fn visit_u128<E>(self, v: u128) -> Result<Yaml, E> {
                Ok(i128::try_from(v).map_or(Yaml::Float(v as f64), Yaml::Int))
            }
            fn visit_f64<E>(self, v: f64) -> Result<Yaml, E> {
                Ok(Yaml::Float(v))
            }
            fn visit_str<E>(self, v: &str) -> Result<Yaml, E> {
                Ok(Yaml::Str(v.to_owned()))
            }
            fn visit_bytes<E>(self, v: &[u8]) -> Result<Yaml, E> {
                Ok(Yaml::Str(String::from_utf8_lossy(v).into_owned()))
            }
            fn visit_unit<E>(self) -> Result<Yaml, E> {
                Ok(Yaml::Null)
            }
            fn visit_none<E>(self) -> Result<Yaml, E> {
                Ok(Yaml::Null)
            }
            fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Yaml, D::Error> {
                Yaml::deserialize(d)
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Yaml, A::Error> {
                let mut items = Vec::new();
                while let Some(item) = seq.next_element()? {
                    items.push(item);
                }
                Ok(Yaml::Seq(items))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Yaml, A::Error> {
                let mut entries = Vec::new();
                while let Some(key) = map.next_key::<Yaml>()? {
                    let key = match key {
                        Yaml::Str(s) => s,
                        other => other.to_string(),
                    };
                    entries.push((key, map.next_value()?));
                }
                Ok(Yaml::Map(entries))
            }
        }
        deserializer.deserialize_any(YamlVisitor)
    }
}

impl fmt::Display for Yaml {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Yaml::Null => f.write_str("null"),
            Yaml::Bool(b) => write!(f, "{b}"),
            Yaml::Int(i) => write!(f, "{i}"),
            Yaml::Float(x) => write!(f, "{x:?}"),
            Yaml::Str(s) => write!(f, "{s:?}"),
            Yaml::Seq(_) => f.write_str("[...]"),
            Yaml::Map(_) => f.write_str("{...}"),
        }
    }
}

/// [`Yaml::listed`] (map files quote whole sequences in their errors).
#[cfg(feature = "navmap")]
pub(crate) struct Listed<'a>(&'a Yaml);

#[cfg(feature = "navmap")]
impl fmt::Display for Listed<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Yaml::Seq(items) => {
                f.write_str("[")?;
                for (i, item) in items.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{}", item.value.listed())?;
                }
                f.write_str("]")
            }
            other => write!(f, "{other}"),
        }
    }
}

/// `text` as a double-quoted YAML scalar, escaping quotes, backslashes and control
/// characters, for the writers of both formats.
pub(crate) fn double_quoted(text: &str) -> String {
    let mut quoted = String::with_capacity(text.len() + 2);
    quoted.push('"');
    for c in text.chars() {
        match c {
            '"' => quoted.push_str("\\\""),
            '\\' => quoted.push_str("\\\\"),
            '\n' => quoted.push_str("\\n"),
            '\t' => quoted.push_str("\\t"),
            '\r' => quoted.push_str("\\r"),
            c if c.is_control() => quoted.push_str(&format!("\\u{:04x}", u32::from(c))),
            c => quoted.push(c),
        }
    }
    quoted.push('"');
    quoted
}

/// The place of an error in a YAML file, as its message starts: `file:line: `, `file: `,
/// `line N: ` or nothing.
pub(crate) struct Prefix<'a>(pub(crate) Option<&'a str>, pub(crate) Option<u64>);

impl fmt::Display for Prefix<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.0, self.1) {
            (Some(file), Some(line)) => write!(f, "{file}:{line}: "),
            (Some(file), None) => write!(f, "{file}: "),
            (None, Some(line)) => write!(f, "line {line}: "),
            (None, None) => Ok(()),
        }
    }
}

/// Why a YAML text could not be read: the parser's message in file terms, and its line
/// when the parser knows it.
pub(crate) struct YamlError {
    pub(crate) line: Option<u64>,
    pub(crate) message: String,
}

/// Parses one YAML document. Non-finite numbers reach the caller, which names their key; with
/// `strict_booleans` only `true`/`false` are booleans (not YAML 1.1's `y`/`n`, `yes`/`no`, …).
/// Nesting depth is limited by serde-saphyr's default budget (64 levels), which keeps
/// recursive readers safe.
pub(crate) fn parse(text: &[u8], strict_booleans: bool) -> Result<Spanned<Yaml>, YamlError> {
    let options = serde_saphyr::options! {
        strict_booleans: strict_booleans,
        non_finite_float_policy: serde_saphyr::NonFiniteFloatPolicy::PassThrough,
        with_snippet: false,
    };
    serde_saphyr::from_slice_with_options(text, options).map_err(|e| YamlError {
        line: e.location().map(|l| l.line()),
        message: message(&e),
    })
}

/// The parser's message without its location (the error has the line), in map terms.
fn message(error: &serde_saphyr::Error) -> String {
    let mut message = error.without_snippet().to_string();
    if let Some(at) = message.rfind(" at line ") {
        message.truncate(at);
    }
    if let Some(rest) = message.strip_prefix("duplicate mapping key: ") {
        let key = rest.split(',').next().unwrap_or(rest);
        format!("the key `{key}` appears twice")
    } else if message.starts_with("multiple YAML documents") {
        "several YAML documents (a map file has one)".to_owned()
    } else if message.starts_with("budget breached: Depth") {
        "collections nested too deeply".to_owned()
    } else {
        message
    }
}
