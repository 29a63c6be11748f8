#!/usr/bin/env python3
"""Reference values from Storm (stormpy 2.0) for MDPs exported by chronomap.

Test-only oracle: stormpy is GPL-3.0 and is never a dependency of the Rust code.
Install it into a throw-away virtual environment:

    python3 -m venv /tmp/storm && /tmp/storm/bin/pip install stormpy==2.0.0

Usage:

    storm_check.py [--float] [--expect EXPECTED.json] [--tol 1e-9] FILE...

FILE is either
  * an explicit DRN file (``mdp::SparseMdp::to_drn``, ``product_drn``, ``restricted_drn``):
    Storm computes ``Pmax=? [F "goal"]`` and, if the model has the label ``decided``,
    ``Rmin=? [F "decided"]`` (the reward model ``time``), in every state. chronomap's expected
    cost is the latter on the *restricted* product (only Pmax-optimal choices); on the full
    product it is another quantity (the least time until decided, whatever the probability);
    or
  * a PRISM model (``.nm``/``.prism``, ``NavigationMdp::to_prism``) with a properties file of
    the same stem (``.props``, one property per line, e.g. from ``mdp::prism_property``):
    Storm computes each property at the initial state (co-safe LTL through the bundled Spot).

Models are built with exact rational arithmetic (``stormpy.Rational``) unless --float is
given, so the values are exact for the decimal numbers written in the files (Storm's default
floating-point engine is only "sound" to a precision of 1e-6, too coarse for a 1e-9 check).

Output (stdout): one JSON object keyed by file name (the base name):
  DRN:   {"states": n, "choices": m, "initial": i, "pmax": [...], "pmax_initial": x,
          "rmin": [...], "rmin_initial": y}        (rmin only with the label "decided")
  PRISM: {"states": n, "choices": m, "properties": {"<property>": value, ...}}
Infinite values (Rmin where "decided" is not reached almost surely) are written as null.

With --expect, the values are compared with a JSON object of the same shape (keys missing
there are not compared; null means infinity) to the absolute tolerance --tol, relative for
values above 1; mismatches are listed on stderr and the exit status is 1.
"""

import argparse
import json
import math
import os
import sys

import stormpy


def number(value):
    """A float, or None for infinity."""
    x = float(value)
    return None if math.isinf(x) else x


def check_drn(path, exact):
    value_type = float if not exact else stormpy.Rational
    model = stormpy.build_model_from_drn[value_type](path)
    initial = int(model.initial_states[0])
    out = {
        "states": model.nr_states,
        "choices": model.nr_choices,
        "initial": initial,
    }
    queries = [("pmax", 'Pmax=? [F "goal"]')]
    if "decided" in model.labeling.get_labels():
        queries.append(("rmin", 'R{"time"}min=? [F "decided"]'))
    for key, text in queries:
        result = stormpy.model_checking(model, stormpy.parse_properties(text)[0])
        values = [number(result.get_value(s)) for s in range(model.nr_states)]
        out[key] = values
        out[key + "_initial"] = values[initial]
    return out


def check_prism(path, exact):
    stem = os.path.splitext(path)[0]
    with open(stem + ".props", encoding="utf-8") as f:
        texts = [line.strip() for line in f if line.strip() and not line.startswith("//")]
    program = stormpy.parse_prism_program(path)
    out = {"properties": {}}
    for text in texts:
        prop = stormpy.parse_properties(text, program)[0]
        value_type = float if not exact else stormpy.Rational
        model = stormpy.build_model[value_type](program, [prop])
        result = stormpy.model_checking(model, prop)
        out["properties"][text] = number(result.get_value(int(model.initial_states[0])))
    full = stormpy.build_model(program)
    out["states"], out["choices"] = full.nr_states, full.nr_choices
    return out


def close(a, b, tol):
    if a is None or b is None:
        return a is None and b is None
    return abs(a - b) <= tol * max(1.0, abs(a), abs(b))


def compare(name, got, expected, tol, problems):
    for key, want in expected.items():
        have = got.get(key)
        where = f"{name}: {key}"
        if isinstance(want, dict):
            compare(where, have or {}, want, tol, problems)
        elif isinstance(want, list):
            if not isinstance(have, list) or len(have) != len(want):
                problems.append(f"{where}: {have!r} vs expected {want!r}")
                continue
            for i, (h, w) in enumerate(zip(have, want)):
                if not close(h, w, tol):
                    problems.append(f"{where}[{i}]: Storm {h!r}, expected {w!r}")
        elif isinstance(want, (int, float)) or want is None:
            if not (isinstance(have, (int, float)) or have is None) or not close(have, want, tol):
                problems.append(f"{where}: Storm {have!r}, expected {want!r}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+")
    parser.add_argument("--float", action="store_true", help="floating point instead of exact")
    parser.add_argument("--expect", help="JSON with the expected values")
    parser.add_argument("--tol", type=float, default=1e-9)
    args = parser.parse_args()
    results = {}
    for path in args.files:
        name = os.path.basename(path)
        if path.endswith((".nm", ".prism")):
            results[name] = check_prism(path, exact=not args.float)
        else:
            results[name] = check_drn(path, exact=not args.float)
    json.dump(results, sys.stdout, indent=1)
    print()
    if args.expect:
        with open(args.expect, encoding="utf-8") as f:
            expected = json.load(f)
        problems = []
        for name, want in expected.items():
            if name in results:
                compare(name, results[name], want, args.tol, problems)
        missing = sorted(set(expected) - set(results))
        for p in problems:
            print(p, file=sys.stderr)
        checked = len(set(expected) & set(results))
        print(
            f"compared {checked} files with the expectations "
            f"({len(problems)} mismatches, {len(missing)} expected files not given)",
            file=sys.stderr,
        )
        if problems:
            sys.exit(1)


if __name__ == "__main__":
    main()
