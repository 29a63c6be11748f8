//! Every bundled behavior tree run by `chronomap bt run` and by the real BehaviorTree.CPP 4.8.2
//! under identical stubs.
//!
//! `tests/bt/btcpp_trees.py` takes every XML file under `tests/data/bt/` (BehaviorTree.CPP's
//! own files in `btcpp/`, Nav2's in `nav2/`, chronomap's at the top and in `groot2/`; not
//! `differential/`, which `bt_differential.rs` runs) and, for each tree of each file, registers
//! its custom actions and conditions in BehaviorTree.CPP (PyPI `behaviortreepy` 0.1.4) as
//! leaves following a seeded outcome script by instance name and its custom decorators as
//! simple decorators passing their child's status; as the binding cannot declare ports, the
//! ports of custom nodes are removed from the tree and its models, identically for both sides.
//! It prints what BehaviorTree.CPP did with the rewritten files (its own `<include>` resolution,
//! relative to each including file), and the rewritten files themselves. Here each case is
//! written to a scratch directory and run through `chronomap bt run --script --json` (with
//! `--tree`, `--stub ID=PASS` for custom decorators, and `--tick-ms 0`, as BehaviorTree.CPP's
//! ticks come microseconds apart) and compared on the root status per tick, every status
//! change, the tick that throws and the root blackboard; a tree BehaviorTree.CPP loads must
//! load, one it refuses must be refused. A tree with a `Sleep` is run several times in
//! BehaviorTree.CPP: 4.8.2's Sleep, halted and restarted, sometimes ends at once (the halted
//! timer's callback, run later on the timer thread, clears the restarted wait); the record most
//! runs give is compared, and the runs where this happened are counted.
//!
//! Trees that use custom controls cannot be compared (the binding cannot register controls):
//! Nav2's navigators. They are listed with the reason. `CHRONOMAP_BT_TREES_SEED` and
//! `CHRONOMAP_BT_TREES_SCRIPTS` choose another seed and number of outcome scripts per tree
//! (default: 1 and 20).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use serde_json::Value;

use crate::bt_differential::{Trace, btcpp_trace, compare, oracle, run_trace};
use crate::common::scratch;

/// The directory of the bundled trees.
fn trees_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/bt")
}

/// Every XML file under `tests/data/bt/` but `differential/`, relative to it, sorted.
fn tree_files() -> Vec<String> {
    fn walk(dir: &Path, rel: &str, out: &mut Vec<String>) {
        for entry in std::fs::read_dir(dir).expect("the tree directory") {
            let entry = entry.expect("a directory entry");
            let name = entry.file_name().into_string().expect("a UTF-8 name");
            let path = format!("{rel}{name}");
            if entry.file_type().expect("a file type").is_dir() {
                if path != "differential" {
                    walk(&entry.path(), &format!("{path}/"), out);
                }
            } else if name.ends_with(".xml") {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    walk(&trees_dir(), "", &mut out);
    out.sort();
    out
}

fn text<'a>(case: &'a Value, key: &str) -> &'a str {
    case[key]
        .as_str()
        .unwrap_or_else(|| panic!("{key} in {case}"))
}

fn strings(case: &Value, key: &str) -> Vec<String> {
    case[key]
        .as_array()
        .unwrap_or_else(|| panic!("{key} in {case}"))
        .iter()
        .map(|v| v.as_str().expect("text").to_owned())
        .collect()
}

/// Writes a case's files and script under `dir` and runs it through `chronomap bt run`.
fn chronomap_trace(case: &Value, dir: &Path) -> Trace {
    for (rel, contents) in case["files"].as_object().expect("files") {
        let path = dir.join(rel);
        std::fs::create_dir_all(path.parent().expect("a parent")).expect("a case directory");
        std::fs::write(&path, contents.as_str().expect("a file's text")).expect("write a file");
    }
    let script = dir.join("case.script");
    std::fs::write(&script, text(case, "script")).expect("write the script");
    let file = dir.join(text(case, "file")).display().to_string();
    let script = script.display().to_string();
    let mut args: Vec<String> = ["bt", "run", &file, "--script", &script, "--json"]
        .map(str::to_owned)
        .to_vec();
    args.extend(["--tick-ms".to_owned(), "0".to_owned()]);
    if let Some(tree) = case["tree"].as_str() {
        args.extend(["--tree".to_owned(), tree.to_owned()]);
    }
    for stub in strings(case, "stubs") {
        args.extend(["--stub".to_owned(), stub]);
    }
    for nodes in strings(case, "nodes") {
        args.extend(["--nodes".to_owned(), dir.join(nodes).display().to_string()]);
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    run_trace(&args)
}

/// The (file, tree) pairs that BehaviorTree.CPP 4.8.2 refuses to load, with why (the tree:
/// `None` for the file's own choice). From BehaviorTree.CPP's messages, as in
/// `tests/data/bt/btcpp/README.md` (Nav2's models file has no tree).
const REFUSED: [(&str, Option<&str>, &str); 7] = [
    (
        "btcpp/examples/test_files/log_test.xml",
        None,
        "main_tree_to_execute",
    ),
    (
        "btcpp/examples/test_files/subtree_test.xml",
        None,
        "Node not recognized: CheckStatus",
    ),
    (
        "btcpp/examples/test_files/subtree_test.xml",
        Some("BehaviorTree"),
        "Node not recognized: CheckStatus",
    ),
    (
        "btcpp/fuzzing/corpus/bt_corpus/corpus2.xml",
        None,
        "timeout_ms",
    ),
    (
        "btcpp/fuzzing/corpus/bt_corpus/corpus3.xml",
        None,
        "<SubTree> must not use the name of a registered Node",
    ),
    (
        "btcpp/fuzzing/corpus/bt_corpus/corpus4.xml",
        None,
        "'ForceSuccess' must have exactly 1 child",
    ),
    ("nav2/nav2_tree_nodes.xml", None, "main_tree_to_execute"),
];

/// The files that cannot be compared: Nav2's navigators use Nav2's custom controls.
const SKIPPED: [&str; 3] = [
    "nav2/follow_point.xml",
    "nav2/navigate_through_poses_w_replanning_and_recovery.xml",
    "nav2/navigate_to_pose_w_replanning_and_recovery.xml",
];

/// Per (file, tree): cases, ticks, status changes, runs that throw, and the load errors of
/// both sides when BehaviorTree.CPP refused it.
#[derive(Default)]
struct Tally {
    cases: usize,
    ticks: usize,
    changes: usize,
    throws: usize,
    /// Cases where BehaviorTree.CPP's runs differed (its Sleep's race): the record most of
    /// them gave is compared.
    races: usize,
    refused: Option<(String, String)>,
}

#[test]
fn bundled_trees_behave_as_behaviortree_cpp() {
    let Some(python) = oracle("bundled_trees_behave_as_behaviortree_cpp") else {
        return;
    };
    let seed: u64 =
        std::env::var("CHRONOMAP_BT_TREES_SEED").map_or(1, |s| s.parse().expect("a seed"));
    let scripts: usize =
        std::env::var("CHRONOMAP_BT_TREES_SCRIPTS").map_or(20, |s| s.parse().expect("a count"));
    let files = tree_files();
    let started = Instant::now();
    let output = Command::new(&python)
        .arg(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/bt/btcpp_trees.py"))
        .arg("--root")
        .arg(trees_dir())
        .args(["--models", "nav2/nav2_tree_nodes.xml"])
        .args([
            "--seed",
            &seed.to_string(),
            "--scripts",
            &scripts.to_string(),
        ])
        .args(&files)
        .output()
        .expect("the oracle runs");
    assert!(
        output.status.success(),
        "tests/bt/btcpp_trees.py failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let lines: Vec<Value> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("the driver prints JSON lines"))
        .collect();
    let oracle_time = started.elapsed();

    // Every file gives cases or the reason it cannot be compared.
    let mut skipped = BTreeMap::new();
    let mut cases = Vec::new();
    for line in &lines {
        match line["skipped"].as_str() {
            Some(why) => {
                skipped.insert(text(line, "file").to_owned(), why.to_owned());
            }
            None => cases.push(line),
        }
    }
    for file in &files {
        assert!(
            skipped.contains_key(file) || cases.iter().any(|c| text(c, "file") == file),
            "{file}: no case and no reason"
        );
    }
    assert_eq!(
        skipped.keys().map(String::as_str).collect::<Vec<_>>(),
        SKIPPED,
        "the files that cannot be compared"
    );
    let clock: Vec<String> = cases
        .iter()
        .filter_map(|c| Some(format!("{}: {}", text(c, "name"), c["clock"].as_str()?)))
        .collect();
    assert!(
        clock.is_empty(),
        "BehaviorTree.CPP's clock ran out (the machine is too slow for this comparison): {}",
        clock.join("; ")
    );

    // chronomap's run of every case, on a few threads.
    let dir = scratch("bt_btcpp_trees");
    let next = AtomicUsize::new(0);
    let workers = std::thread::available_parallelism().map_or(2, |n| n.get().min(4));
    let mut ours: Vec<(usize, Trace)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                s.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(case) = cases.get(i) else {
                            return done;
                        };
                        done.push((i, chronomap_trace(case, &dir.join(i.to_string()))));
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("a worker"))
            .collect()
    });
    ours.sort_by_key(|(i, _)| *i);

    let mut tallies: BTreeMap<(String, Option<String>), Tally> = BTreeMap::new();
    let mut failing = Vec::new();
    let mut report = String::new();
    for (case, (_, mine)) in cases.iter().zip(&ours) {
        let theirs = btcpp_trace(case);
        let key = (
            text(case, "file").to_owned(),
            case["tree"].as_str().map(str::to_owned),
        );
        let tally = tallies.entry(key).or_default();
        tally.cases += 1;
        tally.ticks += theirs.ticks.len();
        tally.changes += theirs.ticks.iter().map(|t| t.1.len()).sum::<usize>();
        tally.throws += usize::from(theirs.error.is_some());
        tally.races += usize::from(case["race"].is_string());
        if let (Some(a), Some(b)) = (&theirs.load_error, &mine.load_error) {
            tally.refused = Some((a.clone(), b.clone()));
        }
        if let Some((kind, what)) = compare(&theirs, mine) {
            let _ = writeln!(
                report,
                "--- {} ({kind}): {what}\n{}",
                text(case, "name"),
                text(case, "script")
            );
            failing.push((*case).clone());
        }
    }

    // The listing: every tree, what was compared and how it ended.
    let mut refused = Vec::new();
    for ((file, tree), t) in &tallies {
        let tree = tree.as_deref();
        let label = format!(
            "{file}{}",
            tree.map_or(String::new(), |t| format!(" --tree {t}"))
        );
        match &t.refused {
            Some((btcpp, ours)) => {
                println!(
                    "{label}: refused by both\n    BT.CPP:    {}\n    chronomap: {}",
                    btcpp.lines().next().unwrap_or(""),
                    ours.lines().last().unwrap_or("")
                );
                refused.push((file.as_str(), tree));
            }
            None => println!(
                "{label}: {} scripts, {} ticks, {} status changes, {} runs that throw{}",
                t.cases,
                t.ticks,
                t.changes,
                t.throws,
                if t.races > 0 {
                    format!(
                        "; in {} BehaviorTree.CPP's Sleep raced (the record most of its runs \
                         gave is compared)",
                        t.races
                    )
                } else {
                    String::new()
                }
            ),
        }
    }
    for (file, why) in &skipped {
        println!("{file}: NOT COMPARED: {why}");
    }
    let total = |f: fn(&Tally) -> usize| tallies.values().map(f).sum::<usize>();
    println!(
        "seed {seed}: {} files, {} trees compared ({} loaded, {} refused by both), {} not \
         compared; {} runs, {} ticks, {} status changes, {} runs that throw, {} where \
         BehaviorTree.CPP's Sleep raced; BT.CPP {:.1} s, both {:.1} s; {} disagreements",
        files.len(),
        tallies.len(),
        tallies.values().filter(|t| t.refused.is_none()).count(),
        refused.len(),
        skipped.len(),
        total(|t| t.cases),
        total(|t| t.ticks),
        total(|t| t.changes),
        total(|t| t.throws),
        total(|t| t.races),
        oracle_time.as_secs_f64(),
        started.elapsed().as_secs_f64(),
        failing.len()
    );
    if !failing.is_empty() {
        let path = dir.join("disagreements.jsonl");
        let lines: Vec<String> = failing.iter().map(Value::to_string).collect();
        std::fs::write(&path, lines.join("\n") + "\n").expect("write the disagreements");
        panic!(
            "{} of {} runs of bundled trees behave differently; all in {}\n{report}",
            failing.len(),
            cases.len(),
            path.display()
        );
    }

    // What BehaviorTree.CPP refuses is what its messages said when this test was written (a
    // broken registration would make it refuse more, and chronomap agree by refusing too).
    let expected: Vec<(&str, Option<&str>)> = REFUSED.iter().map(|r| (r.0, r.1)).collect();
    assert_eq!(refused, expected);
    for (file, tree, why) in REFUSED {
        let t = &tallies[&(file.to_owned(), tree.map(str::to_owned))];
        let btcpp = &t.refused.as_ref().expect("refused").0;
        assert!(btcpp.contains(why), "{file}: {btcpp}");
    }
}
