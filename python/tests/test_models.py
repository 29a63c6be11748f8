"""Temporal models through Python give the command line's numbers, bit for bit, on the bundled
greg door (the FreMEn benchmark of [Krajník 2017] §VI-B)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import chronomap

GREG = "data/door_greg_2016"


@pytest.fixture(scope="module")
def greg(repo):
    train = chronomap.read_pairs(repo / GREG / "training_data.txt.xz")
    tests = [
        chronomap.read_test_set(repo / GREG / f"test_times_{i}.txt.xz",
                                repo / GREG / f"test_data_{i}.txt.xz")
        for i in range(1, 6)
    ]
    return train, tests


def test_reading_the_bundled_files(greg):
    (times, values), tests = greg
    assert times.dtype == np.float64 and values.dtype == np.float64
    assert len(times) == 96480 and len(tests) == 5
    assert np.all(np.diff(times) > 0)
    assert set(np.unique(values)) == {0.0, 1.0}


def test_evaluate_gives_the_published_brier_scores(greg):
    train, tests = greg
    table = chronomap.evaluate(train, tests, ["fremen:0", "fremen:2", "fremen:4"])
    # [Krajník 2017] Table II, greg door: FreMEn orders 0, 2, 4 (the README's table).
    assert [round(x, 4) for x in table["mean_mse"]] == [0.0807, 0.0701, 0.0670]
    assert list(table["model"]) == ["fremen:0", "fremen:2", "fremen:4"]
    assert list(table["fitted"]) == ["fremen:0", "fremen:2", "fremen:4"]


def test_evaluate_equals_the_command_line_bit_for_bit(greg, repo, cli):
    train, tests = greg
    specs = ["mean", "hist:24", "fremen:0", "fremen:2", "fremen:4", "fremen:auto", "auto"]
    table = chronomap.evaluate(train, tests, specs)
    argv = ["eval", "--train", f"{GREG}/training_data.txt.xz", "--models", ",".join(specs)]
    for i in range(1, 6):
        argv += ["--test", f"{GREG}/test_times_{i}.txt.xz,{GREG}/test_data_{i}.txt.xz"]
    expected = cli(*argv, json_output=True)
    assert [m["name"] for m in expected["models"]] == specs
    for row, model in enumerate(expected["models"]):
        assert table["fitted"][row] == model["fitted"]
        for i, test in enumerate(model["tests"]):
            assert table[f"mse_{i + 1}"][row] == test["mse"]  # exactly, not approximately
            assert table[f"binary_error_{i + 1}"][row] == test["binary_error"]
        assert table["mean_mse"][row] == model["mean_mse"]
        assert table["mean_binary_error"][row] == model["mean_binary_error"]
        for i, test in enumerate(model["tests"]):
            assert table[f"ece_{i + 1}"][row] == test["ece"]
        assert table["mean_ece"][row] == model["mean_ece"]
        for key in ["ece", "reliability", "resolution", "uncertainty", "mean_prediction",
                    "base_rate"]:
            assert table[key][row] == model["calibration"][key]
        assert table["within_bins"][row] == model["calibration"]["within_bin"]


def test_evaluate_reports_calibration_that_adds_up_to_the_brier_score(greg):
    train, tests = greg
    table = chronomap.evaluate(train, tests, ["mean", "fremen:4"])
    # The pooled Brier score of all five weeks, from the arrays themselves.
    times = np.concatenate([t for t, _ in tests])
    values = np.concatenate([v for _, v in tests])
    base = values.mean()
    assert table["base_rate"][0] == pytest.approx(base, rel=1e-12)
    assert table["uncertainty"][0] == pytest.approx(base * (1 - base), rel=1e-12)
    model = chronomap.model("fremen:4").observe(*train)
    pooled_brier = np.mean((model.predict(times) - values) ** 2)
    decomposed = (table["reliability"][1] - table["resolution"][1] + table["uncertainty"][1]
                  + table["within_bins"][1])
    assert decomposed == pytest.approx(pooled_brier, rel=1e-12)
    # The training mean predicts one value: one bin, no resolution, ECE = |mean p - base|.
    assert table["resolution"][0] == 0.0
    assert table["ece"][0] == pytest.approx(abs(table["mean_prediction"][0] - base), rel=1e-12)
    # FreMEn of order 4 over-predicts the door on the public weeks (docs/accuracy.md).
    assert table["mean_prediction"][1] > base + 0.04


def test_evaluate_with_days_off_equals_the_command_line(greg, repo, cli):
    train, tests = greg
    calendar = f"{repo}/data/calendars/england_wales_2016.txt"
    table = chronomap.evaluate(train, tests, ["fremen:4"], days_off=calendar)
    argv = ["eval", "--train", f"{GREG}/training_data.txt.xz", "--models", "fremen:4",
            "--days-off", calendar]
    for i in range(1, 6):
        argv += ["--test", f"{GREG}/test_times_{i}.txt.xz,{GREG}/test_data_{i}.txt.xz"]
    expected = cli(*argv, json_output=True)["models"][0]["tests"]
    assert [table[f"mse_{i + 1}"][0] for i in range(5)] == [t["mse"] for t in expected]
    # Good Friday and Easter Monday predicted as Sundays: weeks 1 and 2 better.
    plain = chronomap.evaluate(train, tests, ["fremen:4"])
    assert table["mse_1"][0] < plain["mse_1"][0] - 0.004
    with pytest.raises(ValueError, match="not a date"):
        chronomap.evaluate(train, tests, ["mean"], days_off=f"{repo}/data/README.md")


def _eval_argv(*extra):
    argv = ["eval", "--train", f"{GREG}/training_data.txt.xz", "--models", "auto", *extra]
    for i in range(1, 6):
        argv += ["--test", f"{GREG}/test_times_{i}.txt.xz,{GREG}/test_data_{i}.txt.xz"]
    return argv


def test_recent_days_equals_the_command_line(greg, cli):
    train, tests = greg
    # The stack with its drift candidates (7, 14, 28, 56 days, the default) and without.
    default = chronomap.evaluate(train, tests, ["auto"])
    without = chronomap.evaluate(train, tests, ["auto"], recent_days=None)
    assert round(default["mean_mse"][0], 4) == 0.0591
    assert round(without["mean_mse"][0], 4) == 0.0603
    expected = cli(*_eval_argv(), json_output=True)["models"][0]
    assert default["mean_mse"][0] == expected["mean_mse"]  # exactly, not approximately
    assert default["fitted"][0] == expected["fitted"]
    expected = cli(*_eval_argv("--recent-days", "none"), json_output=True)["models"][0]
    assert without["mean_mse"][0] == expected["mean_mse"]
    assert without["fitted"][0] == expected["fitted"]
    # Other memories: any sequence of ints (here a numpy array) is `--recent-days 14,28`.
    some = chronomap.evaluate(train, tests, ["auto"], recent_days=np.array([14, 28]))
    expected = cli(*_eval_argv("--recent-days", "14,28"), json_output=True)["models"][0]
    assert some["mean_mse"][0] == expected["mean_mse"]


def _drift_candidates(model):
    """The memories in days of the drift candidates `auto` compared (its selection): those of
    the means of the last days (one bin a day)."""
    return [spec["Recent"]["cycles"] for spec, _ in model.selection["Stack"]["errors"]
            if isinstance(spec, dict) and "Recent" in spec and spec["Recent"]["bins"] == 1]


def test_recent_days_reach_the_stack():
    # Three weeks of a daily routine: `auto` compares drift candidates of the memories asked.
    times = np.arange(0.0, 21 * 86400, 600.0)
    values = ((times % 86400) < 8 * 3600).astype(float)
    default = chronomap.model("auto").observe(times, values)
    assert _drift_candidates(default) == [7, 14, 28, 56]
    explicit = chronomap.TemporalModel("auto", recent_days=(7, 14, 28, 56)).observe(times, values)
    at = times[::37] + 21 * 86400
    assert np.array_equal(default.predict(at), explicit.predict(at))
    assert _drift_candidates(chronomap.model("auto", recent_days=range(3, 5))
                             .observe(times, values)) == [3, 4]
    for none in (None, [], ()):
        without = chronomap.TemporalModel("auto", recent_days=none).observe(times, values)
        assert _drift_candidates(without) == []


@pytest.mark.parametrize("days, message", [
    ([0], r"^recent_days\[0\]: 0 \(int\) is not a whole number of days from 1 to 3650"),
    ([7, -14], r"^recent_days\[1\]: -14 \(int\) is not a whole number"),
    ([3651], r"^recent_days\[0\]: 3651 \(int\) is not a whole number"),
    ([2 ** 70], r"^recent_days\[0\]: 1180591620717411303424 \(int\) is not"),
    ([7.0], r"^recent_days\[0\]: 7\.0 \(float\) is not a whole number"),
    ([float("nan")], r"^recent_days\[0\]: nan \(float\) is not a whole number"),
    ([np.float64(7)], r"^recent_days\[0\]: .*7\.0.* \(float64\) is not a whole number"),
    ([True], r"^recent_days\[0\]: True \(bool\) is not a whole number"),
    ([7, "14"], r"^recent_days\[1\]: '14' \(str\) is not a whole number"),
    ([None], r"^recent_days\[0\]: None \(NoneType\) is not a whole number"),
    ("7,14", r"^recent_days: expected a sequence of whole days from 1 to 3650 \(e\.g\. "
             r"\[7, 14\]\) or None, got str"),
    (7, r"^recent_days: expected a sequence .* got int"),
    (7.5, r"^recent_days: expected a sequence .* got float"),
])
def test_recent_days_are_checked_like_the_command_line(greg, days, message):
    train, tests = greg
    calls = [
        lambda: chronomap.model("auto", recent_days=days),
        lambda: chronomap.TemporalModel("auto", recent_days=days),
        lambda: chronomap.evaluate(train, tests, ["auto"], recent_days=days),
    ]
    for call in calls:
        with pytest.raises(ValueError, match=message):
            call()
    # Whole numpy integers and the bounds themselves are days.
    chronomap.model("auto", recent_days=np.array([1, 3650], dtype=np.int64))


def test_evaluate_as_a_data_frame(greg):
    pd = pytest.importorskip("pandas")
    train, tests = greg
    frame = chronomap.evaluate(train, tests[:2], ["fremen:2", "mean"], as_frame=True)
    assert isinstance(frame, pd.DataFrame)
    assert list(frame.columns) == ["model", "fitted", "mse_1", "mse_2", "mean_mse",
                                   "binary_error_1", "binary_error_2", "mean_binary_error",
                                   "ece_1", "ece_2", "mean_ece", "ece", "reliability",
                                   "resolution", "uncertainty", "within_bins",
                                   "mean_prediction", "base_rate"]
    assert frame.loc[0, "mean_mse"] == pytest.approx((frame.loc[0, "mse_1"]
                                                      + frame.loc[0, "mse_2"]) / 2, rel=1e-15)


@pytest.mark.parametrize("spec", ["fremen:2", "fremen:auto", "hist:24", "pergam:2", "stm",
                                  "persistence:2", "auto"])
def test_a_model_saved_in_python_predicts_the_same_in_the_cli(greg, tmp_path, cli, spec):
    (times, values), tests = greg
    model = chronomap.model(spec).observe(times, values)
    path = tmp_path / "door.cmm"
    model.save(path)
    at = tests[0][0][::97]
    times_file = tmp_path / "times.txt"
    np.savetxt(times_file, at, fmt="%.17g")
    out = cli("predict", path, "--times", times_file, json_output=True)
    assert out["spec"] == model.fitted
    assert np.array_equal(np.array([r["p"] for r in out["predictions"]]), model.predict(at))


def test_a_model_fitted_by_the_cli_loads_in_python(greg, repo, tmp_path, cli):
    (times, values), tests = greg
    path = tmp_path / "cli.cmm"
    fitted = cli("fit", "--train", f"{GREG}/training_data.txt.xz", "--model", "fremen:auto",
                 "-o", path, json_output=True)
    loaded = chronomap.load(path)
    assert isinstance(loaded, chronomap.Fremen)
    assert loaded.fitted == fitted["fitted"] and loaded.observations == len(times)
    # The same order chosen on the same held-back quarter, and the same predictions.
    mine = chronomap.Fremen().observe(times, values)
    assert mine.fitted == loaded.fitted
    at = tests[2][0]
    assert np.array_equal(mine.predict(at), loaded.predict(at))
    assert mine.selection["Order"]["order"] == loaded.order


def test_a_model_fitted_with_its_calendar_predicts_holidays_in_python(greg, repo, tmp_path, cli):
    _, tests = greg
    path = tmp_path / "calendar.cmm"
    calendar = f"{repo}/data/calendars/england_wales_2016.txt"
    fitted = cli("fit", "--train", f"{GREG}/training_data.txt.xz", "--model", "fremen:4",
                 "--days-off", calendar, "-o", path, json_output=True)
    assert fitted["kind"] == "calendar" and fitted["days_off"] == 8
    loaded = chronomap.load(path)
    at = tests[0][0]
    times_file = tmp_path / "times.txt"
    np.savetxt(times_file, at, fmt="%.17g")
    out = cli("predict", path, "--times", times_file, json_output=True)
    assert np.array_equal(np.array([r["p"] for r in out["predictions"]]), loaded.predict(at))
    # Good Friday 10:00 (a day off) is predicted as Sunday 20 March 10:00.
    friday, sunday = 1458900000.0, 1458468000.0
    assert loaded.predict(friday) == loaded.predict(sunday)


def test_typed_classes_match_their_specs(greg):
    (times, values), tests = greg
    at = tests[1][0][:500]
    pairs = [
        (chronomap.Fremen(order=4), "fremen:4"),
        (chronomap.Fremen(), "fremen:auto"),
        (chronomap.Mean(), "mean"),
        (chronomap.Hist(bins=168), "hist:168"),
        (chronomap.Persistence(order=2), "persistence:2"),
        (chronomap.Stm(), "stm"),
        (chronomap.PerGaM(components=2), "pergam:2"),
    ]
    for typed, spec in pairs:
        assert typed.spec == spec
        generic = chronomap.model(spec)
        assert type(generic) is type(typed)
        typed.observe(times, values)
        generic.observe(times, values)
        assert np.array_equal(typed.predict(at), generic.predict(at)), spec


def test_observing_in_batches_equals_one_batch(greg):
    (times, values), tests = greg
    whole = chronomap.Fremen(order=3).observe(times, values)
    parts = chronomap.Fremen(order=3)
    for chunk in np.array_split(np.arange(len(times)), 7):
        parts.observe(times[chunk], values[chunk])
    at = tests[0][0]
    assert parts.observations == whole.observations
    np.testing.assert_allclose(parts.predict(at), whole.predict(at), rtol=0, atol=1e-12)


def test_predict_entropy_and_scalars():
    t = np.arange(0, 14 * 86400, 600.0)
    hour = (t % 86400) / 3600
    door = chronomap.Fremen(order=2).observe(t, ((hour >= 8) & (hour < 18)).astype(float))
    noon, night = 15 * 86400 + 12 * 3600.0, 15 * 86400 + 2 * 3600.0
    p = door.predict(np.array([noon, night]))
    assert p.shape == (2,) and p.dtype == np.float64
    assert p[0] > 0.8 and p[1] < 0.2
    assert isinstance(door.predict(noon), float) and door.predict(noon) == p[0]
    # Saturated predictions are certain; a state observed as 0.7 by day is not.
    assert np.array_equal(door.entropy(np.array([noon, night])), np.where((p == 0) | (p == 1), 0.0, door.entropy(np.array([noon, night]))))
    soft = chronomap.Fremen(order=2).observe(t, np.where((hour >= 8) & (hour < 18), 0.7, 0.2))
    q = soft.predict(np.array([noon, night]))
    assert 0 < q.min() and q.max() < 1
    np.testing.assert_allclose(soft.entropy(np.array([noon, night])),
                               -q * np.log2(q) - (1 - q) * np.log2(1 - q), rtol=1e-14)
    # Python ints and lists are numbers too.
    assert door.predict(int(noon)) == p[0]
    assert np.array_equal(door.predict([noon, night]), p)
    # An unobserved model knows nothing.
    assert chronomap.Fremen(order=2).predict(noon) == 0.5
    assert chronomap.Fremen(order=2).entropy(noon) == 1.0


def test_components_reconstruct_the_prediction():
    t = np.arange(0, 21 * 86400, 900.0)
    hour = (t % 86400) / 3600
    values = ((hour >= 9) & (hour < 17)).astype(float)
    door = chronomap.Fremen(order=3).observe(t, values)
    c = door.components
    assert c["period"].shape == (3,) and c["period"][0] == 86400.0
    at = np.linspace(22 * 86400, 23 * 86400, 97)
    rebuilt = c["mean"][0] + sum(
        2 * a * np.cos(2 * np.pi * at / T + phi)
        for T, a, phi in zip(c["period"], c["amplitude"], c["phase"]))
    np.testing.assert_allclose(door.predict(at), np.clip(rebuilt, 0, 1), atol=1e-9)
    assert chronomap.Mean().observe(t, values).components == {}


def test_changing_the_order_without_re_observing(greg):
    (times, values), tests = greg
    door = chronomap.Fremen(order=4).observe(times, values)
    door.order = 2
    assert door.order == 2 and door.fitted == "fremen:2"
    at = tests[0][0]
    np.testing.assert_array_equal(door.predict(at),
                                  chronomap.Fremen(order=2).observe(times, values).predict(at))
    with pytest.raises(TypeError, match="a mean model has no order to change"):
        chronomap.Mean().observe(times, values).order = 3


def test_anomalies_match_the_cli(greg, repo, tmp_path, cli):
    (times, values), tests = greg
    model = chronomap.Fremen(order=2).observe(times, values)
    path = tmp_path / "door.cmm"
    model.save(path)
    found = model.anomalies(*tests[0], confidence=0.75)
    out = cli("anomalies", path, "--test", f"{GREG}/test_times_1.txt.xz,{GREG}/test_data_1.txt.xz",
              "--confidence", "0.75", json_output=True)
    assert len(found["time"]) == len(out["anomalies"]) > 0
    assert np.array_equal(found["time"], [a["time"] for a in out["anomalies"]])
    assert np.array_equal(found["p"], [a["p"] for a in out["anomalies"]])
    assert np.array_equal(tests[0][0][found["index"]], found["time"])


def test_hypertime_model_round_trips(tmp_path):
    t = np.arange(0, 10 * 86400, 1200.0)
    hour = (t % 86400) / 3600
    values = ((hour >= 7) & (hour < 19)).astype(float)
    model = chronomap.Hypertime(components=2).observe(t, values)
    assert isinstance(model, chronomap.Hypertime) and model.kind == "hyt-em"
    assert 86400.0 in set(np.round(model.components["period"]))
    model.save(tmp_path / "h.cmm")
    back = chronomap.load(tmp_path / "h.cmm")
    at = np.arange(11 * 86400, 12 * 86400, 3600.0)
    assert np.array_equal(back.predict(at), model.predict(at))
    assert back.predict(11 * 86400 + 12 * 3600) > 0.7


def test_pickle_and_bytes_round_trip(greg, tmp_path):
    (times, values), tests = greg
    model = chronomap.Fremen().observe(times, values)
    back = pickle.loads(pickle.dumps(model))
    assert type(back) is chronomap.Fremen and back.fitted == model.fitted
    at = tests[4][0]
    assert np.array_equal(back.predict(at), model.predict(at))
    path = tmp_path / "door.cmm"
    model.save(path)
    assert path.read_bytes() == model.to_bytes()       # the same file, byte for byte
    assert np.array_equal(chronomap.loads(path.read_bytes()).predict(at), model.predict(at))
    with pytest.raises(ValueError, match="checksum mismatch"):
        damaged = bytearray(model.to_bytes())
        damaged[-1] ^= 1
        chronomap.loads(bytes(damaged))


def _ticks_while(call):
    """How often Python code in this thread ran while `call` ran in another."""
    import threading

    started, done = threading.Event(), threading.Event()

    def work():
        started.set()
        call()
        done.set()

    worker = threading.Thread(target=work)
    worker.start()
    started.wait()
    ticks = 0
    while not done.is_set():
        ticks += 1
    worker.join()
    return ticks


def test_long_calls_release_the_gil(greg):
    import sys
    import threading

    (times, values), _ = greg
    door = chronomap.Fremen(order=4).observe(times, values)
    many = np.linspace(times[-1], times[-1] + 365 * 86400, 3_000_000)
    # Ticks of this loop in one switch interval: what a call that holds the GIL lets through.
    stop = threading.Timer(0.1, lambda: None)
    calibration = _ticks_while(lambda: stop.run())
    per_interval = calibration / 0.1 * sys.getswitchinterval()
    ticks = _ticks_while(lambda: door.predict(many))
    assert ticks > 20 * per_interval, (ticks, per_interval)   # about 100 intervals here
    # A call known to hold the GIL (pickling a long list) lets through a few intervals.
    data = list(range(3_000_000))
    held = _ticks_while(lambda: pickle.dumps(data))
    assert held < 20 * per_interval, (held, per_interval)
