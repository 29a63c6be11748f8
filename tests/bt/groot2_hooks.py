"""Groot2 hooks and breakpoints acting on the ticks, in BehaviorTree.CPP's Groot2Publisher and
in `chronomap bt run --groot2`, recorded for tests/cli/bt_groot2.rs.

    groot2_hooks.py serve XML SCRIPT --port P --tick-period MS --heartbeat MS
        runs XML with the real BehaviorTree.CPP (behaviortreepy) as `chronomap bt run
        --script SCRIPT --groot2 P --tick-period MS --groot2-heartbeat MS` runs it: leaves that
        are not built-in follow SCRIPT (see groot2_compare.py), a Groot2Publisher on port P
        with that max heartbeat delay, a pause of MS before each tick, "tick K @ 0 ms: STATUS"
        after each and a "result:" line at the end; then it answers until killed.
    groot2_hooks.py session --port P --plan PLAN.json --out OUT.json -- CMD...
        starts CMD (either server), waits for its "serving" note and drives a session (below).

PLAN (JSON): "hooks", inserted before the first tick; "unlocks": for a node uid, what to do
each time its breakpoint is reached (the k-th entry for the k-th time: "desired_status",
"remove_when_done", and "then", requests made while the tick is held, before the unlock, or
"release", a request made instead of the unlock; past the list: unlock with no status and
remove the hook); "held_status": the uids whose breakpoint
holds the tick before any status changed in it (the root), where STATUS is compared while
held (elsewhere it is recorded as "uncompared"); "after": requests made after the run;
"vanish": true makes the client insert its hooks and go away without a word.

The session: SUB on P + 1 (every BREAKPOINT_REACHED notification is recorded), TOGGLE_RECORDING
start and a STATUS before the first tick (all idle, else the run started too early: exit status
3), HOOK_INSERT, HOOKS_DUMP; then, whenever a breakpoint is reached: HOOKS_DUMP, STATUS, the
plan's requests and BREAKPOINT_UNLOCK; after the "result:" line: STATUS, GET_TRANSITIONS,
FULLTREE, BLACKBOARD of every tree instance, HOOKS_DUMP, the plan's requests, REMOVE_ALL_HOOKS
and HOOKS_DUMP. OUT.json has every request and reply as hex, the notifications, the tick lines.
"""

import argparse
import json
import os
import queue
import re
import subprocess
import sys
import threading
import time
import xml.etree.ElementTree as ET

import zmq

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import groot2_compare as gc  # noqa: E402

DEADLINE_S = 60


def serve(args):
    import behaviortreepy as bt

    xml_text = open(args.xml, encoding="utf-8").read()
    script = gc.read_script(args.script)
    outcomes = {}
    status_of = {"SUCCESS": bt.NodeStatus.SUCCESS, "FAILURE": bt.NodeStatus.FAILURE,
                 "RUNNING": bt.NodeStatus.RUNNING}
    name_of = {v: k for k, v in status_of.items()}
    name_of[bt.NodeStatus.IDLE] = "IDLE"

    def outcome(node):
        return status_of[outcomes[node.name()]]

    factory = bt.BehaviorTreeFactory()
    for node_id, kind in sorted(gc.leaves(xml_text, bt).items()):
        if kind == "Condition":
            factory.register_simple_condition(node_id, outcome)
        else:
            factory.register_simple_stateful_action(node_id, outcome, outcome, None)
    tree = factory.create_tree_from_text(xml_text)
    publisher = bt.Groot2Publisher(tree, args.port)
    publisher.set_max_heartbeat_delay(args.heartbeat)
    print("note: groot2: serving on ports %d and %d" % (args.port, args.port + 1),
          file=sys.stderr, flush=True)
    last = max(script)
    status = None
    k = 0
    for k in range(1, last + 1):
        outcomes.update(script.get(k, {}))
        time.sleep(args.tick_period / 1000)
        status = tree.tick_exactly_once()
        print("tick %d @ 0 ms: %s" % (k, name_of[status]), flush=True)
        if status != bt.NodeStatus.RUNNING:
            break
    if status == bt.NodeStatus.RUNNING:
        print("result: still RUNNING after tick %d" % k, flush=True)
    else:
        print("result: %s at tick %d" % (name_of[status], k), flush=True)
    time.sleep(DEADLINE_S)
    del publisher


def reader(stream, lines):
    for line in stream:
        lines.put(line)
    lines.put(None)


def tree_names(session):
    full = session.ask("fulltree", "T")
    root = ET.fromstring(full[1])
    names = []
    for tree in root.findall("BehaviorTree"):
        path = tree.get("_fullpath")
        names.append(path if path else tree.get("ID"))
    return names


def extra(session, requests):
    for label, kind, body in requests:
        session.ask(label, kind, None if body is None else json.dumps(body).encode())


def session(args):
    plan = json.load(open(args.plan, encoding="utf-8"))
    proc = subprocess.Popen(args.command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        line = proc.stderr.readline()
        while line and "groot2: serving" not in line:
            line = proc.stderr.readline()
        if not line:
            raise SystemExit("the server ended before serving: " + proc.stdout.read())
        threading.Thread(target=lambda: proc.stderr.read(), daemon=True).start()
        lines = queue.Queue()
        threading.Thread(target=reader, args=(proc.stdout, lines), daemon=True).start()
        ctx = zmq.Context()
        sub = ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.connect("tcp://127.0.0.1:%d" % (args.port + 1))
        s = gc.Session(args.port)
        s.ask("recording start", "r", b"start")
        codes = s.ask("status before", "S")[1][2::3]
        if not all(c == 0 for c in codes):
            json.dump({"race": True}, open(args.out, "w"))
            sys.exit(3)
        s.ask("hook insert", "I", json.dumps(plan["hooks"]).encode())
        s.ask("hooks dump before", "D")
        output = []
        if plan.get("vanish"):
            s.sock.close()
            sub.close()
            gone = time.monotonic()
            result = None
            while result is None:
                item = lines.get(timeout=DEADLINE_S)
                if item is None:
                    break
                output.append(item)
                if item.startswith("result:"):
                    result = time.monotonic() - gone
            json.dump({"log": s.log, "stdout": output, "result_after_s": result},
                      open(args.out, "w"), indent=1)
            return
        notifications = []
        reached = {}
        unlocks = plan.get("unlocks", {})
        deadline = time.monotonic() + DEADLINE_S
        done = False
        while not done:
            if time.monotonic() > deadline:
                raise SystemExit("no result within %d s: %r" % (DEADLINE_S, output))
            if sub.poll(20):
                parts = sub.recv_multipart()
                notifications.append([p.hex() for p in parts])
                uid = parts[1].decode()
                if uid in unlocks:
                    n = reached.get(uid, 0)
                    reached[uid] = n + 1
                    todo = unlocks[uid][n] if n < len(unlocks[uid]) else {}
                    tag = "%s#%d" % (uid, n + 1)
                    s.ask("hooks dump held " + tag, "D")
                    compared = int(uid) in plan.get("held_status", [])
                    s.ask(("" if compared else "uncompared ") + "status held " + tag, "S")
                    extra(s, todo.get("then", []))
                    if "release" in todo:
                        label, kind, body = todo["release"]
                        extra(s, [(label + " " + tag, kind, body)])
                    else:
                        s.ask("unlock " + tag, "U", json.dumps({
                            "uid": int(uid), "position": 0,
                            "desired_status": todo.get("desired_status", ""),
                            "remove_when_done": todo.get("remove_when_done", True)}).encode())
            while True:
                try:
                    item = lines.get_nowait()
                except queue.Empty:
                    break
                if item is None:
                    raise SystemExit("the server ended without a result: %r" % output)
                output.append(item)
                if item.startswith("result:"):
                    done = True
        # Notifications published after the last unlock.
        while sub.poll(200):
            notifications.append([p.hex() for p in sub.recv_multipart()])
        s.ask("status after", "S")
        s.ask("transitions", "t")
        names = tree_names(s)
        for name in names:
            s.ask("blackboard " + name, "B", name.encode())
        s.ask("hooks dump after", "D")
        extra(s, plan.get("after", []))
        s.ask("hooks remove all", "A")
        s.ask("hooks dump empty", "D")
        json.dump({"log": s.log, "notifications": notifications, "stdout": output,
                   "reached": reached}, open(args.out, "w"), indent=1)
    finally:
        proc.kill()
        proc.wait()


def main():
    argv = sys.argv[1:]
    command = []
    if "--" in argv:
        k = argv.index("--")
        argv, command = argv[:k], argv[k + 1:]
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["serve", "session"])
    parser.add_argument("xml", nargs="?")
    parser.add_argument("script", nargs="?")
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--tick-period", type=int, default=300)
    parser.add_argument("--heartbeat", type=int, default=5000)
    parser.add_argument("--plan")
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    args.command = command
    if args.mode == "serve":
        serve(args)
    else:
        session(args)


if __name__ == "__main__":
    main()
