//! Co-safe linear temporal logic: the task language of a robot on a topological map
//! ([Fentanes 2015] §V). `F Kitchen` ("go to the kitchen"), `F (Kitchen & F Office)` ("the kitchen,
//! then the office"), `!Corridor U Lab` ("reach the lab without passing the corridor").
//!
//! * [`parse`] reads a formula in PRISM-like syntax into an [`Ltl`] syntax tree;
//!   [`LtlError`] points at the offending byte with a caret.
//! * [`check_co_safe`] / [`parse_co_safe`]: co-safe formulas are those whose negation normal
//!   form ([`nnf`]) has no `G` and no `R`, so that every run satisfying them does so by a
//!   finite prefix.
//! * [`to_dfa`] builds the minimal [`Dfa`] over the exclusive alphabet of node labels that
//!   accepts the finite runs satisfying a co-safe formula, by formula progression;
//!   [`compile`] does all three steps.
//!
//! ```
//! use chronomap_topo::ltl::compile;
//!
//! let dfa = compile("!Corridor U Lab")?;
//! assert_eq!(dfa.atoms, ["Corridor", "Lab"]);
//! let [corridor, lab, elsewhere] = [0, 1, 2];
//! assert!(dfa.accepts(&[elsewhere, elsewhere, lab]));
//! assert!(!dfa.accepts(&[elsewhere, corridor, lab]));
//! assert_eq!(dfa.states(), 3); // waiting, done, failed
//! # Ok::<(), chronomap_topo::ltl::LtlError>(())
//! ```
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

use std::collections::HashMap;
use std::fmt;

use thiserror::Error;

use crate::automaton::Dfa;

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
    /// The formula is not (syntactically) co-safe: its negation normal form contains `G` or
    /// `R`, so no finite prefix of a run can guarantee it.
    #[error("{}", not_co_safe(.formula, *.operator, *.negated, *.position))]
    NotCoSafe {
        /// The formula: as given to [`parse_co_safe`], or as [`Ltl`]'s `Display` writes it.
        formula: String,
        /// The offending operator as written: `G` or `R`, or `F` or `U` under a negation.
        operator: char,
        /// Whether the operator is under a negation (so that `F` is `G` in the negation
        /// normal form and `U` is `R`).
        negated: bool,
        /// Byte offset of the operator in `formula`, where the formula was parsed from text.
        position: Option<usize>,
    },
    /// The formula is nested more deeply than [`MAX_DEPTH`] levels.
    #[error("formula nested {depth} levels deep, more than the {limit} supported")]
    TooDeep {
        /// Depth of the syntax tree.
        depth: usize,
        /// The limit, [`MAX_DEPTH`].
        limit: usize,
    },
    /// The automaton would have more states than the limit.
    #[error("the automaton of the formula has more than {limit} states")]
    TooManyStates {
        /// The limit on states explored before minimisation.
        limit: usize,
    },
    /// A state of the automaton would be a disjunction of more than [`MAX_CLAUSES`] clauses.
    #[error("a state of the automaton needs more than {limit} clauses")]
    TooComplex {
        /// The limit, [`MAX_CLAUSES`].
        limit: usize,
    },
}

impl LtlError {
    /// Byte offset in the formula text of what caused the error, if known.
    pub fn position(&self) -> Option<usize> {
        match self {
            LtlError::Syntax { position, .. } => Some(*position),
            LtlError::NotCoSafe { position, .. } => *position,
            LtlError::TooDeep { .. }
            | LtlError::TooManyStates { .. }
            | LtlError::TooComplex { .. } => None,
        }
    }
}

/// The message of [`LtlError::NotCoSafe`].
fn not_co_safe(formula: &str, operator: char, negated: bool, position: Option<usize>) -> String {
    let what = match (operator, negated) {
        ('G', false) => "'G' (always) is not co-safe".to_string(),
        ('R', false) => "'R' (release) is not co-safe".to_string(),
        ('F', true) => {
            "'F' under a negation is 'G' (always) in negation normal form, which is not co-safe"
                .to_string()
        }
        ('U', true) => {
            "'U' under a negation is 'R' (release) in negation normal form, which is not co-safe"
                .to_string()
        }
        (operator, _) => format!("'{operator}' is not co-safe"),
    };
    match position {
        Some(position) => format!(
            "{what} at position {position}\n{}",
            caret(formula, position)
        ),
        None => format!("{what}: {formula}"),
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

/// Whether `name` is an identifier atom `[A-Za-z_][A-Za-z0-9_]*` (also PRISM's identifiers).
pub(crate) fn is_identifier(name: &str) -> bool {
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

/// Where the operators of a parsed formula are: one node per node of the [`Ltl`] tree, with
/// the byte offset of its operator (or atom) and the spans of its operands.
#[derive(Clone, Debug)]
struct Span {
    position: usize,
    children: Vec<Span>,
}

/// A parsed subformula, where it is, and how deep its tree is.
struct Parsed {
    formula: Ltl,
    span: Span,
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
/// use chronomap_topo::ltl::parse;
///
/// let task = parse("F (Kitchen & F \"Office\")")?;
/// assert_eq!(task.to_string(), "F (Kitchen & F Office)");
/// let error = parse("F (Kitchen))").unwrap_err();
/// assert_eq!(error.to_string(), "unexpected ')' at position 11\nF (Kitchen))\n           ^");
/// # Ok::<(), chronomap_topo::ltl::LtlError>(())
/// ```
pub fn parse(text: &str) -> Result<Ltl, LtlError> {
    parse_spanned(text).map(|(formula, _)| formula)
}

/// Reads a formula and where its operators are.
fn parse_spanned(text: &str) -> Result<(Ltl, Span), LtlError> {
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
        Tok::End => Ok((parsed.formula, parsed.span)),
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
            span: Span {
                position,
                children: vec![operand.span],
            },
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
            span: Span {
                position,
                children: vec![left.span, right.span],
            },
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
        self.left_associative(Tok::Or, Ltl::Or, Self::and)
    }

    /// `until ('&' until)*`.
    fn and(&mut self) -> Result<Parsed, LtlError> {
        self.left_associative(Tok::And, Ltl::And, Self::until)
    }

    /// `operand (op operand)*`, grouped from the left.
    fn left_associative(
        &mut self,
        op: Tok,
        build: fn(Box<Ltl>, Box<Ltl>) -> Ltl,
        operand: fn(&mut Self) -> Result<Parsed, LtlError>,
    ) -> Result<Parsed, LtlError> {
        let mut left = operand(self)?;
        let mut operands = 1usize;
        while self.peek().tok == op {
            let token = self.bump();
            let right = operand(self)?;
            if left.depth >= MAX_DEPTH && left.depth >= right.depth {
                // The chain itself is too long (not its operand): say so in its own terms.
                return Err(self.error(
                    token.start,
                    format!(
                        "more than {operands} operands joined by '{}': each adds a level, \
                         and a formula nests at most {MAX_DEPTH} levels deep (group them \
                         with parentheses)",
                        self.source(token)
                    ),
                ));
            }
            left = self.binary_node(token.start, build, left, right)?;
            operands += 1;
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
        let leaf = |formula: Ltl| {
            Ok(Parsed {
                formula,
                span: Span {
                    position: token.start,
                    children: Vec::new(),
                },
                depth: 1,
            })
        };
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

/// Reads a formula and checks that it is co-safe, pointing at the offending operator if it
/// is not.
///
/// # Errors
/// [`LtlError::Syntax`] as [`parse`]; [`LtlError::NotCoSafe`] with the position of the first
/// `G` or `R` of the negation normal form (a `G`, an `R`, or an `F` or `U` under a negation).
///
/// ```
/// use chronomap_topo::ltl::parse_co_safe;
///
/// assert!(parse_co_safe("!Corridor U Lab").is_ok());
/// assert!(parse_co_safe("!G Kitchen").is_ok()); // F !Kitchen
/// let error = parse_co_safe("F Kitchen & !F Office").unwrap_err();
/// assert_eq!(error.position(), Some(13));
/// ```
pub fn parse_co_safe(text: &str) -> Result<Ltl, LtlError> {
    let (formula, span) = parse_spanned(text)?;
    let atoms = atoms(&formula);
    Arena::new()
        .build(&formula, Some(&span), false, &atoms)
        .map_err(|offence| offence.error(text.to_string()))?;
    Ok(formula)
}

/// Checks that a formula is (syntactically) co-safe: its negation normal form uses only
/// `true`, `false`, atoms, negated atoms, `&`, `|`, `X`, `U` and `F`.
///
/// # Errors
/// [`LtlError::NotCoSafe`] (without position) naming the first offending operator;
/// [`LtlError::TooDeep`] for a tree deeper than [`MAX_DEPTH`].
pub fn check_co_safe(formula: &Ltl) -> Result<(), LtlError> {
    check_depth(formula)?;
    let atoms = atoms(formula);
    Arena::new()
        .build(formula, None, false, &atoms)
        .map_err(|offence| offence.error(formula.to_string()))?;
    Ok(())
}

/// Whether [`check_co_safe`] accepts the formula.
pub fn is_co_safe(formula: &Ltl) -> bool {
    check_co_safe(formula).is_ok()
}

/// The negation normal form: negations pushed down to the atoms by De Morgan's laws and the
/// dualities `!X φ = X !φ`, `!F φ = G !φ`, `!G φ = F !φ`, `!(φ U ψ) = !φ R !ψ`,
/// `!(φ R ψ) = !φ U !ψ`; `!true = false`, `!!φ = φ`. Nothing else is simplified.
///
/// ```
/// use chronomap_topo::ltl::{nnf, parse};
///
/// assert_eq!(nnf(&parse("!(a U !b)")?).to_string(), "!a R b");
/// assert_eq!(nnf(&parse("!G a")?).to_string(), "F !a");
/// # Ok::<(), chronomap_topo::ltl::LtlError>(())
/// ```
pub fn nnf(formula: &Ltl) -> Ltl {
    nnf_of(formula, false)
}

fn nnf_of(formula: &Ltl, negated: bool) -> Ltl {
    let boxed = |f: &Ltl, negated: bool| Box::new(nnf_of(f, negated));
    match (formula, negated) {
        (Ltl::True, false) | (Ltl::False, true) => Ltl::True,
        (Ltl::True, true) | (Ltl::False, false) => Ltl::False,
        (Ltl::Atom(name), false) => Ltl::Atom(name.clone()),
        (Ltl::Atom(name), true) => Ltl::Not(Box::new(Ltl::Atom(name.clone()))),
        (Ltl::Not(a), _) => nnf_of(a, !negated),
        (Ltl::And(a, b), false) | (Ltl::Or(a, b), true) => {
            Ltl::And(boxed(a, negated), boxed(b, negated))
        }
        (Ltl::Or(a, b), false) | (Ltl::And(a, b), true) => {
            Ltl::Or(boxed(a, negated), boxed(b, negated))
        }
        (Ltl::Next(a), _) => Ltl::Next(boxed(a, negated)),
        (Ltl::Eventually(a), false) | (Ltl::Always(a), true) => Ltl::Eventually(boxed(a, negated)),
        (Ltl::Always(a), false) | (Ltl::Eventually(a), true) => Ltl::Always(boxed(a, negated)),
        (Ltl::Until(a, b), false) | (Ltl::Release(a, b), true) => {
            Ltl::Until(boxed(a, negated), boxed(b, negated))
        }
        (Ltl::Release(a, b), false) | (Ltl::Until(a, b), true) => {
            Ltl::Release(boxed(a, negated), boxed(b, negated))
        }
    }
}

/// The atoms of a formula, sorted and without repetition: the alphabet of its automaton.
pub fn atoms(formula: &Ltl) -> Vec<String> {
    let mut names = std::collections::BTreeSet::new();
    let mut stack = vec![formula];
    while let Some(f) = stack.pop() {
        match f {
            Ltl::True | Ltl::False => {}
            Ltl::Atom(name) => {
                names.insert(name.clone());
            }
            Ltl::Not(a) | Ltl::Next(a) | Ltl::Eventually(a) | Ltl::Always(a) => stack.push(a),
            Ltl::And(a, b) | Ltl::Or(a, b) | Ltl::Until(a, b) | Ltl::Release(a, b) => {
                stack.push(b);
                stack.push(a);
            }
        }
    }
    names.into_iter().collect()
}

/// The depth of the syntax tree (an atom has depth 1), computed without recursion.
pub fn depth(formula: &Ltl) -> usize {
    let mut deepest = 0;
    let mut stack = vec![(formula, 1)];
    while let Some((f, d)) = stack.pop() {
        deepest = deepest.max(d);
        match f {
            Ltl::True | Ltl::False | Ltl::Atom(_) => {}
            Ltl::Not(a) | Ltl::Next(a) | Ltl::Eventually(a) | Ltl::Always(a) => {
                stack.push((a, d + 1))
            }
            Ltl::And(a, b) | Ltl::Or(a, b) | Ltl::Until(a, b) | Ltl::Release(a, b) => {
                stack.push((a, d + 1));
                stack.push((b, d + 1));
            }
        }
    }
    deepest
}

fn check_depth(formula: &Ltl) -> Result<(), LtlError> {
    match depth(formula) {
        depth if depth > MAX_DEPTH => Err(LtlError::TooDeep {
            depth,
            limit: MAX_DEPTH,
        }),
        _ => Ok(()),
    }
}

/// A `G` or `R` of the negation normal form, found while building it.
struct Offence {
    operator: char,
    negated: bool,
    position: Option<usize>,
}

impl Offence {
    fn error(self, formula: String) -> LtlError {
        LtlError::NotCoSafe {
            formula,
            operator: self.operator,
            negated: self.negated,
            position: self.position,
        }
    }
}

/// Index of a node of an [`Arena`].
type Id = usize;
const TRUE: Id = 0;
const FALSE: Id = 1;

/// A node of the negation normal form of a co-safe formula.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Node {
    True,
    False,
    /// Atom `atom` holds (`holds`) or does not.
    Literal {
        atom: usize,
        holds: bool,
    },
    And(Id, Id),
    Or(Id, Id),
    Next(Id),
    Until(Id, Id),
    Eventually(Id),
}

/// Hash-consed co-safe formulas in negation normal form: equal subformulas share one id.
///
/// The constructors fold constants (`X true = F true = φ U true = true`, the same for
/// `false`, `false U ψ = ψ`, `true U ψ = F ψ`, `F F φ = F φ`, `φ U φ = φ`, `φ & φ = φ`), so that
/// every node other than `true` is false on the empty remainder of a word: that is what
/// makes "the progressed formula is `true`" the acceptance test.
struct Arena {
    nodes: Vec<Node>,
    ids: HashMap<Node, Id>,
}

impl Arena {
    fn new() -> Arena {
        let mut arena = Arena {
            nodes: Vec::new(),
            ids: HashMap::new(),
        };
        arena.intern(Node::True);
        arena.intern(Node::False);
        arena
    }

    fn intern(&mut self, node: Node) -> Id {
        if let Some(&id) = self.ids.get(&node) {
            return id;
        }
        self.nodes.push(node);
        self.ids.insert(node, self.nodes.len() - 1);
        self.nodes.len() - 1
    }

    fn and(&mut self, a: Id, b: Id) -> Id {
        self.junction(a, b, FALSE, TRUE, Node::And)
    }

    fn or(&mut self, a: Id, b: Id) -> Id {
        self.junction(a, b, TRUE, FALSE, Node::Or)
    }

    /// `a ∘ b` for the commutative, idempotent `node` with absorbing element `zero` and
    /// neutral element `one`, operands ordered so that `a ∘ b` and `b ∘ a` share one id.
    fn junction(&mut self, a: Id, b: Id, zero: Id, one: Id, node: fn(Id, Id) -> Node) -> Id {
        if a == zero || b == zero {
            zero
        } else if a == one {
            b
        } else if b == one || a == b {
            a
        } else {
            self.intern(node(a.min(b), a.max(b)))
        }
    }

    fn next(&mut self, a: Id) -> Id {
        match a {
            TRUE | FALSE => a,
            a => self.intern(Node::Next(a)),
        }
    }

    fn eventually(&mut self, a: Id) -> Id {
        match (a, self.nodes[a]) {
            (TRUE | FALSE, _) | (_, Node::Eventually(_)) => a,
            (a, _) => self.intern(Node::Eventually(a)),
        }
    }

    fn until(&mut self, a: Id, b: Id) -> Id {
        match (a, b) {
            (_, TRUE | FALSE) | (FALSE, _) => b,
            (TRUE, b) => self.eventually(b),
            (a, b) if a == b => b,
            (a, b) => self.intern(Node::Until(a, b)),
        }
    }

    /// Builds the negation normal form of `formula` (negated if `negated`), or finds the
    /// operator that makes it not co-safe. `span` locates the operators in the source text.
    fn build(
        &mut self,
        formula: &Ltl,
        span: Option<&Span>,
        negated: bool,
        atoms: &[String],
    ) -> Result<Id, Offence> {
        let child = |k: usize| span.and_then(|s| s.children.get(k));
        let offence = |operator: char| Offence {
            operator,
            negated,
            position: span.map(|s| s.position),
        };
        Ok(match formula {
            Ltl::True => [TRUE, FALSE][usize::from(negated)],
            Ltl::False => [FALSE, TRUE][usize::from(negated)],
            Ltl::Atom(name) => {
                let atom = atoms.binary_search(name).unwrap_or_else(|i| i);
                self.intern(Node::Literal {
                    atom,
                    holds: !negated,
                })
            }
            Ltl::Not(a) => self.build(a, child(0), !negated, atoms)?,
            Ltl::And(a, b) | Ltl::Or(a, b) => {
                let a = self.build(a, child(0), negated, atoms)?;
                let b = self.build(b, child(1), negated, atoms)?;
                if matches!(formula, Ltl::And(..)) != negated {
                    self.and(a, b)
                } else {
                    self.or(a, b)
                }
            }
            Ltl::Next(a) => {
                let a = self.build(a, child(0), negated, atoms)?;
                self.next(a)
            }
            Ltl::Eventually(_) if negated => return Err(offence('F')),
            Ltl::Always(_) if !negated => return Err(offence('G')),
            Ltl::Eventually(a) | Ltl::Always(a) => {
                let a = self.build(a, child(0), negated, atoms)?;
                self.eventually(a)
            }
            Ltl::Until(..) if negated => return Err(offence('U')),
            Ltl::Release(..) if !negated => return Err(offence('R')),
            Ltl::Until(a, b) | Ltl::Release(a, b) => {
                let a = self.build(a, child(0), negated, atoms)?;
                let b = self.build(b, child(1), negated, atoms)?;
                self.until(a, b)
            }
        })
    }
}

/// The most states [`to_dfa`] explores before giving up with [`LtlError::TooManyStates`].
pub const MAX_STATES: usize = 10_000;

/// The most clauses a state of the automaton may have (see [`to_dfa`]), and the most
/// clause pairs one conjunction may combine, before [`LtlError::TooComplex`].
pub const MAX_CLAUSES: usize = 10_000;

/// A conjunction of elementary formulas (ids of literals, `X`, `U` and `F` nodes), sorted.
type Clause = Vec<Id>;

/// A positive boolean combination of elementary formulas in disjunctive normal form: clauses
/// sorted, none a subset of another. This is the unique irredundant form of a monotone
/// boolean function, so two equal combinations have equal `Dnf`s. `[]` is `false`, `[[]]`
/// is `true`.
type Dnf = Vec<Clause>;

fn dnf_true() -> Dnf {
    vec![Vec::new()]
}

/// Whether sorted `small` is a subset of sorted `big`.
fn is_subset(small: &[Id], big: &[Id]) -> bool {
    let mut big = big.iter();
    small.iter().all(|x| big.any(|y| y == x))
}

/// Sorts, removes duplicate and absorbed clauses (`a | a & b = a`).
fn normalise(mut clauses: Vec<Clause>) -> Result<Dnf, LtlError> {
    clauses.sort_unstable_by(|x, y| x.len().cmp(&y.len()).then_with(|| x.cmp(y)));
    clauses.dedup();
    let mut kept: Vec<Clause> = Vec::with_capacity(clauses.len());
    for clause in clauses {
        if !kept.iter().any(|k| is_subset(k, &clause)) {
            kept.push(clause);
        }
    }
    if kept.len() > MAX_CLAUSES {
        return Err(LtlError::TooComplex { limit: MAX_CLAUSES });
    }
    kept.sort_unstable();
    Ok(kept)
}

fn disjunction(a: Dnf, b: Dnf) -> Result<Dnf, LtlError> {
    if a.is_empty() {
        return Ok(b);
    }
    if b.is_empty() {
        return Ok(a);
    }
    let mut clauses = a;
    clauses.extend(b);
    normalise(clauses)
}

fn conjunction(a: &Dnf, b: &Dnf) -> Result<Dnf, LtlError> {
    if a.len().saturating_mul(b.len()) > MAX_CLAUSES {
        return Err(LtlError::TooComplex { limit: MAX_CLAUSES });
    }
    let mut clauses = Vec::with_capacity(a.len() * b.len());
    for x in a {
        for y in b {
            let mut clause: Clause = x.iter().chain(y).copied().collect();
            clause.sort_unstable();
            clause.dedup();
            clauses.push(clause);
        }
    }
    normalise(clauses)
}

/// Formula progression over an [`Arena`]: what remains to be satisfied after one letter.
struct Progression<'a> {
    arena: &'a Arena,
    /// `memo[(id, letter)]`: the progression of node `id` through `letter`.
    memo: HashMap<(Id, usize), Dnf>,
}

impl Progression<'_> {
    /// The disjunctive normal form of node `id` over elementary formulas.
    fn dnf(&self, id: Id) -> Result<Dnf, LtlError> {
        match self.arena.nodes[id] {
            Node::True => Ok(dnf_true()),
            Node::False => Ok(Vec::new()),
            Node::And(a, b) => conjunction(&self.dnf(a)?, &self.dnf(b)?),
            Node::Or(a, b) => disjunction(self.dnf(a)?, self.dnf(b)?),
            Node::Literal { .. } | Node::Next(_) | Node::Until(..) | Node::Eventually(_) => {
                Ok(vec![vec![id]])
            }
        }
    }

    /// The progression of node `id` through `letter`:
    /// `prog(p) = true` iff the letter satisfies the literal `p`, `prog(X φ) = φ`,
    /// `prog(F φ) = prog(φ) | F φ`, `prog(φ U ψ) = prog(ψ) | prog(φ) & (φ U ψ)`.
    fn node(&mut self, id: Id, letter: usize) -> Result<Dnf, LtlError> {
        if let Some(dnf) = self.memo.get(&(id, letter)) {
            return Ok(dnf.clone());
        }
        let dnf = match self.arena.nodes[id] {
            Node::True => dnf_true(),
            Node::False => Vec::new(),
            Node::Literal { atom, holds } if (atom == letter) == holds => dnf_true(),
            Node::Literal { .. } => Vec::new(),
            Node::And(a, b) => conjunction(&self.node(a, letter)?, &self.node(b, letter)?)?,
            Node::Or(a, b) => disjunction(self.node(a, letter)?, self.node(b, letter)?)?,
            Node::Next(a) => self.dnf(a)?,
            Node::Eventually(a) => disjunction(self.node(a, letter)?, vec![vec![id]])?,
            Node::Until(a, b) => {
                let stay = conjunction(&self.node(a, letter)?, &vec![vec![id]])?;
                disjunction(self.node(b, letter)?, stay)?
            }
        };
        self.memo.insert((id, letter), dnf.clone());
        Ok(dnf)
    }

    /// The progression of a state through `letter`.
    fn state(&mut self, state: &Dnf, letter: usize) -> Result<Dnf, LtlError> {
        let mut result = Vec::new();
        for clause in state {
            let mut conjoined = dnf_true();
            for &id in clause {
                if conjoined.is_empty() {
                    break;
                }
                conjoined = conjunction(&conjoined, &self.node(id, letter)?)?;
            }
            result = disjunction(result, conjoined)?;
            if result == dnf_true() {
                break;
            }
        }
        Ok(result)
    }
}

/// The deterministic automaton of a co-safe formula's good prefixes, with at most
/// [`MAX_STATES`] states explored. See [`to_dfa_with_limit`].
///
/// # Errors
/// As [`to_dfa_with_limit`].
///
/// ```
/// use chronomap_topo::ltl::{parse, to_dfa};
///
/// let dfa = to_dfa(&parse("F (Kitchen & F Office)")?)?;
/// assert_eq!(dfa.atoms, ["Kitchen", "Office"]);
/// assert_eq!(dfa.states(), 3);
/// let [kitchen, office, elsewhere] = [0, 1, 2];
/// assert!(dfa.accepts(&[elsewhere, kitchen, elsewhere, office]));
/// assert!(!dfa.accepts(&[office, kitchen]));
/// # Ok::<(), chronomap_topo::ltl::LtlError>(())
/// ```
pub fn to_dfa(formula: &Ltl) -> Result<Dfa, LtlError> {
    to_dfa_with_limit(formula, MAX_STATES)
}

/// The minimal deterministic automaton of a co-safe formula over the exclusive alphabet of
/// [`Dfa`]: letter `i < atoms.len()` is "atom `i` holds (and no other)", letter
/// `atoms.len()` is "no atom holds"; `dfa.atoms == atoms(formula)`.
///
/// The automaton reads the label of every step, the first one included, and accepts a word
/// once the formula's obligations are met within it: the formula is *progressed* through
/// each letter (`prog(X φ) = φ`, `prog(F φ) = prog(φ) | F φ`,
/// `prog(φ U ψ) = prog(ψ) | prog(φ) & (φ U ψ)`, literals become `true` or `false`) and the
/// word is accepted when what remains is `true`. Whatever follows, the formula then holds.
/// `F a` accepts the one-letter word `[a]`; `X a` needs two letters, the second `a`. The
/// accepting state is absorbing; words that can no longer be completed end in a rejecting
/// sink. This is the strong finite-trace semantics (`X`, `F`, `U` meet their obligations
/// inside the word; only trivially true obligations such as `X true` need no more letters),
/// i.e. the *informative* good prefixes: an obligation that is a tautology without being
/// `true` (`X (a | !a)` after one letter) is discharged by the next letter, not at once.
///
/// States are the progressed formulas, each a positive boolean combination of the
/// formula's literals and `X`, `F`, `U` subformulas kept in irredundant disjunctive normal
/// form (sorted, absorbed clauses). There are finitely many such combinations, so the
/// exploration ends; the result is minimised (Moore's partition refinement) and its states
/// numbered in breadth-first order from the initial state (0), letters in order.
///
/// # Errors
/// [`LtlError::NotCoSafe`] (without position; [`parse_co_safe`] gives one),
/// [`LtlError::TooDeep`], [`LtlError::TooManyStates`] if more than `max_states` states are
/// reached before minimisation, [`LtlError::TooComplex`] if a state needs more than
/// [`MAX_CLAUSES`] clauses.
pub fn to_dfa_with_limit(formula: &Ltl, max_states: usize) -> Result<Dfa, LtlError> {
    check_depth(formula)?;
    let atoms = atoms(formula);
    let letters = atoms.len() + 1;
    let mut arena = Arena::new();
    let root = arena
        .build(formula, None, false, &atoms)
        .map_err(|offence| offence.error(formula.to_string()))?;
    let mut progression = Progression {
        arena: &arena,
        memo: HashMap::new(),
    };
    let initial = progression.dnf(root)?;
    let too_many = LtlError::TooManyStates { limit: max_states };
    if max_states == 0 {
        return Err(too_many);
    }
    let mut states = vec![initial.clone()];
    let mut index = HashMap::from([(initial, 0)]);
    let mut delta = Vec::new();
    let mut q = 0;
    while q < states.len() {
        for letter in 0..letters {
            let next = progression.state(&states[q], letter)?;
            let id = match index.get(&next) {
                Some(&id) => id,
                None if states.len() == max_states => return Err(too_many),
                None => {
                    states.push(next.clone());
                    index.insert(next, states.len() - 1);
                    states.len() - 1
                }
            };
            delta.push(id);
        }
        q += 1;
    }
    let accepting: Vec<bool> = states.iter().map(|s| *s == dnf_true()).collect();
    let (accepting, delta) = minimise(&accepting, &delta, letters);
    Ok(Dfa {
        atoms,
        initial: 0,
        accepting,
        delta,
    })
}

/// Reads a co-safe task and builds its automaton: [`parse_co_safe`] then [`to_dfa`].
///
/// # Errors
/// As [`parse_co_safe`] and [`to_dfa`].
pub fn compile(text: &str) -> Result<Dfa, LtlError> {
    to_dfa(&parse_co_safe(text)?)
}

/// Moore's partition refinement of a complete automaton whose states are all reachable from
/// state 0; the classes numbered breadth-first from the class of state 0, letters in order.
/// Returns the minimal automaton's acceptance and transitions.
fn minimise(accepting: &[bool], delta: &[usize], letters: usize) -> (Vec<bool>, Vec<usize>) {
    let n = accepting.len();
    let mut class: Vec<usize> = accepting.iter().map(|&a| usize::from(a)).collect();
    let mut classes = if accepting.iter().all(|&a| a == accepting[0]) {
        1
    } else {
        2
    };
    loop {
        let mut ids: HashMap<Vec<usize>, usize> = HashMap::new();
        let mut refined = Vec::with_capacity(n);
        for q in 0..n {
            let signature: Vec<usize> = std::iter::once(class[q])
                .chain(
                    delta[q * letters..(q + 1) * letters]
                        .iter()
                        .map(|&t| class[t]),
                )
                .collect();
            let fresh = ids.len();
            refined.push(*ids.entry(signature).or_insert(fresh));
        }
        class = refined;
        if ids.len() == classes {
            break;
        }
        classes = ids.len();
    }
    // A representative of each class, and the classes in breadth-first order.
    let mut representative = vec![usize::MAX; classes];
    for q in (0..n).rev() {
        representative[class[q]] = q;
    }
    let mut number = vec![usize::MAX; classes];
    let mut order = vec![class[0]];
    number[class[0]] = 0;
    let mut minimal_delta = Vec::with_capacity(classes * letters);
    let mut next = 0;
    while next < order.len() {
        let q = representative[order[next]];
        for letter in 0..letters {
            let target = class[delta[q * letters + letter]];
            if number[target] == usize::MAX {
                number[target] = order.len();
                order.push(target);
            }
            minimal_delta.push(number[target]);
        }
        next += 1;
    }
    let minimal_accepting = order
        .iter()
        .map(|&c| accepting[representative[c]])
        .collect();
    (minimal_accepting, minimal_delta)
}

#[cfg(test)]
mod tests;
