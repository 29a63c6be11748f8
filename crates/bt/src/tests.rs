//! Tick semantics of every node against hand-written traces.
//!
//! A trace lists the status transitions of one tick in the order they happen, as
//! `name:FROM>TO` with I, R, S, F for idle, running, success and failure. The expected traces
//! were derived by hand from BehaviorTree.CPP 4's node implementations (cited in
//! `runtime.rs`), so a change of semantics shows up as a changed trace.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

use super::script::{Script, ScriptTick, ScriptedOutcomes, run_script, scripted_registry};
use super::*;

const I: Status = Status::Idle;
const R: Status = Status::Running;
const S: Status = Status::Success;
const F: Status = Status::Failure;
const K: Status = Status::Skipped;

fn letter(s: Status) -> char {
    match s {
        Status::Idle => 'I',
        Status::Running => 'R',
        Status::Success => 'S',
        Status::Failure => 'F',
        Status::Skipped => 'K',
    }
}

fn format_transitions(tree: &Tree, transitions: &[Transition]) -> String {
    transitions
        .iter()
        .map(|t| {
            let name = tree.node(t.uid).expect("uids name nodes").name();
            format!("{name}:{}>{}", letter(t.from), letter(t.to))
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// A tree whose leaves all follow scripted outcomes, ticked once per step (100 ms apart).
struct Harness {
    tree: Tree,
    outcomes: ScriptedOutcomes,
    now: Duration,
}

impl Harness {
    fn new(root: NodeDef) -> Harness {
        Harness::from_doc(&one_tree(root))
    }

    fn from_doc(doc: &BtDocument) -> Harness {
        let (registry, outcomes) = scripted_registry(doc).expect("scripted registry");
        let mut tree = Tree::new(doc, &registry).expect("valid tree");
        tree.set_recording(true);
        Harness {
            tree,
            outcomes,
            now: Duration::ZERO,
        }
    }

    /// Sets outcomes, ticks exactly once, returns the root's status and the trace.
    fn tick(&mut self, outcomes: &[(&str, Status)]) -> (Status, String) {
        for (name, status) in outcomes {
            self.outcomes.set(name, *status);
        }
        let status = self.tree.tick_exactly_once(self.now).expect("tick");
        self.now += Duration::from_millis(100);
        let transitions = self.tree.take_transitions();
        (status, format_transitions(&self.tree, &transitions))
    }
}

/// One tick of a trace test: the outcomes set before it, then the root's status and the trace
/// of the tick.
type Step<'a> = (&'a [(&'a str, Status)], Status, &'a str);

impl Harness {
    /// Ticks once per step and checks each tick's status and trace.
    #[track_caller]
    fn steps(&mut self, steps: &[Step<'_>]) {
        for (k, &(outcomes, status, trace)) in steps.iter().enumerate() {
            assert_eq!(
                self.tick(outcomes),
                (status, trace.to_owned()),
                "tick {}",
                k + 1
            );
        }
    }
}

/// Runs `steps` on a fresh tree of `root` ([`Harness::steps`]).
#[track_caller]
fn check(root: NodeDef, steps: &[Step<'_>]) {
    Harness::new(root).steps(steps);
}

/// The one-tree document of `root`.
fn one_tree(root: NodeDef) -> BtDocument {
    BtDocument::single(TreeDef::new("Main", root))
}

/// A tree of `root` whose leaves follow scripted outcomes.
fn scripted(root: NodeDef) -> (Tree, ScriptedOutcomes) {
    let doc = one_tree(root);
    let (registry, outcomes) = scripted_registry(&doc).unwrap();
    (Tree::new(&doc, &registry).unwrap(), outcomes)
}

fn leaf(name: &str) -> NodeDef {
    NodeDef::action(name)
}

fn cond(name: &str) -> NodeDef {
    NodeDef::condition(name)
}

/// `node` named `name` over `children`.
fn named<const N: usize>(node: NodeDef, name: &str, children: [NodeDef; N]) -> NodeDef {
    children.into_iter().fold(node.named(name), NodeDef::child)
}

/// The control node `id` named `name` over `children`.
fn control<const N: usize>(id: &str, name: &str, children: [NodeDef; N]) -> NodeDef {
    named(NodeDef::control(id), name, children)
}

/// The decorator `id` named `name` with the attribute `port = value` over the leaf A.
fn decorator(id: &str, name: &str, port: &str, value: &str) -> NodeDef {
    NodeDef::decorator(id)
        .named(name)
        .port(port, value)
        .child(leaf("A"))
}

// -----------------------------------------------------------------------------------------
// Sequences

#[test]
fn sequence_resumes_at_the_running_child_and_resets_all_on_failure() {
    check(
        control("Sequence", "seq", [leaf("A"), leaf("B"), leaf("C")]),
        &[
            (&[("A", S), ("B", R)], R, "seq:I>R A:I>S B:I>R"),
            // A is not ticked again: the sequence resumes at B.
            (&[("B", S), ("C", R)], R, "B:R>S C:I>R"),
            (&[("C", F)], F, "C:R>F A:S>I B:S>I C:F>I seq:R>F seq:F>I"),
            // After the failure the sequence starts over at A.
            (
                &[("C", S)],
                S,
                "seq:I>R A:I>S B:I>S C:I>S A:S>I B:S>I C:S>I seq:R>S seq:S>I",
            ),
        ],
    );
}

#[test]
fn a_control_whose_children_were_all_skipped_returns_skipped_but_stays_running() {
    // BehaviorTree.CPP 4.8.2: the sequence set itself running; its only child was skipped, so
    // it returns SKIPPED, and `executeTick` keeps its status (running). No transition to
    // SKIPPED is recorded, and the next tick changes nothing.
    check(
        control("Sequence", "seq", [leaf("A").script("_skipIf", "true")]),
        &[(&[("A", S)], K, "seq:I>R"), (&[], K, "")],
    );
}

#[test]
fn sequence_with_memory_retries_the_failed_child_without_ticking_earlier_ones() {
    check(
        control(
            "SequenceWithMemory",
            "swm",
            [leaf("A"), leaf("B"), leaf("C")],
        ),
        &[
            // A succeeds straight from idle with children left: the node yields (returns
            // running), as BehaviorTree.CPP's does in every tree its factory builds.
            (&[("A", S), ("B", F)], R, "swm:I>R A:I>S"),
            // B fails: only B (and C) are reset, A keeps its success and the index stays at B
            // (checked against BehaviorTree.CPP 4.8.2, tests/cli/bt_differential.rs).
            (&[], F, "B:I>F B:F>I swm:R>F swm:F>I"),
            (&[("B", S), ("C", S)], R, "swm:I>R B:I>S"),
            (&[], S, "C:I>S A:S>I B:S>I C:S>I swm:R>S swm:S>I"),
            // Completed: the next run starts at A.
            (&[("A", R)], R, "swm:I>R A:I>R"),
        ],
    );
}

#[test]
fn reactive_sequence_reticks_conditions_and_halts_the_running_child_when_one_fails() {
    check(
        control("ReactiveSequence", "rs", [cond("K"), leaf("A"), leaf("B")]),
        &[
            // B running: every other child is reset to idle.
            (
                &[("K", S), ("A", S), ("B", R)],
                R,
                "rs:I>R K:I>S A:I>S B:I>R K:S>I A:S>I",
            ),
            // K and A are ticked again on every tick.
            (&[], R, "K:I>S A:I>S K:S>I A:S>I"),
            // K fails on tick 3: B is halted (R>I) on that tick.
            (&[("K", F)], F, "K:I>F K:F>I B:R>I rs:R>F rs:F>I"),
        ],
    );
}

#[test]
fn reactive_sequence_halts_a_later_running_child_when_an_earlier_one_runs() {
    check(
        control("ReactiveSequence", "rs", [leaf("A"), leaf("B")]),
        &[
            (&[("A", S), ("B", R)], R, "rs:I>R A:I>S B:I>R A:S>I"),
            (&[("A", R)], R, "A:I>R B:R>I"),
            (
                &[("A", S), ("B", S)],
                S,
                "A:R>S B:I>S A:S>I B:S>I rs:R>S rs:S>I",
            ),
        ],
    );
}

// -----------------------------------------------------------------------------------------
// Fallbacks

#[test]
fn fallback_resumes_at_the_running_child_and_resets_all_on_success() {
    check(
        control("Fallback", "fb", [cond("K"), leaf("A")]),
        &[
            (&[("K", F), ("A", R)], R, "fb:I>R K:I>F A:I>R"),
            // K is not ticked again while A runs (only the reactive fallback would).
            (&[("K", S)], R, ""),
            (&[("A", S)], S, "A:R>S K:F>I A:S>I fb:R>S fb:S>I"),
            // All fail: failure, all reset.
            (
                &[("K", F), ("A", F)],
                F,
                "fb:I>R K:I>F A:I>F K:F>I A:F>I fb:R>F fb:F>I",
            ),
        ],
    );
}

#[test]
fn reactive_fallback_halts_the_running_child_when_an_earlier_one_succeeds() {
    check(
        control("ReactiveFallback", "rf", [cond("K"), leaf("A")]),
        &[
            (&[("K", F), ("A", R)], R, "rf:I>R K:I>F A:I>R K:F>I"),
            (&[], R, "K:I>F K:F>I"),
            (&[("K", S)], S, "K:I>S K:S>I A:R>I rf:R>S rf:S>I"),
        ],
    );
}

// -----------------------------------------------------------------------------------------
// Parallel

fn parallel(success: Option<&str>, failure: Option<&str>, n: usize) -> NodeDef {
    let mut node = NodeDef::control("Parallel").named("par");
    if let Some(s) = success {
        node = node.port("success_count", s);
    }
    if let Some(f) = failure {
        node = node.port("failure_count", f);
    }
    for name in ["A", "B", "C"].into_iter().take(n) {
        node = node.child(leaf(name));
    }
    node
}

#[test]
fn parallel_defaults_need_all_successes_and_do_not_retick_completed_children() {
    check(
        parallel(None, None, 3),
        &[
            (
                &[("A", S), ("B", R), ("C", R)],
                R,
                "par:I>R A:I>S B:I>R C:I>R",
            ),
            (&[("B", S), ("A", F)], R, "B:R>S"),
            (&[("C", S)], S, "C:R>S A:S>I B:S>I C:S>I par:R>S par:S>I"),
        ],
    );
}

#[test]
fn parallel_fails_as_soon_as_success_is_out_of_reach_without_ticking_later_children() {
    // Default success_count = -1 (all 3): one failure makes success impossible.
    let steps: &[Step<'_>] = &[(
        &[("A", F), ("B", S), ("C", S)],
        F,
        "par:I>R A:I>F A:F>I par:R>F par:F>I",
    )];
    check(parallel(None, None, 3), steps);
}

#[test]
fn parallel_negative_success_threshold_counts_from_the_number_of_children() {
    // -2 with 3 children: 3 - 2 + 1 = 2 successes; C is never ticked.
    let tick = [("A", S), ("B", S), ("C", R)];
    let trace = "par:I>R A:I>S B:I>S A:S>I B:S>I par:R>S par:S>I";
    check(parallel(Some("-2"), None, 3), &[(&tick, S, trace)]);
}

#[test]
fn parallel_success_threshold_halts_the_children_still_running() {
    let trace = "par:I>R A:I>R B:I>S A:R>I B:S>I par:R>S par:S>I";
    check(
        parallel(Some("1"), None, 2),
        &[(&[("A", R), ("B", S)], S, trace)],
    );
}

#[test]
fn parallel_failure_threshold_is_reached_by_equality() {
    let mut h = Harness::new(parallel(Some("1"), Some("2"), 3));
    let tick = h.tick(&[("A", F), ("B", F), ("C", R)]);
    assert_eq!(
        tick,
        (F, "par:I>R A:I>F B:I>F A:F>I B:F>I par:R>F par:F>I".into())
    );
}

#[test]
fn parallel_thresholds_above_the_number_of_children_are_errors() {
    let doc = one_tree(parallel(Some("3"), None, 2));
    let (registry, _) = scripted_registry(&doc).unwrap();
    // BehaviorTree.CPP loads the tree and throws at the first tick; `bt check` (strict
    // validation) finds it before.
    let err = crate::validate_strict(&doc, &registry).unwrap_err();
    assert_eq!(err.attribute(), Some("success_count"));
    assert!(
        matches!(
            err.kind(),
            DefinitionErrorKind::ParallelThreshold {
                required: 3,
                children: 2,
                ..
            }
        ),
        "{err}"
    );
    let mut tree = Tree::new(&doc, &registry).unwrap();
    let err = tree.tick_once(Duration::ZERO).unwrap_err();
    assert!(
        err.to_string()
            .contains("success_count = 3 needs 3 children"),
        "{err}"
    );
    // Through the blackboard, the same check happens at the tick.
    let (mut tree, outcomes) = scripted(parallel(Some("{n}"), None, 2));
    tree.blackboard_mut().set("n", 5i64).unwrap();
    outcomes.set("A", S);
    let err = tree.tick_once(Duration::ZERO).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("node 1 (\"par\", Parallel): success_count = 5 needs 5 children"),
        "{err}"
    );
}

// -----------------------------------------------------------------------------------------
// Decorators

#[test]
fn inverter_and_forcing_decorators_map_completed_results_and_pass_running() {
    let inv = named(NodeDef::decorator("Inverter"), "inv", [leaf("A")]);
    let fs = named(NodeDef::decorator("ForceSuccess"), "fs", [leaf("B")]);
    let ff = named(NodeDef::decorator("ForceFailure"), "ff", [leaf("C")]);
    check(
        control("Sequence", "seq", [inv, fs, ff]),
        &[
            (&[("A", R)], R, "seq:I>R inv:I>R A:I>R"),
            (
                &[("A", F), ("B", F), ("C", S)],
                F,
                "A:R>F A:F>I inv:R>S fs:I>R B:I>F B:F>I fs:R>S ff:I>R C:I>S C:S>I ff:R>F \
                 inv:S>I fs:S>I ff:F>I seq:R>F seq:F>I",
            ),
        ],
    );
}

fn retry(attempts: &str) -> NodeDef {
    decorator("RetryUntilSuccessful", "retry", "num_attempts", attempts)
}

#[test]
fn retry_counts_attempts_and_yields_a_tick_between_synchronous_failures() {
    check(
        retry("3"),
        &[
            (&[("A", F)], R, "retry:I>R A:I>F A:F>I"),
            (&[], R, "A:I>F A:F>I"),
            (&[], F, "A:I>F A:F>I retry:R>F retry:F>I"),
            // A success on the second attempt ends the loop; the count starts over afterwards.
            (&[], R, "retry:I>R A:I>F A:F>I"),
            (&[("A", S)], S, "A:I>S A:S>I retry:R>S retry:S>I"),
        ],
    );
}

#[test]
fn retry_retries_at_once_a_child_that_failed_after_running() {
    check(
        retry("3"),
        &[
            (&[("A", R)], R, "retry:I>R A:I>R"),
            // Failed from RUNNING: tried again within the same tick (fails again from IDLE:
            // yields).
            (&[("A", F)], R, "A:R>F A:F>I A:I>F A:F>I"),
            (&[], F, "A:I>F A:F>I retry:R>F retry:F>I"),
        ],
    );
}

#[test]
fn tick_once_follows_the_wake_up_so_all_attempts_happen_in_one_call() {
    let (mut tree, outcomes) = scripted(retry("4"));
    tree.set_recording(true);
    outcomes.set("A", F);
    assert_eq!(tree.tick_once(Duration::ZERO).unwrap(), F);
    let attempts = tree
        .transitions()
        .iter()
        .filter(|t| t.uid == 2 && t.to == F)
        .count();
    assert_eq!(attempts, 4);
}

#[test]
fn retry_with_minus_one_never_gives_up_and_zero_attempts_are_skipped() {
    keeps_running(retry("-1"), ("A", F), 20);
    // BehaviorTree.CPP 4.8.2: no attempt, no tick of the child, and failure.
    check(
        retry("0"),
        &[(&[("A", S)], F, "retry:I>R retry:R>F retry:F>I")],
    );
}

#[test]
fn repeat_counts_cycles_and_a_failure_restarts_the_count() {
    check(
        decorator("Repeat", "rep", "num_cycles", "3"),
        &[
            (&[("A", S)], R, "rep:I>R A:I>S A:S>I"),
            (&[("A", F)], F, "A:I>F A:F>I rep:R>F rep:F>I"),
            (&[("A", S)], R, "rep:I>R A:I>S A:S>I"),
            (&[], R, "A:I>S A:S>I"),
            (&[], S, "A:I>S A:S>I rep:R>S rep:S>I"),
        ],
    );
}

/// Ticks a tree of `root` once with the leaf outcome `first`, then `ticks` more times: the root
/// must run on each of them.
#[track_caller]
fn keeps_running(root: NodeDef, first: (&str, Status), ticks: usize) {
    let mut h = Harness::new(root);
    h.tick(&[first]);
    for _ in 0..ticks {
        assert_eq!(h.tick(&[]).0, R);
    }
}

fn timeout(msec: &str) -> NodeDef {
    decorator("Timeout", "to", "msec", msec)
}

#[test]
fn timeout_halts_the_running_child_at_the_first_tick_after_the_deadline() {
    check(
        timeout("250"),
        &[
            (&[("A", R)], R, "to:I>R A:I>R"), // 0 ms
            (&[], R, ""),                     // 100 ms
            (&[], R, ""),                     // 200 ms
            (&[], F, "A:R>I to:R>F to:F>I"),  // 300 ms >= 250 ms
        ],
    );
}

#[test]
fn timeout_deadline_is_inclusive_and_restarts_with_each_execution() {
    let (mut tree, outcomes) = scripted(timeout("250"));
    tree.set_recording(true);
    let ms = Duration::from_millis;
    outcomes.set("A", R);
    assert_eq!(tree.tick_once(ms(1000)).unwrap(), R);
    outcomes.set("A", S);
    assert_eq!(tree.tick_once(ms(1200)).unwrap(), S); // done before the deadline
    outcomes.set("A", R);
    assert_eq!(tree.tick_once(ms(1300)).unwrap(), R); // new deadline: 1550
    assert_eq!(tree.tick_once(ms(1549)).unwrap(), R);
    tree.take_transitions();
    assert_eq!(tree.tick_once(ms(1550)).unwrap(), F);
    let halt = tree.transitions()[0];
    assert_eq!(
        (halt.uid, halt.from, halt.to, halt.time),
        (2, R, I, ms(1550))
    );
}

#[test]
fn timeout_of_zero_never_expires() {
    keeps_running(timeout("0"), ("A", R), 50);
}

// -----------------------------------------------------------------------------------------
// Subtrees, uids and the blackboard

fn two_tree_doc(subtree: NodeDef) -> BtDocument {
    BtDocument {
        main_tree: Some("Main".into()),
        trees: vec![
            TreeDef::new(
                "Main",
                NodeDef::control("Sequence")
                    .child(leaf("A"))
                    .child(subtree)
                    .child(leaf("B")),
            ),
            TreeDef::new(
                "Sub",
                NodeDef::control("Fallback")
                    .child(cond("C"))
                    .child(leaf("D")),
            ),
        ],
        node_models: Vec::new(),
    }
}

#[test]
fn uids_are_depth_first_with_subtrees_expanded_where_used() {
    let doc = two_tree_doc(NodeDef::subtree("Sub"));
    let h = Harness::from_doc(&doc);
    let order: Vec<(u16, &str)> = h.tree.nodes().iter().map(|n| (n.uid(), n.id())).collect();
    assert_eq!(
        order,
        [
            (1, "Sequence"),
            (2, "A"),
            (3, "Sub"),
            (4, "Fallback"),
            (5, "C"),
            (6, "D"),
            (7, "B")
        ]
    );
    let instances: Vec<(&str, &str, u16)> = h
        .tree
        .subtrees()
        .iter()
        .map(|s| (s.tree_id.as_str(), s.path.as_str(), s.root_uid))
        .collect();
    assert_eq!(instances, [("Main", "", 1), ("Sub", "Sub::3", 4)]);
    assert_eq!(h.tree.node(6).unwrap().path(), "Sub::3/D::6");
    assert_eq!(h.tree.node(0).map(Node::uid), None);
}

#[test]
fn subtree_ticks_its_tree_and_resets_it_when_done() {
    let mut h = Harness::from_doc(&two_tree_doc(NodeDef::subtree("Sub").named("door")));
    assert_eq!(
        h.tick(&[("A", S), ("C", F), ("D", R)]),
        (
            R,
            "Sequence:I>R A:I>S door:I>R Fallback:I>R C:I>F D:I>R".into()
        )
    );
    assert_eq!(
        h.tick(&[("D", S), ("B", S)]),
        (
            S,
            "D:R>S C:F>I D:S>I Fallback:R>S Fallback:S>I door:R>S B:I>S A:S>I door:S>I \
             B:S>I Sequence:R>S Sequence:S>I"
                .into()
        )
    );
}

/// The built-in `SetBlackboard` leaf writing `value` to `key`.
fn set_blackboard(value: &str, key: &str) -> NodeDef {
    NodeDef::action("SetBlackboard")
        .port("value", value)
        .port("output_key", key)
}

/// A document whose subtree reads `{input}` and writes `{out}`.
fn port_doc(subtree: NodeDef) -> (BtDocument, Registry) {
    let mut registry = Registry::new();
    registry
        .register_condition_fn("IsAnswer", |ctx| {
            let v: i64 = ctx.input("value")?;
            Ok(if v == 42 { S } else { F })
        })
        .unwrap();
    registry
        .register_action_fn("Write", |ctx| {
            ctx.set_output("dest", 7.5)?;
            Ok(S)
        })
        .unwrap();
    let doc = BtDocument {
        main_tree: Some("Main".into()),
        trees: vec![
            TreeDef::new(
                "Main",
                NodeDef::control("Sequence")
                    .child(set_blackboard("42", "answer"))
                    .child(subtree),
            ),
            TreeDef::new(
                "Sub",
                NodeDef::control("Sequence")
                    .child(NodeDef::condition("IsAnswer").port("value", "{input}"))
                    .child(NodeDef::action("Write").port("dest", "{out}")),
            ),
        ],
        node_models: Vec::new(),
    };
    (doc, registry)
}

fn run_ports(subtree: NodeDef) -> (Status, Tree) {
    let (doc, registry) = port_doc(subtree);
    let mut tree = Tree::new(&doc, &registry).unwrap();
    let status = tree.tick_once(Duration::ZERO).unwrap();
    (status, tree)
}

#[test]
fn subtree_remapping_reads_and_writes_the_parent_blackboard() {
    let (status, tree) = run_ports(
        NodeDef::subtree("Sub")
            .port("input", "{answer}")
            .port("out", "{result}"),
    );
    assert_eq!(status, S);
    let bb = tree.blackboard();
    assert_eq!(bb.get("answer"), Some(&Value::Str("42".into())));
    assert_eq!(bb.get("result"), Some(&Value::Double(7.5)));
    let sub_scope = tree.subtrees()[1].scope;
    assert_eq!(bb.entries(sub_scope).count(), 0, "nothing stored locally");
}

#[test]
fn subtree_literal_ports_set_the_subtree_key_and_unmapped_keys_stay_local() {
    let (status, tree) = run_ports(NodeDef::subtree("Sub").port("input", "42"));
    assert_eq!(status, S);
    let bb = tree.blackboard();
    assert_eq!(bb.get("out"), None);
    let sub = tree.subtrees()[1].scope;
    assert_eq!(bb.get_in(sub, "out"), Some(&Value::Double(7.5)));
    assert_eq!(bb.get_in(sub, "input"), Some(&Value::Str("42".into())));
    // A literal that is not the answer makes the condition fail.
    let (status, _) = run_ports(NodeDef::subtree("Sub").port("input", "41"));
    assert_eq!(status, F);
}

#[test]
fn subtree_autoremap_shares_keys_under_the_same_name() {
    let (doc, registry) = port_doc(NodeDef::subtree("Sub").autoremapped(true));
    let mut tree = Tree::new(&doc, &registry).unwrap();
    tree.blackboard_mut().set("input", 42i64).unwrap();
    assert_eq!(tree.tick_once(Duration::ZERO).unwrap(), S);
    assert_eq!(tree.blackboard().get("out"), Some(&Value::Double(7.5)));
    // Without autoremap (and no remapping) the subtree cannot see `input`.
    let (doc, registry) = port_doc(NodeDef::subtree("Sub"));
    let mut tree = Tree::new(&doc, &registry).unwrap();
    tree.blackboard_mut().set("input", 42i64).unwrap();
    let err = tree.tick_once(Duration::ZERO).unwrap_err();
    assert_eq!(
        err.to_string(),
        "node 5 (IsAnswer): port \"value\" refers to the blackboard entry \"input\", which does \
         not exist"
    );
}

#[test]
fn at_keys_reach_the_root_blackboard_and_same_name_remaps_expand() {
    let mut registry = Registry::new();
    registry
        .register_action_fn("Copy", |ctx| {
            let v: f64 = ctx.input("speed")?;
            ctx.set_output("target", v * 2.0)?;
            Ok(S)
        })
        .unwrap();
    let doc = BtDocument {
        main_tree: Some("Main".into()),
        trees: vec![
            TreeDef::new("Main", NodeDef::subtree("Sub")),
            TreeDef::new(
                "Sub",
                NodeDef::action("Copy")
                    .port("speed", "{=}")
                    .port("target", "{@doubled}"),
            ),
        ],
        node_models: Vec::new(),
    };
    let mut tree = Tree::new(&doc, &registry).unwrap();
    let sub = tree.subtrees()[1].scope;
    tree.blackboard_mut().set_in(sub, "speed", 0.25).unwrap();
    assert_eq!(tree.tick_once(Duration::ZERO).unwrap(), S);
    assert_eq!(tree.blackboard().get("doubled"), Some(&Value::Double(0.5)));
    assert_eq!(tree.node(2).unwrap().ports()[0].1, "{speed}");
}

#[test]
fn blackboard_keeps_types_and_parses_strings_as_bt_cpp_does() {
    let mut bb = Blackboard::new();
    bb.set("n", 3i64).unwrap();
    bb.set("n", "12").unwrap();
    assert_eq!(bb.get("n"), Some(&Value::Int(12)));
    let err = bb.set("n", "twelve").unwrap_err();
    assert_eq!(
        err.to_string(),
        "blackboard entry \"n\" holds a int; once declared, its type cannot change (cannot \
         store the string \"twelve\")"
    );
    bb.set("x", 0.5).unwrap();
    bb.set("x", 2i64).unwrap();
    assert_eq!(bb.get("x"), Some(&Value::Double(2.0)));
    assert!(bb.set("x", true).is_err());
    bb.set("text", "hello").unwrap();
    bb.set("text", 5i64).unwrap();
    assert_eq!(bb.get("text"), Some(&Value::Int(5)));
    for (text, b) in [
        ("1", true),
        ("true", true),
        ("True", true),
        ("TRUE", true),
        ("0", false),
    ] {
        assert_eq!(bool::from_value(&Value::Str(text.into())), Some(b));
    }
    assert_eq!(bool::from_value(&Value::Str("yes".into())), None);
    assert_eq!(i64::from_value(&Value::Double(4.0)), Some(4));
    assert_eq!(i64::from_value(&Value::Double(4.5)), None);
    assert_eq!(u64::from_value(&Value::Int(-1)), None);
    assert_eq!(f64::from_value(&Value::Str("2.5e-1".into())), Some(0.25));
    assert!(bb.set("", 1i64).is_err());
}

// -----------------------------------------------------------------------------------------
// Leaves: halt hooks, built-in leaves, errors

struct Noop;

impl LeafNode for Noop {
    fn tick(&mut self, _: &mut LeafContext<'_>) -> Result<Status, LeafError> {
        Ok(S)
    }
}

struct Work {
    halts: Arc<AtomicUsize>,
}

impl LeafNode for Work {
    fn tick(&mut self, _: &mut LeafContext<'_>) -> Result<Status, LeafError> {
        Ok(R)
    }
    fn halt(&mut self, ctx: &mut LeafContext<'_>) {
        assert_eq!(ctx.status(), R, "halted while running");
        self.halts.fetch_add(1, Ordering::SeqCst);
    }
}

#[test]
fn halting_a_running_action_calls_its_halt_hook_once() {
    let halts = Arc::new(AtomicUsize::new(0));
    let ok = Arc::new(AtomicBool::new(true));
    let mut registry = Registry::new();
    let h = Arc::clone(&halts);
    registry
        .register(NodeModel::new(NodeCategory::Action, "Work"), move || {
            Box::new(Work {
                halts: Arc::clone(&h),
            })
        })
        .unwrap();
    let flag = Arc::clone(&ok);
    registry
        .register_condition_fn("Ok", move |_| {
            Ok(if flag.load(Ordering::SeqCst) { S } else { F })
        })
        .unwrap();
    let doc = BtDocument::single(TreeDef::new(
        "Main",
        NodeDef::control("ReactiveSequence")
            .child(cond("Ok"))
            .child(leaf("Work")),
    ));
    let mut tree = Tree::new(&doc, &registry).unwrap();
    let ms = Duration::from_millis;
    assert_eq!(tree.tick_once(ms(0)).unwrap(), R);
    assert_eq!(tree.tick_once(ms(100)).unwrap(), R);
    assert_eq!(halts.load(Ordering::SeqCst), 0);
    ok.store(false, Ordering::SeqCst);
    assert_eq!(tree.tick_once(ms(200)).unwrap(), F);
    assert_eq!(halts.load(Ordering::SeqCst), 1);
    assert_eq!(tree.node(3).unwrap().status(), I);
    // Halting the whole tree halts the running action too.
    ok.store(true, Ordering::SeqCst);
    assert_eq!(tree.tick_once(ms(300)).unwrap(), R);
    tree.halt(ms(400));
    assert_eq!(halts.load(Ordering::SeqCst), 2);
    assert!(tree.nodes().iter().all(|n| n.status() == I));
    // Halting an idle tree calls nothing.
    tree.halt(ms(500));
    assert_eq!(halts.load(Ordering::SeqCst), 2);
}

#[test]
fn built_in_leaves_set_blackboard_and_sleep_with_the_injected_clock() {
    let doc = BtDocument::single(TreeDef::new(
        "Main",
        NodeDef::control("Sequence")
            .child(set_blackboard("on", "mode"))
            .child(set_blackboard("{mode}", "@copy"))
            .child(NodeDef::action("Sleep").port("msec", "300"))
            .child(NodeDef::action("AlwaysSuccess")),
    ));
    let mut tree = Tree::new(&doc, &Registry::new()).unwrap();
    let ms = Duration::from_millis;
    assert_eq!(tree.tick_once(ms(1000)).unwrap(), R);
    assert_eq!(
        tree.blackboard().get("copy"),
        Some(&Value::Str("on".into()))
    );
    assert_eq!(tree.tick_once(ms(1299)).unwrap(), R);
    assert_eq!(tree.tick_once(ms(1300)).unwrap(), S);
    let doc = one_tree(NodeDef::action("AlwaysFailure"));
    let mut tree = Tree::new(&doc, &Registry::new()).unwrap();
    assert_eq!(tree.tick_once(ms(0)).unwrap(), F);
}

#[test]
fn leaves_that_break_the_rules_make_the_tick_fail_with_the_node_named() {
    let mut registry = Registry::new();
    registry.register_condition_fn("Busy", |_| Ok(R)).unwrap();
    registry.register_action_fn("Lazy", |_| Ok(I)).unwrap();
    registry
        .register_action_fn("Broken", |_| Err(LeafError::new("motor offline")))
        .unwrap();
    let cases = [
        (
            "Busy",
            "node 1 (Busy): a condition returned RUNNING (conditions return SUCCESS or FAILURE)",
        ),
        ("Lazy", "node 1 (Lazy): the leaf returned IDLE"),
        ("Broken", "node 1 (Broken): motor offline"),
    ];
    for (id, message) in cases {
        let category = if id == "Busy" {
            NodeCategory::Condition
        } else {
            NodeCategory::Action
        };
        let doc = one_tree(NodeDef::new(category, id));
        let mut tree = Tree::new(&doc, &registry).unwrap();
        let err = tree.tick_once(Duration::ZERO).unwrap_err();
        assert_eq!(err.to_string(), message);
    }
}

#[test]
fn ticks_must_not_go_back_in_time() {
    let doc = one_tree(NodeDef::action("AlwaysSuccess"));
    let mut tree = Tree::new(&doc, &Registry::new()).unwrap();
    tree.tick_once(Duration::from_secs(5)).unwrap();
    tree.tick_once(Duration::from_secs(5)).unwrap();
    let err = tree.tick_once(Duration::from_secs(4)).unwrap_err();
    assert_eq!(
        err.to_string(),
        "time went backwards: tick at 4s after a tick at 5s"
    );
}

// -----------------------------------------------------------------------------------------
// Validation

/// The first error of strict validation (what `chronomap bt check` reports).
fn invalid(root: NodeDef) -> DefinitionError {
    let doc = one_tree(root);
    crate::validate_strict(&doc, &Registry::new()).unwrap_err()
}

#[test]
fn validation_names_the_node_and_the_attribute() {
    let e = invalid(NodeDef::control("Sequence").child(NodeDef::action("Fly")));
    assert_eq!(e.attribute(), Some("ID"));
    assert_eq!(
        e.location().cloned(),
        Some(NodeLocation {
            tree: "Main".into(),
            path: vec![0]
        })
    );
    assert!(
        e.to_string()
            .starts_with("tree \"Main\", node at child path 0: unknown node ID \"Fly\"")
    );

    let e = invalid(NodeDef::decorator("EntryUpdated").child(NodeDef::action("AlwaysSuccess")));
    assert_eq!(
        *e.kind(),
        DefinitionErrorKind::UnsupportedNode {
            id: "EntryUpdated".into()
        }
    );

    let e = invalid(
        NodeDef::decorator("Inverter")
            .child(NodeDef::action("AlwaysSuccess"))
            .child(NodeDef::action("AlwaysFailure")),
    );
    assert_eq!(
        e.to_string(),
        "tree \"Main\", root node: Decorator \"Inverter\" needs exactly 1 child, found 2"
    );

    let e = invalid(NodeDef::control("Sequence"));
    assert!(
        e.to_string().ends_with("needs at least 1 child, found 0"),
        "{e}"
    );

    let e = invalid(NodeDef::decorator("Repeat").child(NodeDef::action("AlwaysSuccess")));
    assert_eq!(e.attribute(), Some("num_cycles"));
    assert!(
        e.to_string()
            .ends_with("\"Repeat\" needs the attribute \"num_cycles\"")
    );

    let e = invalid(
        NodeDef::decorator("RetryUntilSuccessful")
            .port("num_attempts", "three")
            .child(NodeDef::action("AlwaysSuccess")),
    );
    assert_eq!(e.attribute(), Some("num_attempts"));
    assert!(e.to_string().ends_with(
        "attribute num_attempts=\"three\" of \"RetryUntilSuccessful\" is invalid (expected an \
         integer)"
    ));

    let e = invalid(
        NodeDef::decorator("Timeout")
            .port("msec", "-5")
            .child(NodeDef::action("AlwaysSuccess")),
    );
    assert!(
        e.to_string().contains("(expected a non-negative integer)"),
        "{e}"
    );

    let e = invalid(
        NodeDef::decorator("Repeat")
            .port("num_cycle", "2")
            .child(NodeDef::action("AlwaysSuccess")),
    );
    assert_eq!(
        *e.kind(),
        DefinitionErrorKind::UnknownPort {
            id: "Repeat".into(),
            port: "num_cycle".into(),
            known: vec!["num_cycles".into()]
        }
    );

    let e = invalid(NodeDef::condition("Sequence"));
    assert!(
        e.to_string()
            .ends_with("\"Sequence\" is a Control node, not a Condition")
    );
}

#[test]
fn validation_checks_trees_subtrees_and_output_ports() {
    let mut registry = Registry::new();
    registry
        .register(
            NodeModel::new(NodeCategory::Action, "Plan")
                .port(PortSpec::input("goal"))
                .port(PortSpec::output("path")),
            || Box::new(Noop),
        )
        .unwrap();
    let doc = BtDocument::single(TreeDef::new(
        "Main",
        NodeDef::action("Plan")
            .port("goal", "dock")
            .port("path", "p"),
    ));
    // BehaviorTree.CPP loads it (and fails when the port is written); strict validation
    // refuses it.
    validate(&doc, &registry).unwrap();
    let e = crate::validate_strict(&doc, &registry).unwrap_err();
    assert_eq!(e.attribute(), Some("path"));
    assert!(e.to_string().ends_with(
        "output port path=\"p\" of \"Plan\" must be a blackboard reference such as \"{path}\""
    ));

    let doc = BtDocument {
        main_tree: Some("Main".into()),
        trees: vec![
            TreeDef::new("Main", NodeDef::subtree("A")),
            TreeDef::new("A", NodeDef::subtree("B")),
            TreeDef::new("B", NodeDef::subtree("A")),
        ],
        node_models: Vec::new(),
    };
    let e = validate(&doc, &registry).unwrap_err();
    assert_eq!(
        *e.kind(),
        DefinitionErrorKind::RecursiveSubTree {
            chain: vec!["A".into(), "B".into(), "A".into()]
        }
    );
    assert_eq!(e.location().unwrap().tree, "B");

    let doc = one_tree(NodeDef::subtree("Missing"));
    let e = validate(&doc, &registry).unwrap_err();
    assert_eq!(
        e.to_string(),
        "tree \"Main\", root node: there is no <BehaviorTree ID=\"Missing\">"
    );

    let mut doc = one_tree(NodeDef::action("AlwaysSuccess"));
    doc.main_tree = Some("Other".into());
    let e = validate(&doc, &registry).unwrap_err();
    assert_eq!(e.attribute(), Some("main_tree_to_execute"));
    doc.main_tree = None;
    doc.trees
        .push(TreeDef::new("Second", NodeDef::action("AlwaysSuccess")));
    validate(&doc, &registry).unwrap();
    assert_eq!(
        Tree::new(&doc, &registry).unwrap_err().to_string(),
        "the document has several trees (Main, Second) and no main_tree_to_execute"
    );
    doc.trees
        .push(TreeDef::new("Main", NodeDef::action("AlwaysSuccess")));
    assert_eq!(
        validate(&doc, &registry).unwrap_err().to_string(),
        "two trees have the ID \"Main\""
    );
}

#[test]
fn declared_but_unregistered_leaves_validate_but_cannot_be_instantiated() {
    let mut doc = one_tree(NodeDef::action("OpenDoor"));
    doc.node_models
        .push(NodeModel::new(NodeCategory::Action, "OpenDoor"));
    let registry = Registry::new();
    validate(&doc, &registry).unwrap();
    let e = Tree::new(&doc, &registry).unwrap_err();
    assert_eq!(
        e.to_string(),
        "tree \"Main\", root node: no implementation is registered for Action \"OpenDoor\""
    );
}

#[test]
fn registry_refuses_built_in_duplicate_and_non_leaf_ids() {
    let mut registry = Registry::new();
    assert_eq!(
        registry.register_action_fn("Sequence", |_| Ok(S)),
        Err(RegistryError::Builtin {
            id: "Sequence".into()
        })
    );
    assert_eq!(
        registry.register_action_fn("Sleep", |_| Ok(S)),
        Err(RegistryError::Builtin { id: "Sleep".into() })
    );
    registry.register_action_fn("Go", |_| Ok(S)).unwrap();
    assert_eq!(
        registry.register_condition_fn("Go", |_| Ok(S)),
        Err(RegistryError::AlreadyRegistered { id: "Go".into() })
    );
    assert!(matches!(
        registry.register_unchecked(NodeCategory::Control, "MyControl", || Box::new(Noop)),
        Err(RegistryError::NotALeaf { .. })
    ));
}

// -----------------------------------------------------------------------------------------
// Scripts

/// `Sequence(BatteryOk, Patrol)` with scripted leaves.
fn patrol() -> (Tree, ScriptedOutcomes) {
    scripted(
        NodeDef::control("Sequence")
            .child(cond("BatteryOk"))
            .child(leaf("Patrol")),
    )
}

#[test]
fn scripts_run_until_the_root_completes_and_report_unused_ticks() {
    let (mut tree, outcomes) = patrol();
    let script = Script {
        ticks: vec![
            ScriptTick::new(1)
                .outcome("BatteryOk", S)
                .outcome("Patrol", R),
            ScriptTick::new(3).at(1000).outcome("Patrol", F),
            ScriptTick::new(5).outcome("Patrol", S),
        ],
    };
    let run = run_script(&mut tree, &outcomes, &script, Duration::from_millis(250)).unwrap();
    let summary: Vec<(u64, u128, Status)> = run
        .ticks
        .iter()
        .map(|t| (t.tick, t.time.as_millis(), t.status))
        .collect();
    assert_eq!(summary, [(1, 0, R), (2, 250, R), (3, 1000, F)]);
    assert!(run.finished);
    assert_eq!(run.unused, [5]);
}

#[test]
fn scripts_are_checked_before_anything_runs() {
    let (mut tree, outcomes) = patrol();
    let run = |tree: &mut Tree, ticks: Vec<ScriptTick>| {
        run_script(
            tree,
            &outcomes,
            &Script { ticks },
            Duration::from_millis(100),
        )
        .unwrap_err()
        .to_string()
    };
    assert_eq!(
        run(&mut tree, vec![ScriptTick::new(1).outcome("Patrl", S)]),
        "tick 1: the tree has no leaf named \"Patrl\" (its leaves: BatteryOk, Patrol)"
    );
    assert_eq!(
        run(&mut tree, vec![ScriptTick::new(2).outcome("BatteryOk", R)]),
        "tick 2: \"BatteryOk\" is a condition and cannot return RUNNING"
    );
    assert_eq!(
        run(&mut tree, vec![ScriptTick::new(2), ScriptTick::new(2)]),
        "tick 2 comes after tick 2 (tick numbers start at 1 and increase)"
    );
    // A tick that fails ends the run; it is recorded, with the changes made before it.
    let failed = run_script(
        &mut tree,
        &outcomes,
        &Script {
            ticks: vec![ScriptTick::new(1).outcome("BatteryOk", S)],
        },
        Duration::from_millis(100),
    )
    .unwrap();
    let failure = failed.failure.expect("tick 1 fails");
    assert_eq!(failure.tick, 1);
    assert_eq!(
        failure.error.to_string(),
        "node 3 (Patrol): ticked, but the script has given no outcome for \"Patrol\" yet"
    );
    assert!(failed.ticks.is_empty() && !failed.finished);
    tree.halt(Duration::ZERO);
    assert_eq!(run(&mut tree, vec![]), "the script has no ticks");
    // Tick 3 would come at 200 ms (100 ms after tick 2), so tick 4 cannot be at 150 ms.
    assert_eq!(
        run(
            &mut tree,
            vec![ScriptTick::new(3), ScriptTick::new(4).at(150)]
        ),
        "tick 4 is at 150 ms, before the previous tick at 200 ms"
    );
    assert_eq!(
        run(
            &mut tree,
            vec![ScriptTick::new(2).at(500), ScriptTick::new(4).at(550)]
        ),
        "tick 4 is at 550 ms, before the previous tick at 600 ms"
    );
}
