//! Decorators, loops over queues, entry updates.

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};

use chronomap_bt::Status::{Failure as F, Running as R, Skipped as K, Success as S};
use chronomap_bt::{Status, Value};

use super::support::{Fixture, main_tree};

// -----------------------------------------------------------------------------------------
// gtest_decorator.cpp

#[test]
fn decorator__inverter_child_success_and_failure() {
    // gtest_decorator.cpp: Decorator.Inverter_ChildSuccess, Inverter_ChildFailure.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(r#"<Inverter><AlwaysSuccess/></Inverter>"#));
    assert_eq!(run.tick(), F);
    let mut run = fx.run(&main_tree(r#"<Inverter><AlwaysFailure/></Inverter>"#));
    assert_eq!(run.tick(), S);
}

#[test]
fn decorator__inverter_in_sequence() {
    // gtest_decorator.cpp: Decorator.Inverter_InSequence.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><Inverter><AlwaysFailure/></Inverter><TestA/></Sequence>"#,
    ));
    assert_eq!(run.tick(), S);
    assert_eq!(fx.count(0), 1);
}

#[test]
fn decorator__force_success_and_force_failure() {
    // gtest_decorator.cpp: ForceSuccess_ChildFailure, ForceSuccess_ChildSuccess,
    // ForceFailure_ChildSuccess, ForceFailure_ChildFailure.
    let fx = Fixture::new();
    for (node, child, expected) in [
        ("ForceSuccess", "AlwaysFailure", S),
        ("ForceSuccess", "AlwaysSuccess", S),
        ("ForceFailure", "AlwaysSuccess", F),
        ("ForceFailure", "AlwaysFailure", F),
    ] {
        let mut run = fx.run(&main_tree(&format!("<{node}><{child}/></{node}>")));
        assert_eq!(run.tick(), expected, "{node}({child})");
    }
}

#[test]
fn decorator__keep_running_until_failure() {
    // gtest_decorator.cpp: Decorator.KeepRunningUntilFailure.
    let mut fx = Fixture::new();
    fx.sequence_action("SuccessTwiceThenFail", |n| if n <= 2 { S } else { F });
    let mut run = fx.run(&main_tree(
        r#"<KeepRunningUntilFailure><SuccessTwiceThenFail/></KeepRunningUntilFailure>"#,
    ));
    assert_eq!([run.tick(), run.tick(), run.tick()], [R, R, F]);
}

#[test]
fn decorator__run_once() {
    // gtest_decorator.cpp: Decorator.RunOnce — the child runs once; then the node is skipped,
    // or (then_skip="false") returns the same result without ticking it.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><RunOnce><TestA/></RunOnce><TestB/></Sequence>"#,
    ));
    for _ in 0..3 {
        assert_eq!(run.tick(), S);
    }
    assert_eq!(fx.counts(), [1, 3, 0, 0]);
    let mut fx = Fixture::new();
    let ticks = fx.sequence_action("FailOnce", |_| F);
    let mut run = fx.run(&main_tree(
        r#"<RunOnce then_skip="false"><FailOnce/></RunOnce>"#,
    ));
    assert_eq!([run.tick(), run.tick(), run.tick()], [F, F, F]);
    assert_eq!(ticks.load(Ordering::SeqCst), 1);
    let mut run = fx.run(&main_tree(r#"<RunOnce><TestA/></RunOnce>"#));
    assert_eq!([run.tick(), run.tick()], [S, K]);
}

#[test]
fn decorator__delay_with_xml() {
    // gtest_decorator.cpp: Decorator.DelayWithXML — the child is ticked only once the delay
    // has passed; the node runs meanwhile.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(r#"<Delay delay_msec="100"><TestA/></Delay>"#));
    // Ticks every 10 ms from t = 10 ms: the deadline is 110 ms.
    for _ in 0..10 {
        assert_eq!(run.tick(), R);
    }
    assert_eq!(fx.count(0), 0);
    assert_eq!(run.tick(), S);
    assert_eq!(fx.count(0), 1);
    // It starts over.
    assert_eq!(run.tick(), R);
}

#[test]
fn decorator__deadline_triggered_and_not_triggered() {
    // gtest_decorator.cpp: DeadlineTest.DeadlineTriggeredTest, DeadlineNotTriggeredTest.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Timeout msec="30"><KeepRunning name="a"/></Timeout>"#,
    ));
    assert_eq!([run.tick(), run.tick(), run.tick()], [R, R, R]);
    assert_eq!(run.tick(), F);
    assert_eq!(run.status_of("a"), Status::Idle);
    let mut run = fx.run(&main_tree(
        r#"<Timeout msec="30"><AsyncSuccess/></Timeout>"#,
    ));
    assert_eq!([run.tick(), run.tick()], [R, S]);
}

#[test]
fn decorator__retry_test_a() {
    // gtest_decorator.cpp: RetryTest.RetryTestA — failures are retried (within one tickOnce,
    // thanks to the wake-ups) until a success.
    let mut fx = Fixture::new();
    let ticks = fx.sequence_action("FailTwice", |n| if n <= 2 { F } else { S });
    let mut run = fx.run(&main_tree(
        r#"<RetryUntilSuccessful num_attempts="3"><FailTwice/></RetryUntilSuccessful>"#,
    ));
    assert_eq!(run.tick(), S);
    assert_eq!(ticks.load(Ordering::SeqCst), 3);
}

#[test]
fn decorator__repeat_test_a() {
    // gtest_decorator.cpp: RepeatTest.RepeatTestA.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(r#"<Repeat num_cycles="3"><TestA/></Repeat>"#));
    assert_eq!(run.tick(), S);
    assert_eq!(fx.count(0), 3);
}

#[test]
fn decorator__retry_until_succesful_old_spelling() {
    // BehaviorTree.CPP 3's misspelled name is registered too (USE_BTCPP3_OLD_NAMES).
    let mut fx = Fixture::new();
    let ticks = fx.sequence_action("FailOnce", |n| if n == 1 { F } else { S });
    let mut run = fx.run(&main_tree(
        r#"<RetryUntilSuccesful num_attempts="2"><FailOnce/></RetryUntilSuccesful>"#,
    ));
    assert_eq!(run.tick(), S);
    assert_eq!(ticks.load(Ordering::SeqCst), 2);
}

// -----------------------------------------------------------------------------------------
// gtest_loop.cpp

fn recorder(fx: &mut Fixture) -> Arc<Mutex<Vec<Value>>> {
    let seen = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&seen);
    fx.registry
        .register_action_fn("Record", move |ctx| {
            sink.lock().unwrap().push(ctx.input::<Value>("value")?);
            Ok(Status::Success)
        })
        .unwrap();
    seen
}

#[test]
fn loop__static_int_queue() {
    // gtest_loop.cpp: LoopNode.StaticIntQueue.
    let mut fx = Fixture::new();
    let seen = recorder(&mut fx);
    let mut run = fx.run(&main_tree(
        r#"<LoopInt queue="1;2;3;4;5" value="{val}"><Record value="{val}"/></LoopInt>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    let ints: Vec<Value> = (1..=5).map(Value::Int).collect();
    assert_eq!(*seen.lock().unwrap(), ints);
}

#[test]
fn loop__static_double_string_and_bool_queues() {
    // gtest_loop.cpp: StaticDoubleQueue, StaticStringQueue, BoolQueue.
    for (node, queue, expected) in [
        (
            "LoopDouble",
            "1.5;2.5;3.5",
            vec![Value::Double(1.5), Value::Double(2.5), Value::Double(3.5)],
        ),
        (
            "LoopString",
            "hello;world;test",
            vec!["hello".into(), "world".into(), "test".into()],
        ),
        (
            "LoopBool",
            "true;false;true",
            vec![Value::Bool(true), Value::Bool(false), Value::Bool(true)],
        ),
    ] {
        let mut fx = Fixture::new();
        let seen = recorder(&mut fx);
        let mut run = fx.run(&main_tree(&format!(
            r#"<{node} queue="{queue}" value="{{val}}"><Record value="{{val}}"/></{node}>"#
        )));
        assert_eq!(run.tick_while_running(), S);
        assert_eq!(*seen.lock().unwrap(), expected, "{node}");
    }
}

#[test]
fn loop__empty_queue_returns_if_empty() {
    // gtest_loop.cpp: EmptyQueue_ReturnsSuccess, EmptyQueue_ReturnsFailure,
    // EmptyQueue_ReturnsSkipped — the child is never ticked.
    let fx = Fixture::new();
    for (if_empty, expected) in [("SUCCESS", S), ("FAILURE", F), ("SKIPPED", K)] {
        let mut run = fx.run(&main_tree(&format!(
            r#"<LoopInt queue="" if_empty="{if_empty}" value="{{val}}"><TestA/></LoopInt>"#
        )));
        assert_eq!(run.tick_while_running(), expected);
    }
    assert_eq!(fx.count(0), 0);
}

#[test]
fn loop__child_failure_stops_loop() {
    // gtest_loop.cpp: LoopNode.ChildFailure_StopsLoop.
    let mut fx = Fixture::new();
    let ticks = fx.sequence_action("FailOnThird", |n| if n == 3 { F } else { S });
    let mut run = fx.run(&main_tree(
        r#"<LoopInt queue="1;2;3;4;5" value="{val}"><FailOnThird/></LoopInt>"#,
    ));
    assert_eq!(run.tick_while_running(), F);
    assert_eq!(ticks.load(Ordering::SeqCst), 3);
}

#[test]
fn loop__dynamic_queue_from_blackboard() {
    // gtest_loop.cpp: LoopNode.DynamicQueueFromBlackboard — the queue on the blackboard is
    // consumed (a shared queue).
    let mut fx = Fixture::new();
    let seen = recorder(&mut fx);
    let mut run = fx.run(&main_tree(
        r#"<LoopInt queue="{my_queue}" value="{val}"><Record value="{val}"/></LoopInt>"#,
    ));
    run.set(
        "my_queue",
        vec![Value::Int(10), Value::Int(20), Value::Int(30)],
    );
    assert_eq!(run.tick_while_running(), S);
    let ints: Vec<Value> = [10, 20, 30].into_iter().map(Value::Int).collect();
    assert_eq!(*seen.lock().unwrap(), ints);
    assert_eq!(run.get("my_queue"), Some(Value::List(Vec::new())));
}

#[test]
fn loop__restart_after_completion() {
    // gtest_loop.cpp: LoopNode.RestartAfterCompletion — a static queue is copied again when
    // the node starts over.
    let mut fx = Fixture::new();
    let seen = recorder(&mut fx);
    let mut run = fx.run(&main_tree(
        r#"<LoopInt queue="1;2" value="{val}"><Record value="{val}"/></LoopInt>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(seen.lock().unwrap().len(), 4);
}

#[test]
fn loop__convert_from_string_int() {
    // gtest_loop.cpp: ConvertFromString_Int — a queue given as text on the blackboard.
    let mut fx = Fixture::new();
    let seen = recorder(&mut fx);
    let mut run = fx.run(&main_tree(
        r#"<Sequence><Script code="q := '7;8'"/><LoopInt queue="{q}" value="{val}"><Record value="{val}"/></LoopInt></Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(*seen.lock().unwrap(), [Value::Int(7), Value::Int(8)]);
}

// -----------------------------------------------------------------------------------------
// gtest_updates.cpp

const CHECK: &str = r#"<BehaviorTree ID="Check">
  <Sequence>
    <Fallback>
      <WasEntryUpdated entry="A"/>
      <TestA/>
    </Fallback>
    <SkipUnlessUpdated entry="A">
      <TestB/>
    </SkipUnlessUpdated>
  </Sequence>
</BehaviorTree>"#;

fn with_check(main: &str) -> String {
    format!(
        r#"<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">{main}</BehaviorTree>{CHECK}</root>"#
    )
}

#[test]
fn entry_updates__no_entry() {
    // gtest_updates.cpp: EntryUpdates.NoEntry — a missing entry is "not updated".
    let fx = Fixture::new();
    let mut run = fx.run(&with_check(
        r#"<Sequence><SubTree ID="Check" _autoremap="true"/></Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 0, 0, 0]);
}

#[test]
fn entry_updates__initialized() {
    // gtest_updates.cpp: EntryUpdates.Initialized — a new entry counts as updated.
    let fx = Fixture::new();
    let mut run = fx.run(&with_check(
        r#"<Sequence><Script code="A:=1;B:=1"/><SubTree ID="Check" _autoremap="true"/></Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [0, 1, 0, 0]);
}

#[test]
fn entry_updates__update_once() {
    // gtest_updates.cpp: EntryUpdates.UpdateOnce — the second look sees no update.
    let fx = Fixture::new();
    let mut run = fx.run(&with_check(
        r#"<Sequence><Script code="A:=1"/><Repeat num_cycles="2"><SubTree ID="Check" _autoremap="true"/></Repeat></Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 1, 0, 0]);
}

#[test]
fn entry_updates__update_twice() {
    // gtest_updates.cpp: EntryUpdates.UpdateTwice — every write (even of the same value) is
    // an update.
    let fx = Fixture::new();
    let mut run = fx.run(&with_check(
        r#"<Repeat num_cycles="2"><Sequence><Script code="A:=1"/><SubTree ID="Check" _autoremap="true"/></Sequence></Repeat>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [0, 2, 0, 0]);
}

#[test]
fn entry_updates__wait_value_update_runs_until_written() {
    // WaitValueUpdate (EntryUpdatedDecorator with RUNNING): runs until the entry is written.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<WaitValueUpdate entry="{A}"><TestA/></WaitValueUpdate>"#,
    ));
    assert_eq!([run.tick(), run.tick()], [R, R]);
    run.set("A", 1);
    assert_eq!(run.tick(), S);
    assert_eq!(run.tick(), R);
    assert_eq!(fx.count(0), 1);
}
