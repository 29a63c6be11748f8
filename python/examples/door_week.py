"""p(t) of the greg door over its first test week, with the observations and the entropy.

    python python/examples/door_week.py -o door_week.png      # from the repository root

Needs matplotlib. The model is FreMEn with its order chosen on held-back training data
(``fremen:auto``), fitted on the bundled training fortnight ([Krajník 2017] §VI-B).
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

import chronomap

REPO = pathlib.Path(__file__).resolve().parents[2]
GREG = REPO / "data" / "door_greg_2016"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-o", "--output", default="door_week.png")
    args = parser.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    times, values = chronomap.read_pairs(GREG / "training_data.txt.xz")
    door = chronomap.Fremen().observe(times, values)               # order chosen on the data
    test_t, test_v = chronomap.read_test_set(GREG / "test_times_1.txt.xz",
                                             GREG / "test_data_1.txt.xz")
    week = np.arange(test_t[0], test_t[0] + 7 * 86400, 300.0)
    p, h = door.predict(week), door.entropy(week)
    days = (week - week[0]) / 86400

    fig, ax = plt.subplots(figsize=(10, 3.6), dpi=110)
    ax.fill_between(days, 0, h, color="tab:orange", alpha=0.25, lw=0, label="entropy (bits)")
    ax.plot(days, p, color="tab:blue", lw=1.2, label=f"p(open), {door.fitted}")
    ax.scatter((test_t - week[0]) / 86400, test_v, s=2, color="k", alpha=0.4,
               label="observed (test week 1)")
    ax.set(xlim=(0, 7), ylim=(-0.05, 1.3), yticks=np.linspace(0, 1, 6),
           xlabel="days into the test week",
           ylabel="probability / bits",
           title=f"greg door: Brier score {np.mean((door.predict(test_t) - test_v) ** 2):.4f}")
    ax.legend(loc="upper right", fontsize=8, ncol=3)
    fig.tight_layout()
    fig.savefig(args.output)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
