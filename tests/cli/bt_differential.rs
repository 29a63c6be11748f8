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

use crate::common::{chronomap, oracle_python, scratch};

/// What both sides record of one case.
#[derive(Debug, PartialEq)]
pub(crate) struct Trace {
    /// The load error, if the tree was refused.
    pub(crate) load_error: Option<String>,
    /// Per tick: the root's status (`None` for the tick that threw) and the status changes.
    pub(crate) ticks: Vec<(Option<String>, Vec<[String; 3]>)>,
    /// The tick that threw, and the message.
    pub(crate) error: Option<(u64, String)>,
    /// The root blackboard: numbers (booleans as 0/1, numeric text as numbers) or text.
    pub(crate) blackboard: BTreeMap<String, Value>,
}

/// A blackboard value as the oracle reads it: `get_double` if it converts, else the text.
pub(crate) fn normalised(value: &Value) -> Value {
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
pub(crate) fn btcpp_trace(case: &Value) -> Trace {
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
pub(crate) fn compare(btcpp: &Trace, ours: &Trace) -> Option<(&'static str, String)> {
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

pub(crate) fn oracle(test: &str) -> Option<String> {
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

/// The regression cases: every kind of disagreement found, minimised and named
/// (`tests/data/bt/differential/NAME.xml`, `NAME.script`), with BehaviorTree.CPP 4.8.2's record
/// of the run (`NAME.btcpp.json`, written by `tests/bt/btcpp_oracle.py run`).
fn regression_cases() -> Vec<(String, PathBuf, PathBuf, Value)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/bt/differential");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .expect("the regression cases")
        .filter_map(|e| {
            let name = e.ok()?.file_name().into_string().ok()?;
            name.strip_suffix(".xml").map(str::to_owned)
        })
        .collect();
    names.sort();
    names
        .into_iter()
        .map(|name| {
            let record = std::fs::read_to_string(dir.join(format!("{name}.btcpp.json")))
                .unwrap_or_else(|e| panic!("{name}.btcpp.json: {e}"));
            let record: Value = serde_json::from_str(&record).expect("a record");
            (
                name.clone(),
                dir.join(format!("{name}.xml")),
                dir.join(format!("{name}.script")),
                record,
            )
        })
        .collect()
}

/// What `chronomap bt run XML --script SCRIPT --json` records, as a [`Trace`] (a decorator
/// `Pass` is stubbed with `--stub Pass=PASS`, BehaviorTree.CPP's `SimpleDecoratorNode`).
fn cli_trace(xml: &Path, script: &Path) -> Trace {
    let xml_text = std::fs::read_to_string(xml).expect("the XML");
    let (xml, script) = (xml.to_str().unwrap(), script.to_str().unwrap());
    let mut args = vec!["bt", "run", xml, "--script", script, "--json"];
    if xml_text.contains("<Pass") {
        args.extend(["--stub", "Pass=PASS"]);
    }
    run_trace(&args)
}

/// What `chronomap` with `args` (a `bt run ... --json`) recorded, as a [`Trace`]: a run that
/// prints nothing on stdout refused the tree.
pub(crate) fn run_trace(args: &[&str]) -> Trace {
    let out = chronomap(args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    if stdout.trim().is_empty() {
        return Trace {
            load_error: Some(stderr.trim().to_owned()),
            ticks: Vec::new(),
            error: None,
            blackboard: BTreeMap::new(),
        };
    }
    let run: Value = serde_json::from_str(&stdout).expect("JSON");
    let changes = |list: &Value| -> Vec<[String; 3]> {
        list.as_array()
            .expect("transitions")
            .iter()
            .map(|t| {
                let s = |k: &str| t[k].as_str().expect("text").to_owned();
                [s("name"), s("from"), s("to")]
            })
            .collect()
    };
    let mut ticks: Vec<_> = run["ticks"]
        .as_array()
        .expect("ticks")
        .iter()
        .map(|t| {
            (
                t["status"].as_str().map(str::to_owned),
                changes(&t["transitions"]),
            )
        })
        .collect();
    let error = run["error"].as_object().map(|e| {
        ticks.push((None, changes(&e["transitions"])));
        (
            e["tick"].as_u64().expect("tick"),
            e["message"].as_str().unwrap_or("").to_owned(),
        )
    });
    assert_eq!(
        out.status.code(),
        Some(if error.is_some() { 1 } else { 0 }),
        "{args:?}: a failed tick exits with 1, after the JSON"
    );
    Trace {
        load_error: None,
        ticks,
        error,
        blackboard: run["blackboard"]
            .as_object()
            .expect("blackboard")
            .iter()
            .map(|(k, v)| (k.clone(), normalised(v)))
            .collect(),
    }
}

#[test]
fn regression_cases_behave_as_behaviortree_cpp() {
    let cases = regression_cases();
    assert!(cases.len() >= 16, "{} cases", cases.len());
    let mut failures = Vec::new();
    for (name, xml, script, record) in &cases {
        let theirs = btcpp_trace(record);
        let ours = cli_trace(xml, script);
        if let Some((kind, what)) = compare(&theirs, &ours) {
            failures.push(format!("{name}: {kind}: {what}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn regression_records_are_what_behaviortree_cpp_does_today() {
    let Some(python) = oracle("regression_records_are_what_behaviortree_cpp_does_today") else {
        return;
    };
    let cases = regression_cases();
    let mut args: Vec<String> = vec!["run".to_owned()];
    for (_, xml, script, _) in &cases {
        args.push(xml.display().to_string());
        args.push(script.display().to_string());
    }
    let output = Command::new(&python)
        .arg(oracle_script())
        .args(&args)
        .output()
        .expect("the oracle runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let fresh = cases_of(&output.stdout);
    assert_eq!(fresh.len(), cases.len());
    for ((name, _, _, stored), fresh) in cases.iter().zip(&fresh) {
        assert_eq!(
            btcpp_trace(stored),
            btcpp_trace(fresh),
            "{name}: the stored record is not what BehaviorTree.CPP does"
        );
    }
}
