//! Sequences, fallbacks, reactive nodes, parallel nodes, IfThenElse, WhileDoElse, Switch,
//! TryCatch.

use chronomap_bt::Status::{Failure as F, Running as R, Skipped as K, Success as S};
use chronomap_bt::{DefinitionErrorKind, Status};

use super::support::{Fixture, main_tree};

fn statuses(run: &mut super::support::Run, ticks: usize) -> Vec<Status> {
    (0..ticks).map(|_| run.tick()).collect()
}

// -----------------------------------------------------------------------------------------
// gtest_sequence.cpp

#[test]
fn sequence__condition_true() {
    // gtest_sequence.cpp: SimpleSequenceTest.ConditionTrue — the action runs after the
    // condition, the sequence returns running, then success.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><AlwaysSuccess/><AsyncSuccess name="action"/></Sequence>"#,
    ));
    assert_eq!(run.tick(), R);
    assert_eq!(run.status_of("action"), R);
    assert_eq!(run.tick(), S);
    assert_eq!(run.status_of("action"), Status::Idle);
}

#[test]
fn sequence__condition_turn_to_false() {
    // gtest_sequence.cpp: SimpleSequenceTest.ConditionTurnToFalse — a (non-reactive) sequence
    // does not tick the condition again while the action runs.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><ScriptCondition name="cond" code="ok"/><KeepRunning name="action"/></Sequence>"#,
    ));
    run.set("ok", true);
    assert_eq!(run.tick(), R);
    run.set("ok", false);
    assert_eq!(run.tick(), R);
    assert_eq!(run.status_of("cond"), S);
    assert_eq!(run.status_of("action"), R);
}

#[test]
fn sequence__triple_action() {
    // gtest_sequence.cpp: SequenceTripleActionTest.TripleAction — asynchronous actions run one
    // after the other.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><AsyncSuccess name="a1"/><AsyncSuccess name="a2"/><AsyncSuccess name="a3"/></Sequence>"#,
    ));
    assert_eq!(run.tick(), R);
    assert_eq!(run.status_of("a1"), R);
    assert_eq!(run.tick(), R);
    assert_eq!((run.status_of("a1"), run.status_of("a2")), (S, R));
    assert_eq!(run.tick(), R);
    assert_eq!(run.status_of("a3"), R);
    assert_eq!(run.tick(), S);
}

#[test]
fn sequence__sequence_with_memory_conditions1_to_false() {
    // gtest_sequence.cpp: ComplexSequenceWithMemoryTest.Conditions1ToFalse — after a failure
    // the failed child is ticked again, not the earlier ones.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<SequenceWithMemory><TestA/><ScriptCondition code="ok"/><TestB/></SequenceWithMemory>"#,
    ));
    run.set("ok", false);
    assert_eq!(run.tick(), F);
    assert_eq!(run.tick(), F);
    assert_eq!(fx.counts(), [1, 0, 0, 0]);
    run.set("ok", true);
    assert_eq!(run.tick(), S);
    assert_eq!(fx.counts(), [1, 1, 0, 0]);
}

#[test]
fn sequence__sequence_star_is_sequence_with_memory() {
    // gtest_sequence.cpp (BehaviorTree.CPP 3 name): SequenceStar behaves as SequenceWithMemory.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<SequenceStar><TestA/><ScriptCondition code="ok"/></SequenceStar>"#,
    ));
    run.set("ok", false);
    assert_eq!(statuses(&mut run, 2), [F, F]);
    assert_eq!(fx.count(0), 1);
}

#[test]
fn sequence__async_sequence_yields_between_children() {
    // AsyncSequence (SequenceNode with make_async): after each child that succeeded from idle
    // it returns running and wakes the tree up; tickOnce follows the wake-up.
    let fx = Fixture::new();
    let xml = main_tree(r#"<AsyncSequence><TestA/><TestB/></AsyncSequence>"#);
    let mut run = fx.run(&xml);
    assert_eq!(run.tree.tick_exactly_once(run.now).unwrap(), R);
    assert_eq!(fx.counts(), [1, 0, 0, 0]);
    assert_eq!(run.tree.tick_exactly_once(run.now).unwrap(), S);
    assert_eq!(fx.counts(), [1, 1, 0, 0]);
    assert_eq!(run.tick(), S);
    assert_eq!(fx.counts(), [2, 2, 0, 0]);
}

// -----------------------------------------------------------------------------------------
// gtest_fallback.cpp

#[test]
fn fallback__condition_true() {
    // gtest_fallback.cpp: SimpleFallbackTest.ConditionTrue — the action is not ticked.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Fallback><AlwaysSuccess/><TestA/></Fallback>"#,
    ));
    assert_eq!(run.tick(), S);
    assert_eq!(fx.count(0), 0);
}

#[test]
fn fallback__condition_change_while_running() {
    // gtest_fallback.cpp: SimpleFallbackTest.ConditionChangeWhileRunning — a (non-reactive)
    // fallback keeps ticking the running action.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Fallback><ScriptCondition code="ok"/><KeepRunning name="action"/></Fallback>"#,
    ));
    run.set("ok", false);
    assert_eq!(run.tick(), R);
    run.set("ok", true);
    assert_eq!(run.tick(), R);
    assert_eq!(run.status_of("action"), R);
}

#[test]
fn fallback__fallback_with_memory_action1_failed() {
    // gtest_fallback.cpp: ComplexFallbackWithMemoryTest.Action1Failed — the first action fails,
    // the second runs, and the fallback succeeds.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Fallback><AlwaysFailure/><AsyncFailure/><AsyncSuccess name="a2"/></Fallback>"#,
    ));
    assert_eq!(statuses(&mut run, 3), [R, R, S]);
}

#[test]
fn fallback__async_fallback_yields_between_children() {
    // AsyncFallback (FallbackNode with make_async): returns running after each failure from
    // idle.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<AsyncFallback><AlwaysFailure/><TestA/></AsyncFallback>"#,
    ));
    assert_eq!(run.tree.tick_exactly_once(run.now).unwrap(), R);
    assert_eq!(fx.count(0), 0);
    assert_eq!(run.tree.tick_exactly_once(run.now).unwrap(), S);
    assert_eq!(fx.count(0), 1);
}

// -----------------------------------------------------------------------------------------
// gtest_reactive.cpp

#[test]
fn reactive__reactive_fallback_condition1_to_true() {
    // gtest_fallback.cpp: ReactiveFallbackTest.Condition1ToTrue — a condition turning true
    // halts the running action.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<ReactiveFallback><ScriptCondition code="c1"/><ScriptCondition code="c2"/><KeepRunning name="action"/></ReactiveFallback>"#,
    ));
    run.set("c1", false);
    run.set("c2", false);
    assert_eq!(run.tick(), R);
    assert_eq!(run.status_of("action"), R);
    run.set("c1", true);
    assert_eq!(run.tick(), S);
    assert_eq!(run.status_of("action"), Status::Idle);
}

#[test]
fn reactive__reactive_fallback_all_children_fail() {
    // gtest_reactive.cpp: Reactive.ReactiveFallback_AllChildrenFail.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<ReactiveFallback><AlwaysFailure/><AlwaysFailure/></ReactiveFallback>"#,
    ));
    assert_eq!(run.tick(), F);
}

#[test]
fn reactive__reactive_fallback_second_child_succeeds() {
    // gtest_reactive.cpp: Reactive.ReactiveFallback_SecondChildSucceeds.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<ReactiveFallback><AlwaysFailure/><TestA/><TestB/></ReactiveFallback>"#,
    ));
    assert_eq!(run.tick(), S);
    assert_eq!(fx.counts(), [1, 0, 0, 0]);
}

#[test]
fn reactive__reactive_sequence_first_child_fails() {
    // gtest_reactive.cpp: Reactive.ReactiveSequence_FirstChildFails.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<ReactiveSequence><AlwaysFailure/><TestA/></ReactiveSequence>"#,
    ));
    assert_eq!(run.tick(), F);
    assert_eq!(fx.count(0), 0);
}

#[test]
fn reactive__reactive_sequence_halt_on_condition_change() {
    // gtest_reactive.cpp: Reactive.ReactiveSequence_HaltOnConditionChange.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<ReactiveSequence><ScriptCondition code="ok"/><KeepRunning name="action"/></ReactiveSequence>"#,
    ));
    run.set("ok", true);
    assert_eq!(run.tick(), R);
    assert_eq!(run.status_of("action"), R);
    run.set("ok", false);
    assert_eq!(run.tick(), F);
    assert_eq!(run.status_of("action"), Status::Idle);
}

#[test]
fn reactive__reactive_sequence_re_evaluates_on_every_tick() {
    // gtest_reactive.cpp: Reactive.ReactiveSequence_ReEvaluatesOnEveryTick.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<ReactiveSequence><TestA/><AsyncSuccess/></ReactiveSequence>"#,
    ));
    assert_eq!(run.tick(), R);
    assert_eq!(fx.count(0), 1);
    assert_eq!(run.tick(), S);
    assert_eq!(fx.count(0), 2);
}

#[test]
fn reactive__reactive_sequence_all_children_succeed() {
    // gtest_reactive.cpp: Reactive.ReactiveSequence_AllChildrenSucceed.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<ReactiveSequence><TestA/><TestB/><TestC/></ReactiveSequence>"#,
    ));
    assert_eq!(run.tick(), S);
    assert_eq!(fx.counts(), [1, 1, 1, 0]);
}

// -----------------------------------------------------------------------------------------
// gtest_parallel.cpp

#[test]
fn parallel__conditions_true() {
    // gtest_parallel.cpp: SimpleParallelTest.ConditionsTrue — all must succeed (-1).
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Parallel success_count="-1" failure_count="1"><AlwaysSuccess/><AsyncSuccess/><AsyncSuccess/></Parallel>"#,
    ));
    assert_eq!(statuses(&mut run, 2), [R, S]);
}

#[test]
fn parallel__threshold_2() {
    // gtest_parallel.cpp: SimpleParallelTest.Threshold_2 — two successes are enough; the
    // running child is halted.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Parallel success_count="2"><TestA/><KeepRunning name="slow"/><TestB/></Parallel>"#,
    ));
    assert_eq!(run.tick(), S);
    assert_eq!(run.status_of("slow"), Status::Idle);
}

#[test]
fn parallel__failing_parallel() {
    // gtest_parallel.cpp: Parallel.FailingParallel — one failure (failure_count 1) fails the
    // node and halts the running children.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Parallel failure_count="1"><AsyncSuccess name="good"/><AlwaysFailure/></Parallel>"#,
    ));
    assert_eq!(run.tick(), F);
    assert_eq!(run.status_of("good"), Status::Idle);
}

#[test]
fn parallel__parallel_all() {
    // gtest_parallel.cpp: Parallel.ParallelAll — every child runs to completion; then failure
    // if at least max_failures failed.
    let fx = Fixture::new();
    let body = |max: u32| {
        main_tree(&format!(
            r#"<ParallelAll max_failures="{max}"><AsyncFailure name="first"/><AsyncSuccess name="second"/><AsyncSuccess name="third"/></ParallelAll>"#
        ))
    };
    let mut run = fx.run(&body(1));
    assert_eq!(statuses(&mut run, 2), [R, F]);
    let mut run = fx.run(&body(2));
    assert_eq!(statuses(&mut run, 2), [R, S]);
}

#[test]
fn parallel__skipped_children_count_towards_all() {
    // gtest_parallel.cpp / BehaviorTree.CPP 4.6 ParallelNode: with a negative success_count,
    // skipped children count as successes (even when all are skipped); with a positive one,
    // a tick in which every child was skipped returns skipped.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Parallel><TestA/><TestB _skipIf="true"/></Parallel>"#,
    ));
    assert_eq!(run.tick(), S);
    let mut run = fx.run(&main_tree(
        r#"<Parallel><TestA _skipIf="true"/><TestB _skipIf="true"/></Parallel>"#,
    ));
    assert_eq!(run.tick(), S);
    let mut run = fx.run(&main_tree(
        r#"<Parallel success_count="2"><TestA _skipIf="true"/><TestB _skipIf="true"/></Parallel>"#,
    ));
    assert_eq!(run.tick(), K);
}

// -----------------------------------------------------------------------------------------
// gtest_if_then_else.cpp

#[test]
fn if_then_else__condition_true_then_branch() {
    // gtest_if_then_else.cpp: ConditionTrue_ThenBranch.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<IfThenElse><AlwaysSuccess/><TestA/><TestB/></IfThenElse>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 0, 0, 0]);
}

#[test]
fn if_then_else__condition_false_else_branch() {
    // gtest_if_then_else.cpp: ConditionFalse_ElseBranch.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<IfThenElse><AlwaysFailure/><TestA/><TestB/></IfThenElse>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [0, 1, 0, 0]);
}

#[test]
fn if_then_else__condition_false_two_children_returns_failure() {
    // gtest_if_then_else.cpp: ConditionFalse_TwoChildren_ReturnsFailure.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<IfThenElse><AlwaysFailure/><TestA/></IfThenElse>"#,
    ));
    assert_eq!(run.tick_while_running(), F);
    assert_eq!(fx.count(0), 0);
}

#[test]
fn if_then_else__branches_fail() {
    // gtest_if_then_else.cpp: ThenBranchFails, ElseBranchFails — the branch's failure is the
    // node's.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<IfThenElse><AlwaysSuccess/><AlwaysFailure/><TestA/></IfThenElse>"#,
    ));
    assert_eq!(run.tick_while_running(), F);
    let mut run = fx.run(&main_tree(
        r#"<IfThenElse><AlwaysFailure/><TestA/><AlwaysFailure/></IfThenElse>"#,
    ));
    assert_eq!(run.tick_while_running(), F);
    assert_eq!(fx.count(0), 0);
}

#[test]
fn if_then_else__condition_running() {
    // gtest_if_then_else.cpp: ConditionRunning — the branch waits for the condition.
    let mut fx = Fixture::new();
    fx.sequence_action("RunningThenSuccess", |n| if n == 1 { R } else { S });
    let mut run = fx.run(&main_tree(
        r#"<IfThenElse><RunningThenSuccess/><TestA/><TestB/></IfThenElse>"#,
    ));
    assert_eq!(run.tick(), R);
    assert_eq!(fx.count(0), 0);
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 0, 0, 0]);
}

#[test]
fn if_then_else__halt_behavior() {
    // gtest_if_then_else.cpp: HaltBehavior — it runs again from the condition.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<IfThenElse><AlwaysSuccess/><TestA/><TestB/></IfThenElse>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.count(0), 2);
}

#[test]
fn if_then_else__invalid_child_count() {
    // gtest_if_then_else.cpp: InvalidChildCount_One, InvalidChildCount_Four — the tree loads
    // and the first tick throws, as in BehaviorTree.CPP; strict validation (`bt check`) finds
    // it before.
    let fx = Fixture::new();
    for body in [
        r#"<IfThenElse><AlwaysSuccess/></IfThenElse>"#,
        r#"<IfThenElse><AlwaysSuccess/><TestA/><TestB/><TestC/></IfThenElse>"#,
    ] {
        let e = fx.refuse(&main_tree(body));
        assert!(
            matches!(e.kind(), DefinitionErrorKind::WrongChildren { .. }),
            "{e}"
        );
        let e = fx.tick_error(&main_tree(body));
        assert!(
            e.to_string()
                .ends_with("IfThenElseNode must have either 2 or 3 children"),
            "{e}"
        );
    }
}

// -----------------------------------------------------------------------------------------
// gtest_while_do_else.cpp

#[test]
fn while_do_else__condition_true_do_branch() {
    // gtest_while_do_else.cpp: ConditionTrue_DoBranch.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<WhileDoElse><AlwaysSuccess/><TestA/><TestB/></WhileDoElse>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 0, 0, 0]);
}

#[test]
fn while_do_else__condition_false_else_branch() {
    // gtest_while_do_else.cpp: ConditionFalse_ElseBranch.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<WhileDoElse><AlwaysFailure/><TestA/><TestB/></WhileDoElse>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [0, 1, 0, 0]);
}

#[test]
fn while_do_else__condition_false_two_children_returns_failure() {
    // gtest_while_do_else.cpp: ConditionFalse_TwoChildren_ReturnsFailure, DoBranchFails.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<WhileDoElse><AlwaysFailure/><TestA/></WhileDoElse>"#,
    ));
    assert_eq!(run.tick_while_running(), F);
    let mut run = fx.run(&main_tree(
        r#"<WhileDoElse><AlwaysSuccess/><AlwaysFailure/><TestA/></WhileDoElse>"#,
    ));
    assert_eq!(run.tick_while_running(), F);
    assert_eq!(fx.count(0), 0);
}

#[test]
fn while_do_else__condition_changes_halts_else() {
    // gtest_while_do_else.cpp: ConditionChanges_HaltsElse, ConditionChanges_HaltsDo — the
    // condition is ticked every time; a change halts the running branch.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<WhileDoElse><ScriptCondition code="c"/><KeepRunning name="do"/><KeepRunning name="else"/></WhileDoElse>"#,
    ));
    run.set("c", false);
    assert_eq!(run.tick(), R);
    assert_eq!(
        (run.status_of("do"), run.status_of("else")),
        (Status::Idle, R)
    );
    run.set("c", true);
    assert_eq!(run.tick(), R);
    assert_eq!(
        (run.status_of("do"), run.status_of("else")),
        (R, Status::Idle)
    );
    run.set("c", false);
    assert_eq!(run.tick(), R);
    assert_eq!(
        (run.status_of("do"), run.status_of("else")),
        (Status::Idle, R)
    );
}

#[test]
fn while_do_else__halt_behavior_and_invalid_child_count() {
    // gtest_while_do_else.cpp: HaltBehavior, InvalidChildCount_One.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<WhileDoElse><AlwaysSuccess/><TestA/><TestB/></WhileDoElse>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.count(0), 2);
    let one = main_tree(r#"<WhileDoElse><AlwaysSuccess/></WhileDoElse>"#);
    let e = fx.refuse(&one);
    assert!(
        matches!(e.kind(), DefinitionErrorKind::WrongChildren { .. }),
        "{e}"
    );
    let e = fx.tick_error(&one);
    assert!(
        e.to_string()
            .ends_with("WhileDoElseNode must have either 2 or 3 children"),
        "{e}"
    );
}

// -----------------------------------------------------------------------------------------
// gtest_switch.cpp

const SWITCH: &str = r#"<Switch3 name="simple_switch" variable="{my_var}" case_1="1" case_2="42" case_3="666">
    <AsyncSuccess name="action_1"/>
    <AsyncSuccess name="action_42"/>
    <AsyncSuccess name="action_666"/>
    <AsyncSuccess name="action_default"/>
</Switch3>"#;

fn switch_statuses(run: &super::support::Run) -> [Status; 4] {
    ["action_1", "action_42", "action_666", "action_default"].map(|n| run.status_of(n))
}

#[test]
fn switch__default_case() {
    // gtest_switch.cpp: SwitchTest.DefaultCase — no variable: the default child.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(SWITCH));
    assert_eq!(run.tick(), R);
    assert_eq!(
        switch_statuses(&run),
        [Status::Idle, Status::Idle, Status::Idle, R]
    );
    assert_eq!(run.tick(), S);
    assert_eq!(switch_statuses(&run), [Status::Idle; 4]);
}

#[test]
fn switch__case1_case2_case_none() {
    // gtest_switch.cpp: SwitchTest.Case1, Case2, CaseNone.
    let fx = Fixture::new();
    for (value, running) in [("1", 0), ("42", 1), ("none", 3)] {
        let mut run = fx.run(&main_tree(SWITCH));
        run.set("my_var", value);
        assert_eq!(run.tick(), R);
        let mut expected = [Status::Idle; 4];
        expected[running] = R;
        assert_eq!(switch_statuses(&run), expected, "{value}");
        assert_eq!(run.tick(), S);
        assert_eq!(switch_statuses(&run), [Status::Idle; 4]);
    }
}

#[test]
fn switch__case_switch_to_action2() {
    // gtest_switch.cpp: SwitchTest.CaseSwitchToAction2 — a new match halts the running branch.
    let mut fx = Fixture::new();
    fx.registry
        .register_action_fn("Forever", |_| Ok(Status::Running))
        .unwrap();
    let mut run = fx.run(&main_tree(
        r#"<Switch2 variable="{my_var}" case_1="1" case_2="42"><Forever name="action_1"/><AsyncSuccess name="action_42"/><AsyncSuccess name="action_default"/></Switch2>"#,
    ));
    run.set("my_var", "1");
    assert_eq!(run.tick(), R);
    assert_eq!(run.status_of("action_1"), R);
    run.set("my_var", "42");
    assert_eq!(run.tick(), R);
    assert_eq!(run.status_of("action_1"), Status::Idle);
    assert_eq!(run.status_of("action_42"), R);
    assert_eq!(run.tick(), S);
}

#[test]
fn switch__action_failure() {
    // gtest_switch.cpp: SwitchTest.ActionFailure — the branch's failure is the node's.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Switch2 variable="{my_var}" case_1="1" case_2="42"><AsyncFailure name="action_1"/><TestA/><TestB/></Switch2>"#,
    ));
    run.set("my_var", "1");
    assert_eq!(statuses(&mut run, 2), [R, F]);
    assert_eq!(run.status_of("action_1"), Status::Idle);
}

#[test]
fn switch__string_equality_rejects_trailing_characters() {
    // gtest_switch.cpp: SwitchStringEquality.RejectsTrailingCharacters — "5" matches "5.0"
    // (as reals), "5abc" and "5 " do not match "5".
    let fx = Fixture::new();
    let xml = main_tree(
        r#"<Switch2 variable="{v}" case_1="5.0" case_2="-7"><TestA/><TestB/><TestC/></Switch2>"#,
    );
    for (value, expected) in [
        ("5", [1, 0, 0]),
        ("5abc", [0, 0, 1]),
        ("5 ", [0, 0, 1]),
        ("-7", [0, 1, 0]),
    ] {
        let before = fx.counts();
        let mut run = fx.run(&xml);
        run.set("v", value);
        assert_eq!(run.tick(), S);
        let after = fx.counts();
        let delta: Vec<usize> = (0..3).map(|k| after[k] - before[k]).collect();
        assert_eq!(delta, expected, "{value:?}");
    }
}

// -----------------------------------------------------------------------------------------
// gtest_try_catch.cpp

#[test]
fn try_catch__all_try_children_succeed() {
    // gtest_try_catch.cpp: AllTryChildrenSucceed.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<TryCatch><TestA/><TestB/><TestC/></TryCatch>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 1, 0, 0]);
}

#[test]
fn try_catch__second_child_fails_catch_executed() {
    // gtest_try_catch.cpp: FirstChildFails_CatchExecuted, SecondChildFails_CatchExecuted.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<TryCatch><TestA/><AlwaysFailure/><TestC/><TestB/></TryCatch>"#,
    ));
    assert_eq!(run.tick_while_running(), F);
    assert_eq!(fx.counts(), [1, 1, 0, 0]);
}

#[test]
fn try_catch__catch_returns_success_node_still_returns_failure() {
    // gtest_try_catch.cpp: CatchReturnsSuccess_NodeStillReturnsFAILURE,
    // CatchReturnsFailure_NodeStillReturnsFAILURE.
    let fx = Fixture::new();
    for catch in ["AlwaysSuccess", "AlwaysFailure"] {
        let mut run = fx.run(&main_tree(&format!(
            r#"<TryCatch><AlwaysFailure/><{catch}/></TryCatch>"#
        )));
        assert_eq!(run.tick_while_running(), F);
    }
}

#[test]
fn try_catch__async_catch_completes_inside_sequence() {
    // gtest_try_catch.cpp: CatchChildRunning, AsyncCatchCompletesInsideSequence — a running
    // catch keeps the node running; then failure, and the next sibling is not ticked.
    let mut fx = Fixture::new();
    let ticks = fx.sequence_action("AsyncCleanup", |n| if n <= 5 { R } else { S });
    let mut run = fx.run(&main_tree(
        r#"<Sequence><TryCatch><AlwaysFailure/><AsyncCleanup/></TryCatch><TestA/></Sequence>"#,
    ));
    for k in 1..=5 {
        assert_eq!(run.tick(), R);
        assert_eq!(ticks.load(std::sync::atomic::Ordering::SeqCst), k);
    }
    assert_eq!(run.tick(), F);
    assert_eq!(fx.count(0), 0);
}

#[test]
fn try_catch__catch_on_halt() {
    // gtest_try_catch.cpp: CatchOnHalt_Disabled, CatchOnHalt_Enabled — halting during the try
    // runs the catch only with catch_on_halt.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(r#"<TryCatch><KeepRunning/><TestA/></TryCatch>"#));
    assert_eq!(run.tick(), R);
    run.halt();
    assert_eq!(fx.count(0), 0);
    let mut run = fx.run(&main_tree(
        r#"<TryCatch catch_on_halt="true"><KeepRunning/><TestA/></TryCatch>"#,
    ));
    assert_eq!(run.tick(), R);
    run.halt();
    assert_eq!(fx.count(0), 1);
}

#[test]
fn try_catch__catch_on_halt_not_triggered_when_already_in_catch() {
    // gtest_try_catch.cpp: CatchOnHalt_NotTriggeredWhenAlreadyInCatch.
    let mut fx = Fixture::new();
    let ticks = fx.sequence_action("RunningCatch", |_| R);
    let mut run = fx.run(&main_tree(
        r#"<TryCatch catch_on_halt="true"><AlwaysFailure/><RunningCatch/></TryCatch>"#,
    ));
    assert_eq!(run.tick(), R);
    run.halt();
    assert_eq!(ticks.load(std::sync::atomic::Ordering::SeqCst), 1);
}

#[test]
fn try_catch__re_execute_after_failure() {
    // gtest_try_catch.cpp: ReExecuteAfterFailure, ReExecuteAfterSuccess.
    let mut fx = Fixture::new();
    fx.sequence_action("FailThenSucceed", |n| if n == 1 { F } else { S });
    let mut run = fx.run(&main_tree(
        r#"<TryCatch><FailThenSucceed/><TestA/></TryCatch>"#,
    ));
    assert_eq!(run.tick_while_running(), F);
    assert_eq!(fx.count(0), 1);
    run.halt();
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.count(0), 1);
}

#[test]
fn try_catch__minimum_two_children_parse_time_validation() {
    // gtest_try_catch.cpp: MinimumTwoChildren_ParseTimeValidation.
    let fx = Fixture::new();
    let e = fx.refuse(&main_tree(r#"<TryCatch><AlwaysSuccess/></TryCatch>"#));
    assert!(
        matches!(e.kind(), DefinitionErrorKind::WrongChildren { .. }),
        "{e}"
    );
}
