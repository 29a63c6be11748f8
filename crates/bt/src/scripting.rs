//! BehaviorTree.CPP 4's scripting language (its `scripting/` directory: `operators.hpp`,
//! `script_parser.cpp`, `any_types.hpp`), in pure Rust: parsed once when a tree is
//! instantiated ([`Program::parse`]), evaluated at tick time against a node's blackboard scope
//! ([`Program::eval`]).
//!
//! The `Script` and `ScriptCondition` nodes, the `Precondition` decorator and the pre- and
//! post-condition attributes (`_skipIf`, `_onSuccess`, …) run such programs.
//!
//! ```
//! use std::collections::BTreeMap;
//! use chronomap_bt::scripting::{Environment, Program};
//! use chronomap_bt::{Blackboard, Value};
//!
//! let mut blackboard = Blackboard::new();
//! let mut enums = BTreeMap::new();
//! enums.insert("RED".to_owned(), 1);
//! let program = Program::parse("A := 40; B := A + 2; color := RED; B == 42 && color == 1")?;
//! let scope = blackboard.root();
//! let mut env = Environment::new(&mut blackboard, scope, &enums);
//! assert_eq!(program.eval(&mut env)?, Value::Bool(true));
//! assert_eq!(blackboard.get("B"), Some(&Value::Int(42)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Grammar
//! A program is statements separated by `;` (empty statements are allowed); its value is the
//! value of the last statement. From the loosest to the tightest binding:
//!
//! | level | operators |
//! |---|---|
//! | assignment (one per statement, the left side a variable) | `:=` (creates the entry if needed), `=` (the entry must exist), `+=`, `-=`, `*=`, `/=` |
//! | string concatenation, left-associative | `..` |
//! | conditional (not chained without parentheses) | `c ? a : b` |
//! | logical, left-associative, one precedence level as in BehaviorTree.CPP | `&&`, `and`, `\|\|`, `or` |
//! | comparison, chained (`a < b < c` is `a < b && b < c`) | `==`, `!=`, `<`, `<=`, `>`, `>=` |
//! | bitwise, left-associative | `\|`, `^`, then `&` |
//! | arithmetic, left-associative | `+`, `-`, then `*`, `/` |
//! | prefix | `-`, `!`, `~` |
//! | atoms | `( … )`, `true`, `false`, numbers (`42`, `0x2A`, `4.2`, `4.2e1`), strings in single quotes (`'text'`, no escapes), variables |
//!
//! Variables are blackboard keys (`[A-Za-z_@][A-Za-z0-9_]*`; `@key` is the root blackboard's
//! `key`), or the names of enum values registered with
//! [`Registry::register_enum`](super::Registry::register_enum), which read as integers and
//! take precedence over blackboard keys, as in BehaviorTree.CPP's `ExprName::evaluate`.
//!
//! # Types (BehaviorTree.CPP's `ExprBinaryArithmetic`, `ExprComparison`, `ExprAssignment`)
//! * Arithmetic needs two numbers (booleans count as 0 and 1); `+` also concatenates two
//!   strings. Integers stay integers for `+ - *` (BehaviorTree.CPP computes in `double`; the
//!   values are the same while they are exact); `/` gives a real; dividing by zero is an error.
//!   Bitwise operators need integral numbers.
//! * `..` concatenates the texts of any two values.
//! * Comparison: two numbers (real equality within `f32::EPSILON`, as BehaviorTree.CPP's
//!   `IsSame`), two strings, or a string and a number, the string being converted with
//!   BehaviorTree.CPP's `StringToDouble` (`true`/`false`, an enum name, or a number; otherwise
//!   an error). Anything else is an error.
//! * A condition's truth (`&&`, `||`, `!`, `? :`, `_skipIf`, …): a boolean, a number ≠ 0, or a
//!   string `true`/`false`/`1`/`0`; other strings are an error.
//! * Assignment: an entry keeps its type once it holds a number or a boolean (see
//!   [`Blackboard`]); a string assigned to a number entry is converted (an enum name, or
//!   number text) and anything else is an error such as "cannot store the string "hello"";
//!   `=`, `+=`, … on an entry that does not exist are errors that suggest `:=`.
//!
//! # Deviations
//! * `&&` and `||` evaluate both operands, as BehaviorTree.CPP does (no short circuit).
//! * Mixing arithmetic and bitwise operators without parentheses (`a + b & c`) is accepted
//!   (as `(a + b) & c`); BehaviorTree.CPP's grammar rejects it.
//! * Entries that BehaviorTree.CPP creates empty when a tree is instantiated (every `{key}`
//!   port) do not exist here until written, so `=` to them before that is an error.
//!
//! # Bounds
//! Parsing is linear in the length of the text, and nesting (parentheses, prefix operators,
//! conditionals) is limited to [`MAX_NESTING`] levels so that neither parsing nor evaluation
//! can overflow the stack; chains of binary operators are stored flat.

use std::collections::BTreeMap;
use std::fmt;

use thiserror::Error;

use super::blackboard::{Blackboard, FromValue, ScopeId, Value};

/// The deepest nesting of parentheses, prefix operators and conditionals a script may have.
pub const MAX_NESTING: usize = 64;

/// Why a script did not parse or could not be evaluated.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("{message}")]
pub struct ScriptError {
    message: String,
}

impl ScriptError {
    fn new(message: impl Into<String>) -> ScriptError {
        ScriptError {
            message: message.into(),
        }
    }

    /// The message.
    pub fn message(&self) -> &str {
        &self.message
    }
}

/// What a script is evaluated against: a blackboard scope and the registered enum values.
pub struct Environment<'a> {
    blackboard: &'a mut Blackboard,
    scope: ScopeId,
    enums: &'a BTreeMap<String, i64>,
}

impl<'a> Environment<'a> {
    /// An environment: variables are the keys of `blackboard` seen from `scope`, and the names
    /// of `enums`.
    pub fn new(
        blackboard: &'a mut Blackboard,
        scope: ScopeId,
        enums: &'a BTreeMap<String, i64>,
    ) -> Environment<'a> {
        Environment {
            blackboard,
            scope,
            enums,
        }
    }
}

/// A parsed script: statements to evaluate in order.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    statements: Vec<Expr>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AssignOp {
    Create,
    Existing,
    Plus,
    Minus,
    Times,
    Div,
}

impl AssignOp {
    fn text(self) -> &'static str {
        match self {
            AssignOp::Create => ":=",
            AssignOp::Existing => "=",
            AssignOp::Plus => "+=",
            AssignOp::Minus => "-=",
            AssignOp::Times => "*=",
            AssignOp::Div => "/=",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum BinOp {
    Plus,
    Minus,
    Times,
    Div,
    BitAnd,
    BitOr,
    BitXor,
    And,
    Or,
    Concat,
}

impl BinOp {
    fn text(self) -> &'static str {
        match self {
            BinOp::Plus => "+",
            BinOp::Minus => "-",
            BinOp::Times => "*",
            BinOp::Div => "/",
            BinOp::BitAnd => "&",
            BinOp::BitOr => "|",
            BinOp::BitXor => "^",
            BinOp::And => "&&",
            BinOp::Or => "||",
            BinOp::Concat => "..",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CmpOp {
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum UnOp {
    Negate,
    Not,
    Complement,
}

#[derive(Clone, Debug, PartialEq)]
enum Expr {
    Literal(Value),
    Name(String),
    Unary(UnOp, Box<Expr>),
    /// A left-associative chain `first op1 e1 op2 e2 …`, stored flat.
    Chain(Box<Expr>, Vec<(BinOp, Expr)>),
    Compare(Box<Expr>, Vec<(CmpOp, Expr)>),
    If(Box<Expr>, Box<Expr>, Box<Expr>),
    Assign(String, AssignOp, Box<Expr>),
}

// ----------------------------------------------------------------------------------------
// Lexer

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Int(i64),
    Real(f64),
    Str(String),
    Name(String),
    True,
    False,
    Op(&'static str),
    Semi,
    End,
}

const OPERATORS: [&str; 30] = [
    ":=", "+=", "-=", "*=", "/=", "==", "!=", "<=", ">=", "&&", "||", "..", "=", "+", "-", "*",
    "/", "<", ">", "!", "&", "|", "^", "~", "?", ":", "(", ")", "and", "or",
];

fn lex(code: &str) -> Result<Vec<(usize, Tok)>, ScriptError> {
    let bytes = code.as_bytes();
    let mut tokens = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if c.is_ascii_whitespace() {
            i += 1;
            continue;
        }
        let start = i;
        if c == b';' {
            tokens.push((start, Tok::Semi));
            i += 1;
        } else if c == b'\'' {
            let end = code[i + 1..].find('\'').ok_or_else(|| {
                ScriptError::new(format!("unterminated string starting at column {}", i + 1))
            })?;
            tokens.push((start, Tok::Str(code[i + 1..i + 1 + end].to_owned())));
            i += end + 2;
        } else if c.is_ascii_digit() {
            if c == b'0' && matches!(bytes.get(i + 1), Some(b'x' | b'X')) {
                let mut j = i + 2;
                while j < bytes.len() && bytes[j].is_ascii_hexdigit() {
                    j += 1;
                }
                let value = i64::from_str_radix(&code[i + 2..j], 16).map_err(|_| {
                    ScriptError::new(format!(
                        "invalid hexadecimal number {:?} at column {}",
                        &code[i..j],
                        i + 1
                    ))
                })?;
                tokens.push((start, Tok::Int(value)));
                i = j;
            } else {
                let mut j = i;
                while j < bytes.len() && bytes[j].is_ascii_digit() {
                    j += 1;
                }
                let mut real = false;
                if j + 1 < bytes.len() && bytes[j] == b'.' && bytes[j + 1].is_ascii_digit() {
                    real = true;
                    j += 1;
                    while j < bytes.len() && bytes[j].is_ascii_digit() {
                        j += 1;
                    }
                }
                if j < bytes.len() && matches!(bytes[j], b'e' | b'E') {
                    let mut k = j + 1;
                    if k < bytes.len() && matches!(bytes[k], b'+' | b'-') {
                        k += 1;
                    }
                    if k < bytes.len() && bytes[k].is_ascii_digit() {
                        real = true;
                        j = k;
                        while j < bytes.len() && bytes[j].is_ascii_digit() {
                            j += 1;
                        }
                    }
                }
                let text = &code[i..j];
                let token = if real {
                    text.parse().map(Tok::Real).ok()
                } else {
                    text.parse().map(Tok::Int).ok()
                };
                let token = token.ok_or_else(|| {
                    ScriptError::new(format!("invalid number {text:?} at column {}", i + 1))
                })?;
                tokens.push((start, token));
                i = j;
            }
        } else if c.is_ascii_alphabetic() || c == b'_' || c == b'@' {
            let mut j = i + 1;
            while j < bytes.len() && (bytes[j].is_ascii_alphanumeric() || bytes[j] == b'_') {
                j += 1;
            }
            let word = &code[i..j];
            tokens.push((
                start,
                match word {
                    "true" => Tok::True,
                    "false" => Tok::False,
                    "and" => Tok::Op("and"),
                    "or" => Tok::Op("or"),
                    _ => Tok::Name(word.to_owned()),
                },
            ));
            i = j;
        } else {
            let rest = &code[i..];
            let op = OPERATORS[..28]
                .iter()
                .find(|op| rest.starts_with(**op))
                .ok_or_else(|| {
                    let ch = rest.chars().next().unwrap_or(' ');
                    ScriptError::new(format!("unexpected character {ch:?} at column {}", i + 1))
                })?;
            tokens.push((start, Tok::Op(op)));
            i += op.len();
        }
    }
    tokens.push((code.len(), Tok::End));
    Ok(tokens)
}

// ----------------------------------------------------------------------------------------
// Parser: recursive descent, one function per precedence level; chains are loops.

struct Parser {
    tokens: Vec<(usize, Tok)>,
    pos: usize,
    depth: usize,
}

impl Parser {
    fn peek(&self) -> &Tok {
        &self.tokens[self.pos].1
    }

    fn peek_op(&self) -> Option<&'static str> {
        match self.peek() {
            Tok::Op(op) => Some(op),
            _ => None,
        }
    }

    fn column(&self) -> usize {
        self.tokens[self.pos].0 + 1
    }

    fn error(&self, what: &str) -> ScriptError {
        let found = match self.peek() {
            Tok::End => "the end".to_owned(),
            Tok::Semi => "';'".to_owned(),
            Tok::Op(op) => format!("'{op}'"),
            Tok::Int(i) => i.to_string(),
            Tok::Real(x) => x.to_string(),
            Tok::Str(s) => format!("'{s}'"),
            Tok::Name(n) => n.clone(),
            Tok::True => "true".to_owned(),
            Tok::False => "false".to_owned(),
        };
        ScriptError::new(format!(
            "syntax error at column {}: expected {what}, found {found}",
            self.column()
        ))
    }

    fn nest(&mut self) -> Result<(), ScriptError> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return Err(ScriptError::new(format!(
                "script nested deeper than {MAX_NESTING} levels at column {}",
                self.column()
            )));
        }
        Ok(())
    }

    fn statement(&mut self) -> Result<Expr, ScriptError> {
        let lhs = self.concat()?;
        let op = match self.peek_op() {
            Some(":=") => AssignOp::Create,
            Some("=") => AssignOp::Existing,
            Some("+=") => AssignOp::Plus,
            Some("-=") => AssignOp::Minus,
            Some("*=") => AssignOp::Times,
            Some("/=") => AssignOp::Div,
            _ => return Ok(lhs),
        };
        let Expr::Name(name) = lhs else {
            return Err(ScriptError::new(format!(
                "the left operand of '{}' at column {} is not a blackboard entry",
                op.text(),
                self.column()
            )));
        };
        self.pos += 1;
        let rhs = self.concat()?;
        Ok(Expr::Assign(name, op, Box::new(rhs)))
    }

    fn chain(
        &mut self,
        next: fn(&mut Parser) -> Result<Expr, ScriptError>,
        ops: &[(&str, BinOp)],
    ) -> Result<Expr, ScriptError> {
        let first = next(self)?;
        let mut rest = Vec::new();
        while let Some(op) = self.peek_op() {
            let Some(&(_, bin)) = ops.iter().find(|(text, _)| *text == op) else {
                break;
            };
            self.pos += 1;
            rest.push((bin, next(self)?));
        }
        Ok(if rest.is_empty() {
            first
        } else {
            Expr::Chain(Box::new(first), rest)
        })
    }

    fn concat(&mut self) -> Result<Expr, ScriptError> {
        self.chain(Parser::conditional, &[("..", BinOp::Concat)])
    }

    fn conditional(&mut self) -> Result<Expr, ScriptError> {
        let condition = self.logical()?;
        if self.peek_op() != Some("?") {
            return Ok(condition);
        }
        self.pos += 1;
        self.nest()?;
        let then = self.concat()?;
        if self.peek_op() != Some(":") {
            return Err(self.error("':' of a conditional"));
        }
        self.pos += 1;
        let otherwise = self.logical()?;
        self.depth -= 1;
        Ok(Expr::If(
            Box::new(condition),
            Box::new(then),
            Box::new(otherwise),
        ))
    }

    fn logical(&mut self) -> Result<Expr, ScriptError> {
        self.chain(
            Parser::comparison,
            &[
                ("&&", BinOp::And),
                ("and", BinOp::And),
                ("||", BinOp::Or),
                ("or", BinOp::Or),
            ],
        )
    }

    fn comparison(&mut self) -> Result<Expr, ScriptError> {
        let first = self.bit_or()?;
        let mut rest = Vec::new();
        loop {
            let op = match self.peek_op() {
                Some("==") => CmpOp::Eq,
                Some("!=") => CmpOp::Ne,
                Some("<") => CmpOp::Lt,
                Some("<=") => CmpOp::Le,
                Some(">") => CmpOp::Gt,
                Some(">=") => CmpOp::Ge,
                _ => break,
            };
            self.pos += 1;
            rest.push((op, self.bit_or()?));
        }
        Ok(if rest.is_empty() {
            first
        } else {
            Expr::Compare(Box::new(first), rest)
        })
    }

    fn bit_or(&mut self) -> Result<Expr, ScriptError> {
        self.chain(
            Parser::bit_and,
            &[("|", BinOp::BitOr), ("^", BinOp::BitXor)],
        )
    }

    fn bit_and(&mut self) -> Result<Expr, ScriptError> {
        self.chain(Parser::sum, &[("&", BinOp::BitAnd)])
    }

    fn sum(&mut self) -> Result<Expr, ScriptError> {
        self.chain(Parser::product, &[("+", BinOp::Plus), ("-", BinOp::Minus)])
    }

    fn product(&mut self) -> Result<Expr, ScriptError> {
        self.chain(Parser::prefix, &[("*", BinOp::Times), ("/", BinOp::Div)])
    }

    fn prefix(&mut self) -> Result<Expr, ScriptError> {
        let op = match self.peek_op() {
            Some("-") => UnOp::Negate,
            Some("!") => UnOp::Not,
            Some("~") => UnOp::Complement,
            _ => return self.atom(),
        };
        self.pos += 1;
        self.nest()?;
        let operand = self.prefix()?;
        self.depth -= 1;
        Ok(Expr::Unary(op, Box::new(operand)))
    }

    fn atom(&mut self) -> Result<Expr, ScriptError> {
        let expr = match self.peek().clone() {
            Tok::Int(i) => Expr::Literal(Value::Int(i)),
            Tok::Real(x) => Expr::Literal(Value::Double(x)),
            Tok::Str(s) => Expr::Literal(Value::Str(s)),
            Tok::True => Expr::Literal(Value::Bool(true)),
            Tok::False => Expr::Literal(Value::Bool(false)),
            Tok::Name(n) => Expr::Name(n),
            Tok::Op("(") => {
                self.pos += 1;
                self.nest()?;
                let inner = self.statement()?;
                if self.peek_op() != Some(")") {
                    return Err(self.error("')'"));
                }
                self.depth -= 1;
                inner
            }
            _ => return Err(self.error("a value, a variable or '('")),
        };
        self.pos += 1;
        Ok(expr)
    }
}

impl Program {
    /// Parses a script (BehaviorTree.CPP's `ParseScript`).
    ///
    /// # Errors
    /// [`ScriptError`] with the column of the first syntax error, or nesting deeper than
    /// [`MAX_NESTING`].
    pub fn parse(code: &str) -> Result<Program, ScriptError> {
        let tokens = lex(code)?;
        let mut parser = Parser {
            tokens,
            pos: 0,
            depth: 0,
        };
        let mut statements = Vec::new();
        loop {
            match parser.peek() {
                Tok::End => break,
                Tok::Semi => parser.pos += 1,
                _ => {
                    statements.push(parser.statement()?);
                    match parser.peek() {
                        Tok::End => break,
                        Tok::Semi => parser.pos += 1,
                        _ => return Err(parser.error("';' or the end of the script")),
                    }
                }
            }
        }
        if statements.is_empty() {
            return Err(ScriptError::new("the script is empty"));
        }
        Ok(Program { statements })
    }

    /// Evaluates the statements in order; the value of the last one.
    ///
    /// # Errors
    /// [`ScriptError`]: an unknown variable, operands of the wrong types, an entry whose type
    /// cannot change, division by zero, …
    pub fn eval(&self, env: &mut Environment<'_>) -> Result<Value, ScriptError> {
        let mut last = Value::Bool(false);
        for statement in &self.statements {
            last = eval(statement, env)?;
        }
        Ok(last)
    }

    /// Evaluates and converts the result to a truth value ([`truthy`]).
    ///
    /// # Errors
    /// As [`Program::eval`], and a result that is no truth value.
    pub fn eval_bool(&self, env: &mut Environment<'_>) -> Result<bool, ScriptError> {
        truthy(&self.eval(env)?)
    }
}

/// The truth of a value: a boolean, a number ≠ 0, or the text `true`/`false`/`1`/`0` (and the
/// other spellings `convertFromString<bool>` accepts).
///
/// # Errors
/// Other text and lists.
pub fn truthy(value: &Value) -> Result<bool, ScriptError> {
    match value {
        Value::Bool(b) => Ok(*b),
        Value::Int(i) => Ok(*i != 0),
        Value::Double(x) => Ok(*x != 0.0),
        other => bool::from_value(other).ok_or_else(|| {
            ScriptError::new(format!("{:?} is not a truth value", other.to_string()))
        }),
    }
}

// ----------------------------------------------------------------------------------------
// Evaluation

#[derive(Clone, Copy)]
enum Num {
    Int(i64),
    Real(f64),
}

impl Num {
    fn real(self) -> f64 {
        match self {
            Num::Int(i) => i as f64,
            Num::Real(x) => x,
        }
    }

    fn value(self) -> Value {
        match self {
            Num::Int(i) => Value::Int(i),
            Num::Real(x) => Value::Double(x),
        }
    }
}

fn number(value: &Value) -> Option<Num> {
    match value {
        Value::Bool(b) => Some(Num::Int(i64::from(*b))),
        Value::Int(i) => Some(Num::Int(*i)),
        Value::Double(x) => Some(Num::Real(*x)),
        _ => None,
    }
}

fn describe(value: &Value) -> String {
    match value {
        Value::Str(s) => format!("the string '{s}'"),
        other => format!("the {} {other}", other.type_name()),
    }
}

/// BehaviorTree.CPP's `StringToDouble`: `true`/`false`, an enum name, or number text.
fn string_to_number(text: &str, enums: &BTreeMap<String, i64>) -> Result<Num, ScriptError> {
    if text == "true" {
        return Ok(Num::Int(1));
    }
    if text == "false" {
        return Ok(Num::Int(0));
    }
    if let Some(&v) = enums.get(text) {
        return Ok(Num::Int(v));
    }
    if let Ok(i) = text.trim().parse::<i64>() {
        return Ok(Num::Int(i));
    }
    text.trim()
        .parse::<f64>()
        .map(Num::Real)
        .map_err(|_| ScriptError::new(format!("cannot compare the string '{text}' with a number")))
}

fn eval(expr: &Expr, env: &mut Environment<'_>) -> Result<Value, ScriptError> {
    match expr {
        Expr::Literal(v) => Ok(v.clone()),
        Expr::Name(name) => lookup(name, env),
        Expr::Unary(op, operand) => {
            let v = eval(operand, env)?;
            match op {
                UnOp::Not => Ok(Value::Bool(!truthy(&v)?)),
                UnOp::Negate => match number(&v) {
                    Some(Num::Int(i)) => Ok(i
                        .checked_neg()
                        .map_or(Value::Double(-(i as f64)), Value::Int)),
                    Some(Num::Real(x)) => Ok(Value::Double(-x)),
                    None => Err(ScriptError::new(format!("cannot negate {}", describe(&v)))),
                },
                UnOp::Complement => match integral(&v) {
                    Some(i) => Ok(Value::Int(!i)),
                    None => Err(ScriptError::new(format!(
                        "'~' needs an integer, not {}",
                        describe(&v)
                    ))),
                },
            }
        }
        Expr::Chain(first, rest) => {
            let mut acc = eval(first, env)?;
            for (op, operand) in rest {
                let rhs = eval(operand, env)?;
                acc = binary(*op, &acc, &rhs)?;
            }
            Ok(acc)
        }
        Expr::Compare(first, rest) => {
            let mut lhs = eval(first, env)?;
            for (op, operand) in rest {
                let rhs = eval(operand, env)?;
                if !compare(*op, &lhs, &rhs, env.enums)? {
                    return Ok(Value::Bool(false));
                }
                lhs = rhs;
            }
            Ok(Value::Bool(true))
        }
        Expr::If(condition, then, otherwise) => {
            if truthy(&eval(condition, env)?)? {
                eval(then, env)
            } else {
                eval(otherwise, env)
            }
        }
        Expr::Assign(name, op, rhs) => assign(name, *op, rhs, env),
    }
}

fn lookup(name: &str, env: &Environment<'_>) -> Result<Value, ScriptError> {
    if let Some(&v) = env.enums.get(name) {
        return Ok(Value::Int(v));
    }
    env.blackboard
        .get_in(env.scope, name)
        .cloned()
        .ok_or_else(|| ScriptError::new(format!("variable not found: {name}")))
}

fn integral(value: &Value) -> Option<i64> {
    match number(value)? {
        Num::Int(i) => Some(i),
        Num::Real(x) => i64::from_value(&Value::Double(x)),
    }
}

fn binary(op: BinOp, lhs: &Value, rhs: &Value) -> Result<Value, ScriptError> {
    let mismatch = || {
        ScriptError::new(format!(
            "operator '{}' cannot be applied to {} and {}",
            op.text(),
            describe(lhs),
            describe(rhs)
        ))
    };
    match op {
        BinOp::Concat => Ok(Value::Str(format!("{lhs}{rhs}"))),
        BinOp::And | BinOp::Or => {
            let (l, r) = (truthy(lhs)?, truthy(rhs)?);
            Ok(Value::Bool(if op == BinOp::And { l && r } else { l || r }))
        }
        BinOp::BitAnd | BinOp::BitOr | BinOp::BitXor => {
            let (Some(l), Some(r)) = (integral(lhs), integral(rhs)) else {
                return Err(mismatch());
            };
            Ok(Value::Int(match op {
                BinOp::BitAnd => l & r,
                BinOp::BitOr => l | r,
                _ => l ^ r,
            }))
        }
        BinOp::Plus | BinOp::Minus | BinOp::Times | BinOp::Div => {
            if let (Value::Str(l), Value::Str(r), BinOp::Plus) = (lhs, rhs, op) {
                return Ok(Value::Str(format!("{l}{r}")));
            }
            let (Some(l), Some(r)) = (number(lhs), number(rhs)) else {
                return Err(mismatch());
            };
            arithmetic(op, l, r).map(Num::value)
        }
    }
}

fn arithmetic(op: BinOp, l: Num, r: Num) -> Result<Num, ScriptError> {
    if op == BinOp::Div {
        if r.real() == 0.0 {
            return Err(ScriptError::new("division by zero"));
        }
        return Ok(Num::Real(l.real() / r.real()));
    }
    if let (Num::Int(a), Num::Int(b)) = (l, r) {
        let exact = match op {
            BinOp::Plus => a.checked_add(b),
            BinOp::Minus => a.checked_sub(b),
            _ => a.checked_mul(b),
        };
        if let Some(v) = exact {
            return Ok(Num::Int(v));
        }
    }
    let (a, b) = (l.real(), r.real());
    Ok(Num::Real(match op {
        BinOp::Plus => a + b,
        BinOp::Minus => a - b,
        _ => a * b,
    }))
}

fn compare(
    op: CmpOp,
    lhs: &Value,
    rhs: &Value,
    enums: &BTreeMap<String, i64>,
) -> Result<bool, ScriptError> {
    use std::cmp::Ordering;
    let ordering = match (lhs, rhs) {
        (Value::Str(l), Value::Str(r)) => l.cmp(r),
        _ => {
            let to_number = |v: &Value| match v {
                Value::Str(s) => string_to_number(s, enums).map(Some),
                other => Ok(number(other)),
            };
            let (Some(l), Some(r)) = (to_number(lhs)?, to_number(rhs)?) else {
                return Err(ScriptError::new(format!(
                    "cannot compare {} with {}",
                    describe(lhs),
                    describe(rhs)
                )));
            };
            match (l, r) {
                (Num::Int(a), Num::Int(b)) => a.cmp(&b),
                _ => {
                    let (a, b) = (l.real(), r.real());
                    if (a - b).abs() <= f64::from(f32::EPSILON) {
                        Ordering::Equal
                    } else if a < b {
                        Ordering::Less
                    } else if a > b {
                        Ordering::Greater
                    } else {
                        return Ok(op == CmpOp::Ne); // NaN
                    }
                }
            }
        }
    };
    Ok(match op {
        CmpOp::Eq => ordering == Ordering::Equal,
        CmpOp::Ne => ordering != Ordering::Equal,
        CmpOp::Lt => ordering == Ordering::Less,
        CmpOp::Le => ordering != Ordering::Greater,
        CmpOp::Gt => ordering == Ordering::Greater,
        CmpOp::Ge => ordering != Ordering::Less,
    })
}

fn assign(
    name: &str,
    op: AssignOp,
    rhs: &Expr,
    env: &mut Environment<'_>,
) -> Result<Value, ScriptError> {
    let existing = env.blackboard.get_in(env.scope, name).cloned();
    if existing.is_none() && op != AssignOp::Create {
        return Err(ScriptError::new(format!(
            "the blackboard entry [{name}] doesn't exist yet; use the operator [:=] to create \
             it, not [{}]",
            op.text()
        )));
    }
    let value = eval(rhs, env)?;
    let new = match (op, existing) {
        (AssignOp::Create | AssignOp::Existing, None) => value,
        (AssignOp::Create | AssignOp::Existing, Some(old)) => match (&old, &value) {
            // "special case: string to other type": enum names and number text.
            (Value::Int(_) | Value::Double(_), Value::Str(s)) => {
                match string_to_number(s, env.enums) {
                    Ok(n) => n.value(),
                    Err(_) => {
                        return Err(ScriptError::new(format!(
                            "cannot assign {} to the entry [{name}], which holds {}",
                            describe(&value),
                            describe(&old)
                        )));
                    }
                }
            }
            // An entry holding text has BehaviorTree.CPP's type std::string, which takes no
            // number from a script ("The right operand has type [long] and can't be
            // converted to [std::string]").
            (Value::Str(_), Value::Int(_) | Value::Double(_) | Value::Bool(_)) => {
                return Err(ScriptError::new(format!(
                    "cannot assign {} to the entry [{name}], which holds text (BehaviorTree.CPP: \
                     \"Error assigning a value to entry [{name}] with type [std::string]\")",
                    describe(&value)
                )));
            }
            _ => value,
        },
        (op, Some(old)) => {
            if let (Some(l), Some(r)) = (number(&old), number(&value)) {
                let bin = match op {
                    AssignOp::Plus => BinOp::Plus,
                    AssignOp::Minus => BinOp::Minus,
                    AssignOp::Times => BinOp::Times,
                    _ => BinOp::Div,
                };
                arithmetic(bin, l, r)?.value()
            } else if let (Value::Str(r), AssignOp::Plus) = (&value, op) {
                Value::Str(format!("{old}{r}"))
            } else {
                return Err(ScriptError::new(format!(
                    "operator '{}' cannot be applied to the entry [{name}], which holds {}, \
                     and {}",
                    op.text(),
                    describe(&old),
                    describe(&value)
                )));
            }
        }
        (_, None) => unreachable!("checked above"),
    };
    env.blackboard
        .set_in_by_script(env.scope, name, new)
        .map_err(|e| ScriptError::new(e.to_string()))?;
    Ok(env
        .blackboard
        .get_in(env.scope, name)
        .cloned()
        .unwrap_or(Value::Bool(false)))
}

impl fmt::Display for Program {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "<script of {} statements>", self.statements.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(code: &str, bb: &mut Blackboard) -> Result<Value, ScriptError> {
        let mut enums = BTreeMap::new();
        enums.insert("RED".to_owned(), 1);
        enums.insert("BLUE".to_owned(), 2);
        let scope = bb.root();
        Program::parse(code)?.eval(&mut Environment::new(bb, scope, &enums))
    }

    fn value(code: &str) -> Value {
        run(code, &mut Blackboard::new()).unwrap()
    }

    #[test]
    fn literals_and_arithmetic() {
        assert_eq!(value("1 + 2 * 3"), Value::Int(7));
        assert_eq!(value("(1 + 2) * 3"), Value::Int(9));
        assert_eq!(value("7 / 2"), Value::Double(3.5));
        assert_eq!(value("0x1F + 1"), Value::Int(32));
        assert_eq!(value("1.5e1"), Value::Double(15.0));
        assert_eq!(value("-3 - -2"), Value::Int(-1));
        assert_eq!(value("'ab' .. 'cd' .. 1"), Value::Str("abcd1".into()));
        assert_eq!(value("'ab' + 'cd'"), Value::Str("abcd".into()));
        assert_eq!(value("5 & 3 | 8"), Value::Int(9));
        assert_eq!(value("5 ^ 1"), Value::Int(4));
        assert_eq!(value("~0"), Value::Int(-1));
    }

    #[test]
    fn logic_comparison_and_conditional() {
        assert_eq!(value("1 < 2 && 2 <= 2"), Value::Bool(true));
        assert_eq!(value("1 < 2 < 3"), Value::Bool(true));
        assert_eq!(value("3 > 2 > 2"), Value::Bool(false));
        assert_eq!(value("true and false or true"), Value::Bool(true));
        assert_eq!(value("!true"), Value::Bool(false));
        assert_eq!(value("2 > 1 ? 'yes' : 'no'"), Value::Str("yes".into()));
        assert_eq!(value("'10' == 10"), Value::Bool(true));
        assert_eq!(value("'RED' == 1"), Value::Bool(true));
        assert_eq!(value("RED != BLUE"), Value::Bool(true));
        assert_eq!(value("1.1 == (1.0 + 0.1)"), Value::Bool(true));
        assert!(run("'hello' == 1", &mut Blackboard::new()).is_err());
    }

    #[test]
    fn assignments() {
        let mut bb = Blackboard::new();
        run("A := 1; B := 'text'; C := 2.5", &mut bb).unwrap();
        assert_eq!(bb.get("A"), Some(&Value::Int(1)));
        run("A += 2; A *= 3; B += '!'", &mut bb).unwrap();
        assert_eq!(bb.get("A"), Some(&Value::Int(9)));
        assert_eq!(bb.get("B"), Some(&Value::Str("text!".into())));
        run("A = BLUE", &mut bb).unwrap();
        assert_eq!(bb.get("A"), Some(&Value::Int(2)));
        let e = run("A = 'hello'", &mut bb).unwrap_err();
        assert!(e.message().contains("cannot assign"), "{e}");
        let e = run("D = 1", &mut bb).unwrap_err();
        assert!(e.message().contains(":="), "{e}");
        assert!(run("A /= 0", &mut bb).is_err());
        assert!(run("@G := 3", &mut bb).is_ok());
        assert_eq!(bb.get("G"), Some(&Value::Int(3)));
        assert!(run("unknown + 1", &mut bb).is_err());
    }

    #[test]
    fn syntax_errors_and_bounds() {
        for bad in [
            "A :=",
            "1 +",
            "(1",
            "'open",
            "1 = 2",
            "A := := 1",
            "",
            ";",
            "a ? b",
            "#",
        ] {
            assert!(Program::parse(bad).is_err(), "{bad:?} parsed");
        }
        let deep = format!("{}1{}", "(".repeat(10_000), ")".repeat(10_000));
        let e = Program::parse(&deep).unwrap_err();
        assert!(e.message().contains("nested deeper"), "{e}");
        let negations = format!("{}1", "-".repeat(100_000));
        assert!(Program::parse(&negations).is_err());
        // A long flat chain is fine (stored flat, evaluated in a loop).
        let long = vec!["1"; 100_000].join(" + ");
        assert_eq!(value(&long), Value::Int(100_000));
        assert!(Program::parse("A := 1;; B := 2;").is_ok());
    }
}
