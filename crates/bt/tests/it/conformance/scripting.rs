//! Scripts, pre- and post-conditions, skipping, enums, blackboard and subtree remapping.

use chronomap_bt::Status::{Failure as F, Running as R, Skipped as K, Success as S};
use chronomap_bt::{Status, TickErrorKind, Value};

use super::support::{Fixture, main_tree};

// -----------------------------------------------------------------------------------------
// gtest_preconditions.cpp

#[test]
fn preconditions_decorator__integers() {
    // gtest_preconditions.cpp: PreconditionsDecorator.Integers.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code = "A:=1; B:=1; C:=3" />
            <Precondition if="A==B" else="FAILURE"><TestA/></Precondition>
            <Precondition if="A==C" else="SUCCESS"><TestB/></Precondition>
            <Precondition if="A!=C" else="FAILURE"><TestC/></Precondition>
        </Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 0, 1, 0]);
}

#[test]
fn preconditions_decorator__double_equals() {
    // gtest_preconditions.cpp: PreconditionsDecorator.DoubleEquals.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code = " A:=1.1; B:=(1.0+0.1); C:= 2.0 " />
            <Precondition if="A==B" else="FAILURE"><TestA/></Precondition>
            <Precondition if="A==C" else="SUCCESS"><TestB/></Precondition>
            <Precondition if="A!=C" else="FAILURE"><TestC/></Precondition>
        </Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 0, 1, 0]);
}

#[test]
fn preconditions_decorator__string_equals() {
    // gtest_preconditions.cpp: PreconditionsDecorator.StringEquals.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code = "A:='hello'" />
            <Script code = "B:='world'" />
            <Script code = "C:='world'" />
            <Precondition if=" A==B " else="SUCCESS"><TestA/></Precondition>
            <Precondition if=" B==C " else="FAILURE"><TestB/></Precondition>
        </Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [0, 1, 0, 0]);
}

#[test]
fn preconditions_decorator__checks_condition_once() {
    // gtest_preconditions.cpp: PreconditionsDecorator.ChecksConditionOnce — while the child
    // runs, the condition is not evaluated again.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code = "A:=0" />
            <Script code = "B:=0" />
            <Precondition if=" A==0 " else="FAILURE">
                <KeepRunning _while="B==0" />
            </Precondition>
        </Sequence>"#,
    ));
    assert_eq!(run.tick(), R);
    run.set("A", 1);
    assert_eq!(run.tick(), R);
    run.set("B", 1);
    // The _while turns false: the child is halted and skipped, the sequence skips past it.
    assert_eq!(run.tick(), S);
}

#[test]
fn preconditions_decorator__can_run_children_multiple_times() {
    // gtest_preconditions.cpp: PreconditionsDecorator.CanRunChildrenMultipleTimes.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code = "A:=0" />
            <Script code = "B:=0" />
            <Script code = "C:=1" />
            <Repeat num_cycles="3">
                <Sequence>
                    <Precondition if=" A==0 " else="SUCCESS"><TestA/></Precondition>
                    <KeepRunning _while="C==0" />
                    <KeepRunning _while="B==0" />
                </Sequence>
            </Repeat>
        </Sequence>"#,
    ));
    assert_eq!(run.tick(), R);
    assert_eq!(fx.count(0), 1);
    run.set("A", 1);
    run.set("B", 1);
    run.set("C", 0);
    assert_eq!(run.tick(), R);
    assert_eq!(fx.count(0), 1);
    run.set("A", 0);
    run.set("C", 1);
    assert_eq!(run.tick(), S);
    assert_eq!(fx.count(0), 2);
}

#[test]
fn preconditions__basic() {
    // gtest_preconditions.cpp: Preconditions.Basic — _successIf / _failureIf replace the tick.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code = "A:=1" />
            <TestA _successIf= "A==1"/>
            <TestB _successIf= "A==2"/>
            <Fallback>
                <TestC _failureIf= "A==1"/>
                <TestD _failureIf= "A!=1"/>
            </Fallback>
        </Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [0, 1, 0, 1]);
}

#[test]
fn preconditions__issue533() {
    // gtest_preconditions.cpp: Preconditions.Issue533 — _skipIf and _onSuccess drive a
    // sequence of three leaves over three ticks.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <TestA _skipIf="A!=1" />
            <TestB _skipIf="A!=2" _onSuccess="A=1"/>
            <TestC _skipIf="A!=3" _onSuccess="A=2"/>
        </Sequence>"#,
    ));
    run.set("A", 3);
    run.tick();
    assert_eq!(fx.counts(), [0, 0, 1, 0]);
    run.tick();
    assert_eq!(fx.counts(), [0, 1, 1, 0]);
    run.tick();
    assert_eq!(fx.counts(), [1, 1, 1, 0]);
}

#[test]
fn preconditions__issue615_no_skip_when_running_a() {
    // gtest_preconditions.cpp: Preconditions.Issue615_NoSkipWhenRunning_A — _skipIf is not
    // checked while the node runs.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<KeepRunningUntilFailure _skipIf="check == true"><AlwaysSuccess/></KeepRunningUntilFailure>"#,
    ));
    run.set("check", false);
    assert_eq!(run.tick(), R);
    run.set("check", true);
    assert_eq!(run.tick(), R);
}

#[test]
fn preconditions__issue615_no_skip_when_running_b() {
    // gtest_preconditions.cpp: Preconditions.Issue615_NoSkipWhenRunning_B.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(r#"<KeepRunning _skipIf="check==false"/>"#));
    run.set("check", false);
    assert_eq!(run.tick(), K);
    run.set("check", true);
    assert_eq!(run.tick(), R);
    run.set("check", false);
    assert_eq!(run.tick(), R);
}

#[test]
fn preconditions__remapping() {
    // gtest_preconditions.cpp: Preconditions.Remapping — _skipIf of a SubTree node is evaluated
    // in the subtree's scope, through its remappings.
    let mut fx = Fixture::new();
    fx.registry
        .register_action_fn("SimpleOutput", |ctx| {
            ctx.set_output("output", true)?;
            Ok(Status::Success)
        })
        .unwrap();
    let xml = r#"<root BTCPP_format="4" main_tree_to_execute="Main">
        <BehaviorTree ID="Main">
          <Sequence>
            <SimpleOutput output="{param}" />
            <Script code="value:=true" />
            <SubTree ID="Sub1" param="{param}"/>
            <SubTree ID="Sub1" param="{value}"/>
            <SubTree ID="Sub1" param="true"/>
            <TestA/>
          </Sequence>
        </BehaviorTree>
        <BehaviorTree ID="Sub1">
          <Sequence>
            <SubTree ID="Sub2" _skipIf="param != true" />
          </Sequence>
        </BehaviorTree>
        <BehaviorTree ID="Sub2">
          <TestB/>
        </BehaviorTree>
    </root>"#;
    let mut run = fx.run(xml);
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 3, 0, 0]);
}

#[test]
fn preconditions__while_calls_on_halt() {
    // gtest_preconditions.cpp: Preconditions.WhileCallsOnHalt — a false _while halts the
    // running node, which runs _onHalted, and skips it.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><KeepRunning _while="A==1" _onHalted="B=69" /></Sequence>"#,
    ));
    run.set("A", 1);
    run.set("B", 0);
    assert_eq!(run.tick(), R);
    assert_eq!(run.get("B"), Some(Value::Int(0)));
    run.set("A", 0);
    assert_eq!(run.tick(), K);
    assert_eq!(run.get("B"), Some(Value::Int(69)));
}

#[test]
fn preconditions__skipped_sequence() {
    // gtest_preconditions.cpp: Preconditions.SkippedSequence — a sequence whose only child is
    // skipped is skipped, and runs normally afterwards.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><AlwaysSuccess _skipIf="skip"/></Sequence>"#,
    ));
    for (skip, expected) in [(true, K), (false, S), (true, K), (false, S)] {
        run.set("skip", skip);
        assert_eq!(run.tick_while_running(), expected, "skip = {skip}");
    }
}

// -----------------------------------------------------------------------------------------
// gtest_postconditions.cpp

#[test]
fn post_conditions__basic_test() {
    // gtest_postconditions.cpp: PostConditions.BasicTest — post-conditions run after a tick and
    // after a pre-condition that completed the node.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code = "A:=1; B:=1; C:=1; D:=1" />
            <AlwaysSuccess _onSuccess="B=42"/>
            <ForceSuccess><AlwaysSuccess _failureIf="A!=0" _onFailure="C=42"/></ForceSuccess>
            <ForceSuccess><AlwaysFailure _onFailure="D=42"/></ForceSuccess>
        </Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    for key in ["B", "C", "D"] {
        assert_eq!(run.get(key), Some(Value::Int(42)), "{key}");
    }
}

#[test]
fn post_conditions__issue539() {
    // gtest_postconditions.cpp: PostConditions.Issue539 — _onFailure and _post run at every
    // attempt of a retried leaf.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code = "x:=0; y:=0" />
            <RetryUntilSuccessful num_attempts="5">
                <AlwaysFailure _onFailure="x  += 1"  _post="y  += 1" />
            </RetryUntilSuccessful>
        </Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), F);
    assert_eq!(run.get("x"), Some(Value::Int(5)));
    assert_eq!(run.get("y"), Some(Value::Int(5)));
}

#[test]
fn post_conditions__issue601() {
    // gtest_postconditions.cpp: PostConditions.Issue601 — a running Sleep halted by its
    // parallel sibling's failure runs _onHalted, not _post.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code="test := 'start'"/>
            <Parallel failure_count="1" success_count="-1">
                <Sleep msec="1000" _onHalted="test = 'halted'" _post="test = 'post'"/>
                <AlwaysFailure/>
            </Parallel>
        </Sequence>"#,
    ));
    run.tick_while_running();
    assert_eq!(run.get("test"), Some(Value::from("halted")));
}

// -----------------------------------------------------------------------------------------
// gtest_skipping.cpp

#[test]
fn skipping_logic__sequence() {
    // gtest_skipping.cpp: SkippingLogic.Sequence — _skipIf is checked after _failureIf and
    // _successIf.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code = "A:=1"/>
            <TestA _successIf="A==2" _failureIf="A!=1" _skipIf="A==1"/>
            <TestB/>
        </Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [0, 1, 0, 0]);
}

#[test]
fn skipping_logic__skip_all() {
    // gtest_skipping.cpp: SkippingLogic.SkipAll.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <TestA _skipIf="A==1"/>
            <TestB _skipIf="A<2"/>
            <TestC _skipIf="A>0"/>
        </Sequence>"#,
    ));
    run.set("A", 1);
    assert_eq!(run.tick_while_running(), K);
    assert_eq!(fx.counts(), [0, 0, 0, 0]);
}

#[test]
fn skipping_logic__skip_subtree() {
    // gtest_skipping.cpp: SkippingLogic.SkipSubtree.
    let fx = Fixture::new();
    let mut run = fx.run(
        r#"<root BTCPP_format="4" main_tree_to_execute="main">
            <BehaviorTree ID="main">
                <Sequence>
                    <TestA/>
                    <Script code=" data:=true "/>
                    <SubTree ID="sub" _skipIf="data"/>
                </Sequence>
            </BehaviorTree>
            <BehaviorTree ID="sub"><TestB/></BehaviorTree>
        </root>"#,
    );
    run.set("A", 1);
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(fx.counts(), [1, 0, 0, 0]);
}

#[test]
fn skipping_logic__reactive_single_child() {
    // gtest_skipping.cpp: SkippingLogic.ReactiveSingleChild — no error, skipped.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<ReactiveSequence><AlwaysSuccess _skipIf="flag"/></ReactiveSequence>"#,
    ));
    run.set("flag", true);
    assert_eq!(run.tick_while_running(), K);
}

#[test]
fn skipping_logic__skipping_reactive_sequence() {
    // gtest_skipping.cpp: SkippingLogic.SkippingReactiveSequence — a skipped child is skipped
    // again at every tick of a reactive sequence; a child that is not skipped is re-ticked.
    let fx = Fixture::new();
    let noskip = main_tree(
        r#"<ReactiveSequence><Script code=" value:=50 "/><TestA _skipIf="value < 25"/><AsyncSuccess/></ReactiveSequence>"#,
    );
    let skip = main_tree(
        r#"<ReactiveSequence><Script code=" value:=10 "/><TestB _skipIf="value < 25"/><AsyncSuccess/></ReactiveSequence>"#,
    );
    let mut expected_a = 0;
    for (xml, counts_a) in [(&noskip, true), (&skip, false)] {
        let mut run = fx.run(xml);
        for _ in 0..3 {
            let mut status = Status::Idle;
            while !status.is_completed() {
                status = run.tick();
                if counts_a {
                    expected_a += 1;
                }
            }
            assert_eq!(status, S);
        }
    }
    assert_eq!(fx.count(0), expected_a);
    assert_eq!(fx.count(1), 0);
}

#[test]
fn skipping_logic__while_skip() {
    // gtest_skipping.cpp: SkippingLogic.WhileSkip — a false _while skips the node.
    let fx = Fixture::new();
    for (doit, expected_a, expected_b) in [("true", 1, 0), ("false", 1, 0)] {
        let leaf = if doit == "true" { "TestA" } else { "TestB" };
        let mut run = fx.run(&main_tree(&format!(
            r#"<Sequence><Script code=" doit:={doit} "/><Sequence><{leaf} _while="doit"/></Sequence></Sequence>"#
        )));
        assert_eq!(run.tick_while_running(), S);
        assert_eq!((fx.count(0), fx.count(1)), (expected_a, expected_b));
    }
}

#[test]
fn skipping_logic__retry_and_repeat_pass_skipped_through() {
    // BehaviorTree.CPP 4.6 RetryNode / RepeatNode: a skipped child skips the decorator (and
    // the counter is kept); Inverter and ForceSuccess pass SKIPPED through.
    let fx = Fixture::new();
    for node in [
        "RetryUntilSuccessful num_attempts=\"3\"",
        "Repeat num_cycles=\"3\"",
        "Inverter",
        "ForceSuccess",
    ] {
        let tag = node.split(' ').next().unwrap();
        let mut run = fx.run(&main_tree(&format!(
            r#"<{node}><TestA _skipIf="true"/></{tag}>"#
        )));
        assert_eq!(run.tick(), K, "{tag}");
    }
    assert_eq!(fx.count(0), 0);
}

// -----------------------------------------------------------------------------------------
// Scripting (gtest_preconditions.cpp, gtest_blackboard.cpp, gtest_enums.cpp)

#[test]
fn scripting__operators_and_precedence() {
    // The operators of BehaviorTree.CPP's scripting language, as its Script nodes use them.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code="a := 2 + 3 * 4; b := (2 + 3) * 4; c := 7 / 2; d := 0x10 | 1; e := 6 &amp; 3 ^ 1"/>
            <Script code="s := 'x' .. a .. 'y'; t := a > 10 ? 'big' : 'small'; u := !(a == 14) || false"/>
            <Script code="a += 1; a -= 3; a *= 2; n := -a; m := ~0; chain := 1 < 2 < 3"/>
        </Sequence>"#,
    ));
    assert_eq!(run.tick(), S);
    let get = |k: &str| run.get(k).unwrap();
    assert_eq!(get("b"), Value::Int(20));
    assert_eq!(get("c"), Value::Double(3.5));
    assert_eq!(get("d"), Value::Int(17));
    assert_eq!(get("s"), Value::from("x14y"));
    assert_eq!(get("t"), Value::from("big"));
    assert_eq!(get("u"), Value::Bool(false));
    assert_eq!(get("a"), Value::Int(24));
    assert_eq!(get("n"), Value::Int(-24));
    assert_eq!(get("m"), Value::Int(-1));
    assert_eq!(get("chain"), Value::Bool(true));
}

#[test]
fn scripting__script_condition() {
    // ScriptCondition: success when the result is true.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Fallback><ScriptCondition code="x > 3 and x < 10"/><TestA/></Fallback>"#,
    ));
    run.set("x", 5);
    assert_eq!(run.tick(), S);
    run.set("x", 50);
    assert_eq!(run.tick(), S);
    assert_eq!(fx.count(0), 1);
}

#[test]
fn scripting__type_errors_at_tick_time() {
    // gtest_blackboard.cpp: CheckTypeSafety — assigning a string to a number entry fails; so
    // do comparing a number with a string that is no number, and `=` on a missing entry.
    let fx = Fixture::new();
    for code in [
        "A := 1; A = 'hello'",
        "A := 1; A == 'hello'",
        "Z = 1",
        "A := 'x'; A -= 1",
    ] {
        let xml = main_tree(&format!(r#"<Script code="{code}"/>"#));
        let doc = super::support::document(&xml, &fx.registry);
        let mut tree = chronomap_bt::Tree::new(&doc, &fx.registry).unwrap();
        let e = tree.tick_once(std::time::Duration::ZERO).unwrap_err();
        assert!(
            matches!(e.kind(), TickErrorKind::Script { .. }),
            "{code}: {e}"
        );
        assert!(e.to_string().contains("Script"), "{e}");
    }
}

#[test]
fn scripting__code_from_the_blackboard() {
    // Script's `code` is an input port: it may come from the blackboard.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(r#"<Script code="{program}"/>"#));
    run.set("program", "x := 40 + 2");
    assert_eq!(run.tick(), S);
    assert_eq!(run.get("x"), Some(Value::Int(42)));
}

#[test]
fn enums__string_to_enum() {
    // gtest_enums.cpp: Enums.StrintToEnum — enum names read as their values in scripts.
    let mut fx = Fixture::new();
    for (name, value) in [("Red", 0), ("Blue", 1), ("Green", 2), ("Undefined", 3)] {
        fx.registry.register_enum(name, value);
    }
    let mut run = fx.run(&main_tree(
        r#"<Sequence><Script code=" my_color := Red "/><Script code=" other := Green + 1 "/><ScriptCondition code="my_color == 0 &amp;&amp; 'Blue' == Blue"/></Sequence>"#,
    ));
    assert_eq!(run.tick(), S);
    assert_eq!(run.get("my_color"), Some(Value::Int(0)));
    assert_eq!(run.get("other"), Some(Value::Int(3)));
}

#[test]
fn enums__switch_node_with_enum() {
    // gtest_enums.cpp: Enums.SwitchNodeWithEnum — Switch compares enum names by value.
    let mut fx = Fixture::new();
    for (name, value) in [("Red", 0), ("Blue", 1), ("Green", 2), ("Undefined", 3)] {
        fx.registry.register_enum(name, value);
    }
    let mut run = fx.run(&main_tree(
        r#"<Sequence>
            <Script code=" my_color := Blue "/>
            <Switch4 variable="{my_color}" case_1="Red" case_2="Blue" case_3="Green" case_4="Undefined">
                <AlwaysFailure name="case_red" />
                <AlwaysSuccess name="case_blue" />
                <AlwaysFailure name="case_green" />
                <AlwaysFailure name="case_undefined" />
                <AlwaysFailure name="default_case" />
            </Switch4>
        </Sequence>"#,
    ));
    assert_eq!(run.tick_while_running(), S);
}

// -----------------------------------------------------------------------------------------
// gtest_blackboard.cpp, gtest_subtree.cpp

#[test]
fn blackboard__root_blackboard() {
    // gtest_blackboard.cpp: BlackboardTest.RootBlackboard — `@key` in a script of a subtree
    // writes the root blackboard.
    let fx = Fixture::new();
    let mut run = fx.run(
        r#"<root BTCPP_format="4" main_tree_to_execute="Main">
            <BehaviorTree ID="Main"><SubTree ID="Sub"/></BehaviorTree>
            <BehaviorTree ID="Sub"><Sequence><Script code="@var1 := 42; local := 1"/><Script code="@var2 := @var1 + 1"/></Sequence></BehaviorTree>
        </root>"#,
    );
    assert_eq!(run.tick(), S);
    assert_eq!(run.get("var1"), Some(Value::Int(42)));
    assert_eq!(run.get("var2"), Some(Value::Int(43)));
    assert_eq!(run.get("local"), None);
}

#[test]
fn blackboard__set_blackboard_upd_ts_seq_id() {
    // gtest_blackboard.cpp: BlackboardTest.SetBlackboard_Upd_Ts_SeqId — every write of an
    // entry (even SetBlackboard with the same value) increments its sequence number.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><SetBlackboard value="hello" output_key="key"/><WasEntryUpdated entry="key"/><SetBlackboard value="hello" output_key="key"/><WasEntryUpdated entry="key"/></Sequence>"#,
    ));
    let root = run.tree.blackboard().root();
    assert_eq!(run.tick(), S);
    assert_eq!(run.tree.blackboard().sequence_id_in(root, "key"), Some(2));
}

#[test]
fn blackboard__unset_blackboard() {
    // UnsetBlackboard removes the entry (BehaviorTree.CPP's Blackboard::unset).
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><Script code="A := 1"/><UnsetBlackboard key="A"/><Fallback><ScriptCondition code="A == 1" _skipIf="true"/><WasEntryUpdated entry="A"/><TestA/></Fallback></Sequence>"#,
    ));
    assert_eq!(run.tick(), S);
    assert_eq!(run.get("A"), None);
    assert_eq!(fx.count(0), 1);
}

#[test]
fn subtree__script_remap() {
    // gtest_subtree.cpp: SubTree.ScriptRemap — a script in a subtree writes the remapped
    // entry of the parent.
    let fx = Fixture::new();
    let mut run = fx.run(
        r#"<root BTCPP_format="4" main_tree_to_execute="MainTree">
            <BehaviorTree ID="MainTree">
                <Sequence>
                    <Script code = "value:=0" />
                    <SubTree ID="mySubtree" value="{value}" />
                </Sequence>
            </BehaviorTree>
            <BehaviorTree ID="mySubtree">
                <Script code = "value:=1" />
            </BehaviorTree>
        </root>"#,
    );
    assert_eq!(run.tick_while_running(), S);
    assert_eq!(run.get("value"), Some(Value::Int(1)));
}

#[test]
fn subtree__subtree_plus_autoremap_scripts() {
    // gtest_subtree.cpp: SubTree.SubtreePlusA/B — with _autoremap, entries created by scripts
    // in the subtree land in the parent; without it they stay local.
    let fx = Fixture::new();
    let xml = |autoremap: &str| {
        format!(
            r#"<root BTCPP_format="4" main_tree_to_execute="Main">
                <BehaviorTree ID="Main"><Sequence><Script code="msg := 'hi'"/><SubTree ID="Sub" _autoremap="{autoremap}"/></Sequence></BehaviorTree>
                <BehaviorTree ID="Sub"><Script code="reply := msg .. '!'; _private := 1"/></BehaviorTree>
            </root>"#
        )
    };
    let mut run = fx.run(&xml("true"));
    assert_eq!(run.tick(), S);
    assert_eq!(run.get("reply"), Some(Value::from("hi!")));
    assert_eq!(run.get("_private"), None);
    let mut run = fx.run(&xml("false"));
    let e = run.tree.tick_once(run.now).unwrap_err();
    assert!(e.to_string().contains("variable not found: msg"), "{e}");
}

#[test]
fn skipping_logic__a_skipped_node_keeps_its_status() {
    // A skipped node keeps its status ("preserve the IDLE state if skipped, but communicate
    // SKIPPED to parent"): no transition to SKIPPED is recorded, as BehaviorTree.CPP's loggers
    // see none (checked against BehaviorTree.CPP 4.8.2 by tests/cli/bt_differential.rs), and
    // the node starts afresh at the next tick.
    let fx = Fixture::new();
    let mut run = fx.run(&main_tree(
        r#"<Sequence><TestA _skipIf="skip"/><TestB/></Sequence>"#,
    ));
    run.tree.set_recording(true);
    run.set("skip", true);
    assert_eq!(run.tick(), S);
    assert!(run.tree.transitions().iter().all(|t| t.to != K));
    assert!(run.tree.transitions().iter().all(|t| t.uid != 2));
    assert_eq!(run.status_of("TestA"), Status::Idle);
    run.set("skip", false);
    assert_eq!(run.tick(), S);
    assert_eq!(fx.counts(), [1, 2, 0, 0]);
}
