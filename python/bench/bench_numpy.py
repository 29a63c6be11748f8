"""The Python face's overhead: the same work from numpy and in Rust, in one run.

    python python/bench/bench_numpy.py            # from the repository root, after pip install ./python

* predict: 10^6 float64 times from numpy through ``TemporalModel.predict`` against the Rust
  call it makes (``predict_into`` on a Rust vector, timed in Rust), for FreMEn order 4 fitted on
  the bundled greg door;
* observe: 10^6 observations (the greg door's ten weeks, 96,480, repeated 11 times) from
  numpy through ``Fremen(order=2).observe`` against the same model built and fed in Rust.

Each is run ``--repeat`` times alternately; the medians and their ratio are printed (goal: at
most 1.2). ``--json`` prints them as one object.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import statistics
import time

import numpy as np

import chronomap
from chronomap import _native

REPO = pathlib.Path(__file__).resolve().parents[2]
GREG = REPO / "data" / "door_greg_2016" / "training_data.txt.xz"


def timed(f):
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=11)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    times, values = chronomap.read_pairs(GREG)
    door = chronomap.Fremen(order=4).observe(times, values)
    at = np.linspace(times[-1], times[-1] + 7 * 86400, 1_000_000)
    week = 7 * 86400.0
    shift = np.ceil((times[-1] - times[0] + 1) / week) * week       # whole weeks: same phases
    big_t = np.concatenate([times + k * shift for k in range(11)])[:1_000_000]
    big_v = np.tile(values, 11)[:1_000_000]
    at_list, big_t_list, big_v_list = at.tolist(), big_t.tolist(), big_v.tolist()

    rows = {}
    python, rust = [], []
    for _ in range(args.repeat):
        python.append(timed(lambda: door.predict(at)))
        rust.append(_native._rust_predict_seconds(door, at_list))
    rows["predict 1e6 times (fremen:4)"] = (statistics.median(python), statistics.median(rust))
    python, rust = [], []
    for _ in range(args.repeat):
        python.append(timed(lambda: chronomap.Fremen(order=2).observe(big_t, big_v)))
        rust.append(_native._rust_observe_seconds("fremen:2", big_t_list, big_v_list))
    rows["observe 1e6 observations (fremen:2)"] = (statistics.median(python),
                                                  statistics.median(rust))
    if args.json:
        print(json.dumps({name: {"python_s": p, "rust_s": r, "ratio": p / r}
                          for name, (p, r) in rows.items()}, indent=2))
        return
    print(f"chronomap {chronomap.__version__}, Python {platform.python_version()}, "
          f"numpy {np.__version__}, median of {args.repeat}")
    print(f"{'':40} {'numpy→Python':>13} {'Rust':>10} {'ratio':>7}")
    for name, (p, r) in rows.items():
        print(f"{name:40} {p * 1e3:10.2f} ms {r * 1e3:7.2f} ms {p / r:7.3f}")


if __name__ == "__main__":
    main()
