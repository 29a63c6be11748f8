use super::*;

fn a(name: &str) -> Ltl {
    Ltl::atom(name)
}
fn not(f: Ltl) -> Ltl {
    Ltl::Not(Box::new(f))
}
fn and(f: Ltl, g: Ltl) -> Ltl {
    Ltl::And(Box::new(f), Box::new(g))
}
fn or(f: Ltl, g: Ltl) -> Ltl {
    Ltl::Or(Box::new(f), Box::new(g))
}
fn x(f: Ltl) -> Ltl {
    Ltl::Next(Box::new(f))
}
fn f(f: Ltl) -> Ltl {
    Ltl::Eventually(Box::new(f))
}
fn g(f: Ltl) -> Ltl {
    Ltl::Always(Box::new(f))
}
fn u(f: Ltl, g: Ltl) -> Ltl {
    Ltl::Until(Box::new(f), Box::new(g))
}
fn r(f: Ltl, g: Ltl) -> Ltl {
    Ltl::Release(Box::new(f), Box::new(g))
}

fn parsing_table() -> Vec<(&'static str, Ltl)> {
    vec![
        ("a", a("a")),
        ("true", Ltl::True),
        ("false", Ltl::False),
        ("True", a("True")),
        ("a & b | c", or(and(a("a"), a("b")), a("c"))),
        ("a | b & c", or(a("a"), and(a("b"), a("c")))),
        ("a & b & c", and(and(a("a"), a("b")), a("c"))),
        ("a | b | c", or(or(a("a"), a("b")), a("c"))),
        ("a U b U c", u(a("a"), u(a("b"), a("c")))),
        ("a R b U c", r(a("a"), u(a("b"), a("c")))),
        ("(a U b) U c", u(u(a("a"), a("b")), a("c"))),
        ("a U b & c", and(u(a("a"), a("b")), a("c"))),
        ("a & b U c", and(a("a"), u(a("b"), a("c")))),
        ("a | b R c", or(a("a"), r(a("b"), a("c")))),
        ("!a U b", u(not(a("a")), a("b"))),
        ("F a U b", u(f(a("a")), a("b"))),
        ("X F G a", x(f(g(a("a"))))),
        ("!F a", not(f(a("a")))),
        ("!!a", not(not(a("a")))),
        ("G!a", g(not(a("a")))),
        ("a -> b -> c", or(not(a("a")), or(not(a("b")), a("c")))),
        ("a -> b | c", or(not(a("a")), or(a("b"), a("c")))),
        ("a | b -> c", or(not(or(a("a"), a("b"))), a("c"))),
        ("a U b -> c", or(not(u(a("a"), a("b"))), a("c"))),
        ("(a | b) & c", and(or(a("a"), a("b")), a("c"))),
        ("a && b || ~c", or(and(a("a"), a("b")), not(a("c")))),
        ("true U false", u(Ltl::True, Ltl::False)),
        ("F Kitchen", f(a("Kitchen"))),
        ("FKitchen", a("FKitchen")),
        ("F(Kitchen)", f(a("Kitchen"))),
        ("XF", a("XF")),
        ("Xa U Rb", u(a("Xa"), a("Rb"))),
        ("_x1 & WayPoint1", and(a("_x1"), a("WayPoint1"))),
        (
            "F (Kitchen & F Office)",
            f(and(a("Kitchen"), f(a("Office")))),
        ),
        ("!Corridor U Lab", u(not(a("Corridor")), a("Lab"))),
        ("F\"LabDoor1\"", f(a("LabDoor1"))),
        ("\"X\" U \"true\"", u(a("X"), a("true"))),
        ("\"Lab-Door.1\"", a("Lab-Door.1")),
        ("  F\ta\n", f(a("a"))),
        ("((a))", a("a")),
    ]
}

#[test]
fn parses_precedence_associativity_keywords_and_quoted_atoms() {
    for (text, expected) in parsing_table() {
        assert_eq!(parse(text), Ok(expected.clone()), "{text:?}");
        assert_eq!(text.parse::<Ltl>(), Ok(expected), "{text:?}");
    }
}

#[test]
fn display_writes_what_parse_reads_with_few_parentheses() {
    for (text, tree) in parsing_table() {
        let written = tree.to_string();
        assert_eq!(parse(&written), Ok(tree), "{text:?} written as {written:?}");
    }
    let cases = [
        (or(a("a"), or(a("b"), a("c"))), "a | (b | c)"),
        (or(or(a("a"), a("b")), a("c")), "a | b | c"),
        (u(u(a("a"), a("b")), a("c")), "(a U b) U c"),
        (u(a("a"), u(a("b"), a("c"))), "a U b U c"),
        (not(and(a("a"), a("b"))), "!(a & b)"),
        (f(u(a("a"), a("b"))), "F (a U b)"),
        (and(or(a("a"), a("b")), a("c")), "(a | b) & c"),
        (x(not(a("a"))), "X !a"),
        (a("X"), "\"X\""),
        (a("Lab-Door"), "\"Lab-Door\""),
        (u(Ltl::True, Ltl::False), "true U false"),
    ];
    for (tree, text) in cases {
        assert_eq!(tree.to_string(), text);
    }
}

#[test]
fn syntax_errors_carry_the_byte_position_and_a_message() {
    let cases: &[(&str, usize, &str)] = &[
        ("", 0, "empty formula"),
        ("  \t", 0, "empty formula"),
        ("F (Kitchen))", 11, "unexpected ')'"),
        ("(a & b", 0, "unclosed '('"),
        ("F (a & (b | c)", 2, "unclosed '('"),
        (
            "(a b)",
            3,
            "expected ')' to close the '(' at position 0, found 'b'",
        ),
        (")", 0, "unexpected ')', expected an operand"),
        ("()", 1, "unexpected ')', expected an operand"),
        ("a &", 2, "missing operand after '&'"),
        ("a U ", 2, "missing operand after 'U'"),
        ("F", 0, "missing operand after 'F'"),
        ("a -> !", 5, "missing operand after '!'"),
        ("a ->", 2, "missing operand after '->'"),
        ("& a", 0, "unexpected '&', expected an operand"),
        ("a | | b", 4, "unexpected '|', expected an operand"),
        ("a $ b", 2, "unexpected character '$'"),
        ("a - b", 2, "unexpected character '-' (did you mean '->'?)"),
        ("Küche", 1, "unexpected character 'ü'"),
        (
            "a b",
            2,
            "unexpected 'b' after a complete formula (missing operator?)",
        ),
        (
            "F a G b",
            4,
            "unexpected 'G' after a complete formula (missing operator?)",
        ),
        ("F \"Lab", 2, "unterminated quoted name"),
        ("\"\"", 0, "empty quoted name"),
        (
            "\"Lab Door\"",
            4,
            "whitespace in a quoted name (node names contain none)",
        ),
    ];
    for &(text, position, message) in cases {
        match parse(text) {
            Err(LtlError::Syntax {
                formula,
                position: p,
                message: m,
            }) => {
                assert_eq!((p, m.as_str()), (position, message), "{text:?}");
                assert_eq!(formula, text);
            }
            other => panic!("{text:?} gave {other:?}"),
        }
        assert_eq!(parse(text).unwrap_err().position(), Some(position));
    }
}

#[test]
fn syntax_errors_display_a_caret_under_the_position() {
    let shown = |text: &str| parse(text).unwrap_err().to_string();
    assert_eq!(
        shown("F (Kitchen))"),
        "unexpected ')' at position 11\nF (Kitchen))\n           ^"
    );
    assert_eq!(
        shown("a &"),
        "missing operand after '&' at position 2\na &\n  ^"
    );
    // Only the line of the error, and the caret counts characters, not bytes.
    assert_eq!(
        shown("F a &\n  (b |"),
        "missing operand after '|' at position 11\n  (b |\n     ^"
    );
    assert_eq!(
        shown("\"Küche\" $"),
        "unexpected character '$' at position 9\n\"Küche\" $\n        ^"
    );
    assert_eq!(
        shown("F a &\r\n  b $"),
        "unexpected character '$' at position 11\n  b $\n    ^"
    );
    assert_eq!(
        shown("F (a &\r\n b"),
        "unclosed '(' at position 2\nF (a &\n  ^"
    );
    // Tabs are kept so the caret lines up.
    assert_eq!(
        shown("\ta $"),
        "unexpected character '$' at position 3\n\ta $\n\t  ^"
    );
}

#[test]
fn nesting_deeper_than_the_limit_is_an_error_not_a_stack_overflow() {
    let deep = |open: &str, n: usize, inner: &str, close: &str| {
        format!("{}{inner}{}", open.repeat(n), close.repeat(n))
    };
    // MAX_DEPTH parentheses are fine, one more is not.
    assert_eq!(parse(&deep("(", MAX_DEPTH, "a", ")")), Ok(a("a")));
    let error = parse(&deep("(", MAX_DEPTH + 1, "a", ")")).unwrap_err();
    assert_eq!(error.position(), Some(MAX_DEPTH));
    assert!(parse(&deep("(", 100_000, "a", ")")).is_err());
    // Trees: MAX_DEPTH - 1 unary operators over an atom is MAX_DEPTH levels.
    let ok = deep("X ", MAX_DEPTH - 1, "a", "");
    assert!(parse(&ok).is_ok());
    assert!(parse(&deep("X ", MAX_DEPTH, "a", "")).is_err());
    assert!(parse(&deep("!", 100_000, "a", "")).is_err());
    assert!(parse(&deep("a -> ", 100_000, "a", "")).is_err());
    assert!(parse(&deep("a U ", 100_000, "a", "")).is_err());
    // Left-associative chains build deep trees without recursion in the parser.
    let chain = deep("a & ", MAX_DEPTH, "a", "");
    let error = parse(&chain).unwrap_err();
    assert_eq!(error.position(), Some(4 * (MAX_DEPTH - 1) + 2));
    assert!(error.to_string().starts_with(&format!(
        "formula nested more than {MAX_DEPTH} levels deep at position"
    )));
}
