"""Shrinks trees on which `chronomap bt run` and BehaviorTree.CPP disagree.

    python tests/bt/minimise.py CHRONOMAP_BIN DISAGREEMENTS.jsonl [--out DIR] [--limit N]

Reads the cases that tests/cli/bt_differential.rs wrote (one JSON object per line, as
tests/bt/btcpp_oracle.py prints them) and, for each, removes what it can while both still
disagree in the same way: children of controls, decorators and controls replaced by a child,
pre- and post-conditions, unused subtrees, leaves and script ticks. The shrunk cases are printed
grouped by what differs (and written to DIR as NAME.xml / NAME.script when --out is given), so a
disagreement can be read in a few lines and kept as a named regression case.
"""

import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(__file__))
import btcpp_oracle  # noqa: E402


def normalised(v):
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, str):
        try:
            return float(v.strip())
        except ValueError:
            return {"true": 1.0, "false": 0.0}.get(v, v)
    return v


def chronomap_case(binary, xml, script, workdir):
    xml_path = os.path.join(workdir, "case.xml")
    script_path = os.path.join(workdir, "case.script")
    with open(xml_path, "w") as f:
        f.write(xml)
    with open(script_path, "w") as f:
        f.write(script)
    p = subprocess.run([binary, "bt", "run", xml_path, "--script", script_path, "--json"],
                       capture_output=True, text=True)
    if not p.stdout.strip():
        return {"load_error": p.stderr.strip() or "no output", "ticks": [], "error": None, "blackboard": {}}
    d = json.loads(p.stdout)
    ticks = [{"status": t["status"], "transitions": [[c["name"], c["from"], c["to"]] for c in t["transitions"]]}
             for t in d["ticks"]]
    error = None
    if d.get("error"):
        e = d["error"]
        ticks.append({"status": None, "transitions": [[c["name"], c["from"], c["to"]] for c in e["transitions"]]})
        error = {"tick": e["tick"], "message": e["message"]}
    return {"load_error": None, "ticks": ticks, "error": error, "blackboard": d.get("blackboard", {})}


def difference(theirs, ours):
    """The kind of the first difference, or None (as tests/cli/bt_differential.rs compares)."""
    if theirs["load_error"] or ours["load_error"]:
        return None if (theirs["load_error"] and ours["load_error"]) else "load"
    for a, b in zip(theirs["ticks"], ours["ticks"]):
        if a["status"] != b["status"]:
            return "status"
        if a["transitions"] != b["transitions"]:
            return "transitions"
    te = theirs["error"]["tick"] if theirs["error"] else None
    oe = ours["error"]["tick"] if ours["error"] else None
    if len(theirs["ticks"]) != len(ours["ticks"]) or te != oe:
        return "error tick"
    tb = {k: normalised(v) for k, v in theirs["blackboard"].items()}
    ob = {k: normalised(v) for k, v in ours["blackboard"].items()}
    if tb != ob:
        return "blackboard"
    return None


def candidates(root):
    """Smaller variants of the document `root` (an ElementTree element), one change each."""
    trees = [t for t in root if t.tag == "BehaviorTree"]
    used = set()
    for t in trees:
        for e in t.iter("SubTree"):
            used.add(e.get("ID"))
    for i, t in enumerate(trees):
        if t.get("ID") != "Main" and t.get("ID") not in used:
            c = copy.deepcopy(root)
            c.remove([x for x in c if x.tag == "BehaviorTree"][i])
            yield c
    paths = []

    def walk(e, path):
        paths.append(path)
        for k, child in enumerate(list(e)):
            walk(child, path + [k])

    for i, t in enumerate(root):
        if t.tag == "BehaviorTree":
            walk(t, [i])
    for path in paths:
        c = copy.deepcopy(root)
        node = c
        parent = None
        for k in path:
            parent, node = node, list(node)[k]
        if parent is None or node.tag == "BehaviorTree":
            continue
        children = list(node)
        # Replace the node by one of its children.
        for k in range(len(children)):
            d = copy.deepcopy(c)
            n = d
            p = None
            for j in path:
                p, n = n, list(n)[j]
            idx = list(p).index(n)
            p.remove(n)
            p.insert(idx, list(n)[k])
            yield d
        # Remove a child.
        if len(children) > 1:
            for k in range(len(children)):
                d = copy.deepcopy(c)
                n = d
                for j in path:
                    n = list(n)[j]
                n.remove(list(n)[k])
                yield d
        # Drop an attribute that is a pre- or post-condition.
        for a in list(node.attrib):
            if a.startswith("_") and a != "_autoremap":
                d = copy.deepcopy(c)
                n = d
                for j in path:
                    n = list(n)[j]
                del n.attrib[a]
                yield d


def script_candidates(script):
    lines = [l for l in script.splitlines() if l.strip()]
    for k in range(len(lines) - 1, 0, -1):
        yield "\n".join(lines[:k]) + "\n"


def leaves_of(root):
    return {e.get("name") for e in root.iter() if e.tag in ("Act", "Cond")}


def restrict_script(script, names):
    out = []
    for line in script.splitlines():
        head, _, rest = line.partition(":")
        pairs = [p.strip() for p in rest.split(",") if p.strip() and p.split("=")[0].strip() in names]
        if pairs or not out:
            out.append("%s: %s" % (head, ", ".join(pairs)))
    return "\n".join(out) + "\n"


def shrink(binary, oracle, case, workdir):
    xml, script = case["xml"], case["script"]

    def kind(x, s):
        theirs = oracle.run("min", x, s)
        ours = chronomap_case(binary, x, s, workdir)
        return difference(theirs, ours)

    target = kind(xml, script)
    if target is None:
        return None
    changed = True
    while changed:
        changed = False
        root = ET.fromstring(xml)
        for c in candidates(root):
            x = ET.tostring(c, encoding="unicode")
            s = restrict_script(script, leaves_of(c))
            if kind(x, s) == target:
                xml, script, changed = x, s, True
                break
        if changed:
            continue
        for s in script_candidates(script):
            if kind(xml, s) == target:
                script, changed = s, True
                break
    return target, xml, script


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("cases")
    ap.add_argument("--out")
    ap.add_argument("--limit", type=int, default=20)
    args = ap.parse_args()
    capture = btcpp_oracle.Capture()
    oracle = btcpp_oracle.Oracle(capture, btcpp_oracle.MAX_TICKS)
    out = capture.out
    workdir = tempfile.mkdtemp()
    seen = {}
    with open(args.cases) as f:
        cases = [json.loads(l) for l in f if l.strip()]
    for case in cases[: args.limit]:
        r = shrink(args.binary, oracle, case, workdir)
        if r is None:
            continue
        target, xml, script = r
        key = (target, xml)
        if key in seen:
            continue
        seen[key] = case["name"]
        out.write("=== %s: %s\n%s\n%s\n" % (case["name"], target, xml, script))
        out.flush()
        if args.out:
            os.makedirs(args.out, exist_ok=True)
            with open(os.path.join(args.out, case["name"] + ".xml"), "w") as f:
                f.write(xml)
            with open(os.path.join(args.out, case["name"] + ".script"), "w") as f:
                f.write(script)
    out.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
