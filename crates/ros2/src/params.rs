//! The node's parameters as ROS 2 has them: flat names (`states.door.model`) with typed values
//! (`rcl_interfaces/msg/ParameterValue`), gathered from parameter files and `-p` arguments in
//! the order rcl applies them, each value remembering where it came from (file and line, or
//! the argument), so that every error names its source.
//!
//! A parameter file is ROS 2's YAML layout, `NODE: {ros__parameters: {...}}`, read with
//! [serde-saphyr](https://docs.rs/serde-saphyr). Nested mappings and dotted keys are the same
//! parameters (`states: {door: {model: x}}` is `states.door.model: x`, as `launch_ros` writes
//! either). Values: `true`/`false` (rcl's `yes`/`no`/`on`/`off` too, where a boolean is
//! expected), integers, floating point numbers, strings, and lists of one type (integers mixed
//! with floating point numbers are read as floating point). Which entries of a file apply is
//! rcl's rule: `/**`, `/*/NAME`, `NAME` or `/NS/NAME` matching the node, in file order.
//!
//! The typed checks (what each parameter means) are [`crate::config`]'s.
//!
//! ```
//! use chronomap_ros2::params::{ParamFile, ParamSet, Value};
//!
//! let file = ParamFile::parse("p.yaml".as_ref(), b"/**:\n  ros__parameters:\n    states.door.model: hist:24\n    horizon: 600\n")?;
//! let mut set = ParamSet::default();
//! file.apply_matching("/robot1/chronomap", &mut set)?;
//! set.apply_override("horizon", "7.5", "-p horizon:=7.5")?;
//! assert_eq!(set.values["states.door.model"].value, Value::String("hist:24".into()));
//! assert_eq!(set.values["horizon"].value, Value::Double(7.5));
//! assert_eq!(set.values["horizon"].origin.to_string(), "-p horizon:=7.5");
//! # Ok::<(), chronomap_ros2::config::ConfigError>(())
//! ```

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use serde::de::{self, Deserialize, Deserializer, MapAccess, SeqAccess, Visitor};
use serde_saphyr::Spanned;

use crate::config::ConfigError;

/// A parameter value (`rcl_interfaces/msg/ParameterValue`).
pub use ros2_client::ParameterValue as Value;

/// Largest parameter file read (the node's parameters fit in a few kilobytes).
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// Where a parameter's value came from.
#[derive(Clone, Debug, PartialEq)]
pub enum Origin {
    /// A line of a parameter file.
    File {
        /// The file.
        path: PathBuf,
        /// The line (from 1).
        line: u64,
    },
    /// A command-line argument (`-p horizon:=600`).
    Argument(String),
    /// Set at run time through the `set_parameters` service.
    Service,
}

impl Origin {
    /// The source as errors name it: the file, the argument or `set_parameters`.
    pub fn source(&self) -> String {
        match self {
            Origin::File { path, .. } => path.display().to_string(),
            Origin::Argument(a) => a.clone(),
            Origin::Service => "set_parameters".to_string(),
        }
    }

    /// The line, for files.
    pub fn line(&self) -> Option<u64> {
        match self {
            Origin::File { line, .. } => Some(*line),
            _ => None,
        }
    }

    /// The folder relative paths in this value are relative to: the file's folder, else the
    /// working directory.
    pub fn folder(&self) -> PathBuf {
        match self {
            Origin::File { path, .. } => path.parent().unwrap_or(Path::new("")).to_path_buf(),
            _ => PathBuf::new(),
        }
    }

    /// An error about the parameter `key` of this value.
    pub fn error(&self, key: Option<&str>, message: impl Into<String>) -> ConfigError {
        ConfigError {
            file: self.source(),
            line: self.line(),
            key: key.map(str::to_string),
            message: message.into(),
        }
    }
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.source())?;
        if let Some(line) = self.line() {
            write!(f, ":{line}")?;
        }
        Ok(())
    }
}

/// A value and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// The value.
    pub value: Value,
    /// Its source.
    pub origin: Origin,
}

/// Parameters by flat name; a later value replaces an earlier one.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParamSet {
    /// The values.
    pub values: BTreeMap<String, Entry>,
    /// Where each nested mapping (`states.door`) was first given: errors about a section
    /// (a missing key) point there.
    pub sections: BTreeMap<String, Origin>,
}

impl ParamSet {
    /// Sets `name` (a later value wins).
    pub fn insert(&mut self, name: &str, value: Value, origin: Origin) {
        let mut prefix = String::new();
        for token in name
            .split('.')
            .take(name.split('.').count().saturating_sub(1))
        {
            if !prefix.is_empty() {
                prefix.push('.');
            }
            prefix.push_str(token);
            self.sections
                .entry(prefix.clone())
                .or_insert_with(|| origin.clone());
        }
        self.values
            .insert(name.to_string(), Entry { value, origin });
    }

    /// Applies `-p NAME:=VALUE` (`text` is YAML, as rcl reads it; `argument` is the argument
    /// as given, for errors).
    ///
    /// # Errors
    /// A value that is not one parameter value (a mapping, mixed lists, `null`).
    pub fn apply_override(
        &mut self,
        name: &str,
        text: &str,
        argument: &str,
    ) -> Result<(), ConfigError> {
        let origin = Origin::Argument(argument.to_string());
        let tree = parse_tree(text.as_bytes())
            .map_err(|(_, message)| origin.error(Some(name), message))?;
        if let Tree::Map(_) = tree.value {
            return Err(origin.error(
                Some(name),
                "a mapping is not a parameter value (name nested parameters with dots: a.b:=1)",
            ));
        }
        let value = value_of(&tree.value).map_err(|m| origin.error(Some(name), m))?;
        self.insert(name, value, origin);
        Ok(())
    }
}

/// A parsed YAML node with its position.
#[derive(Debug)]
enum Tree {
    Null,
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
    Seq(Vec<Spanned<Tree>>),
    Map(Vec<(Spanned<String>, Spanned<Tree>)>),
}

struct TreeVisitor;

impl<'de> Visitor<'de> for TreeVisitor {
    type Value = Tree;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a YAML value")
    }
    fn visit_bool<E>(self, v: bool) -> Result<Tree, E> {
        Ok(Tree::Bool(v))
    }
    fn visit_i64<E>(self, v: i64) -> Result<Tree, E> {
        Ok(Tree::Int(v))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Tree, E> {
        i64::try_from(v)
            .map(Tree::Int)
            .map_err(|_| E::custom(format!("{v} is out of the range of a 64-bit integer")))
    }
    fn visit_i128<E: de::Error>(self, v: i128) -> Result<Tree, E> {
        i64::try_from(v)
            .map(Tree::Int)
            .map_err(|_| E::custom(format!("{v} is out of the range of a 64-bit integer")))
    }
    fn visit_u128<E: de::Error>(self, v: u128) -> Result<Tree, E> {
        i64::try_from(v)
            .map(Tree::Int)
            .map_err(|_| E::custom(format!("{v} is out of the range of a 64-bit integer")))
    }
    fn visit_f64<E>(self, v: f64) -> Result<Tree, E> {
        Ok(Tree::Float(v))
    }
    fn visit_str<E>(self, v: &str) -> Result<Tree, E> {
        Ok(Tree::Str(v.to_string()))
    }
    fn visit_string<E>(self, v: String) -> Result<Tree, E> {
        Ok(Tree::Str(v))
    }
    fn visit_unit<E>(self) -> Result<Tree, E> {
        Ok(Tree::Null)
    }
    fn visit_none<E>(self) -> Result<Tree, E> {
        Ok(Tree::Null)
    }
    fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Tree, D::Error> {
        d.deserialize_any(TreeVisitor)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Tree, A::Error> {
        let mut items = Vec::new();
        while let Some(item) = seq.next_element::<Spanned<Tree>>()? {
            items.push(item);
        }
        Ok(Tree::Seq(items))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Tree, A::Error> {
        let mut items: Vec<(Spanned<String>, Spanned<Tree>)> = Vec::new();
        while let Some(key) = map.next_key::<Spanned<String>>()? {
            if items.iter().any(|(k, _)| k.value == key.value) {
                return Err(de::Error::custom(format!(
                    "the key `{}` appears twice (line {})",
                    key.value,
                    key.referenced.line()
                )));
            }
            let value = map.next_value::<Spanned<Tree>>()?;
            items.push((key, value));
        }
        Ok(Tree::Map(items))
    }
}

impl<'de> Deserialize<'de> for Tree {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Tree, D::Error> {
        d.deserialize_any(TreeVisitor)
    }
}

/// Parses YAML text: the tree, or the line and message of the parser's error.
fn parse_tree(text: &[u8]) -> Result<Spanned<Tree>, (Option<u64>, String)> {
    let options = serde_saphyr::options! {
        strict_booleans: true,
        with_snippet: false,
    };
    serde_saphyr::from_slice_with_options::<Spanned<Tree>>(text, options)
        .map_err(|e| (e.location().map(|l| l.line()), parser_message(&e)))
}

/// The parser's message without its location (the error carries the line).
fn parser_message(error: &serde_saphyr::Error) -> String {
    let mut message = error.without_snippet().to_string();
    if let Some(at) = message.rfind(" at line ") {
        message.truncate(at);
    }
    if let Some(rest) = message.strip_prefix("duplicate mapping key: ") {
        let key = rest.split(',').next().unwrap_or(rest);
        format!("the key `{key}` appears twice")
    } else if message.starts_with("multiple YAML documents") {
        "several YAML documents (a parameter file has one)".to_owned()
    } else {
        message
    }
}

/// A scalar or list as a parameter value.
fn value_of(tree: &Tree) -> Result<Value, String> {
    Ok(match tree {
        Tree::Null => {
            return Err(
                "no value (`~`/null); write \"\" for an empty string or leave the parameter out"
                    .into(),
            );
        }
        Tree::Bool(b) => Value::Boolean(*b),
        Tree::Int(i) => Value::Integer(*i),
        Tree::Float(f) => Value::Double(*f),
        Tree::Str(s) => Value::String(s.clone()),
        Tree::Map(_) => unreachable!("mappings are flattened"),
        Tree::Seq(items) => {
            let all = |f: fn(&Tree) -> bool| items.iter().all(|i| f(&i.value));
            if items.is_empty() {
                return Err("an empty list (a parameter's type comes from its values)".into());
            }
            if all(|t| matches!(t, Tree::Bool(_))) {
                Value::BooleanArray(
                    items
                        .iter()
                        .map(|i| matches!(i.value, Tree::Bool(true)))
                        .collect(),
                )
            } else if all(|t| matches!(t, Tree::Int(_))) {
                Value::IntegerArray(
                    items
                        .iter()
                        .map(|i| match i.value {
                            Tree::Int(v) => v,
                            _ => 0,
                        })
                        .collect(),
                )
            } else if all(|t| matches!(t, Tree::Int(_) | Tree::Float(_))) {
                Value::DoubleArray(
                    items
                        .iter()
                        .map(|i| match i.value {
                            Tree::Int(v) => v as f64,
                            Tree::Float(v) => v,
                            _ => 0.0,
                        })
                        .collect(),
                )
            } else if all(|t| matches!(t, Tree::Str(_))) {
                Value::StringArray(
                    items
                        .iter()
                        .map(|i| match &i.value {
                            Tree::Str(s) => s.clone(),
                            _ => String::new(),
                        })
                        .collect(),
                )
            } else {
                return Err(
                    "a list of mixed or nested values (a parameter is a list of booleans, \
                     numbers or strings)"
                        .into(),
                );
            }
        }
    })
}

/// One `NODE: {ros__parameters: ...}` entry of a file.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeEntry {
    /// The node key as written (`chronomap`, `/robot1/chronomap`, `/**`).
    pub key: String,
    /// Where it is.
    pub origin: Origin,
    /// Its parameters.
    pub params: ParamSet,
}

/// A parameter file: its node entries in file order.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamFile {
    /// The file.
    pub path: PathBuf,
    /// The entries.
    pub entries: Vec<NodeEntry>,
}

impl ParamFile {
    /// Reads the parameter file `path`.
    ///
    /// # Errors
    /// A file that cannot be read, is larger than [`MAX_FILE_BYTES`] or is not a parameter
    /// file (naming line and key).
    pub fn read(path: &Path) -> Result<ParamFile, ConfigError> {
        let error = |message: String| ConfigError {
            file: path.display().to_string(),
            line: None,
            key: None,
            message,
        };
        let file = std::fs::File::open(path).map_err(|e| error(format!("cannot read: {e}")))?;
        if file.metadata().is_ok_and(|m| m.is_dir()) {
            return Err(error("cannot read: a folder, not a parameter file".into()));
        }
        let mut bytes = Vec::new();
        use std::io::Read;
        file.take(MAX_FILE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| error(format!("cannot read: {e}")))?;
        if bytes.len() as u64 > MAX_FILE_BYTES {
            return Err(error(format!(
                "larger than {MAX_FILE_BYTES} bytes: not a parameter file"
            )));
        }
        Self::parse(path, &bytes)
    }

    /// Parses the text of the parameter file `path`.
    ///
    /// # Errors
    /// As [`ParamFile::read`].
    pub fn parse(path: &Path, text: &[u8]) -> Result<ParamFile, ConfigError> {
        let at = |line: u64| Origin::File {
            path: path.to_path_buf(),
            line,
        };
        let file_error = |line: Option<u64>, key: Option<String>, message: String| ConfigError {
            file: path.display().to_string(),
            line,
            key,
            message,
        };
        let blank = text
            .split(|&b| b == b'\n')
            .all(|l| l.trim_ascii().is_empty() || l.trim_ascii_start().starts_with(b"#"));
        if blank {
            return Ok(ParamFile {
                path: path.to_path_buf(),
                entries: Vec::new(),
            });
        }
        let tree = parse_tree(text).map_err(|(line, m)| file_error(line, None, m))?;
        let Tree::Map(nodes) = tree.value else {
            return Err(file_error(
                Some(tree.referenced.line()),
                None,
                "not a parameter file (expected `NODE_NAME: {ros__parameters: {...}}`)".into(),
            ));
        };
        let mut entries = Vec::new();
        for (key, body) in nodes {
            let line = key.referenced.line();
            let Tree::Map(items) = body.value else {
                return Err(file_error(
                    Some(body.referenced.line()),
                    None,
                    format!(
                        "{}: not a node entry (expected `ros__parameters:` under it)",
                        key.value
                    ),
                ));
            };
            let mut params = ParamSet::default();
            let mut found = false;
            for (k, v) in items {
                if k.value != "ros__parameters" {
                    return Err(file_error(
                        Some(k.referenced.line()),
                        None,
                        format!(
                            "{}: unknown key `{}` (a node entry holds `ros__parameters` only)",
                            key.value, k.value
                        ),
                    ));
                }
                found = true;
                match v.value {
                    Tree::Map(items) => flatten("", &items, &at, &mut params)?,
                    Tree::Null => {}
                    _ => {
                        return Err(file_error(
                            Some(v.referenced.line()),
                            None,
                            format!(
                                "{}: ros__parameters is not a mapping of parameters",
                                key.value
                            ),
                        ));
                    }
                }
            }
            if !found {
                return Err(file_error(
                    Some(line),
                    None,
                    format!("{}: no `ros__parameters`", key.value),
                ));
            }
            entries.push(NodeEntry {
                key: key.value,
                origin: at(line),
                params,
            });
        }
        Ok(ParamFile {
            path: path.to_path_buf(),
            entries,
        })
    }

    /// Applies, in file order, every entry whose node name matches the node `fqn`
    /// (`/robot1/chronomap`), as rcl does for `--params-file`.
    ///
    /// # Errors
    /// None yet (the values were checked when parsed); kept for symmetry.
    pub fn apply_matching(&self, fqn: &str, set: &mut ParamSet) -> Result<(), ConfigError> {
        for entry in &self.entries {
            if node_matches(&entry.key, fqn) {
                for (name, value) in &entry.params.values {
                    set.insert(name, value.value.clone(), value.origin.clone());
                }
                for (name, origin) in &entry.params.sections {
                    set.sections
                        .entry(name.clone())
                        .or_insert_with(|| origin.clone());
                }
            }
        }
        Ok(())
    }
}

/// Adds the parameters of a mapping under `prefix`.
fn flatten(
    prefix: &str,
    items: &[(Spanned<String>, Spanned<Tree>)],
    at: &dyn Fn(u64) -> Origin,
    out: &mut ParamSet,
) -> Result<(), ConfigError> {
    for (key, value) in items {
        let name = if prefix.is_empty() {
            key.value.clone()
        } else {
            format!("{prefix}.{}", key.value)
        };
        let origin = at(key.referenced.line());
        if name.is_empty() || name.split('.').any(str::is_empty) {
            return Err(origin.error(
                None,
                format!("{name:?} is not a parameter name (tokens separated by single dots)"),
            ));
        }
        match &value.value {
            Tree::Map(inner) => {
                out.sections
                    .entry(name.clone())
                    .or_insert_with(|| origin.clone());
                flatten(&name, inner, at, out)?;
            }
            other => {
                let v = value_of(other).map_err(|m| origin.error(Some(&name), m))?;
                if let Some(previous) = out.values.get(&name) {
                    return Err(origin.error(
                        Some(&name),
                        format!(
                            "given twice in this entry (also at {}; nested and dotted keys are \
                             the same parameter)",
                            previous.origin
                        ),
                    ));
                }
                out.insert(&name, v, origin);
            }
        }
    }
    Ok(())
}

/// Whether the node-name pattern `pattern` of a parameter file (`/**`, `/*/name`, `name`,
/// `/ns/name`) matches the node `fqn`: `*` is one token, `**` any number of them.
pub fn node_matches(pattern: &str, fqn: &str) -> bool {
    fn tokens(s: &str) -> Vec<&str> {
        s.trim_start_matches('/')
            .split('/')
            .filter(|t| !t.is_empty())
            .collect()
    }
    fn matches(p: &[&str], n: &[&str]) -> bool {
        match p.split_first() {
            None => n.is_empty(),
            Some((&"**", rest)) => (0..=n.len()).any(|k| matches(rest, &n[k..])),
            Some((&t, rest)) => n
                .split_first()
                .is_some_and(|(&first, tail)| (t == "*" || t == first) && matches(rest, tail)),
        }
    }
    // A name without a leading `/` is relative to the root namespace.
    matches(&tokens(pattern), &tokens(fqn))
}

/// The value as a short text for messages (`600.0`, `"hist:24"`, `[1.0, 2.0]`).
pub fn show(value: &Value) -> String {
    match value {
        Value::NotSet => "not set".into(),
        Value::Boolean(b) => b.to_string(),
        Value::Integer(i) => i.to_string(),
        Value::Double(d) => format!("{d:?}"),
        Value::String(s) => format!("{s:?}"),
        Value::ByteArray(a) => format!("{a:?}"),
        Value::BooleanArray(a) => format!("{a:?}"),
        Value::IntegerArray(a) => format!("{a:?}"),
        Value::DoubleArray(a) => format!("{a:?}"),
        Value::StringArray(a) => format!("{a:?}"),
    }
}

/// What kind of value it is, for messages (`an integer`, `the string "auto"`).
pub fn describe(value: &Value) -> String {
    match value {
        Value::NotSet => "no value".into(),
        Value::Boolean(b) => format!("the boolean {b}"),
        Value::Integer(i) => format!("the integer {i}"),
        Value::Double(d) => format!("the number {d:?}"),
        Value::String(s) => format!("the string {s:?}"),
        other => format!("the list {}", show(other)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(text: &str) -> ParamFile {
        ParamFile::parse(Path::new("p.yaml"), text.as_bytes()).unwrap()
    }

    fn error(text: &str) -> String {
        ParamFile::parse(Path::new("p.yaml"), text.as_bytes())
            .unwrap_err()
            .to_string()
    }

    /// The file rclpy 9.1.2 was probed with (`automatically_declare_parameters_from_overrides`):
    /// node `/probe` got `states.door.model`, `states.door.topic`, `seq`, `a` = 1; node
    /// `/robot/probe` got `b` = 2 and `c` = 3 instead of `a`.
    const PROBED: &str = "\
/**:
  ros__parameters:
    states.door.model: hist:24
    states:
      door:
        topic: /door
    seq: [0.5, 1.5]
probe:
  ros__parameters:
    a: 1
/robot/probe:
  ros__parameters:
    b: 2
/*/probe:
  ros__parameters:
    c: 3
other:
  ros__parameters:
    d: 4
";

    #[test]
    fn entries_apply_to_the_nodes_they_name_as_in_rcl() {
        let f = file(PROBED);
        let names = |fqn: &str| {
            let mut set = ParamSet::default();
            f.apply_matching(fqn, &mut set).unwrap();
            set.values.keys().cloned().collect::<Vec<_>>()
        };
        assert_eq!(
            names("/probe"),
            ["a", "seq", "states.door.model", "states.door.topic"]
        );
        assert_eq!(
            names("/robot/probe"),
            ["b", "c", "seq", "states.door.model", "states.door.topic"]
        );
        let mut set = ParamSet::default();
        f.apply_matching("/probe", &mut set).unwrap();
        assert_eq!(set.values["seq"].value, Value::DoubleArray(vec![0.5, 1.5]));
        assert_eq!(
            set.values["states.door.topic"].origin,
            Origin::File {
                path: "p.yaml".into(),
                line: 6
            }
        );
        // The section `states.door` is where it was first given: the dotted key, line 3.
        assert_eq!(set.sections["states.door"].line(), Some(3));
        assert!(node_matches("/**", "/a/b/c"));
        assert!(node_matches("/**/c", "/c"));
        assert!(node_matches("/a/**/c", "/a/b/b/c"));
        assert!(!node_matches("/*/c", "/c"));
        assert!(!node_matches("c", "/a/c"));
    }

    /// rclpy: `-p a:=5 --params-file f2` gives the file's a = 10; `--params-file f2 -p a:=5`
    /// gives 5: the later source wins.
    #[test]
    fn later_sources_win_and_overrides_are_yaml_values() {
        let f2 = file("/**:\n  ros__parameters:\n    a: 10\n");
        let mut set = ParamSet::default();
        set.apply_override("a", "5", "-p a:=5").unwrap();
        f2.apply_matching("/probe", &mut set).unwrap();
        assert_eq!(set.values["a"].value, Value::Integer(10));
        set.apply_override("a", "5", "-p a:=5").unwrap();
        assert_eq!(set.values["a"].value, Value::Integer(5));
        // Values as rcl types them (probed): 1 integer, 1.0 and 1e3 double, '1' string,
        // [1, 2] integers, [a, b] strings, 0x10 sixteen.
        let cases = [
            ("1", Value::Integer(1)),
            ("1.0", Value::Double(1.0)),
            ("1e3", Value::Double(1000.0)),
            ("'1'", Value::String("1".into())),
            ("\"1\"", Value::String("1".into())),
            ("true", Value::Boolean(true)),
            ("hist:24", Value::String("hist:24".into())),
            ("[1,2]", Value::IntegerArray(vec![1, 2])),
            ("[a,b]", Value::StringArray(vec!["a".into(), "b".into()])),
            ("0x10", Value::Integer(16)),
            // rcl refuses a mixed list; reading it as doubles is kinder to `origin: [0, 0.5]`.
            ("[0, 0.5]", Value::DoubleArray(vec![0.0, 0.5])),
        ];
        for (text, expected) in cases {
            set.apply_override("x", text, "-p").unwrap();
            assert_eq!(set.values["x"].value, expected, "{text}");
        }
        for (text, message) in [
            (
                "{a: 1}",
                "-p x:={a: 1}: x: a mapping is not a parameter value",
            ),
            ("[true, 1]", "a list of mixed or nested values"),
            ("~", "no value (`~`/null)"),
            ("[]", "an empty list"),
        ] {
            let e = set
                .apply_override("x", text, &format!("-p x:={text}"))
                .unwrap_err()
                .to_string();
            assert!(e.contains(message), "{text}: {e}");
        }
    }

    #[test]
    fn bad_files_are_refused_by_line() {
        for (text, expected) in [
            ("probe:\n  a: 1\n", "p.yaml:2: probe: unknown key `a`"),
            ("probe: {}\n", "p.yaml:1: probe: no `ros__parameters`"),
            ("probe: 3\n", "p.yaml:1: probe: not a node entry"),
            ("- a\n", "p.yaml:1: not a parameter file"),
            (
                "p:\n  ros__parameters:\n    a: 1\n    a: 2\n",
                "the key `a` appears twice",
            ),
            (
                "p:\n  ros__parameters:\n    a: {b: 1}\n    a.b: 2\n",
                "p.yaml:4: a.b: given twice in this entry (also at p.yaml:3",
            ),
            (
                "p:\n  ros__parameters:\n    a: [1, x]\n",
                "p.yaml:3: a: a list of mixed",
            ),
            (
                "p:\n  ros__parameters:\n    a: ~\n",
                "p.yaml:3: a: no value",
            ),
            ("a: b\n---\nc: d\n", "several YAML documents"),
        ] {
            let message = error(text);
            assert!(message.contains(expected), "{text:?}: {message}");
        }
        assert!(file("# nothing\n\n").entries.is_empty());
    }
}
