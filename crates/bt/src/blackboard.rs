//! The blackboard: typed values under string keys, shared by the nodes of a tree through their
//! ports, with one scope per subtree instance (BehaviorTree.CPP 4's `Blackboard`).
//!
//! # Key resolution (BehaviorTree.CPP `Blackboard::getEntry` / `createEntryImpl`)
//! In a scope, a key is looked up
//! 1. at the root scope if it starts with `@` (`@battery` is the root's `battery`);
//! 2. among the scope's own entries;
//! 3. if the key is remapped (`<SubTree ID="T" target="{goal}"/>` maps `target` to `goal`),
//!    as the remapped key in the parent scope, recursively;
//! 4. with `_autoremap`, as the same key in the parent scope, except for private keys (those
//!    starting with `_`).
//!
//! A value written to a key that does not exist yet is created where that lookup would have
//! gone: in the parent for remapped and auto-remapped keys, locally otherwise.
//!
//! # Types
//! [`Value`] holds a bool, an i64, an f64 or a string. Strings convert on reading to the type
//! asked for with BehaviorTree.CPP's `convertFromString` rules ([`FromValue`]), so literal port
//! values and text written by any node are read as numbers where numbers are wanted. As in
//! BehaviorTree.CPP (`Blackboard::set`: "once declared, the type of a port shall not change"),
//! an entry that holds a bool or a number keeps its type: a string written to it is parsed to
//! that type, an integer written to a number entry is converted when exact, and anything else
//! is a [`BlackboardError::TypeChange`]. An entry that holds a string accepts any value.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A blackboard value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Value {
    /// A boolean.
    Bool(bool),
    /// A signed integer.
    Int(i64),
    /// A floating-point number.
    Double(f64),
    /// Text (also every literal port value before it is converted).
    Str(String),
    /// A list of values: BehaviorTree.CPP's `SharedQueue<T>` (`std::deque` behind a shared
    /// pointer) that the `Loop*` nodes pop from. Its text is the items separated by `;`, and
    /// text such as `"1;2;3"` converts to a list as `convertFromString<SharedQueue<T>>` does.
    List(Vec<Value>),
}

impl Value {
    /// The type name in messages (`bool`, `int`, `double`, `string`).
    pub fn type_name(&self) -> &'static str {
        match self {
            Value::Bool(_) => "bool",
            Value::Int(_) => "int",
            Value::Double(_) => "double",
            Value::Str(_) => "string",
            Value::List(_) => "list",
        }
    }
}

impl fmt::Display for Value {
    /// `true`, `42`, `0.5`, or the text itself.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => write!(f, "{b}"),
            Value::Int(i) => write!(f, "{i}"),
            Value::Double(x) => write!(f, "{x}"),
            Value::Str(s) => f.write_str(s),
            Value::List(items) => {
                for (k, item) in items.iter().enumerate() {
                    if k > 0 {
                        f.write_str(";")?;
                    }
                    write!(f, "{item}")?;
                }
                Ok(())
            }
        }
    }
}

impl From<bool> for Value {
    fn from(b: bool) -> Value {
        Value::Bool(b)
    }
}

impl From<i64> for Value {
    fn from(i: i64) -> Value {
        Value::Int(i)
    }
}

impl From<i32> for Value {
    fn from(i: i32) -> Value {
        Value::Int(i64::from(i))
    }
}

impl From<f64> for Value {
    fn from(x: f64) -> Value {
        Value::Double(x)
    }
}

impl From<&str> for Value {
    fn from(s: &str) -> Value {
        Value::Str(s.to_owned())
    }
}

impl From<String> for Value {
    fn from(s: String) -> Value {
        Value::Str(s)
    }
}

impl From<Vec<Value>> for Value {
    fn from(items: Vec<Value>) -> Value {
        Value::List(items)
    }
}

/// BehaviorTree.CPP's `convertFromString<bool>`: `1`, `true`, `True`, `TRUE` and `0`, `false`,
/// `False`, `FALSE`.
pub(crate) fn parse_bool(text: &str) -> Option<bool> {
    match text {
        "1" | "true" | "True" | "TRUE" => Some(true),
        "0" | "false" | "False" | "FALSE" => Some(false),
        _ => None,
    }
}

/// Largest magnitude below which every integer is an exact `f64` (2^53).
const EXACT_F64_INT: f64 = 9_007_199_254_740_992.0;

fn int_of_double(x: f64) -> Option<i64> {
    (x.is_finite() && x.fract() == 0.0 && x.abs() <= EXACT_F64_INT).then_some(x as i64)
}

fn double_of_int(i: i64) -> Option<f64> {
    ((i as f64).abs() <= EXACT_F64_INT).then_some(i as f64)
}

/// A type that port values and blackboard entries can be read as.
///
/// Conversions: a string is parsed (`convertFromString`); an `f64` integral value reads as an
/// integer and an integer as an `f64` when exact; `0`/`1` read as booleans; anything reads as a
/// `String` (its text).
pub trait FromValue: Sized {
    /// What the type looks like, for error messages (`"an integer"`).
    const EXPECTED: &'static str;

    /// The value as this type, if it converts.
    fn from_value(value: &Value) -> Option<Self>;
}

impl FromValue for Value {
    const EXPECTED: &'static str = "a value";
    fn from_value(value: &Value) -> Option<Value> {
        Some(value.clone())
    }
}

impl FromValue for bool {
    const EXPECTED: &'static str = "a boolean (true, false, 1 or 0)";
    fn from_value(value: &Value) -> Option<bool> {
        match value {
            Value::Bool(b) => Some(*b),
            Value::Int(0) => Some(false),
            Value::Int(1) => Some(true),
            Value::Int(_) | Value::Double(_) | Value::List(_) => None,
            Value::Str(s) => parse_bool(s),
        }
    }
}

impl FromValue for i64 {
    const EXPECTED: &'static str = "an integer";
    fn from_value(value: &Value) -> Option<i64> {
        match value {
            Value::Bool(b) => Some(i64::from(*b)),
            Value::Int(i) => Some(*i),
            Value::Double(x) => int_of_double(*x),
            Value::Str(s) => s.parse().ok(),
            Value::List(_) => None,
        }
    }
}

impl FromValue for u64 {
    const EXPECTED: &'static str = "a non-negative integer";
    fn from_value(value: &Value) -> Option<u64> {
        match value {
            Value::Str(s) => s.parse().ok(),
            other => i64::from_value(other).and_then(|i| u64::try_from(i).ok()),
        }
    }
}

impl FromValue for f64 {
    const EXPECTED: &'static str = "a number";
    fn from_value(value: &Value) -> Option<f64> {
        match value {
            Value::Bool(_) | Value::List(_) => None,
            Value::Int(i) => double_of_int(*i),
            Value::Double(x) => Some(*x),
            Value::Str(s) => s.parse().ok(),
        }
    }
}

impl FromValue for String {
    const EXPECTED: &'static str = "text";
    fn from_value(value: &Value) -> Option<String> {
        Some(value.to_string())
    }
}

impl FromValue for Vec<Value> {
    const EXPECTED: &'static str = "a list (items separated by ';')";
    /// A list as it is; text split at `;` (BehaviorTree.CPP's `convertFromString` of a
    /// `SharedQueue`: empty text is an empty list); a single other value is a list of one.
    fn from_value(value: &Value) -> Option<Vec<Value>> {
        Some(match value {
            Value::List(items) => items.clone(),
            Value::Str(s) if s.is_empty() => Vec::new(),
            Value::Str(s) => s.split(';').map(|t| Value::Str(t.to_owned())).collect(),
            other => vec![other.clone()],
        })
    }
}

/// Why the blackboard refused a write.
#[derive(Clone, Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum BlackboardError {
    /// The entry holds a value of another type and the new value does not convert.
    #[error(
        "blackboard entry \"{key}\" holds a {old}; once declared, its type cannot change \
         (cannot store the {new} {value:?})"
    )]
    TypeChange {
        /// The key (in the scope where the entry lives).
        key: String,
        /// The entry's type.
        old: &'static str,
        /// The new value's type.
        new: &'static str,
        /// The new value, as text.
        value: String,
    },
    /// An empty key (`{}` or `@`).
    #[error("empty blackboard key")]
    EmptyKey,
}

/// A blackboard scope: the root, or the scope of one subtree instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ScopeId(usize);

impl ScopeId {
    /// The position of the scope (0 is the root).
    pub fn index(self) -> usize {
        self.0
    }
}

#[derive(Clone, Debug, Default)]
struct Scope {
    parent: Option<ScopeId>,
    remap: BTreeMap<String, String>,
    autoremap: bool,
    entries: BTreeMap<String, Entry>,
}

/// A value and its sequence number (BehaviorTree.CPP 4.5's `Entry::sequence_id`: 1 when the
/// entry is created, incremented by every write).
#[derive(Clone, Debug)]
struct Entry {
    /// `None` for an entry left without a value (see [`Blackboard::clear_scripted_in`]).
    value: Option<Value>,
    sequence_id: u64,
    /// Created by a script's assignment (`x := 0`): BehaviorTree.CPP 4.8.2 gives such an
    /// entry no port type, and `SetBlackboard` writing a literal to it leaves it without a
    /// value (see [`Blackboard::clear_scripted_in`]).
    scripted: bool,
    /// Declared by a port of type std::string: text written to it stays text.
    text: bool,
    /// Its port type is BehaviorTree.CPP's `BT::Any` (declared by such a port, copied by
    /// `SetBlackboard` from a script's entry, or emptied once): `SetBlackboard` cannot write a
    /// literal to it.
    any_typed: bool,
}

/// The type of the port that declared an entry ([`Blackboard::declare_in`]), as far as
/// `SetBlackboard` cares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeclaredType {
    /// `std::string`: text stays text.
    Text,
    /// `BT::Any`: text cannot be converted to it.
    Any,
    /// Another type: text is converted to it.
    Other,
}

/// What [`Blackboard::write_text_to_scripted_in`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScriptedWrite {
    /// The entry was not made by a script: write the text as usual.
    NotScripted,
    /// The entry now has no value.
    Emptied,
    /// BehaviorTree.CPP throws (`Can't convert string [...] to type [BT::Any]`).
    Refused,
}

/// The blackboard of a tree: a root scope and one scope per subtree instance.
#[derive(Clone, Debug)]
pub struct Blackboard {
    scopes: Vec<Scope>,
}

impl Default for Blackboard {
    fn default() -> Blackboard {
        Blackboard::new()
    }
}

impl Blackboard {
    /// An empty blackboard with a root scope.
    pub fn new() -> Blackboard {
        Blackboard {
            scopes: vec![Scope::default()],
        }
    }

    /// The root scope (of the main tree).
    pub fn root(&self) -> ScopeId {
        ScopeId(0)
    }

    /// A new scope under `parent` with explicit remappings (subtree key → parent key) and
    /// optional auto-remapping, as a `SubTree` node creates.
    ///
    /// # Panics
    /// If `parent` is not a scope of this blackboard.
    pub fn add_scope(
        &mut self,
        parent: ScopeId,
        remap: BTreeMap<String, String>,
        autoremap: bool,
    ) -> ScopeId {
        assert!(parent.0 < self.scopes.len(), "unknown scope {parent:?}");
        self.scopes.push(Scope {
            parent: Some(parent),
            remap,
            autoremap,
            entries: BTreeMap::new(),
        });
        ScopeId(self.scopes.len() - 1)
    }

    /// The number of scopes.
    pub fn scope_count(&self) -> usize {
        self.scopes.len()
    }

    /// Where `key` leads from `scope`: the scope and key of an existing entry (`Ok`), or the
    /// scope and key where a new entry would be created (`Err`).
    fn resolve(&self, scope: ScopeId, key: &str) -> Result<(ScopeId, String), (ScopeId, String)> {
        if let Some(rest) = key.strip_prefix('@') {
            return self.resolve(self.root(), rest);
        }
        let s = &self.scopes[scope.0];
        if s.entries.contains_key(key) {
            return Ok((scope, key.to_owned()));
        }
        if let Some(parent) = s.parent {
            if let Some(external) = s.remap.get(key) {
                return self.resolve(parent, external);
            }
            if s.autoremap && !key.starts_with('_') {
                return self.resolve(parent, key);
            }
        }
        Err((scope, key.to_owned()))
    }

    /// The value of `key` seen from `scope`, if it exists.
    pub fn get_in(&self, scope: ScopeId, key: &str) -> Option<&Value> {
        let (at, key) = self.resolve(scope, key).ok()?;
        self.scopes[at.0]
            .entries
            .get(&key)
            .and_then(|e| e.value.as_ref())
    }

    /// The sequence number of the entry `key` seen from `scope`, if it exists: 1 after it was
    /// created, incremented by every write (BehaviorTree.CPP 4.5's `Entry::sequence_id`, which
    /// `SkipUnlessUpdated` and `WasEntryUpdated` compare).
    pub fn sequence_id_in(&self, scope: ScopeId, key: &str) -> Option<u64> {
        let (at, key) = self.resolve(scope, key).ok()?;
        self.scopes[at.0].entries.get(&key).map(|e| e.sequence_id)
    }

    /// Removes the entry `key` of `scope` itself (BehaviorTree.CPP's `Blackboard::unset`, which
    /// does not follow remappings; a key starting with `@` is removed from the root scope).
    /// Returns whether there was such an entry.
    pub fn unset_in(&mut self, scope: ScopeId, key: &str) -> bool {
        let (scope, key) = match key.strip_prefix('@') {
            Some(rest) => (self.root(), rest),
            None => (scope, key),
        };
        self.scopes[scope.0].entries.remove(key).is_some()
    }

    /// The value of `key` in the root scope.
    pub fn get(&self, key: &str) -> Option<&Value> {
        self.get_in(self.root(), key)
    }

    /// The value of `key` in the root scope as `T`, if it exists and converts.
    pub fn get_as<T: FromValue>(&self, key: &str) -> Option<T> {
        self.get(key).and_then(T::from_value)
    }

    /// Writes `value` to `key` seen from `scope` (see the module documentation for where it
    /// lands and how types are kept).
    ///
    /// # Errors
    /// [`BlackboardError::TypeChange`] if the entry holds another type and the value does not
    /// convert; [`BlackboardError::EmptyKey`] for an empty key.
    pub fn set_in(
        &mut self,
        scope: ScopeId,
        key: &str,
        value: impl Into<Value>,
    ) -> Result<(), BlackboardError> {
        let value = value.into();
        if key.is_empty() || key == "@" {
            return Err(BlackboardError::EmptyKey);
        }
        match self.resolve(scope, key) {
            Ok((at, key)) => {
                let entry = self.scopes[at.0]
                    .entries
                    .get_mut(&key)
                    .expect("resolved entries exist");
                entry.value = Some(match &entry.value {
                    Some(_) if entry.text && matches!(value, Value::Str(_)) => value,
                    Some(old) => converted(&key, old, value)?,
                    None => value,
                });
                entry.sequence_id += 1;
            }
            Err((at, key)) => {
                self.scopes[at.0].entries.insert(
                    key,
                    Entry {
                        value: Some(value),
                        sequence_id: 1,
                        scripted: false,
                        text: false,
                        any_typed: false,
                    },
                );
            }
        }
        Ok(())
    }

    /// [`Blackboard::set_in`] from a script's assignment: an entry it creates is marked as
    /// made by a script.
    ///
    /// # Errors
    /// As [`Blackboard::set_in`].
    pub fn set_in_by_script(
        &mut self,
        scope: ScopeId,
        key: &str,
        value: Value,
    ) -> Result<(), BlackboardError> {
        let created = self.sequence_id_in(scope, key).is_none();
        self.set_in(scope, key, value)?;
        if let Ok((at, key)) = self.resolve(scope, key)
            && let Some(entry) = self.scopes[at.0].entries.get_mut(&key)
        {
            entry.scripted |= created;
        }
        Ok(())
    }

    /// Creates the entry `key` seen from `scope` without a value, unless it exists (what
    /// BehaviorTree.CPP does when it loads a tree, for every port remapped to the blackboard).
    /// Reads find nothing in it until it is written. The port's type decides what text
    /// written to it later becomes (see [`DeclaredType`]).
    pub fn declare_in(&mut self, scope: ScopeId, key: &str, port_type: DeclaredType) {
        if key.is_empty() || key == "@" {
            return;
        }
        if let Err((at, key)) = self.resolve(scope, key) {
            self.scopes[at.0].entries.insert(
                key,
                Entry {
                    value: None,
                    sequence_id: 0,
                    scripted: false,
                    text: port_type == DeclaredType::Text,
                    any_typed: port_type == DeclaredType::Any,
                },
            );
        }
    }

    /// Whether the entry `key` seen from `scope` was created by a script (or copied by
    /// `SetBlackboard` from one that was: the copy takes the source's port type).
    pub fn is_scripted_in(&self, scope: ScopeId, key: &str) -> bool {
        self.resolve(scope, key)
            .ok()
            .and_then(|(at, key)| self.scopes[at.0].entries.get(&key))
            .is_some_and(|e| e.scripted)
    }

    /// Marks the entry `key` seen from `scope` as having BehaviorTree.CPP's port type
    /// `BT::Any` (an entry `SetBlackboard` made by copying a script's entry takes its type).
    pub fn mark_any_typed_in(&mut self, scope: ScopeId, key: &str) {
        if let Ok((at, key)) = self.resolve(scope, key)
            && let Some(entry) = self.scopes[at.0].entries.get_mut(&key)
        {
            entry.any_typed = true;
        }
    }

    /// What `SetBlackboard` with a literal `value` does to an entry without a port type, in
    /// BehaviorTree.CPP 4.8.2, where the text is converted to the entry's port type. For an
    /// entry a script (or a `SubTree`'s literal port) created, the conversion yields nothing
    /// and the entry is written without a value: it still exists (its sequence number goes
    /// up, as for any write) but reads find nothing ([`ScriptedWrite::Emptied`]). Written so
    /// from its own scope, the entry then has the type of that empty value, `BT::Any`, which
    /// a later literal cannot be converted to; written through a subtree's remapping, it keeps
    /// its type. For an entry of type `BT::Any` the conversion throws
    /// ([`ScriptedWrite::Refused`]). Other entries: [`ScriptedWrite::NotScripted`], nothing
    /// changed.
    pub fn write_text_to_scripted_in(&mut self, scope: ScopeId, key: &str) -> ScriptedWrite {
        let Ok((at, key)) = self.resolve(scope, key) else {
            return ScriptedWrite::NotScripted;
        };
        match self.scopes[at.0].entries.get_mut(&key) {
            Some(entry) if entry.any_typed => ScriptedWrite::Refused,
            Some(entry) if entry.scripted => {
                entry.value = None;
                entry.any_typed = at == scope;
                entry.sequence_id += 1;
                ScriptedWrite::Emptied
            }
            _ => ScriptedWrite::NotScripted,
        }
    }

    /// Writes `value` to `key` in the root scope.
    ///
    /// # Errors
    /// As [`Blackboard::set_in`].
    pub fn set(&mut self, key: &str, value: impl Into<Value>) -> Result<(), BlackboardError> {
        self.set_in(self.root(), key, value)
    }

    /// Writes `value` to the scope's own entry `key`, ignoring remapping (how a `SubTree`
    /// attribute with a literal value sets the subtree's key).
    pub fn set_local(&mut self, scope: ScopeId, key: &str, value: Value) {
        let entries = &mut self.scopes[scope.0].entries;
        let sequence_id = entries.get(key).map_or(1, |e| e.sequence_id + 1);
        entries.insert(
            key.to_owned(),
            Entry {
                value: Some(value),
                sequence_id,
                // A value set without a port type, as a script's: `SetBlackboard` treats the
                // entry as it treats a script's.
                scripted: true,
                text: false,
                any_typed: false,
            },
        );
    }

    /// The scope's own entries, by key.
    pub fn entries(&self, scope: ScopeId) -> impl Iterator<Item = (&str, &Value)> {
        self.scopes[scope.0]
            .entries
            .iter()
            .filter_map(|(k, e)| Some((k.as_str(), e.value.as_ref()?)))
    }
}

/// The value to store in an existing entry that holds `old`.
fn converted(key: &str, old: &Value, new: Value) -> Result<Value, BlackboardError> {
    let same = std::mem::discriminant(old) == std::mem::discriminant(&new);
    if same || matches!(old, Value::Str(_)) {
        return Ok(new);
    }
    let kept = match old {
        Value::List(_) => match &new {
            Value::Str(_) => Vec::<Value>::from_value(&new).map(Value::List),
            _ => None,
        },
        Value::Bool(_) => bool::from_value(&new).map(Value::Bool),
        Value::Int(_) => match &new {
            Value::Str(_) | Value::Double(_) => i64::from_value(&new).map(Value::Int),
            _ => None,
        },
        Value::Double(_) => match &new {
            Value::Str(_) | Value::Int(_) => f64::from_value(&new).map(Value::Double),
            _ => None,
        },
        Value::Str(_) => unreachable!("handled above"),
    };
    kept.ok_or_else(|| BlackboardError::TypeChange {
        key: key.to_owned(),
        old: old.type_name(),
        new: new.type_name(),
        value: new.to_string(),
    })
}
