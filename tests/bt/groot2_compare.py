"""Groot2 protocol sessions against BehaviorTree.CPP's Groot2Publisher and `chronomap bt run
--groot2`, recorded for tests/cli/bt_groot2.rs.

    groot2_compare.py btcpp XML SCRIPT --port P --out OUT.json
        runs XML with the real BehaviorTree.CPP (behaviortreepy): every leaf that is not a
        built-in node follows SCRIPT (chronomap's `bt run --script` format: actions are
        StatefulActionNodes, conditions SimpleConditionNodes), a Groot2Publisher on port P.
    groot2_compare.py chronomap --port P --out OUT.json -- CMD...
        starts CMD (a `chronomap bt run ... --groot2 P --linger S` command), waits for its
        "serving" note, and runs the same session.

The session (same for both): TOGGLE_RECORDING start and a STATUS before the first tick (all
idle, else the run started too early: exit status 3), the ticks, then FULLTREE, STATUS,
BLACKBOARD (every tree instance, and a name that is none), GET_TRANSITIONS, HOOKS_DUMP, a
few hooks inserted, dumped and removed, TOGGLE_RECORDING stop, and malformed requests. OUT.json
lists every request and reply as hex. Replies are compared by the Rust test.
"""

import argparse
import json
import re
import struct
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import zmq

TIMEOUT_MS = 5000


def request(sock, parts):
    sock.send_multipart(parts)
    if not sock.poll(TIMEOUT_MS):
        raise SystemExit("no reply within %d ms to %r" % (TIMEOUT_MS, parts[:1]))
    return sock.recv_multipart()


class Session:
    def __init__(self, port):
        self.ctx = zmq.Context()
        self.sock = self.ctx.socket(zmq.REQ)
        self.sock.setsockopt(zmq.LINGER, 0)
        self.sock.connect("tcp://127.0.0.1:%d" % port)
        self.log = []
        self.next_id = 1000

    def ask(self, label, kind, body=None, raw=None):
        if raw is None:
            self.next_id += 1
            parts = [struct.pack("<BBI", 2, ord(kind), self.next_id)]
            if body is not None:
                parts.append(body)
        else:
            parts = raw
        reply = request(self.sock, parts)
        self.log.append({"label": label, "request": [p.hex() for p in parts],
                         "reply": [p.hex() for p in reply]})
        return reply

    def before_ticks(self):
        self.ask("recording start", "r", b"start")
        reply = self.ask("status before", "S")
        codes = reply[1][2::3]
        return all(c == 0 for c in codes)

    def after_ticks(self):
        full = self.ask("fulltree", "T")
        root = ET.fromstring(full[1])
        names = []
        for bt in root.findall("BehaviorTree"):
            path = bt.get("_fullpath")
            names.append(path if path else bt.get("ID"))
        self.ask("status", "S")
        self.ask("blackboard all", "B", ";".join(names).encode())
        for name in names:
            self.ask("blackboard " + name, "B", name.encode())
        self.ask("blackboard none", "B", b"NoSuchTree")
        self.ask("transitions", "t")
        self.ask("transitions again", "t")
        self.ask("hooks dump empty", "D")
        hook = {"enabled": True, "uid": 2, "mode": 1, "once": False,
                "desired_status": "SUCCESS", "position": 0}
        hooks = [dict(hook, uid=u) for u in (3, 1, 2)]
        self.ask("hook insert", "I", json.dumps(hooks).encode())
        self.ask("hook insert unknown node", "I", json.dumps(dict(hook, uid=4000)).encode())
        self.ask("hooks dump", "D")
        self.ask("hook remove", "R", json.dumps({"uid": 1, "position": 0}).encode())
        self.ask("hook remove missing", "R", json.dumps({"uid": 1, "position": 0}).encode())
        self.ask("hook remove post", "R", json.dumps({"uid": 2, "position": 1}).encode())
        self.ask("unlock missing", "U", json.dumps(
            {"uid": 3000, "desired_status": "SUCCESS", "position": 0,
             "remove_when_done": True}).encode())
        self.ask("hooks disable", "X")
        self.ask("hooks dump disabled", "D")
        self.ask("hooks remove all", "A")
        self.ask("hooks dump after", "D")
        self.ask("recording stop", "r", b"stop")
        self.ask("recording other", "r", b"pause")
        # Malformed requests.
        self.ask("short header", None, raw=[b"\x02S\x01"])
        self.ask("long header", None, raw=[b"\x02S\x01\x00\x00\x00\x00"])
        self.ask("unknown type", None, raw=[struct.pack("<BBI", 2, ord("Z"), 77)])
        self.ask("breakpoint reached as request", None, raw=[struct.pack("<BBI", 2, ord("N"), 78)])
        self.ask("wrong protocol", None, raw=[struct.pack("<BBI", 7, ord("S"), 79)])
        self.ask("blackboard one part", None, raw=[struct.pack("<BBI", 2, ord("B"), 80)])
        self.ask("blackboard three parts", None,
                 raw=[struct.pack("<BBI", 2, ord("B"), 81), names[0].encode(), b"x"])
        self.ask("status two parts", None, raw=[struct.pack("<BBI", 2, ord("S"), 82), b"x"])
        self.ask("status after", "S")


def read_script(path):
    """chronomap's script: `tick N [@ MS]: name=outcome, ...` lines."""
    ticks = {}
    for line in open(path, encoding="utf-8"):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        m = re.match(r"tick\s+(\d+)\s*(?:@\s*\d+)?\s*:(.*)$", line)
        if not m:
            raise SystemExit("bad script line: " + line)
        pairs = {}
        for item in m.group(2).split(","):
            item = item.strip()
            if item:
                name, outcome = item.split("=")
                pairs[name.strip()] = outcome.strip().upper()
        ticks[int(m.group(1))] = pairs
    return ticks


def leaves(xml_text, bt):
    """Leaf IDs of the document that BehaviorTree.CPP does not know: ID -> 'Action' or
    'Condition'."""
    root = ET.fromstring(xml_text)
    known = set()
    factory = bt.BehaviorTreeFactory()
    del factory
    builtin = {
        "AlwaysFailure", "AlwaysSuccess", "Script", "ScriptCondition", "SetBlackboard", "Sleep",
        "UnsetBlackboard", "WasEntryUpdated", "SubTree",
    }
    models = {}
    for m in root.iter("TreeNodesModel"):
        for e in m:
            models[e.get("ID")] = e.tag
    found = {}
    for tree in root.findall("BehaviorTree"):
        for e in tree.iter():
            if e is tree or len(list(e)) > 0:
                continue
            tag, node_id = e.tag, e.get("ID")
            if tag in ("Action", "Condition"):
                found[node_id] = tag
            elif tag not in builtin and tag not in known:
                found[tag] = "Condition" if models.get(tag) == "Condition" else "Action"
    return found


def run_btcpp(args):
    import behaviortreepy as bt

    xml_text = open(args.xml, encoding="utf-8").read()
    script = read_script(args.script)
    outcomes = {}
    status_of = {"SUCCESS": bt.NodeStatus.SUCCESS, "FAILURE": bt.NodeStatus.FAILURE,
                 "RUNNING": bt.NodeStatus.RUNNING}

    def outcome(node):
        return status_of[outcomes[node.name()]]

    factory = bt.BehaviorTreeFactory()
    for node_id, kind in sorted(leaves(xml_text, bt).items()):
        if kind == "Condition":
            factory.register_simple_condition(node_id, outcome)
        else:
            factory.register_simple_stateful_action(node_id, outcome, outcome, None)
    tree = factory.create_tree_from_text(xml_text)
    publisher = bt.Groot2Publisher(tree, args.port)
    session = Session(args.port)
    if not session.before_ticks():
        raise SystemExit("BehaviorTree.CPP's tree is not idle before its first tick")
    last = max(script)
    ticked = 0
    for k in range(1, last + 1):
        outcomes.update(script.get(k, {}))
        status = tree.tick_exactly_once()
        ticked += 1
        if status != bt.NodeStatus.RUNNING:
            break
    session.after_ticks()
    json.dump({"ticks": ticked, "log": session.log}, open(args.out, "w"), indent=1)
    del publisher


def run_chronomap(args):
    proc = subprocess.Popen(args.command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        line = proc.stderr.readline()
        while line and "groot2: serving" not in line:
            line = proc.stderr.readline()
        if not line:
            raise SystemExit("chronomap ended before serving: " + proc.stdout.read())
        session = Session(args.port)
        idle = session.before_ticks()
        if not idle:
            json.dump({"race": True}, open(args.out, "w"))
            sys.exit(3)
        output = []
        for line in proc.stdout:
            output.append(line)
            if line.startswith("result:"):
                break
        ticks = sum(1 for line in output if line.startswith("tick "))
        session.after_ticks()
        json.dump({"ticks": ticks, "log": session.log, "stdout": output}, open(args.out, "w"),
                  indent=1)
    finally:
        proc.kill()
        proc.wait()


def zmtp_greeting():
    """A ZMTP 3.0 greeting (NULL mechanism, client) and a READY command for a REQ socket."""
    greeting = b"\xff" + b"\x00" * 8 + b"\x7f" + bytes([3, 0]) + b"NULL" + b"\x00" * 16
    greeting += b"\x00" + b"\x00" * 31
    body = b"\x05READY" + b"\x0bSocket-Type" + struct.pack(">I", 3) + b"REQ"
    return greeting + bytes([0x04, len(body)]) + body


def run_hostile(args):
    """Bad input on the wire while chronomap ticks; what each client got, as JSON."""
    import socket
    out = {}
    silent = socket.create_connection(("127.0.0.1", args.port))  # connects, never sends
    garbage = socket.create_connection(("127.0.0.1", args.port))
    garbage.sendall(b"GET / HTTP/1.1\r\n\r\n" * 10)
    big = socket.create_connection(("127.0.0.1", args.port))
    big.settimeout(10)
    big.sendall(zmtp_greeting())
    big.sendall(b"\x01\x00")  # the REQ delimiter frame, more to follow
    big.sendall(b"\x02" + struct.pack(">Q", 100_000_000))  # a 100 MB frame declared
    sent = 0
    try:
        for _ in range(64):
            big.sendall(b"\x00" * 65536)
            sent += 65536
        out["big_closed"] = big.recv(1 << 16) == b""
    except OSError:
        out["big_closed"] = True
    out["big_sent"] = sent
    ctx = zmq.Context()
    mute = ctx.socket(zmq.REQ)  # asks and never reads the reply
    mute.setsockopt(zmq.LINGER, 0)
    mute.connect("tcp://127.0.0.1:%d" % args.port)
    mute.send(struct.pack("<BBI", 2, ord("T"), 5))
    huge = ctx.socket(zmq.REQ)
    huge.setsockopt(zmq.LINGER, 0)
    huge.connect("tcp://127.0.0.1:%d" % args.port)
    huge.send_multipart([struct.pack("<BBI", 2, ord("B"), 6), b"x" * (2 << 20)])
    out["huge_answered"] = bool(huge.poll(2000))
    many = Session(args.port)
    reply = many.ask("many parts", None, raw=[struct.pack("<BBI", 2, ord("S"), 7)] + [b"p"] * 19)
    out["many_parts"] = [p.decode("latin-1") for p in reply]
    good = Session(args.port)
    reply = good.ask("status", "S")
    out["status_header"] = reply[0][:6].hex()
    out["status_len"] = len(reply[1])
    reply = good.ask("fulltree", "T")
    out["fulltree_starts"] = reply[1][:23].decode()
    for s in (silent, garbage, big):
        s.close()
    json.dump(out, open(args.out, "w"), indent=1)


def main():
    argv = sys.argv[1:]
    command = []
    if "--" in argv:
        k = argv.index("--")
        argv, command = argv[:k], argv[k + 1:]
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["btcpp", "chronomap", "hostile"])
    parser.add_argument("xml", nargs="?")
    parser.add_argument("script", nargs="?")
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    args.command = command
    if args.mode == "btcpp":
        run_btcpp(args)
    elif args.mode == "hostile":
        run_hostile(args)
    else:
        run_chronomap(args)


if __name__ == "__main__":
    main()
