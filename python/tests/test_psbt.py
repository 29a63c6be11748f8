"""Person search trees ([Stüde 2024] §5.4) synthesised from Python equal `chronomap psbt`'s."""

from __future__ import annotations

import numpy as np
import pytest

import chronomap

MAP = "data/atc_copa_map_grid/atc_map.yaml"
TRACKS = ["data/atc_20121024_1hz/atc-1024-13_train.csv.xz",
          "data/atc_20121024_1hz/atc-1024-14_train.csv.xz"]
START, TIME = (21.25, -18.25), 1351056600.0        # 2012-10-24T05:30Z, the README's example


def test_from_tracks_equals_the_cli(repo, tmp_path, cli):
    plan = chronomap.psbt_synthesize(repo / MAP, START, TIME, tracks=[repo / t for t in TRACKS])
    out = cli("psbt", "--map", MAP, "--activity", ",".join(TRACKS), "--from=21.25,-18.25",
              "--time", "2012-10-24T05:30Z", json_output=True)
    assert plan["tree_xml"] == out["tree_xml"]
    assert '<root BTCPP_format="4" main_tree_to_execute="PersonSearch">' in plan["tree_xml"]
    tree = tmp_path / "search.xml"
    tree.write_text(plan["tree_xml"])
    cli("bt", "check", tree)                      # a tree our BehaviorTree.CPP reader accepts
    assert plan["p_success"] == out["p_success"] and 0 < plan["p_success"] <= 1
    assert plan["expected_time_s"] == out["expected_time_s"]
    assert plan["candidates"] == out["candidates"] == 730
    assert np.array_equal(plan["places"], out["places"])
    assert plan["choices"] == out["choices"]


def test_from_a_copa_map_equals_the_cli(repo, tmp_path, cli):
    x, t, y = chronomap.read_rate_samples(
        repo / "data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz")
    copa = chronomap.CopaMap.fit(x, t, y, inducing=40, iterations=20)
    path = tmp_path / "atc.cmcopa"
    copa.save(path)
    plan = chronomap.psbt_synthesize(repo / MAP, START, TIME, copa=copa)
    out = cli("psbt", "--map", MAP, "--activity", path, "--from=21.25,-18.25",
              "--time", "2012-10-24T05:30Z", json_output=True)
    assert plan["model_t"] == out["model_t"]
    assert plan["tree_xml"] == out["tree_xml"] and plan["p_success"] == out["p_success"]


def test_bad_requests(repo):
    with pytest.raises(TypeError, match="one of them"):
        chronomap.psbt_synthesize(repo / MAP, START, TIME)
    with pytest.raises(FileNotFoundError, match="no-such-map.yaml"):
        chronomap.psbt_synthesize(repo / "no-such-map.yaml", START, TIME, tracks=TRACKS)
    with pytest.raises(ValueError, match="places: "):
        chronomap.psbt_synthesize(repo / MAP, START, TIME, tracks=[repo / TRACKS[0]], places=99)
    with pytest.raises(ValueError, match="finite"):
        chronomap.psbt_synthesize(repo / MAP, (float("nan"), 0.0), TIME, tracks=TRACKS)
