"""CoPA-Map ([Stüde 2024] §4.2) and Warped Hypertime events ([Krajník 2019] §V-D) from numpy
give what `chronomap activity` and `chronomap hypertime` give, on the bundled ATC grid and
Lincoln pedestrian detections."""

from __future__ import annotations

import numpy as np
import pytest

import chronomap

ATC = "data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz"
LINCOLN = "data/lincoln_pedestrians_2017/whytes/wednesday_thursday_days_nights_only_ones.txt.xz"
# Small settings keep the fit to about a second; the defaults are those of the command line.
SMALL = dict(inducing=40, iterations=20)


@pytest.fixture(scope="module")
def atc(repo):
    return chronomap.read_rate_samples(repo / ATC)


def test_rate_samples(atc):
    x, t, y = atc
    assert x.shape == (76456, 2) and t.shape == y.shape == (76456,)
    assert t.min() == 0.0 and t.max() == 119.0 and y.min() >= 0


def test_copa_map_fitted_in_python_equals_the_cli(atc, tmp_path, cli):
    x, t, y = atc
    model = chronomap.CopaMap.fit(x, t, y, **SMALL)
    path = tmp_path / "py.cmcopa"
    model.save(path)
    out = cli("activity", "predict", "--model", path, "--t", "5", "--cell", "2", json_output=True)
    rows = out["predictions"]
    points = np.array([[r["x1"], r["x2"]] for r in rows])
    mean, std = model.predict(points, 5.0)
    assert len(rows) > 100
    assert np.array_equal(mean, [r["mean"] for r in rows])
    assert np.array_equal(std, [r["std"] for r in rows])
    # And the command line's own fit, with the same settings and seed, is the same model.
    cli_path = tmp_path / "cli.cmcopa"
    cli("activity", "fit", "--train", ATC, "--inducing", "40", "--iterations", "20",
        "-o", cli_path, json_output=True)
    theirs = chronomap.load_copa_map(cli_path)
    assert np.array_equal(theirs.periods, model.periods)
    assert np.array_equal(theirs.predict(points, 5.0)[0], mean)
    # Per-point times give the same as one time for all.
    assert np.array_equal(model.predict(points, np.full(len(points), 5.0))[0], mean)


def test_copa_map_bad_input(atc, tmp_path):
    x, t, y = atc
    with pytest.raises(ValueError, match=r"^x: expected shape \(N, 2\) \(x1, x2 in metres\), "
                                         r"got \(76456, 1\)$"):
        chronomap.CopaMap.fit(x[:, :1], t, y, **SMALL)
    bad = y.copy()
    bad[7] = -1.0
    with pytest.raises(ValueError, match="sample 7"):
        chronomap.CopaMap.fit(x, t, bad, **SMALL)
    with pytest.raises(ValueError, match="^scale: 'log' is not 'rate' or 'log1p'$"):
        chronomap.CopaMap.fit(x, t, y, scale="log", **SMALL)
    model = chronomap.CopaMap.fit(x[:4000], t[:4000], y[:4000], **SMALL)
    with pytest.raises(ValueError, match=r"^t\[1\]: time NaN is not a finite number$"):
        model.predict(x[:2], np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="^2 positions but 3 times$"):
        model.predict(x[:2], np.zeros(3))
    # A temporal model's file is not a CoPA-Map.
    other = tmp_path / "door.cmm"
    chronomap.Mean().observe([0.0], [1.0]).save(other)
    with pytest.raises(ValueError, match="door.cmm: "):
        chronomap.load_copa_map(other)


def test_hypertime_events_equal_the_cli(repo, cli):
    events = chronomap.read_events(repo / LINCOLN)
    assert events.shape == (61489, 3)
    at = [1495792800.0, 1495816200.0]          # 2017-05-26 10:00 and 16:30 UTC
    model = chronomap.HypertimeEvents.fit(events, components=2)
    out = cli("hypertime", "--train", LINCOLN, "--at", "1495792800,1495816200",
              "--components", "2", "--cell", "0.5", json_output=True)
    assert np.array_equal(model.periods, out["periods_secs"])
    assert model.components == out["components"] == 2
    density = model.density(at, cell=0.5)
    assert np.array_equal(density["total_per_hour"], [m["total_per_hour"] for m in out["maps"]])
    assert np.array_equal(density["per_m2_hour"].max(axis=(1, 2)),
                          [m["max_per_m2_hour"] for m in out["maps"]])
    # Quiet in the morning, busy in the afternoon, in the plane's rate as on the map.
    rate = model.rate(at) * 3600
    assert 0 < rate[0] < rate[1] and density["total_per_hour"][0] < density["total_per_hour"][1]
    lam = model.intensity(np.full(3, at[1]), events[:3, 1], events[:3, 2])
    assert lam.shape == (3,) and np.all(lam > 0)
    with pytest.raises(ValueError, match=r"^events: expected shape \(N, 3\) \(t, x, y\)"):
        chronomap.HypertimeEvents.fit(events[:, :2])
    with pytest.raises(ValueError, match=r"^times\[0\]: NaN is not a finite number$"):
        model.rate([np.nan])
