#!/usr/bin/env python3
"""Times Storm (stormpy 2.0) end to end on navigation cases exported by chronomap.

Benchmark tool of `chronomap bench plan` (which embeds this file and runs it with the Python
named by --storm-python). stormpy is GPL-3.0 and is never a dependency of the Rust code.

Usage:

    storm_time.py [--repeat N] [--exact] CASE.nm ...

Each CASE.nm (``NavigationMdp::to_prism``) comes with CASE.props (one co-safe LTL property,
``mdp::prism_property``), CASE.drn (the product, ``mdp::product_drn``) and CASE.restricted.drn
(``mdp::restricted_drn``). One sweep over all cases is timed (time.perf_counter, inside this
script, so Python start-up and ``import stormpy`` are excluded and reported apart) for each of

  * prism_ltl: parse the PRISM file and the property, build the model, check ``Pmax=? [ ltl ]``
    at the initial state (Storm translates the formula with Spot and builds its own product):
    Storm end to end from the same input chronomap plans from (the predictions at t);
  * drn: build chronomap's product from DRN and check ``Pmax=? [F "goal"]`` in every state, then
    build the restricted product and check ``R{"time"}min=? [F "decided"]`` in every state:
    Storm solving chronomap's products (Storm's LTL path has no "least expected time among the
    Pmax-optimal policies");

with the engines
  * default: floating point, stormpy's default environment (sound, precision 1e-6);
  * sound12: floating point, sound, precision 1e-12 (chronomap's tolerance);
  * exact:   rational arithmetic (only with --exact; slow).

The first sweep of each (path, engine) is a warm-up; the time reported is the median of
--repeat further sweeps. Output (stdout): one JSON object
  {"stormpy": version, "import_seconds": s, "cases": n, "repeat": r,
   "timings": [{"path": p, "engine": e, "seconds": median, "sweeps": [...]}, ...],
   "pmax": {"<path>/<engine>": {"CASE": Pmax at the initial state, ...}, ...},
   "script_seconds": s}
"""

import time

_STARTED = time.perf_counter()

import argparse  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402

_BEFORE_IMPORT = time.perf_counter()
import stormpy  # noqa: E402
import stormpy.environments  # noqa: E402

IMPORT_SECONDS = time.perf_counter() - _BEFORE_IMPORT


def environment(engine):
    if engine == "exact":
        return stormpy.environments.exact()
    env = stormpy.environments.sound()
    if engine == "sound12":
        precision = stormpy.Rational("1/1000000000000")
        env.solver().min_max().precision = precision
        env.solver().native().precision = precision
    return env


def build_prism(program, props, engine):
    if engine == "exact":
        return stormpy.build_model[stormpy.Rational](program, props)
    return stormpy.build_model(program, props)


def build_drn(path, engine):
    if engine == "exact":
        return stormpy.build_model_from_drn[stormpy.Rational](path)
    return stormpy.build_model_from_drn(path)


def prism_ltl(stem, engine, env):
    """Pmax of the co-safe LTL property at the initial state, from the PRISM file."""
    with open(stem + ".props", encoding="utf-8") as f:
        text = f.read().strip()
    program = stormpy.parse_prism_program(stem + ".nm")
    props = stormpy.parse_properties(text, program)
    model = build_prism(program, props, engine)
    initial = int(model.initial_states[0])
    result = stormpy.model_checking(
        model, props[0], only_initial_states=True, environment=env
    )
    return float(result.get_value(initial))


def drn(stem, engine, env):
    """Pmax on the product and Rmin on the restricted product, every state, from DRN."""
    product = build_drn(stem + ".drn", engine)
    pmax = stormpy.parse_properties('Pmax=? [F "goal"]')[0]
    result = stormpy.model_checking(product, pmax, environment=env)
    initial = int(product.initial_states[0])
    value = float(result.get_value(initial))
    restricted = build_drn(stem + ".restricted.drn", engine)
    rmin = stormpy.parse_properties('R{"time"}min=? [F "decided"]')[0]
    stormpy.model_checking(restricted, rmin, environment=env)
    return value


def sweep(stems, path, engine):
    check = prism_ltl if path == "prism_ltl" else drn
    env = environment(engine)
    started = time.perf_counter()
    values = {os.path.basename(stem): check(stem, engine, env) for stem in stems}
    return time.perf_counter() - started, values


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", help="CASE.nm files")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--exact", action="store_true", help="also time exact arithmetic")
    args = parser.parse_args()
    stems = [os.path.splitext(path)[0] for path in args.files]
    engines = ["default", "sound12"] + (["exact"] if args.exact else [])
    timings, pmax = [], {}
    for path in ["prism_ltl", "drn"]:
        for engine in engines:
            _, values = sweep(stems, path, engine)  # warm-up
            sweeps = [sweep(stems, path, engine)[0] for _ in range(max(1, args.repeat))]
            timings.append(
                {
                    "path": path,
                    "engine": engine,
                    "seconds": statistics.median(sweeps),
                    "sweeps": sweeps,
                }
            )
            pmax[f"{path}/{engine}"] = values
    json.dump(
        {
            "stormpy": stormpy.__version__,
            "import_seconds": IMPORT_SECONDS,
            "cases": len(stems),
            "repeat": max(1, args.repeat),
            "timings": timings,
            "pmax": pmax,
            "script_seconds": time.perf_counter() - _STARTED,
        },
        sys.stdout,
    )
    print()


if __name__ == "__main__":
    main()
