//! Co-safe linear temporal logic: the task language of a robot on a topological map
//! (seed 003 §V). `F Kitchen` ("go to the kitchen"), `F (Kitchen & F Office)` ("the kitchen,
//! then the office"), `!Corridor U Lab` ("reach the lab without passing the corridor").
//!
//! * [`parse`] reads a formula in PRISM-like syntax into an [`Ltl`] syntax tree;
//!   [`LtlError`] points at the offending byte with a caret.
//!
//! ## Syntax
//! Atoms are identifiers `[A-Za-z_][A-Za-z0-9_]*` (node names such as `WayPoint1`) or
//! double-quoted names as PRISM writes labels (`"LabDoor1"`); `true` and `false` are the
//! constants. Operators, from the loosest to the tightest binding:
//!
//! | operators | meaning | associativity |
//! |---|---|---|
//! | `->` | implication (desugared to `!a \| b`) | right |
//! | `\|`, `\|\|` | or | left |
//! | `&`, `&&` | and | left |
//! | `U`, `R` | until, release | right |
//! | `!`, `~`, `X`, `F`, `G` | not, next, eventually, always | prefix |
//!
//! The keywords `X F G U R true false` are whole words: `F Kitchen` is "eventually Kitchen",
//! `FKitchen` is an atom. An atom that collides with a keyword can be quoted: `F "X"`.

use std::fmt;

use thiserror::Error;

/// The deepest nesting [`parse`] accepts (parentheses and unary operators count, and so do
/// the levels of the syntax tree a chain like `a & b & c` builds). Bounds the recursion of
/// every function of this module on parsed formulas.
pub const MAX_DEPTH: usize = 256;

/// A linear temporal logic formula over atoms (node names).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Ltl {
    /// Holds everywhere.
    True,
    /// Holds nowhere.
    False,
    /// The robot is at the named node.
    Atom(String),
    /// Negation `!φ`.
    Not(Box<Ltl>),
    /// Conjunction `φ & ψ`.
    And(Box<Ltl>, Box<Ltl>),
    /// Disjunction `φ | ψ`.
    Or(Box<Ltl>, Box<Ltl>),
    /// `X φ`: φ holds at the next step.
    Next(Box<Ltl>),
    /// `φ U ψ`: ψ eventually holds, and φ holds at every step before.
    Until(Box<Ltl>, Box<Ltl>),
    /// `F φ`: φ holds now or at some later step.
    Eventually(Box<Ltl>),
    /// `G φ`: φ holds now and at every later step (not co-safe).
    Always(Box<Ltl>),
    /// `φ R ψ`: ψ holds up to and including the first step where φ holds, or forever
    /// (not co-safe).
    Release(Box<Ltl>, Box<Ltl>),
}

impl Ltl {
    /// The atom `name`.
    pub fn atom(name: &str) -> Ltl {
        Ltl::Atom(name.to_string())
    }
}

impl std::str::FromStr for Ltl {
    type Err = LtlError;

    fn from_str(text: &str) -> Result<Ltl, LtlError> {
        parse(text)
    }
}

/// Binding strength of the printed forms, loosest first.
const OR: u8 = 1;
const AND: u8 = 2;
const UNTIL: u8 = 3;
const UNARY: u8 = 4;
const PRIMARY: u8 = 5;

impl Ltl {
    fn level(&self) -> u8 {
        match self {
            Ltl::True | Ltl::False | Ltl::Atom(_) => PRIMARY,
            Ltl::Not(_) | Ltl::Next(_) | Ltl::Eventually(_) | Ltl::Always(_) => UNARY,
            Ltl::Until(..) | Ltl::Release(..) => UNTIL,
            Ltl::And(..) => AND,
            Ltl::Or(..) => OR,
        }
    }

    /// Writes `self`, in parentheses if it binds more loosely than `at_least`.
    fn write(&self, f: &mut fmt::Formatter<'_>, at_least: u8) -> fmt::Result {
        let parens = self.level() < at_least;
        if parens {
            f.write_str("(")?;
        }
        match self {
            Ltl::True => f.write_str("true")?,
            Ltl::False => f.write_str("false")?,
            Ltl::Atom(name) if is_identifier(name) && keyword(name).is_none() => {
                f.write_str(name)?
            }
            Ltl::Atom(name) => write!(f, "\"{name}\"")?,
            Ltl::Not(a) => {
                f.write_str("!")?;
                a.write(f, UNARY)?;
            }
            Ltl::Next(a) | Ltl::Eventually(a) | Ltl::Always(a) => {
                f.write_str(match self {
                    Ltl::Next(_) => "X ",
                    Ltl::Eventually(_) => "F ",
                    _ => "G ",
                })?;
                a.write(f, UNARY)?;
            }
            Ltl::Until(a, b) | Ltl::Release(a, b) => {
                a.write(f, UNARY)?;
                f.write_str(if matches!(self, Ltl::Until(..)) {
                    " U "
                } else {
                    " R "
                })?;
                b.write(f, UNTIL)?;
            }
            Ltl::And(a, b) => {
                a.write(f, AND)?;
                f.write_str(" & ")?;
                b.write(f, UNTIL)?;
            }
            Ltl::Or(a, b) => {
                a.write(f, OR)?;
                f.write_str(" | ")?;
                b.write(f, AND)?;
            }
        }
        if parens {
            f.write_str(")")?;
        }
        Ok(())
    }
}

/// The formula in the syntax [`parse`] reads, with as few parentheses as the precedences
/// allow: `parse(&f.to_string()) == Ok(f)` for every formula whose atom names are not empty
/// and contain no whitespace and no `"`.
impl fmt::Display for Ltl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write(f, OR)
    }
}

/// Why a formula could not be read or turned into an automaton.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum LtlError {
    /// The text is not a formula. `Display` shows the line of the formula with a caret under
    /// the offending byte.
    #[error("{message} at position {position}\n{}", caret(.formula, *.position))]
    Syntax {
        /// The formula as given.
        formula: String,
        /// Byte offset of the offending token in `formula`.
        position: usize,
        /// What is wrong.
        message: String,
    },
}

impl LtlError {
    /// Byte offset in the formula text of what caused the error, if known.
    pub fn position(&self) -> Option<usize> {
        match self {
            LtlError::Syntax { position, .. } => Some(*position),
        }
    }
}

/// The line of `formula` that holds byte `position`, and a caret under it on the next line.
fn caret(formula: &str, position: usize) -> String {
    let position = (0..=position.min(formula.len()))
        .rev()
        .find(|&p| formula.is_char_boundary(p))
        .unwrap_or(0);
    let start = formula[..position].rfind('\n').map_or(0, |i| i + 1);
    let end = formula[position..]
        .find('\n')
        .map_or(formula.len(), |i| position + i);
    // Tabs are copied so that the caret lines up however the terminal expands them.
    let indent: String = formula[start..position]
        .chars()
        .map(|c| if c == '\t' { '\t' } else { ' ' })
        .collect();
    format!("{}\n{indent}^", formula[start..end].trim_end_matches('\r'))
}

/// Whether `name` is an identifier atom `[A-Za-z_][A-Za-z0-9_]*`.
fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The token of a keyword.
fn keyword(word: &str) -> Option<Tok> {
    Some(match word {
        "true" => Tok::True,
        "false" => Tok::False,
        "X" => Tok::Next,
        "F" => Tok::Eventually,
        "G" => Tok::Always,
        "U" => Tok::Until,
        "R" => Tok::Release,
        _ => return None,
    })
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Tok {
    Name,
    True,
    False,
    Not,
    Next,
    Eventually,
    Always,
    And,
    Or,
    Implies,
    Until,
    Release,
    Open,
    Close,
    End,
}

/// A token: its kind and its bytes `start..end` in the formula.
#[derive(Clone, Copy, Debug)]
struct Token {
    tok: Tok,
    start: usize,
    end: usize,
}

/// A parsed subformula and how deep its tree is.
struct Parsed {
    formula: Ltl,
    depth: usize,
}

fn lex(text: &str) -> Result<Vec<Token>, LtlError> {
    let error = |position: usize, message: String| LtlError::Syntax {
        formula: text.to_string(),
        position,
        message,
    };
    let bytes = text.as_bytes();
    let mut tokens = Vec::new();
    let mut chars = text.char_indices().peekable();
    while let Some((start, c)) = chars.next() {
        let token = |tok: Tok, end: usize| Token { tok, start, end };
        let next = bytes.get(start + 1).copied();
        match c {
            c if c.is_whitespace() => continue,
            c if c.is_ascii_alphabetic() || c == '_' => {
                let mut end = start + 1;
                while let Some(&(i, c)) = chars.peek() {
                    if !(c.is_ascii_alphanumeric() || c == '_') {
                        break;
                    }
                    end = i + 1;
                    chars.next();
                }
                tokens.push(token(keyword(&text[start..end]).unwrap_or(Tok::Name), end));
            }
            '"' => {
                let Some(length) = text[start + 1..].find('"') else {
                    return Err(error(start, "unterminated quoted name".into()));
                };
                let name = &text[start + 1..start + 1 + length];
                if name.is_empty() {
                    return Err(error(start, "empty quoted name".into()));
                }
                if let Some(i) = name.find(char::is_whitespace) {
                    return Err(error(
                        start + 1 + i,
                        "whitespace in a quoted name (node names contain none)".into(),
                    ));
                }
                while chars.next_if(|&(i, _)| i <= start + 1 + length).is_some() {}
                tokens.push(token(Tok::Name, start + length + 2));
            }
            '!' | '~' => tokens.push(token(Tok::Not, start + 1)),
            '(' => tokens.push(token(Tok::Open, start + 1)),
            ')' => tokens.push(token(Tok::Close, start + 1)),
            '&' | '|' => {
                let tok = if c == '&' { Tok::And } else { Tok::Or };
                if next == Some(c as u8) {
                    chars.next();
                    tokens.push(token(tok, start + 2));
                } else {
                    tokens.push(token(tok, start + 1));
                }
            }
            '-' if next == Some(b'>') => {
                chars.next();
                tokens.push(token(Tok::Implies, start + 2));
            }
            '-' => {
                return Err(error(
                    start,
                    "unexpected character '-' (did you mean '->'?)".into(),
                ));
            }
            c => return Err(error(start, format!("unexpected character {c:?}"))),
        }
    }
    tokens.push(Token {
        tok: Tok::End,
        start: text.len(),
        end: text.len(),
    });
    Ok(tokens)
}

/// Reads a formula.
///
/// # Errors
/// [`LtlError::Syntax`] with the byte position of the first problem: an empty formula, an
/// unknown character, an unterminated or empty quoted name, an operator without operand,
/// an unclosed `(`, input after a complete formula, or nesting deeper than [`MAX_DEPTH`].
///
/// ```
/// use chronomap_core::ltl::parse;
///
/// let task = parse("F (Kitchen & F \"Office\")")?;
/// assert_eq!(task.to_string(), "F (Kitchen & F Office)");
/// let error = parse("F (Kitchen))").unwrap_err();
/// assert_eq!(error.to_string(), "unexpected ')' at position 11\nF (Kitchen))\n           ^");
/// # Ok::<(), chronomap_core::ltl::LtlError>(())
/// ```
pub fn parse(text: &str) -> Result<Ltl, LtlError> {
    let tokens = lex(text)?;
    let mut parser = Parser {
        text,
        tokens,
        next: 0,
        nesting: 0,
    };
    if parser.peek().tok == Tok::End {
        return Err(parser.error(0, "empty formula".into()));
    }
    let parsed = parser.implies()?;
    let token = parser.peek();
    match token.tok {
        Tok::End => Ok(parsed.formula),
        Tok::Close => Err(parser.error(token.start, "unexpected ')'".into())),
        _ => Err(parser.error(
            token.start,
            format!(
                "unexpected '{}' after a complete formula (missing operator?)",
                parser.source(token)
            ),
        )),
    }
}

struct Parser<'a> {
    text: &'a str,
    tokens: Vec<Token>,
    next: usize,
    /// Parentheses and unary operators open around the current token.
    nesting: usize,
}

impl Parser<'_> {
    fn peek(&self) -> Token {
        self.tokens[self.next.min(self.tokens.len() - 1)]
    }

    fn bump(&mut self) -> Token {
        let token = self.peek();
        if token.tok != Tok::End {
            self.next += 1;
        }
        token
    }

    fn source(&self, token: Token) -> &str {
        &self.text[token.start..token.end]
    }

    fn error(&self, position: usize, message: String) -> LtlError {
        LtlError::Syntax {
            formula: self.text.to_string(),
            position,
            message,
        }
    }

    /// The node `build(operand)` of a unary operator at `position`, within [`MAX_DEPTH`].
    fn unary_node(
        &self,
        position: usize,
        build: fn(Box<Ltl>) -> Ltl,
        operand: Parsed,
    ) -> Result<Parsed, LtlError> {
        let depth = self.depth(position, operand.depth)?;
        Ok(Parsed {
            formula: build(Box::new(operand.formula)),
            depth,
        })
    }

    /// The node `build(left, right)` of a binary operator at `position`, within
    /// [`MAX_DEPTH`].
    fn binary_node(
        &self,
        position: usize,
        build: fn(Box<Ltl>, Box<Ltl>) -> Ltl,
        left: Parsed,
        right: Parsed,
    ) -> Result<Parsed, LtlError> {
        let depth = self.depth(position, left.depth.max(right.depth))?;
        Ok(Parsed {
            formula: build(Box::new(left.formula), Box::new(right.formula)),
            depth,
        })
    }

    /// The depth of a node over operands at most `operands` deep.
    fn depth(&self, position: usize, operands: usize) -> Result<usize, LtlError> {
        if operands >= MAX_DEPTH {
            return Err(self.too_deep(position));
        }
        Ok(operands + 1)
    }

    fn too_deep(&self, position: usize) -> LtlError {
        self.error(
            position,
            format!("formula nested more than {MAX_DEPTH} levels deep"),
        )
    }

    /// Counts one more level of recursion (a parenthesis or an operator whose operand is
    /// parsed recursively); [`Parser::leave`] counts it back.
    fn enter(&mut self, token: Token) -> Result<(), LtlError> {
        if self.nesting >= MAX_DEPTH {
            return Err(self.too_deep(token.start));
        }
        self.nesting += 1;
        Ok(())
    }

    fn leave(&mut self) {
        self.nesting -= 1;
    }

    /// `or ('->' implies)?`, desugared to `!a | b`.
    fn implies(&mut self) -> Result<Parsed, LtlError> {
        let left = self.or()?;
        if self.peek().tok != Tok::Implies {
            return Ok(left);
        }
        let arrow = self.bump();
        self.enter(arrow)?;
        let right = self.implies();
        self.leave();
        let not = self.unary_node(arrow.start, Ltl::Not, left)?;
        self.binary_node(arrow.start, Ltl::Or, not, right?)
    }

    /// `and ('|' and)*`.
    fn or(&mut self) -> Result<Parsed, LtlError> {
        let mut left = self.and()?;
        while self.peek().tok == Tok::Or {
            let op = self.bump();
            let right = self.and()?;
            left = self.binary_node(op.start, Ltl::Or, left, right)?;
        }
        Ok(left)
    }

    /// `until ('&' until)*`.
    fn and(&mut self) -> Result<Parsed, LtlError> {
        let mut left = self.until()?;
        while self.peek().tok == Tok::And {
            let op = self.bump();
            let right = self.until()?;
            left = self.binary_node(op.start, Ltl::And, left, right)?;
        }
        Ok(left)
    }

    /// `unary (('U' | 'R') until)?`.
    fn until(&mut self) -> Result<Parsed, LtlError> {
        let left = self.unary()?;
        let build = match self.peek().tok {
            Tok::Until => Ltl::Until,
            Tok::Release => Ltl::Release,
            _ => return Ok(left),
        };
        let op = self.bump();
        self.enter(op)?;
        let right = self.until();
        self.leave();
        self.binary_node(op.start, build, left, right?)
    }

    /// `('!' | '~' | 'X' | 'F' | 'G') unary | primary`.
    fn unary(&mut self) -> Result<Parsed, LtlError> {
        let build: fn(Box<Ltl>) -> Ltl = match self.peek().tok {
            Tok::Not => Ltl::Not,
            Tok::Next => Ltl::Next,
            Tok::Eventually => Ltl::Eventually,
            Tok::Always => Ltl::Always,
            _ => return self.primary(),
        };
        let op = self.bump();
        self.enter(op)?;
        let operand = self.unary();
        self.leave();
        self.unary_node(op.start, build, operand?)
    }

    /// An atom, a constant, or a parenthesised formula.
    fn primary(&mut self) -> Result<Parsed, LtlError> {
        let token = self.bump();
        let leaf = |formula: Ltl| Ok(Parsed { formula, depth: 1 });
        match token.tok {
            Tok::True => leaf(Ltl::True),
            Tok::False => leaf(Ltl::False),
            Tok::Name => leaf(Ltl::Atom(self.source(token).trim_matches('"').to_string())),
            Tok::Open => {
                self.enter(token)?;
                let inner = self.implies();
                self.leave();
                let inner = inner?;
                if self.peek().tok != Tok::Close {
                    let found = self.peek();
                    return Err(if found.tok == Tok::End {
                        self.error(token.start, "unclosed '('".into())
                    } else {
                        self.error(
                            found.start,
                            format!(
                                "expected ')' to close the '(' at position {}, found '{}'",
                                token.start,
                                self.source(found)
                            ),
                        )
                    });
                }
                self.bump();
                Ok(inner)
            }
            Tok::End => {
                // The formula ends right after an operator (the formula is not empty: that
                // was checked first).
                match self.next.checked_sub(1).map(|i| self.tokens[i]) {
                    Some(operator) => Err(self.error(
                        operator.start,
                        format!("missing operand after '{}'", self.source(operator)),
                    )),
                    None => Err(self.error(0, "empty formula".into())),
                }
            }
            _ => Err(self.error(
                token.start,
                format!("unexpected '{}', expected an operand", self.source(token)),
            )),
        }
    }
}

#[cfg(test)]
mod tests;
