"""The repository's bundled behavior trees run by BehaviorTree.CPP 4.8.2 under stubs that
`chronomap bt run` gives identically.

    python tests/bt/btcpp_trees.py --root DIR [--models FILE] [--seed S] [--scripts N] FILE...

For every tree file (a path under ``--root``) this prints JSON lines on standard output: one
"case" per tree of the file and outcome script, in the format of ``btcpp_oracle.py`` (``name``,
``xml``, ``script``, ``load_error``, ``ticks``, ``error``, ``blackboard``), with what
chronomap needs to run exactly the same input: ``file`` (the tree file, relative to the root),
``tree`` (``null``: the file's own choice, ``main_tree_to_execute`` or its only tree; else the
tree ID given to ``create_tree`` / ``--tree``), ``files`` (every file of its ``<include>``
closure, relative to the root, as rewritten below), ``stubs`` (``--stub ID=PASS`` for its
custom decorators), ``nodes`` (``--nodes`` files, relative to the root) and ``rewrites``
(what was changed). A file that cannot be compared gives one line ``{"file", "skipped":
reason}``.

Custom nodes are the IDs a tree uses that BehaviorTree.CPP 4.8.2 does not build in
(``BehaviorTreeFactory``'s constructor, ``BUILTIN`` below). Their category comes from the
explicit form (``<Action ID="X"/>``), from a ``<TreeNodesModel>`` of the include closure, from a
``--models`` file in the tree file's directory (Nav2's ``nav2_tree_nodes.xml``, as in a Nav2
installation), or, for a node that nothing declares, from its children: none, an action; one, a
decorator (a tag that names a tree is left alone: BehaviorTree.CPP 4 needs
``<SubTree ID="..."/>``). They are registered in BehaviorTree.CPP as ``btcpp_oracle``'s
``Act``, ``Cond`` and ``Pass`` are: actions as stateful actions and conditions as conditions
returning the outcome script's outcome for their instance name (``name``, else the ID),
decorators as simple decorators passing their child's status (``--stub ID=PASS``). A tree that
uses a custom control is skipped: the Python binding cannot register controls.

The binding cannot declare ports either, so every file of the closure is rewritten, identically
for both sides: the ports (attributes BehaviorTree.CPP reads as ports: a letter first, not
``name``/``ID``) of custom node instances are removed, and so are the ``input_port`` /
``output_port`` / ``inout_port`` elements of their models (with their lines); undeclared custom
nodes are declared in the ``<TreeNodesModel>`` of the file that uses them. Nothing else changes
(comments, other attributes, pre- and post-conditions stay). ``custom`` in a case says where
each custom node's category came from.

The outcome scripts come from ``btcpp_oracle.Generator.table`` over the custom leaves the tree
reaches, seeded by ``--seed``, the file, the tree and the script's number; a tree without custom
leaves gets one. BehaviorTree.CPP loads the rewritten main file from a temporary copy of the
closure with ``create_tree_from_file`` (a tree chosen by ID: ``register_behavior_tree_from_text``
in the file's directory and ``create_tree``, see ``FileFactory``), so that includes resolve
relative to each including file, as ``chronomap bt run`` resolves them. Its ticks come
microseconds apart, so no ``Sleep``, ``Timeout`` or ``Delay`` of the bundled trees expires
(chronomap runs them with ``--tick-ms 0``); a run that took longer than the shortest literal
duration of such a node is repeated, and marked ``"clock"`` if it keeps doing so. A tree with a
``Sleep`` is run several times and the record most runs give is kept (``"race"`` says how many
differed): see ``settled_run``.
"""

import argparse
import json
import os
import random
import re
import shutil
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import btcpp_oracle  # noqa: E402

bt = btcpp_oracle.bt

# Every node ID that BehaviorTree.CPP 4.8.2 registers in BehaviorTreeFactory's constructor
# (src/bt_factory.cpp; SequenceStar only with USE_BTCPP3_OLD_NAMES, which the binding lacks).
BUILTIN = frozenset("""
    Fallback AsyncFallback Sequence AsyncSequence SequenceWithMemory Parallel ParallelAll
    ReactiveSequence ReactiveFallback IfThenElse WhileDoElse Inverter RetryUntilSuccessful
    KeepRunningUntilFailure Repeat Timeout Delay RunOnce ForceSuccess ForceFailure
    AlwaysSuccess AlwaysFailure Script ScriptCondition SetBlackboard Sleep UnsetBlackboard
    SubTree Precondition Switch2 Switch3 Switch4 Switch5 Switch6 LoopInt LoopBool LoopDouble
    LoopString WasEntryUpdated SkipUnlessUpdated WaitValueUpdate
""".split())
EXPLICIT = ("Action", "Condition", "Decorator", "Control")
PORT_TAGS = ("input_port", "output_port", "inout_port")
# Reserved attributes (BT::IsReservedAttribute): never ports.
RESERVED = frozenset(["name", "ID", "_autoremap", "_failureIf", "_successIf", "_skipIf",
                      "_while", "_onHalted", "_onFailure", "_onSuccess", "_post"])
# Nodes that wait on BehaviorTree.CPP's clock, and the port giving the duration.
CLOCK = {"Sleep": "msec", "Timeout": "msec", "Delay": "delay_msec"}

TOKEN = re.compile(
    r"<!--.*?-->|<!\[CDATA\[.*?\]\]>|<\?.*?\?>|<!DOCTYPE[^>]*>|</[^>]*>"
    r"|<([A-Za-z_:][\w.:-]*)((?:\s+[^\s=/>]+\s*=\s*(?:\"[^\"]*\"|'[^']*'))*)\s*(/?)>",
    re.S)
ATTR = re.compile(r"\s+([^\s=/>]+)\s*=\s*(?:\"[^\"]*\"|'[^']*')")


def is_port(attr):
    """Whether BehaviorTree.CPP reads an attribute as a port (BT::IsAllowedPortName)."""
    return bool(attr) and attr[0].isalpha() and attr not in RESERVED


class Source:
    """One XML file: its text, its elements (ElementTree) and each element's start tag."""

    def __init__(self, rel, text):
        self.rel = rel
        self.text = text
        self.root = None
        self.tags = {}  # element -> (start, end, attribute spans {name: (start, end)}, closed)
        try:
            self.root = ET.fromstring(text.encode("utf-8"))
        except (ET.ParseError, ValueError):
            return  # BehaviorTree.CPP and chronomap get the text as it is and refuse it
        starts = []
        for m in TOKEN.finditer(text):
            if m.group(1) is None:
                continue
            spans = {}
            base = m.start(2)
            for a in ATTR.finditer(m.group(2) or ""):
                spans[a.group(1)] = (base + a.start(), base + a.end())
            starts.append((m.group(1), m.start(), m.end(), spans, m.group(3) == "/"))
        elements = list(self.root.iter())
        if [s[0] for s in starts] != [e.tag for e in elements]:
            raise SystemExit("%s: cannot match the start tags of the text to its elements" % rel)
        for e, (_, start, end, spans, closed) in zip(elements, starts):
            self.tags[e] = (start, end, spans, closed)

    def trees(self):
        if self.root is None or self.root.tag != "root":
            return []
        return [t for t in self.root if t.tag == "BehaviorTree"]

    def models(self):
        if self.root is None:
            return []
        return [m for t in self.root if t.tag == "TreeNodesModel" for m in t]


def node_id(e):
    """(ID, explicit category or None) of an element of a tree body."""
    if e.tag in EXPLICIT:
        return e.get("ID", ""), e.tag
    return e.tag, None


def body_nodes(tree):
    """Every element of a <BehaviorTree> body, depth first."""
    for child in tree:
        yield from child.iter()


class Closure:
    """A tree file with every file its <include>s reach, relative to the including file."""

    def __init__(self, root_dir, rel):
        self.root_dir = root_dir
        self.sources = {}  # rel -> Source
        self.problems = []
        self.add(rel)
        self.main = self.sources[rel]

    def add(self, rel):
        if rel in self.sources:
            return
        path = os.path.join(self.root_dir, rel)
        if not os.path.isfile(path):
            return  # both sides refuse a missing include
        with open(path, encoding="utf-8") as f:
            source = Source(rel, f.read())
        self.sources[rel] = source
        if source.root is None:
            return
        for inc in source.root.findall("include"):
            target = inc.get("path")
            if target is None or inc.get("ros_pkg") is not None or os.path.isabs(target):
                continue
            joined = os.path.normpath(os.path.join(os.path.dirname(rel), target))
            if joined.startswith(".."):
                self.problems.append("%s includes %s, outside the tree files" % (rel, target))
                continue
            self.add(joined.replace(os.sep, "/"))


class Custom:
    """The custom nodes of a closure and their categories."""

    def __init__(self, closure, external):
        self.category = {}  # ID -> Action | Condition | Decorator | Control
        self.declared_by = {}  # ID -> where the category comes from
        self.undeclared = {}  # ID -> rel of the first file using it
        self.used = {}  # ID -> first rel using it
        self.tree_ids = set()
        sources = closure.sources.values()
        for s in sources:
            for t in s.trees():
                self.tree_ids.add(t.get("ID"))
        children = {}
        for s in sources:
            for t in s.trees():
                for e in body_nodes(t):
                    nid, explicit = node_id(e)
                    if nid in BUILTIN or e.tag == "SubTree" or not nid:
                        continue
                    self.used.setdefault(nid, s.rel)
                    children.setdefault(nid, len(list(e)))
                    if explicit and nid not in self.category:
                        self.category[nid] = explicit
                        self.declared_by[nid] = "explicit form in %s" % s.rel
        for s in sources:
            for m in s.models():
                nid = m.get("ID")
                if m.tag in EXPLICIT and nid and nid not in BUILTIN and nid not in self.category:
                    self.category[nid] = m.tag
                    self.declared_by[nid] = "<TreeNodesModel> of %s" % s.rel
        for nid in self.used:
            if nid not in self.category and nid in external:
                self.category[nid] = external[nid][0]
                self.declared_by[nid] = external[nid][1]
        for nid, rel in self.used.items():
            if nid in self.category or nid in self.tree_ids:
                continue
            n = children[nid]
            if n <= 1:
                self.category[nid] = "Action" if n == 0 else "Decorator"
                self.declared_by[nid] = "undeclared in %s, a %s by its children" % (
                    rel, "leaf" if n == 0 else "decorator")
                self.undeclared[nid] = rel

    def controls(self):
        return sorted(i for i in self.used if self.category.get(i) == "Control")

    def registered(self):
        """The custom nodes the trees use, but controls: those registered in
        BehaviorTree.CPP and rewritten."""
        return {i: c for i, c in self.category.items() if c != "Control" and i in self.used}


def rewrite(source, custom):
    """The text of `source` with the ports of custom nodes removed and undeclared custom nodes
    declared; the list of changes."""
    if source.root is None:
        return source.text, []
    registered = custom.registered()
    edits = []
    changes = []

    def line(pos):
        return source.text.count("\n", 0, pos) + 1

    for t in source.trees():
        for e in body_nodes(t):
            nid, _ = node_id(e)
            if nid not in registered or e.tag == "SubTree":
                continue
            start, _, spans, _ = source.tags[e]
            for attr, span in spans.items():
                if is_port(attr):
                    edits.append((span[0], span[1], ""))
                    changes.append("%s:%d: port %s of %s removed"
                                   % (source.rel, line(start), attr, nid))
    model_root = None
    for t in source.root:
        if t.tag == "TreeNodesModel" and model_root is None:
            model_root = t
    for m in source.models():
        if m.tag not in EXPLICIT or m.get("ID") not in registered:
            continue
        for p in m:
            if p.tag not in PORT_TAGS:
                continue
            start, end, _, closed = source.tags[p]
            if not closed:
                close = re.compile(r"</%s\s*>" % re.escape(p.tag)).search(source.text, end)
                end = close.end()
            # The whole line, when the element is alone on it.
            before = source.text.rfind("\n", 0, start)
            if before >= 0 and source.text[before + 1:start].strip() == "":
                start = before
            edits.append((start, end, ""))
            changes.append("%s:%d: model port %s of %s removed" % (
                source.rel, line(start + 1), p.get("name"), m.get("ID")))
    new = sorted(i for i, rel in custom.undeclared.items() if rel == source.rel)
    if new:
        decl = "".join('    <%s ID="%s"/>\n' % (custom.category[i], i) for i in new)
        if model_root is not None:
            start, end, _, closed = source.tags[model_root]
            if closed:
                edits.append((start, end, "<TreeNodesModel>\n%s  </TreeNodesModel>" % decl))
            else:
                close = re.compile(r"</TreeNodesModel\s*>").search(source.text, end)
                edits.append((close.start(), close.start(), decl + "  "))
        else:
            close = source.text.rfind("</root")
            edits.append((close, close, "  <TreeNodesModel>\n%s  </TreeNodesModel>\n" % decl))
        changes += ["%s: %s declared as an %s" % (source.rel, i, custom.category[i]) for i in new]
    text = source.text
    for start, end, replacement in sorted(edits, reverse=True):
        text = text[:start] + replacement + text[end:]
    return text, changes


def reachable_leaves(closure, custom, tree_id):
    """(actions, conditions): instance names of the custom leaves that tree `tree_id` reaches
    through its SubTrees."""
    by_id = {}
    for s in closure.sources.values():
        for t in s.trees():
            by_id.setdefault(t.get("ID"), t)
    actions, conditions = set(), set()
    seen = set()

    def walk(tid):
        if tid in seen or tid not in by_id:
            return
        seen.add(tid)
        for e in body_nodes(by_id[tid]):
            if e.tag == "SubTree":
                walk(e.get("ID"))
                continue
            nid, _ = node_id(e)
            cat = custom.category.get(nid)
            name = e.get("name") or nid
            if cat == "Action":
                actions.add(name)
            elif cat == "Condition":
                conditions.add(name)

    walk(tree_id)
    # A name both kinds use follows a condition's outcomes (never running).
    return sorted(actions - conditions), sorted(conditions)


def shortest_clock(closure):
    """The shortest literal duration (ms) of a Sleep, Timeout or Delay in the closure."""
    found = []
    for s in closure.sources.values():
        for t in s.trees():
            for e in body_nodes(t):
                nid, _ = node_id(e)
                if nid in CLOCK:
                    try:
                        found.append(int(e.get(CLOCK[nid], "")))
                    except ValueError:
                        pass
    return min(found) if found else None


class FileFactory:
    """A BehaviorTreeFactory that creates the tree from the file `path` where
    `btcpp_oracle.Oracle.run` creates it from text, so that includes resolve relative to the
    file. (A tree chosen by ID is registered from the text: the binding's
    `register_behavior_tree_from_file` takes no Python path. It is done in the file's
    directory, where BehaviorTree.CPP then resolves includes: its XMLParser starts from the
    working directory.)"""

    def __init__(self, factory, path):
        self.factory = factory
        self.path = path

    def create_tree_from_text(self, _xml):
        return self.factory.create_tree_from_file(self.path)

    def __getattr__(self, name):
        return getattr(self.factory, name)


class TreeOracle(btcpp_oracle.Oracle):
    """btcpp_oracle's Oracle with a file's custom nodes registered as its Act, Cond and Pass."""

    def __init__(self, capture, max_ticks):
        super().__init__(capture, max_ticks)
        self.registered = {}
        self.path = None

    def factory(self):
        os.chdir(os.path.dirname(self.path))
        factory = bt.BehaviorTreeFactory()
        outcomes = self.outcomes

        def outcome(node):
            name = node.name()
            if name not in outcomes:
                raise RuntimeError(
                    'ticked, but the script has given no outcome for "%s" yet' % name)
            return btcpp_oracle.STATUS[outcomes[name]]

        for nid, category in sorted(self.registered.items()):
            if category == "Action":
                factory.register_simple_stateful_action(nid, outcome, outcome)
            elif category == "Condition":
                factory.register_simple_condition(nid, outcome)
            elif category == "Decorator":
                factory.register_simple_decorator(nid, lambda status, node: status)
        return FileFactory(factory, self.path)


def record(case):
    """What the comparison reads of a case."""
    return json.dumps([case[k] for k in ("load_error", "ticks", "error", "blackboard")])


def settled_run(oracle, name, xml, script, tree_id, clock, racy):
    """`oracle.run`, repeated where BehaviorTree.CPP's timers may change the record.

    A run that took longer than `clock` ms (the shortest Sleep/Timeout/Delay) is run again,
    and marked "clock" after three such runs. Where the tree has a `Sleep` (`racy`), the case
    is run three times, and up to seven until one record has four: BehaviorTree.CPP 4.8.2's
    Sleep, halted and restarted, sometimes ends at once, as the halted timer's callback runs
    later on the timer thread and clears the restarted wait. The record most runs gave is
    kept, with "race" saying how many runs differed."""
    records, slow = [], 0
    while True:
        started = time.monotonic()
        case = oracle.run(name, xml, script, tree_id)
        took = (time.monotonic() - started) * 1000
        if clock is not None and took >= clock:
            slow += 1
            if slow < 3:
                continue
            case["clock"] = ("BehaviorTree.CPP took %.0f ms, longer than its shortest "
                             "Sleep/Timeout/Delay (%d ms), three times" % (took, clock))
            return case
        records.append(case)
        if not racy:
            return case
        keys = [record(r) for r in records]
        best = max(keys, key=keys.count)
        if (len(records) == 3 and keys.count(best) == 3) or keys.count(best) == 4 \
                or len(records) == 7:
            chosen = records[keys.index(best)]
            if keys.count(best) < len(records):
                chosen["race"] = "%d of %d runs of BehaviorTree.CPP gave other records" % (
                    len(records) - keys.count(best), len(records))
            return chosen


def external_models(root_dir, models, rel):
    """{ID: (category, where)} of the --models files in the directory of `rel`."""
    out = {}
    for m in models:
        if os.path.dirname(m) != os.path.dirname(rel):
            continue
        with open(os.path.join(root_dir, m), encoding="utf-8") as f:
            source = Source(m, f.read())
        for e in source.models():
            if e.tag in EXPLICIT and e.get("ID") and e.get("ID") not in BUILTIN:
                out.setdefault(e.get("ID"), (e.tag, "<TreeNodesModel> of %s" % m))
    return out


def cases_of_file(oracle, root_dir, rel, models, seed, scripts, max_ticks, scratch):
    closure = Closure(root_dir, rel)
    custom = Custom(closure, external_models(root_dir, models, rel))
    controls = custom.controls()
    if controls:
        where = sorted({custom.declared_by[c] for c in controls})
        return [{"file": rel, "skipped": "uses custom controls %s (%s): BehaviorTree.CPP's Python "
                 "binding cannot register controls" % (", ".join(controls), "; ".join(where))}]
    if closure.problems:
        return [{"file": rel, "skipped": "; ".join(closure.problems)}]
    files, rewrites = {}, []
    for r, source in sorted(closure.sources.items()):
        files[r], changes = rewrite(source, custom)
        rewrites += changes
    # The models files that declare nodes of this closure, rewritten as the tree files are.
    nodes = []
    for m in models:
        if any(custom.declared_by.get(i, "").endswith("of %s" % m) for i in custom.used):
            with open(os.path.join(root_dir, m), encoding="utf-8") as f:
                files[m], changes = rewrite(Source(m, f.read()), custom)
            rewrites += changes
            nodes.append(m)
    work = tempfile.mkdtemp(dir=scratch)
    for r, text in files.items():
        path = os.path.join(work, r)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
    oracle.path = os.path.join(work, rel)
    oracle.registered = custom.registered()
    stubs = sorted("%s=PASS" % i for i, c in custom.registered().items() if c == "Decorator")

    main = closure.main
    default = main.root.get("main_tree_to_execute") if main.root is not None else None
    all_trees = [t.get("ID") for s in closure.sources.values() for t in s.trees()]
    if default is None and len(all_trees) == 1:
        default = all_trees[0]
    choices = [None] + [t.get("ID") for t in main.trees() if t.get("ID") != default]
    clock = shortest_clock(closure)
    racy = any(node_id(e)[0] == "Sleep" for s in closure.sources.values() for t in s.trees()
               for e in body_nodes(t))
    out = []
    for choice in choices:
        run_tree = default if choice is None else choice
        actions, conditions = reachable_leaves(closure, custom, run_tree) if run_tree else ([], [])
        texts = []
        for k in range(scripts if actions or conditions else 1):
            gen = btcpp_oracle.Generator(random.Random("%d/%s/%s/%d" % (seed, rel, choice, k)))
            gen.actions, gen.conditions = list(actions), list(conditions)
            text = gen.table(max_ticks)
            if text not in texts:
                texts.append(text)
        for k, script in enumerate(texts):
            name = "%s%s#%d" % (rel, "" if choice is None else "@" + choice, k)
            case = settled_run(oracle, name, files[rel], script, choice, clock, racy)
            case.update({"file": rel, "tree": choice, "files": files, "stubs": stubs,
                         "nodes": nodes, "rewrites": rewrites,
                         "custom": {i: custom.declared_by.get(i, "not declared: the ID of a tree")
                                    for i in sorted(custom.used)}})
            out.append(case)
            if case["load_error"] is not None:
                break  # the other scripts would be refused as well
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", help="tree files, relative to --root")
    parser.add_argument("--root", required=True, help="the directory of the tree files")
    parser.add_argument("--models", action="append", default=[],
                        help="a file of node models for the tree files in its directory "
                             "(relative to --root; repeatable)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--scripts", type=int, default=20, help="outcome scripts per tree")
    parser.add_argument("--max-ticks", type=int, default=btcpp_oracle.MAX_TICKS)
    args = parser.parse_args()
    args.root = os.path.abspath(args.root)

    capture = btcpp_oracle.Capture()
    oracle = TreeOracle(capture, args.max_ticks)
    out = capture.out
    scratch = tempfile.mkdtemp(prefix="btcpp_trees_")
    try:
        for rel in args.files:
            for case in cases_of_file(oracle, args.root, rel, args.models, args.seed,
                                      args.scripts, args.max_ticks, scratch):
                out.write(json.dumps(case) + "\n")
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    out.flush()
    # Without destructors (see btcpp_oracle.Oracle.kept).
    os._exit(0)


if __name__ == "__main__":
    main()
