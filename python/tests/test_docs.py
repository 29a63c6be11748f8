"""The Python examples of the README and docs/python.md run, and say what they print."""

from __future__ import annotations

import re

import numpy as np
import pytest

FENCE = re.compile(r"```python\n(.*?)```", re.S)


@pytest.fixture
def in_scratch(repo, tmp_path, monkeypatch):
    """Runs in an empty directory where `data/` is the repository's (examples write files)."""
    (tmp_path / "data").symlink_to(repo / "data")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def run_examples(path):
    blocks = FENCE.findall(path.read_text())
    assert blocks, f"{path.name} has no Python example"
    namespace = {}
    for i, block in enumerate(blocks):
        if "# chronomap serve" in block:
            continue  # needs a running service: the same calls are tested in test_client.py
        exec(compile(block, f"{path.name}, Python example {i + 1}", "exec"), namespace)  # noqa: S102
    return namespace


def test_readme_example(repo, in_scratch, capsys):
    ns = run_examples(repo / "README.md")
    # "print(door.predict(monday_1pm), door.entropy(monday_1pm))  # 0.29..., 0.87..."
    assert round(ns["door"].predict(ns["monday_1pm"]), 2) == 0.29
    assert round(ns["door"].entropy(ns["monday_1pm"]), 2) == 0.87
    assert ns["p"].shape == (1008,) and (in_scratch / "door.cmm").exists()


def test_python_guide_examples(repo, in_scratch, capsys):
    ns = run_examples(repo / "docs" / "python.md")
    printed = capsys.readouterr().out
    assert "[ 24. 168.]" in printed and "fremen:10" in printed
    assert [round(x, 4) for x in ns["scores"]["mean_mse"]] == [0.0807, 0.0701, 0.0670, 0.0591]
    assert np.array_equal(ns["people"].periods, [43200.0])
    # "Arrive by T": the deadline plan of the Witham trip, as its comments say.
    fast = ns["fast"]
    assert round(fast["probability"], 4) == 0.5216 and fast["first_edge"] == "Kitchen_Ramp2"
    assert round(fast["min_time_probability"], 4) == 0.0878
    assert fast["min_time_first_edge"] == "Kitchen_GroundCentral"
    assert ns["d"][-1] == 100.0 and ns["p_in_time"][-1] == fast["probability"]
    # Times from pandas: the door of "Times from pandas and numpy", open 08:00-18:00 UTC.
    assert "1.0" in printed.splitlines()
    assert ns["p_week"].index.name == "time" and str(ns["p_week"].index.tz) == "UTC"
    assert ns["p_week"]["2016-03-21 12:00"] == 1.0 and ns["p_week"]["2016-03-21 03:00"] == 0.0
    assert str(ns["local"].index.tz) == "Europe/Prague"
