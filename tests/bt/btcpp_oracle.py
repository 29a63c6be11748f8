"""BehaviorTree.CPP 4.8.2 as an oracle for `chronomap bt run`: random trees, run by the real library.

Two modes, each printing one JSON object per line (a "case") on standard output:

* ``generate --seed S --trees N``: a seeded generator of random trees over every built-in
  control, decorator and leaf of BehaviorTree.CPP 4.8.2 that does not need a wall clock, with
  Script / ScriptCondition nodes, pre- and post-conditions and SubTrees with remapping; each tree
  comes with an outcome table (what every leaf returns at every tick) in the format of
  ``chronomap bt run --script``.
* ``run FILE.xml FILE.script [TREE_ID] ...``: trees given as files (regression cases, trees written
  by others), run under the same rules.

Custom leaves ``Act`` and ``Cond`` follow the outcome table; a decorator ``Pass`` passes its
child's status (a ``SimpleDecoratorNode``, what ``--stub Pass=PASS`` stands in for).

Every case is run by BehaviorTree.CPP (PyPI ``behaviortreepy`` 0.1.4, which compiles in 4.8.2):
custom leaves ``Act`` (a stateful action) and ``Cond`` (a condition) return the table's outcome
for their instance name at the current tick; the root is ticked with ``tickExactlyOnce`` until it
stops running or ``--max-ticks`` (30) ticks were done. Recorded per tick: the root's status and
every status change, in order, as BehaviorTree.CPP's own ``StdCoutLogger`` reports it (transitions
to idle and halts included; the logger prints names, which the generator makes unique); a tick
that throws ends the run with its message; at the end, the root blackboard.

A case is ``{"name", "xml", "script", "load_error", "ticks": [{"status", "transitions":
[[name, from, to], ...]}], "error": null | {"tick", "message"}, "blackboard": {key: number |
string}}``. The Rust side (tests/cli/bt_differential.rs) runs the same XML and script through
chronomap and compares. Only the standard library and behaviortreepy are used.
"""

import argparse
import json
import os
import random
import re
import sys
import tempfile

import behaviortreepy as bt

MAX_TICKS = 30
STATUS = {
    "success": bt.NodeStatus.SUCCESS,
    "failure": bt.NodeStatus.FAILURE,
    "running": bt.NodeStatus.RUNNING,
}
ANSI = re.compile(r"\x1b\[[0-9;]*m")
LOG_LINE = re.compile(r"^\[[0-9.]+\]: (\S+)\s+(\S+) -> (\S+)$")

# ---------------------------------------------------------------------------------------------
# The generator


class Generator:
    """Random trees and outcome tables from one seed (Python's Mersenne Twister)."""

    # The variables every script may use; the init script sets them all.
    VARIABLES = ("x", "y", "h", "p", "sw")

    def __init__(self, rng):
        self.rng = rng
        self.counter = 0
        self.actions = []
        self.conditions = []

    def fresh(self):
        self.counter += 1
        return "n%d" % self.counter

    def script_code(self):
        r = self.rng
        return r.choice([
            "x += 1", "x := x + 1", "y := 2", "y += x", "sw := 1", "sw := 2", "sw := 3",
            "h := h + 1", "x := 0", "p := x * 2", "y := y - 1", "x += 2; sw := x",
        ])

    def condition_code(self):
        r = self.rng
        return r.choice([
            "x < 3", "x > 1", "y == 2", "x == y", "sw == 2", "x >= 2 && y < 3", "h > 0",
            "x != 1 || y > 0",
        ])

    def attributes(self, name, extra):
        attrs = [("name", name)] + extra
        r = self.rng
        # Pre- and post-conditions on any node.
        for key, choices in (
            ("_skipIf", ["x > 2", "y == 2", "sw == 3", "h > 1"]),
            ("_failureIf", ["x == 2", "y > 2", "p > 3"]),
            ("_successIf", ["x == 3", "y == 1", "sw == 1"]),
            ("_while", ["x < 4", "y < 3", "h < 2"]),
            ("_onSuccess", ["x += 1", "p += 1", "sw := 2"]),
            ("_onFailure", ["y += 1", "p += 2", "x := 0"]),
            ("_onHalted", ["h += 1", "x += 1"]),
            ("_post", ["p += 1", "y := x"]),
        ):
            if r.random() < 0.06:
                attrs.append((key, r.choice(choices)))
        return attrs

    def leaf(self):
        r = self.rng
        name = self.fresh()
        kind = r.choices(
            ["Act", "Cond", "AlwaysSuccess", "AlwaysFailure", "Script", "ScriptCondition",
             "SetBlackboard", "WasEntryUpdated"],
            weights=[40, 20, 4, 4, 10, 8, 3, 2],
        )[0]
        extra = []
        if kind == "Act":
            self.actions.append(name)
        elif kind == "Cond":
            self.conditions.append(name)
        elif kind == "Script":
            extra = [("code", self.script_code())]
        elif kind == "ScriptCondition":
            extra = [("code", self.condition_code())]
        elif kind == "SetBlackboard":
            extra = [("output_key", r.choice(["x", "y", "sw"])), ("value", r.choice(["1", "2", "3"]))]
        elif kind == "WasEntryUpdated":
            extra = [("entry", r.choice(["x", "{x}", "y", "{sw}"]))]
        return (kind, self.attributes(name, extra), [])

    def node(self, depth, subtrees):
        r = self.rng
        if depth <= 0 or r.random() < 0.25 + 0.1 * (3 - depth):
            return self.leaf()
        category = r.choices(["control", "decorator", "subtree"], weights=[55, 40, 5 if subtrees else 0])[0]
        name = self.fresh()
        if category == "subtree":
            sub = r.choice(subtrees)
            extra = [("ID", sub)]
            mode = r.random()
            if mode < 0.4:
                extra.append(("_autoremap", "true"))
            elif mode < 0.8:
                for v in self.VARIABLES:
                    if r.random() < 0.8:
                        extra.append((v, "{%s}" % v))
            else:
                extra += [("x", "{y}"), ("y", "{x}"), ("sw", "2"), ("h", "{h}"), ("p", "{p}")]
            return ("SubTree", self.attributes(name, extra), [])
        if category == "control":
            kind = r.choices(
                ["Sequence", "Fallback", "SequenceWithMemory", "ReactiveSequence",
                 "ReactiveFallback", "AsyncSequence", "AsyncFallback", "Parallel", "ParallelAll",
                 "IfThenElse", "WhileDoElse", "Switch2", "Switch3"],
                weights=[14, 12, 10, 8, 8, 3, 3, 8, 6, 7, 7, 4, 3],
            )[0]
            extra = []
            if kind in ("IfThenElse", "WhileDoElse"):
                n = r.choice([2, 3, 3])
            elif kind == "Switch2":
                n = 3
                extra = [("variable", "{sw}"), ("case_1", "1"), ("case_2", "2")]
            elif kind == "Switch3":
                n = 4
                extra = [("variable", "{sw}"), ("case_1", "1"), ("case_2", "2"), ("case_3", "3")]
            else:
                n = r.choice([1, 2, 2, 3, 3, 4])
            if kind == "Parallel":
                extra = [("success_count", str(r.choice([-1, 1, 2, n]))),
                         ("failure_count", str(r.choice([1, 1, -1, 2])))]
            elif kind == "ParallelAll":
                extra = [("max_failures", str(r.choice([1, 1, 2, -1, n])))]
            if kind in ("Parallel", "ParallelAll") and r.random() < 0.03:
                extra = extra[1:]
            children = [self.node(depth - 1, subtrees) for _ in range(n)]
            return (kind, self.attributes(name, extra), children)
        kind = r.choices(
            ["Inverter", "ForceSuccess", "ForceFailure", "RetryUntilSuccessful", "Repeat",
             "KeepRunningUntilFailure", "RunOnce", "Precondition", "SkipUnlessUpdated",
             "LoopInt"],
            weights=[8, 6, 6, 8, 7, 5, 5, 7, 2, 2],
        )[0]
        extra = []
        if kind == "RetryUntilSuccessful":
            extra = [("num_attempts", str(r.choice([1, 2, 3, -1])))]
        elif kind == "Repeat":
            extra = [("num_cycles", str(r.choice([1, 2, 3])))]
        elif kind == "RunOnce":
            extra = [("then_skip", r.choice(["true", "false"]))]
        elif kind == "Precondition":
            extra = [("if", self.condition_code()),
                     ("else", r.choice(["FAILURE", "SUCCESS", "RUNNING", "SKIPPED"]))]
        elif kind == "SkipUnlessUpdated":
            extra = [("entry", r.choice(["x", "{y}"]))]
        elif kind == "LoopInt":
            extra = [("queue", r.choice(["1;2;3", "5", "1;2"])), ("value", "{v}"),
                     ("if_empty", r.choice(["SUCCESS", "FAILURE", "SKIPPED"]))]
        if kind in ("RetryUntilSuccessful", "Repeat", "RunOnce") and r.random() < 0.03:
            # A port left out: BehaviorTree.CPP loads the tree and throws when it ticks the node
            # (or uses the port's default). Ports it needs when it loads the tree (a
            # Precondition's `if`) are not left out: a tree refused half-built can end its
            # process (an `_onHalted` script that throws from a destructor).
            extra = []
        return (kind, self.attributes(name, extra), [self.node(depth - 1, subtrees)])

    def tree(self):
        r = self.rng
        subtrees = []
        bodies = []
        for i in range(r.choice([0, 0, 1, 2])):
            sid = "Sub%d" % (i + 1)
            bodies.append((sid, self.node(2, list(subtrees))))
            subtrees.append(sid)
        body = self.node(r.choice([2, 3, 4]), subtrees)
        if r.random() < 0.85:
            init = ("Script", [("name", self.fresh()), ("code", "x := 0; y := 0; h := 0; p := 0; sw := 1")], [])
            top = r.choice(["Sequence", "SequenceWithMemory", "ReactiveSequence"])
            main = (top, [("name", self.fresh())], [init, body])
        else:
            main = body
        trees = [("Main", main)] + bodies
        self.keep_reachable_leaves(trees)
        return trees

    def keep_reachable_leaves(self, trees):
        """Only leaves that the main tree reaches (through its SubTrees) get outcomes."""
        by_id = dict(trees)
        reached = set()
        seen = set()

        def walk(node):
            kind, attrs, children = node
            attrs = dict(attrs)
            if kind in ("Act", "Cond"):
                reached.add(attrs["name"])
            if kind == "SubTree" and attrs["ID"] not in seen:
                seen.add(attrs["ID"])
                walk(by_id[attrs["ID"]])
            for c in children:
                walk(c)

        walk(by_id["Main"])
        self.actions = [a for a in self.actions if a in reached]
        self.conditions = [c for c in self.conditions if c in reached]

    def table(self, ticks):
        """The outcome script: every leaf set at tick 1, some changed at later ticks."""
        r = self.rng
        lines = []
        current = {}
        for k in range(1, ticks + 1):
            changes = []
            for name in self.actions + self.conditions:
                if k == 1 or r.random() < 0.25:
                    choices = ["success", "failure", "running"] if name in self.actions else ["success", "failure"]
                    weights = [4, 3, 3] if name in self.actions else [1, 1]
                    o = r.choices(choices, weights=weights)[0]
                    if current.get(name) != o or k == 1:
                        changes.append((name, o))
                        current[name] = o
            if k == ticks and not changes and current:
                # The last line keeps the script as long as the run may be.
                name = sorted(current)[0]
                changes.append((name, current[name]))
            if changes:
                lines.append("tick %d: %s" % (k, ", ".join("%s=%s" % c for c in changes)))
        if not lines:
            lines.append("tick %d:" % ticks)
        return "\n".join(lines) + "\n"


def escape(value):
    return (value.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace('"', "&quot;"))


def to_xml(trees):
    def element(node, indent):
        kind, attrs, children = node
        text = " ".join('%s="%s"' % (k, escape(v)) for k, v in attrs)
        pad = "  " * indent
        if not children:
            return "%s<%s %s/>\n" % (pad, kind, text)
        inner = "".join(element(c, indent + 1) for c in children)
        return "%s<%s %s>\n%s%s</%s>\n" % (pad, kind, text, inner, pad, kind)

    out = ['<root BTCPP_format="4" main_tree_to_execute="Main">\n']
    for tid, root in trees:
        out.append('  <BehaviorTree ID="%s">\n%s  </BehaviorTree>\n' % (tid, element(root, 2)))
    out.append('  <TreeNodesModel>\n    <Action ID="Act"/>\n    <Condition ID="Cond"/>\n  </TreeNodesModel>\n')
    out.append("</root>\n")
    return "".join(out)


# ---------------------------------------------------------------------------------------------
# Running a case through BehaviorTree.CPP


def parse_script(text):
    """{tick: [(name, outcome)]} from the `chronomap bt run --script` format."""
    table = {}
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        head, _, rest = line.partition(":")
        tick = int(head.split()[1].split("@")[0])
        pairs = []
        for pair in rest.split(","):
            pair = pair.strip()
            if pair:
                name, _, outcome = pair.partition("=")
                pairs.append((name.strip(), outcome.strip().lower()))
        table[tick] = pairs
    return table


class Capture:
    """The process's standard output (file descriptor 1), where BehaviorTree.CPP's
    StdCoutLogger prints, redirected to a temporary file that is read after every tick."""

    def __init__(self):
        sys.stdout.flush()
        self.file = tempfile.TemporaryFile()
        self.saved = os.dup(1)
        os.dup2(self.file.fileno(), 1)
        self.out = os.fdopen(os.dup(self.saved), "w")

    def take(self):
        self.file.seek(0)
        data = self.file.read()
        self.file.seek(0)
        self.file.truncate()
        return data.decode("utf-8", "replace")


def transitions_of(text):
    result = []
    for line in text.splitlines():
        m = LOG_LINE.match(ANSI.sub("", line).strip())
        if m:
            result.append([m.group(1), m.group(2), m.group(3)])
    return result


def blackboard_of(tree):
    values = {}
    board = tree.root_blackboard()
    for key in sorted(board.get_keys()):
        try:
            values[key] = board.get_double(key)
            continue
        except Exception:
            pass
        try:
            values[key] = board.get_string(key)
        except Exception as e:
            # BehaviorTree.CPP creates an entry, without a value, for every port remapped to
            # the blackboard when it loads the tree: to a script such an entry is as absent
            # as one never created, so it is left out.
            if "hasn't been initialized" not in str(e):
                values[key] = "<unreadable: %s>" % e
    return values


class Oracle:
    def __init__(self, capture, max_ticks):
        self.capture = capture
        self.max_ticks = max_ticks
        self.outcomes = {}
        # Every tree is kept until the process ends: BehaviorTree.CPP's Tree destructor halts a
        # running tree, and an `_onHalted` script that throws there terminates the process.
        self.kept = []

    def factory(self):
        factory = bt.BehaviorTreeFactory()
        outcomes = self.outcomes

        def outcome(node):
            name = node.name()
            if name not in outcomes:
                raise RuntimeError('ticked, but the script has given no outcome for "%s" yet' % name)
            return STATUS[outcomes[name]]

        factory.register_simple_stateful_action("Act", outcome, outcome)
        factory.register_simple_condition("Cond", outcome)
        # A SimpleDecoratorNode passing its child's status: what `chronomap bt run --stub
        # Pass=PASS` stands in for a declared decorator with.
        factory.register_simple_decorator("Pass", lambda status, node: status)
        return factory

    def run(self, name, xml, script, tree_id=None):
        case = {"name": name, "xml": xml, "script": script, "load_error": None, "ticks": [],
                "error": None, "blackboard": {}}
        self.outcomes.clear()
        table = parse_script(script)
        factory = self.factory()
        try:
            if tree_id is None:
                tree = factory.create_tree_from_text(xml)
            else:
                factory.register_behavior_tree_from_text(xml)
                tree = factory.create_tree(tree_id)
        except Exception as e:
            case["load_error"] = str(e)
            self.capture.take()
            return case
        self.kept.append(tree)
        logger = bt.StdCoutLogger(tree)
        self.kept.append(logger)
        self.capture.take()
        for k in range(1, self.max_ticks + 1):
            for leaf, o in table.get(k, []):
                self.outcomes[leaf] = o
            try:
                status = tree.tick_exactly_once()
            except Exception as e:
                logger.flush()
                case["ticks"].append({"status": None, "transitions": transitions_of(self.capture.take())})
                case["error"] = {"tick": k, "message": str(e)}
                break
            logger.flush()
            case["ticks"].append({"status": status.name, "transitions": transitions_of(self.capture.take())})
            if status != bt.NodeStatus.RUNNING:
                break
        logger.set_enabled(False)
        case["blackboard"] = blackboard_of(tree)
        return case


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="mode", required=True)
    g = sub.add_parser("generate")
    g.add_argument("--seed", type=int, default=1)
    g.add_argument("--trees", type=int, default=1000)
    g.add_argument("--first", type=int, default=0, help="index of the first tree to print")
    r = sub.add_parser("run")
    r.add_argument("files", nargs="+", help="XML file, script file[, tree ID], ...")
    for p in (g, r):
        p.add_argument("--max-ticks", type=int, default=MAX_TICKS)
    args = parser.parse_args()

    capture = Capture()
    oracle = Oracle(capture, args.max_ticks)
    out = capture.out
    if args.mode == "generate":
        for i in range(args.trees):
            rng = random.Random("%d/%d" % (args.seed, i))
            gen = Generator(rng)
            trees = gen.tree()
            xml = to_xml(trees)
            script = gen.table(args.max_ticks)
            if i < args.first:
                continue
            case = oracle.run("seed%d-tree%d" % (args.seed, i), xml, script)
            out.write(json.dumps(case) + "\n")
    else:
        files = list(args.files)
        while files:
            xml_path, script_path = files[0], files[1]
            files = files[2:]
            tree_id = None
            if files and not os.path.exists(files[0]):
                tree_id = files.pop(0)
            with open(xml_path) as f:
                xml = f.read()
            with open(script_path) as f:
                script = f.read()
            case = oracle.run(os.path.basename(xml_path), xml, script, tree_id)
            out.write(json.dumps(case) + "\n")
    out.flush()
    # Without destructors (see Oracle.kept).
    os._exit(0)


if __name__ == "__main__":
    main()
