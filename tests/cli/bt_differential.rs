//! `chronomap bt run` against the real BehaviorTree.CPP 4.8.2, side by side.
//!
//! `tests/bt/btcpp_oracle.py` generates random trees (every built-in control, decorator and
//! leaf that needs no wall clock, Script and ScriptCondition, pre- and post-conditions, SubTrees
//! with remapping) with outcome tables from a seed, and runs each through BehaviorTree.CPP
//! (PyPI `behaviortreepy` 0.1.4, Python binding of 4.8.2): the root's status at every tick,
//! every status change as BehaviorTree.CPP's own `StdCoutLogger` reports it, the tick that
//! throws, and the root blackboard at the end. Each case is then run here through chronomap's
//! reader, runtime and script runner (what `chronomap bt run --script` does, in process) and
//! compared on all four. Every kind of disagreement found this way has been minimised into a
//! named case under `tests/data/bt/differential/`, whose BehaviorTree.CPP results are stored
//! beside it, so [`regression_cases_behave_as_behaviortree_cpp`] runs without the oracle too.
//!
//! The oracle runs when `CHRONOMAP_BT_PYTHON` names a Python with `behaviortreepy==0.1.4`
//! (`.ci/run` makes one); `CHRONOMAP_BT_DIFF_SEED` and `CHRONOMAP_BT_DIFF_TREES` choose another
//! seed and number of trees (CI: seed 1, 4000 trees).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use chronomap_bt::script::{run_script, scripted_registry};
use chronomap_bt::{Registry, Tree, Value as BtValue};
use chronomap_io::{BtReadOptions, parse_bt_script, parse_bt_xml_in};
use serde_json::{Value, json};

use crate::common::{oracle_python, scratch};

/// What both sides record of one case.
#[derive(Debug, PartialEq)]
struct Trace {
    /// The load error, if the tree was refused.
    load_error: Option<String>,
    /// Per tick: the root's status (`None` for the tick that threw) and the status changes.
    ticks: Vec<(Option<String>, Vec<[String; 3]>)>,
    /// The tick that threw, and the message.
    error: Option<(u64, String)>,
    /// The root blackboard: numbers (booleans as 0/1, numeric text as numbers) or text.
    blackboard: BTreeMap<String, Value>,
}

/// A blackboard value as the oracle reads it: `get_double` if it converts, else the text.
fn normalised(value: &Value) -> Value {
    match value {
        Value::Bool(b) => json!(f64::from(u8::from(*b))),
        Value::Number(n) => json!(n.as_f64()),
        Value::String(s) => match s.trim().parse::<f64>() {
            Ok(x) if x.is_finite() => json!(x),
            _ => match s.as_str() {
                "true" => json!(1.0),
                "false" => json!(0.0),
                _ => value.clone(),
            },
        },
        other => other.clone(),
    }
}

fn bt_value_json(value: &BtValue) -> Value {
    match value {
        BtValue::Bool(b) => json!(b),
        BtValue::Int(i) => json!(i),
        BtValue::Double(d) => json!(d),
        BtValue::Str(s) => json!(s),
        BtValue::List(items) => json!(
            items
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(";")
        ),
    }
}

/// The oracle's record of a case.
fn btcpp_trace(case: &Value) -> Trace {
    let ticks = case["ticks"]
        .as_array()
        .map(|ticks| {
            ticks
                .iter()
                .map(|t| {
                    let changes = t["transitions"]
                        .as_array()
                        .expect("transitions")
                        .iter()
                        .map(|c| {
                            let s = |i: usize| c[i].as_str().expect("a name or status").to_owned();
                            [s(0), s(1), s(2)]
                        })
                        .collect();
                    (t["status"].as_str().map(str::to_owned), changes)
                })
                .collect()
        })
        .unwrap_or_default();
    Trace {
        load_error: case["load_error"].as_str().map(str::to_owned),
        ticks,
        error: case["error"].as_object().map(|e| {
            (
                e["tick"].as_u64().expect("tick"),
                e["message"].as_str().unwrap_or("").to_owned(),
            )
        }),
        blackboard: case["blackboard"]
            .as_object()
            .map(|b| b.iter().map(|(k, v)| (k.clone(), normalised(v))).collect())
            .unwrap_or_default(),
    }
}

/// chronomap's record of a case: read, instantiate and run as `chronomap bt run --script`.
fn chronomap_trace(name: &str, xml: &str, script: &str, dir: &Path) -> Trace {
    let refused = |e: String| Trace {
        load_error: Some(e),
        ticks: Vec::new(),
        error: None,
        blackboard: BTreeMap::new(),
    };
    let read = match parse_bt_xml_in(name, xml, dir, &Registry::new(), &BtReadOptions::default()) {
        Ok(read) => read,
        Err(e) => return refused(e.to_string()),
    };
    let doc = &read.document;
    let (registry, outcomes) = match scripted_registry(doc) {
        Ok(r) => r,
        Err(e) => return refused(e.to_string()),
    };
    let main = match doc.main_tree_id() {
        Ok(id) => id.to_owned(),
        Err(e) => return refused(e.to_string()),
    };
    let mut tree = match Tree::with_main(doc, &main, &registry) {
        Ok(tree) => tree,
        Err(e) => return refused(e.to_string()),
    };
    let script = parse_bt_script(name, script).expect("the oracle's scripts parse");
    let ran = run_script(&mut tree, &outcomes, &script, Duration::from_millis(100))
        .expect("the oracle's scripts fit their trees");
    let name_of = |uid: u16| tree.node(uid).map_or("?", |n| n.name()).to_owned();
    let changes = |list: &[chronomap_bt::Transition]| {
        list.iter()
            .map(|t| [name_of(t.uid), t.from.to_string(), t.to.to_string()])
            .collect::<Vec<_>>()
    };
    let mut ticks: Vec<_> = ran
        .ticks
        .iter()
        .map(|t| (Some(t.status.to_string()), changes(&t.transitions)))
        .collect();
    let error = ran.failure.as_ref().map(|f| {
        ticks.push((None, changes(&f.transitions)));
        (f.tick, f.error.to_string())
    });
    let board = tree.blackboard();
    let blackboard = board
        .entries(board.root())
        .map(|(k, v)| (k.to_owned(), normalised(&bt_value_json(v))))
        .collect();
    Trace {
        load_error: None,
        ticks,
        error,
        blackboard,
    }
}

/// What differs between the two records, by kind, with the first difference described; `None`
/// when they agree (messages are not compared, only where errors happen).
fn compare(btcpp: &Trace, ours: &Trace) -> Option<(&'static str, String)> {
    match (&btcpp.load_error, &ours.load_error) {
        (Some(_), Some(_)) => return None,
        (None, Some(e)) => {
            return Some((
                "load",
                format!("chronomap refuses a tree BT.CPP loads: {e}"),
            ));
        }
        (Some(e), None) => {
            return Some((
                "load",
                format!("chronomap loads a tree BT.CPP refuses: {e}"),
            ));
        }
        (None, None) => {}
    }
    for (k, (theirs, mine)) in btcpp.ticks.iter().zip(&ours.ticks).enumerate() {
        if theirs.0 != mine.0 {
            return Some((
                "status",
                format!(
                    "tick {}: BT.CPP {:?}, chronomap {:?}\n  BT.CPP:    {:?}\n  chronomap: {:?}",
                    k + 1,
                    theirs.0,
                    mine.0,
                    theirs.1,
                    mine.1
                ),
            ));
        }
        if theirs.1 != mine.1 {
            return Some((
                "transitions",
                format!(
                    "tick {}:\n  BT.CPP:    {:?}\n  chronomap: {:?}",
                    k + 1,
                    theirs.1,
                    mine.1
                ),
            ));
        }
    }
    if btcpp.ticks.len() != ours.ticks.len()
        || btcpp.error.as_ref().map(|e| e.0) != ours.error.as_ref().map(|e| e.0)
    {
        return Some((
            "error tick",
            format!(
                "BT.CPP {} ticks, error {:?}; chronomap {} ticks, error {:?}",
                btcpp.ticks.len(),
                btcpp.error,
                ours.ticks.len(),
                ours.error
            ),
        ));
    }
    if btcpp.blackboard != ours.blackboard {
        return Some((
            "blackboard",
            format!(
                "BT.CPP {:?}\n  chronomap {:?}",
                btcpp.blackboard, ours.blackboard
            ),
        ));
    }
    None
}

/// Compares every case; a report of the disagreements (empty when none) and counts.
fn differ(cases: &[Value], dir: &Path) -> (String, BTreeMap<&'static str, usize>, Vec<Value>) {
    let mut report = String::new();
    let mut kinds = BTreeMap::new();
    let mut failing = Vec::new();
    for case in cases {
        let name = case["name"].as_str().expect("name");
        let theirs = btcpp_trace(case);
        let ours = chronomap_trace(
            name,
            case["xml"].as_str().expect("xml"),
            case["script"].as_str().expect("script"),
            dir,
        );
        if let Some((kind, what)) = compare(&theirs, &ours) {
            *kinds.entry(kind).or_insert(0) += 1;
            if kinds.values().sum::<usize>() <= 5 {
                let _ = writeln!(
                    report,
                    "--- {name}: {kind}: {what}\n{}\n{}",
                    case["xml"].as_str().unwrap_or(""),
                    case["script"].as_str().unwrap_or("")
                );
            }
            failing.push(case.clone());
        }
    }
    (report, kinds, failing)
}

fn oracle(test: &str) -> Option<String> {
    oracle_python(
        "BT",
        test,
        "BehaviorTree.CPP",
        "set CHRONOMAP_BT_PYTHON to a Python with behaviortreepy==0.1.4 (.ci/run makes one)",
    )
}

fn oracle_script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/bt/btcpp_oracle.py")
}

fn cases_of(stdout: &[u8]) -> Vec<Value> {
    String::from_utf8_lossy(stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("the oracle prints JSON lines"))
        .collect()
}

#[test]
fn random_trees_behave_as_behaviortree_cpp() {
    let Some(python) = oracle("random_trees_behave_as_behaviortree_cpp") else {
        return;
    };
    let seed: u64 =
        std::env::var("CHRONOMAP_BT_DIFF_SEED").map_or(1, |s| s.parse().expect("a seed"));
    let trees: usize =
        std::env::var("CHRONOMAP_BT_DIFF_TREES").map_or(4000, |s| s.parse().expect("a count"));
    let started = Instant::now();
    let output = Command::new(&python)
        .arg(oracle_script())
        .args([
            "generate",
            "--seed",
            &seed.to_string(),
            "--trees",
            &trees.to_string(),
        ])
        .output()
        .expect("the oracle runs");
    assert!(
        output.status.success(),
        "the oracle failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let cases = cases_of(&output.stdout);
    assert_eq!(cases.len(), trees);
    let oracle_time = started.elapsed();
    let dir = scratch("bt_differential_random");
    let (report, kinds, failing) = differ(&cases, &dir);
    let ticks: usize = cases
        .iter()
        .map(|c| c["ticks"].as_array().map_or(0, Vec::len))
        .sum();
    let changes: usize = cases
        .iter()
        .flat_map(|c| c["ticks"].as_array().into_iter().flatten())
        .map(|t| t["transitions"].as_array().map_or(0, Vec::len))
        .sum();
    let errors = cases.iter().filter(|c| c["error"].is_object()).count();
    let refused = cases.iter().filter(|c| c["load_error"].is_string()).count();
    println!(
        "seed {seed}: {trees} trees, {ticks} ticks, {changes} status changes, {errors} runs \
         that throw, {refused} trees refused; BT.CPP {:.1} s, both {:.1} s; disagreements: {kinds:?}",
        oracle_time.as_secs_f64(),
        started.elapsed().as_secs_f64()
    );
    if !failing.is_empty() {
        let path = dir.join("disagreements.jsonl");
        let lines: Vec<String> = failing.iter().map(Value::to_string).collect();
        std::fs::write(&path, lines.join("\n") + "\n").expect("write the disagreements");
        panic!(
            "{} of {trees} trees behave differently ({kinds:?}); all in {}\n{report}",
            failing.len(),
            path.display()
        );
    }
}
