#!/usr/bin/env python3
"""Reward-bounded reachability from Storm (stormpy 2.0) for deadline plans exported by chronomap.

Test-only oracle: stormpy is GPL-3.0 and is never a dependency of the Rust code.
Install it into a throw-away virtual environment:

    python3 -m venv /tmp/storm && /tmp/storm/bin/pip install stormpy==2.0.0

Usage:

    storm_deadline.py [--float] FILE.drn:K[,K...] ...

Each FILE.drn is a duration-branching MDP (``deadline::duration_branching_mdp`` written with
``SparseMdp::to_drn``: integer action rewards of the reward model ``time`` count buckets, the
label ``goal`` marks the goal states). For every bound K Storm computes
``Pmax=? [F{"time"}<=K "goal"]`` at the initial state (Storm computes bounded properties for
the initial states only), with exact rational arithmetic unless --float is given.

Output (stdout): one JSON object keyed by file name (the base name):
  {"states": n, "choices": m, "bounds": {"K": value, ...}}
"""

import argparse
import json
import os
import sys

import stormpy


def check(path, bounds, exact):
    value_type = float if not exact else stormpy.Rational
    model = stormpy.build_model_from_drn[value_type](path)
    initial = int(model.initial_states[0])
    out = {"states": model.nr_states, "choices": model.nr_choices, "bounds": {}}
    for k in bounds:
        prop = stormpy.parse_properties(f'Pmax=? [F{{"time"}}<={k} "goal"]')[0]
        result = stormpy.model_checking(model, prop, only_initial_states=True)
        out["bounds"][str(k)] = float(result.get_value(initial))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="+", help="FILE.drn:K[,K...]")
    parser.add_argument("--float", action="store_true", help="floating point instead of exact")
    args = parser.parse_args()
    results = {}
    for case in args.cases:
        path, _, bounds = case.rpartition(":")
        if not path or not bounds:
            sys.exit(f"not FILE.drn:K[,K...]: {case}")
        ks = [int(k) for k in bounds.split(",")]
        results[os.path.basename(path)] = check(path, ks, exact=not args.float)
        print(f"{case}: {results[os.path.basename(path)]['bounds']}", file=sys.stderr)
    json.dump(results, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
