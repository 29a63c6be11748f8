"""A behavior tree run by the real BehaviorTree.CPP 4 (behaviortreepy), watched through
`Groot2Publisher` on a given port: the live source of chronomap's Groot2 monitor tests.

    python btcpp_groot2_tree.py --port 1667 [--tree patrol|inspect] [--period-ms 50] [--seconds 300]

The leaves are scripted on the round number (one round is one pass of the root from IDLE to a
result), so the same rounds give the same statuses on every run:

* `BatteryOk` fails every 5th round, so the `Dock` subtree runs then;
* `MoveTo` is RUNNING for two ticks, then SUCCESS;
* `DetectPerson` succeeds in the kitchen on rounds divisible by 3, in the office on the others
  of even number, and fails otherwise;
* `PathBlocked` succeeds on rounds divisible by 4 (so its `Inverter` fails and the round ends
  in FAILURE there);
* `CheckDoor` succeeds on odd rounds;
* the `_skipIf` script is skipped on even rounds (BT.CPP 4 tells its parent SKIPPED but keeps
  the node IDLE, so a monitor never sees SKIPPED from it).

The blackboard of the main tree holds `round` (int), `even_round` (bool), `battery` (double),
`robot` (string), `rounds_seen` and `greeted` (ints, written by scripts); the `dock` subtree's
holds `dock_station` (string, from `robot`) and `charge` (double) once it has run.

It prints one line `ready port=PORT nodes=N` once the publisher is bound, then ticks every
`--period-ms` until `--seconds` have passed (it always stops by itself) or it is killed.
"""

import argparse
import sys
import time

import behaviortreepy as bt

S = bt.NodeStatus

# 37 nodes in the main tree (the SubTree node among them), 6 in the Dock subtree: 43 in all
# (Groot2's free edition shows 20).
PATROL = """
<root BTCPP_format="4" main_tree_to_execute="Patrol">
  <BehaviorTree ID="Patrol">
    <Sequence name="patrol_round">
      <Script name="count_round" code="rounds_seen := rounds_seen + 1"/>
      <ReactiveFallback name="power">
        <BatteryOk name="battery_ok"/>
        <SubTree ID="Dock" name="dock" station="{robot}"/>
      </ReactiveFallback>
      <Fallback name="find_person">
        <Sequence name="look_kitchen">
          <MoveTo name="go_kitchen"/>
          <DetectPerson name="detect_kitchen"/>
        </Sequence>
        <Sequence name="look_office">
          <MoveTo name="go_office"/>
          <DetectPerson name="detect_office"/>
        </Sequence>
        <ForceSuccess name="give_up">
          <Say name="say_not_found"/>
        </ForceSuccess>
      </Fallback>
      <Parallel name="greet" success_count="2" failure_count="1">
        <Say name="say_hello"/>
        <Say name="wave"/>
      </Parallel>
      <Script name="note_greeting" _skipIf="even_round" code="greeted := round"/>
      <RetryUntilSuccessful name="retry_report" num_attempts="3">
        <Say name="report"/>
      </RetryUntilSuccessful>
      <Repeat name="check_doors" num_cycles="2">
        <Sequence name="door_round">
          <CheckDoor name="check_door"/>
          <Say name="door_done"/>
        </Sequence>
      </Repeat>
      <Fallback name="tidy">
        <Inverter name="not_messy">
          <CheckDoor name="messy"/>
        </Inverter>
        <Say name="tidy_up"/>
      </Fallback>
      <IfThenElse name="light">
        <CheckDoor name="is_dark"/>
        <Say name="lights_on"/>
        <Say name="lights_off"/>
      </IfThenElse>
      <ForceSuccess name="log_round">
        <Say name="log"/>
      </ForceSuccess>
      <Inverter name="not_blocked">
        <PathBlocked name="path_blocked"/>
      </Inverter>
      <Say name="round_done"/>
    </Sequence>
  </BehaviorTree>
  <BehaviorTree ID="Dock">
    <Sequence name="docking">
      <Script name="choose_station" code="dock_station := station; charge := 0.25"/>
      <MoveTo name="go_dock"/>
      <Fallback name="plug">
        <Say name="plug_in"/>
        <Say name="call_help"/>
      </Fallback>
    </Sequence>
  </BehaviorTree>
</root>
"""

# 12 nodes.
INSPECT = """
<root BTCPP_format="4" main_tree_to_execute="Inspect">
  <BehaviorTree ID="Inspect">
    <Sequence name="inspect_round">
      <Script name="count_round" code="rounds_seen := rounds_seen + 1"/>
      <Fallback name="reach_shelf">
        <MoveTo name="go_shelf"/>
        <Say name="shelf_unreachable"/>
      </Fallback>
      <Sequence name="scan">
        <DetectPerson name="detect_shelf"/>
        <Say name="scan_done"/>
      </Sequence>
      <ForceSuccess name="report_scan">
        <Inverter name="no_person">
          <PathBlocked name="aisle_blocked"/>
        </Inverter>
      </ForceSuccess>
      <Say name="inspect_done"/>
    </Sequence>
  </BehaviorTree>
</root>
"""

TREES = {"patrol": PATROL, "inspect": INSPECT}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--tree", choices=sorted(TREES), default="patrol")
    parser.add_argument("--period-ms", type=int, default=50)
    parser.add_argument("--seconds", type=float, default=300.0)
    args = parser.parse_args()

    state = {"round": 0}
    factory = bt.BehaviorTreeFactory()
    factory.register_simple_condition(
        "BatteryOk", lambda node: S.FAILURE if state["round"] % 5 == 0 else S.SUCCESS
    )

    def detect(node):
        k = state["round"]
        found = {
            "detect_kitchen": k % 3 == 0,
            "detect_office": k % 2 == 0,
            "detect_shelf": k % 2 == 1,
        }
        return S.SUCCESS if found.get(node.name(), False) else S.FAILURE

    factory.register_simple_action("DetectPerson", detect)
    factory.register_simple_condition(
        "PathBlocked", lambda node: S.SUCCESS if state["round"] % 4 == 0 else S.FAILURE
    )
    factory.register_simple_condition(
        "CheckDoor", lambda node: S.SUCCESS if state["round"] % 2 == 1 else S.FAILURE
    )
    factory.register_simple_action("Say", lambda node: S.SUCCESS)
    remaining = {}

    def move_start(node):
        remaining[node.uid()] = 2
        return S.RUNNING

    def move_running(node):
        remaining[node.uid()] -= 1
        return S.RUNNING if remaining[node.uid()] > 0 else S.SUCCESS

    factory.register_simple_stateful_action("MoveTo", move_start, move_running)
    blackboard = bt.Blackboard.create()
    blackboard.set_string("robot", "tiago")
    blackboard.set_int("rounds_seen", 0)

    def next_round():
        state["round"] += 1
        k = state["round"]
        blackboard.set_int("round", k)
        blackboard.set_bool("even_round", k % 2 == 0)
        blackboard.set_double("battery", 100.0 - (k % 5) * 20.0)

    next_round()
    tree = factory.create_tree_from_text(TREES[args.tree], blackboard)
    publisher = bt.Groot2Publisher(tree, args.port)
    nodes = TREES[args.tree].count("name=")
    print(f"ready port={args.port} nodes={nodes}", flush=True)

    end = time.monotonic() + args.seconds
    while time.monotonic() < end:
        status = tree.tick_exactly_once()
        if status != S.RUNNING:
            next_round()
        time.sleep(args.period_ms / 1000.0)
    del publisher
    return 0


if __name__ == "__main__":
    sys.exit(main())
