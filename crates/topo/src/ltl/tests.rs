use super::*;
use chronomap_core::rng::SplitMix64;

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
    assert_eq!(depth(&parse(&ok).unwrap()), MAX_DEPTH);
    assert!(parse(&deep("X ", MAX_DEPTH, "a", "")).is_err());
    assert!(parse(&deep("!", 100_000, "a", "")).is_err());
    assert!(parse(&deep("a -> ", 100_000, "a", "")).is_err());
    assert!(parse(&deep("a U ", 100_000, "a", "")).is_err());
    // Left-associative chains build deep trees without recursion in the parser.
    let chain = deep("a & ", MAX_DEPTH, "a", "");
    let error = parse(&chain).unwrap_err();
    assert_eq!(error.position(), Some(4 * (MAX_DEPTH - 1) + 2));
    assert!(
        error.to_string().starts_with(&format!(
            "more than {} operands joined by '&': each adds a level, and a formula nests at \
             most {MAX_DEPTH} levels deep",
            MAX_DEPTH
        )),
        "{error}"
    );
    // A flat conjunction of 300 `F` operands names the operand count, not a nesting.
    let flat: Vec<String> = (0..300).map(|i| format!("F a{i}")).collect();
    let error = parse_co_safe(&flat.join(" & ")).unwrap_err().to_string();
    assert!(
        error.starts_with("more than 255 operands joined by '&'"),
        "{error}"
    );
    // The deepest formula parse accepts still builds its automaton: X^k a has k + 3 states.
    let dfa = to_dfa(&parse(&ok).unwrap()).unwrap();
    assert_eq!(dfa.states(), MAX_DEPTH + 2);
    // Deeper trees built by hand are refused by the automaton construction.
    let mut tall = a("a");
    for _ in 0..MAX_DEPTH {
        tall = x(tall);
    }
    assert_eq!(
        to_dfa(&tall),
        Err(LtlError::TooDeep {
            depth: MAX_DEPTH + 1,
            limit: MAX_DEPTH
        })
    );
}

#[test]
fn atoms_are_sorted_and_unique() {
    let formula = parse("F (b & F a) | !c U b | X \"a\"").unwrap();
    assert_eq!(atoms(&formula), ["a", "b", "c"]);
    assert_eq!(atoms(&Ltl::True), Vec::<String>::new());
}

#[test]
fn negation_normal_form_pushes_negations_to_the_atoms() {
    let cases = [
        ("!(a U !b)", r(not(a("a")), a("b"))),
        ("!(a R b)", u(not(a("a")), not(a("b")))),
        ("!G a", f(not(a("a")))),
        ("!F a", g(not(a("a")))),
        ("!(a & X b)", or(not(a("a")), x(not(a("b"))))),
        ("!(a | !b)", and(not(a("a")), a("b"))),
        ("!true", Ltl::False),
        ("!!!a", not(a("a"))),
        ("a -> b", or(not(a("a")), a("b"))),
    ];
    for (text, expected) in cases {
        assert_eq!(nnf(&parse(text).unwrap()), expected, "{text}");
    }
}

#[test]
fn formulas_with_g_or_r_in_negation_normal_form_are_rejected() {
    let cases: &[(&str, char, bool, usize)] = &[
        ("G a", 'G', false, 0),
        ("F G a", 'G', false, 2),
        ("!F a", 'F', true, 1),
        ("a R b", 'R', false, 2),
        ("!(a U b)", 'U', true, 4),
        ("F a -> b", 'F', true, 0),
        ("F Kitchen & !F Office", 'F', true, 13),
        ("a & X (b | !X F c)", 'F', true, 14),
    ];
    for &(text, operator, negated, position) in cases {
        assert_eq!(
            parse_co_safe(text),
            Err(LtlError::NotCoSafe {
                formula: text.to_string(),
                operator,
                negated,
                position: Some(position),
            }),
            "{text}"
        );
        let formula = parse(text).unwrap();
        assert!(!is_co_safe(&formula), "{text}");
        assert_eq!(
            to_dfa(&formula),
            Err(LtlError::NotCoSafe {
                formula: formula.to_string(),
                operator,
                negated,
                position: None,
            })
        );
    }
    for text in [
        "!G a",
        "!(a R !b)",
        "!X !a",
        "!(!a | !F b)",
        "a -> F b",
        "F a | X (b U c)",
    ] {
        assert!(parse_co_safe(text).is_ok(), "{text}");
    }
    assert_eq!(
        parse_co_safe("F a & !F b").unwrap_err().to_string(),
        "'F' under a negation is 'G' (always) in negation normal form, which is not co-safe \
         at position 7\nF a & !F b\n       ^"
    );
    assert_eq!(
        to_dfa(&g(a("a"))).unwrap_err().to_string(),
        "'G' (always) is not co-safe: G a"
    );
}

/// The DFA of a co-safe formula.
fn dfa(text: &str) -> Dfa {
    compile(text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

/// A word of node names, `-` for a node no atom names.
fn word(dfa: &Dfa, names: &str) -> Vec<usize> {
    names
        .split_whitespace()
        .map(|n| dfa.letter_of(Some(n)))
        .collect()
}

fn accepts(dfa: &Dfa, names: &str) -> bool {
    dfa.accepts(&word(dfa, names))
}

#[test]
fn eventually_a_is_the_hand_made_two_state_automaton() {
    let d = dfa("F a");
    assert_eq!(
        d,
        Dfa {
            atoms: vec!["a".into()],
            initial: 0,
            accepting: vec![false, true],
            delta: vec![1, 0, 1, 1],
        }
    );
    assert!(accepts(&d, "a") && accepts(&d, "- - a -"));
    assert!(!accepts(&d, "") && !accepts(&d, "- -"));
}

#[test]
fn both_of_two_nodes_needs_four_states_numbered_breadth_first() {
    let d = dfa("F a & F b");
    // Letters a, b, none. 0: neither visited, 1: a visited, 2: b visited, 3: both.
    assert_eq!(d.accepting, [false, false, false, true]);
    assert_eq!(d.delta, [1, 2, 0, 1, 3, 1, 3, 2, 2, 3, 3, 3]);
    assert!(accepts(&d, "a b") && accepts(&d, "b - a") && accepts(&d, "a a - b"));
    assert!(!accepts(&d, "a a") && !accepts(&d, "b"));
}

#[test]
fn known_automata_have_the_expected_sizes_and_words() {
    // (formula, states, accepted words, rejected words)
    let cases: &[(&str, usize, &[&str], &[&str])] = &[
        (
            "F (a & F b)",
            3,
            &["a b", "a - b", "b a b"],
            &["b a", "a a", ""],
        ),
        (
            "!a U b",
            3,
            &["b", "- - b", "b a"],
            &["a b", "- a b", "-", ""],
        ),
        ("X a", 4, &["- a", "a a", "a a -"], &["a", "a - a", ""]),
        ("a", 3, &["a", "a -"], &["- a", ""]),
        ("true", 1, &["", "-"], &[]),
        ("false", 1, &[], &["", "-"]),
        ("F v1 | F v14", 2, &["v14", "- v1"], &["- -"]),
        ("!G a", 2, &["-", "a a -"], &["a a", ""]),
        (
            "F (a & X b)",
            3,
            &["a b", "- a b", "a a b"],
            &["a - b", "b a"],
        ),
        ("a | true", 1, &[""], &[]),
        // The alphabet is exclusive: two atoms never hold together.
        ("F (a & b)", 1, &[], &["a b", "b a"]),
        ("X true", 1, &[""], &[]),
        // A remaining obligation that is a tautology is discharged by the next letter, not
        // before: progression accepts once the obligations are met inside the word.
        ("X (a | !a)", 3, &["- -", "a a"], &["-", "a", ""]),
    ];
    for &(text, states, good, bad) in cases {
        let d = dfa(text);
        assert!(d.is_consistent(), "{text}");
        assert_eq!(d.states(), states, "{text}: {d:?}");
        for w in good {
            assert!(accepts(&d, w), "{text} should accept {w:?}");
        }
        for w in bad {
            assert!(!accepts(&d, w), "{text} should reject {w:?}");
        }
    }
    // `a`: the first letter is checked (the automaton reads the initial state's label).
    let first = dfa("a");
    assert!(!first.accepting[first.initial]);
    // `!a U b` fails for good once `a` is seen: the state after `a` is a rejecting sink.
    let until = dfa("!a U b");
    let sink = until.next(until.initial, until.letter_of(Some("a")));
    assert!(!until.accepting[sink]);
    assert!((0..until.letters()).all(|l| until.next(sink, l) == sink));
    // The atoms are those of the formula, even where simplification drops them.
    assert_eq!(dfa("a | true").atoms, ["a"]);
    assert!(dfa("true").accepts(&[]));
    assert_eq!(dfa("false").delta, [0]);
}

#[test]
fn equivalent_formulas_give_identical_automata() {
    let same = [
        ("F a & F b", "F b & F a"),
        ("F a & F b", "F (a & F b) | F (b & F a)"),
        ("!a U b", "!(a R !b)"),
        ("F !a", "!G a"),
        ("F F a", "true U a"),
        ("X X a", "X (X a & true)"),
        ("a -> F b", "!a | F b"),
    ];
    for (left, right) in same {
        assert_eq!(dfa(left), dfa(right), "{left} vs {right}");
    }
}

#[test]
fn visiting_six_nodes_in_order_builds_fast() {
    let start = std::time::Instant::now();
    let d = dfa("F (a & F (b & F (c & F (d & F (e & F f)))))");
    let elapsed = start.elapsed();
    assert!(elapsed.as_secs_f64() < 0.5, "took {elapsed:?}");
    assert_eq!(d.states(), 7);
    assert!(accepts(&d, "a - b c c d - e f"));
    assert!(accepts(&d, "f a b c d e f"));
    assert!(!accepts(&d, "a b c d f e"));
}

#[test]
fn limits_give_errors_instead_of_running_away() {
    // F a & F b & F c explores all 8 subsets of {a, b, c} before minimisation.
    let three = parse("F a & F b & F c").unwrap();
    assert_eq!(to_dfa_with_limit(&three, 8).map(|d| d.states()), Ok(8));
    assert_eq!(
        to_dfa_with_limit(&three, 7),
        Err(LtlError::TooManyStates { limit: 7 })
    );
    assert_eq!(
        to_dfa_with_limit(&three, 7).unwrap_err().to_string(),
        "the automaton of the formula has more than 7 states"
    );
    // 2^14 ways to choose one disjunct of each of 14 conjuncts.
    let wide = (0..14)
        .map(|i| format!("(X p{i} | X X p{i})"))
        .collect::<Vec<_>>()
        .join(" & ");
    assert_eq!(
        to_dfa(&parse(&wide).unwrap()),
        Err(LtlError::TooComplex { limit: MAX_CLAUSES })
    );
}

// ---------------------------------------------------------------------------------------
// Oracle: a direct evaluator of the finite-trace semantics, against the automata.

const NAMES: [&str; 3] = ["a", "b", "c"];

/// Negation normal form, written independently of the module's (G and R kept).
fn push_negations(formula: &Ltl, negated: bool) -> Ltl {
    let both = |lhs: &Ltl, rhs: &Ltl| (push_negations(lhs, negated), push_negations(rhs, negated));
    match formula {
        Ltl::True if negated => Ltl::False,
        Ltl::False if negated => Ltl::True,
        Ltl::Atom(_) if negated => not(formula.clone()),
        Ltl::True | Ltl::False | Ltl::Atom(_) => formula.clone(),
        Ltl::Not(inner) => push_negations(inner, !negated),
        Ltl::And(lhs, rhs) => {
            let (lhs, rhs) = both(lhs, rhs);
            if negated { or(lhs, rhs) } else { and(lhs, rhs) }
        }
        Ltl::Or(lhs, rhs) => {
            let (lhs, rhs) = both(lhs, rhs);
            if negated { and(lhs, rhs) } else { or(lhs, rhs) }
        }
        Ltl::Next(inner) => x(push_negations(inner, negated)),
        Ltl::Eventually(inner) if negated => g(push_negations(inner, true)),
        Ltl::Eventually(inner) => f(push_negations(inner, false)),
        Ltl::Always(inner) if negated => f(push_negations(inner, true)),
        Ltl::Always(inner) => g(push_negations(inner, false)),
        Ltl::Until(lhs, rhs) => {
            let (lhs, rhs) = both(lhs, rhs);
            if negated { r(lhs, rhs) } else { u(lhs, rhs) }
        }
        Ltl::Release(lhs, rhs) => {
            let (lhs, rhs) = both(lhs, rhs);
            if negated { u(lhs, rhs) } else { r(lhs, rhs) }
        }
    }
}

fn has_g_or_r(formula: &Ltl) -> bool {
    match formula {
        Ltl::True | Ltl::False | Ltl::Atom(_) => false,
        Ltl::Always(_) | Ltl::Release(..) => true,
        Ltl::Not(i) | Ltl::Next(i) | Ltl::Eventually(i) => has_g_or_r(i),
        Ltl::And(l, r) | Ltl::Or(l, r) | Ltl::Until(l, r) => has_g_or_r(l) || has_g_or_r(r),
    }
}

/// Whether the co-safe NNF `formula` holds at position `i <= word.len()` of a finite word
/// over letters 0, 1, 2 (atoms a, b, c) and 3 (none), with strong semantics: `X`, `F` and `U`
/// must meet their obligations inside the word. Position `word.len()` is the end of the
/// word, where no atom and no negated atom holds, only what is trivially true
/// (`true`, `X true`, `F true`, ...).
fn holds(formula: &Ltl, word: &[usize], i: usize) -> bool {
    let n = word.len();
    let letter = |name: &str| NAMES.iter().position(|&m| m == name).unwrap();
    match formula {
        Ltl::True => true,
        Ltl::False => false,
        Ltl::Atom(name) => i < n && word[i] == letter(name),
        Ltl::Not(inner) => match &**inner {
            Ltl::Atom(name) => i < n && word[i] != letter(name),
            _ => panic!("not in negation normal form: {formula}"),
        },
        Ltl::And(l, r) => holds(l, word, i) && holds(r, word, i),
        Ltl::Or(l, r) => holds(l, word, i) || holds(r, word, i),
        Ltl::Next(inner) => holds(inner, word, (i + 1).min(n)),
        Ltl::Eventually(inner) => (i..=n).any(|j| holds(inner, word, j)),
        Ltl::Until(l, r) => (i..=n).any(|j| holds(r, word, j) && (i..j).all(|k| holds(l, word, k))),
        Ltl::Always(_) | Ltl::Release(..) => panic!("not co-safe: {formula}"),
    }
}

/// A formula over a, b, c of depth at most `depth`, with every operator (the co-safe ones
/// more often).
fn generate(rng: &mut SplitMix64, depth: usize) -> Ltl {
    let mut pick = |n: u64| rng.next_u64() % n;
    if depth == 0 || pick(100) < 10 {
        return match pick(20) {
            0 => Ltl::True,
            1 => Ltl::False,
            k => a(NAMES[k as usize % 3]),
        };
    }
    let op = pick(15);
    let mut sub = || generate(rng, depth - 1);
    match op {
        0 | 1 => not(sub()),
        2 | 3 => and(sub(), sub()),
        4 | 5 => or(sub(), sub()),
        6 | 7 => x(sub()),
        8 | 9 => u(sub(), sub()),
        10 | 11 => f(sub()),
        12 => g(sub()),
        13 => r(sub(), sub()),
        _ => or(not(sub()), sub()),
    }
}

/// Words over the 4 letters of a, b, c and none, up to `max_len` letters.
fn all_words(max_len: usize) -> Vec<Vec<usize>> {
    let mut words = vec![Vec::new()];
    let mut layer = vec![Vec::new()];
    for _ in 0..max_len {
        layer = layer
            .iter()
            .flat_map(|w: &Vec<usize>| {
                (0..4).map(move |l| {
                    let mut w = w.clone();
                    w.push(l);
                    w
                })
            })
            .collect();
        words.extend(layer.iter().cloned());
    }
    words
}

/// Whether no two states of `dfa` accept the same language (table filling, independent of
/// the module's minimisation).
fn is_minimal(dfa: &Dfa) -> bool {
    let n = dfa.states();
    let mut distinct: Vec<Vec<bool>> = (0..n)
        .map(|p| {
            (0..n)
                .map(|q| dfa.accepting[p] != dfa.accepting[q])
                .collect()
        })
        .collect();
    let mut changed = true;
    while changed {
        changed = false;
        for p in 0..n {
            for q in 0..n {
                if !distinct[p][q]
                    && (0..dfa.letters()).any(|l| distinct[dfa.next(p, l)][dfa.next(q, l)])
                {
                    distinct[p][q] = true;
                    changed = true;
                }
            }
        }
    }
    (0..n).all(|p| (0..n).all(|q| p == q || distinct[p][q]))
}

#[test]
fn automata_agree_with_the_finite_trace_evaluator_on_all_short_words() {
    let mut rng = SplitMix64::new(0x17_c0_5a_fe);
    let words = all_words(6);
    assert_eq!(words.len(), 5461);
    let mut checked = 0;
    let mut rejected = 0;
    let mut sizes = Vec::new();
    let mut seen = std::collections::HashSet::new();
    while checked < 80 {
        let formula = generate(&mut rng, 4);
        if !seen.insert(formula.clone()) {
            continue;
        }
        let normal = push_negations(&formula, false);
        assert_eq!(normal, nnf(&formula), "{formula}");
        assert_eq!(is_co_safe(&formula), !has_g_or_r(&normal), "{formula}");
        if has_g_or_r(&normal) {
            rejected += 1;
            continue;
        }
        let dfa = to_dfa(&formula).unwrap_or_else(|e| panic!("{formula}: {e}"));
        assert!(dfa.is_consistent() && dfa.initial == 0, "{formula}");
        assert_eq!(dfa.atoms, atoms(&formula));
        assert!(is_minimal(&dfa), "{formula}: {dfa:?}");
        // Co-safe: at most one accepting state, and it is absorbing.
        let accepting: Vec<usize> = (0..dfa.states()).filter(|&q| dfa.accepting[q]).collect();
        assert!(accepting.len() <= 1, "{formula}");
        for &q in &accepting {
            assert!((0..dfa.letters()).all(|l| dfa.next(q, l) == q));
        }
        let to_letter: Vec<usize> = NAMES
            .iter()
            .map(|n| dfa.letter_of(Some(n)))
            .chain([dfa.letter_of(None)])
            .collect();
        for w in &words {
            let letters: Vec<usize> = w.iter().map(|&l| to_letter[l]).collect();
            assert_eq!(
                dfa.accepts(&letters),
                holds(&normal, w, 0),
                "{formula} on {w:?}"
            );
        }
        sizes.push(dfa.states());
        checked += 1;
    }
    // The generator covers both kinds, and automata of several sizes.
    assert!(rejected >= 20, "{rejected} rejected");
    sizes.sort_unstable();
    sizes.dedup();
    assert!(
        sizes.len() >= 4 && sizes.last() >= Some(&5),
        "sizes {sizes:?}"
    );
}
