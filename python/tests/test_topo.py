"""chronomap.EdgeModels against `chronomap topo fit | predict` and `chronomap plan` on the
bundled Witham Wharf edge traversals (STRANDS, summer 2014)."""

from __future__ import annotations

import numpy as np
import pytest

from chronomap.topo import EdgeModels, load_edge_models

EDGES = "data/witham_topological_nav/edges"
# 2014-09-04 (the day after the data) at 03:00, 10:00 and 14:00 UTC, and a week later at 16:30.
TIMES = [1409799600.0, 1409824800.0, 1409839200.0, 1410453000.0]
TASKS = [("Station", "F Kitchen"), ("Station", "F (Printer & F Kitchen)"),
         ("Station", "!Ramp1 U Kitchen"), ("Kitchen", "F Station")]


@pytest.fixture(scope="module")
def fitted(repo, cli, tmp_path_factory):
    """The models fitted in Python and by `chronomap topo fit` (as in the README), both saved."""
    folder = tmp_path_factory.mktemp("witham")
    cli_file = folder / "cli.cmt"
    cli("topo", "fit", "--edges", repo / EDGES, "-o", cli_file, "--success-order", "1")
    models = EdgeModels.fit(repo / EDGES, success_order=1)
    py_file = folder / "python.cmt"
    models.save(py_file)
    return models, py_file, cli_file


def test_fit_gives_the_models_topo_fit_writes(fitted):
    models, py_file, cli_file = fitted
    assert len(models.nodes) == 18 and len(models.edges) == 61
    assert "LabDoor1_LabDoor2" in models.edges
    assert py_file.read_bytes() == cli_file.read_bytes()
    assert models.last_time == pytest.approx(1409788722.0, abs=86400)


@pytest.mark.parametrize("time", TIMES)
def test_predict_agrees_with_topo_predict(fitted, cli, time):
    models, py_file, cli_file = fitted
    mine = models.predict(time)
    for source in (py_file, cli_file):
        theirs = cli("topo", "predict", source, "--time", time, json_output=True)["edges"]
        assert mine["edge"] == [e["edge"] for e in theirs] == models.edges
        assert mine["from"] == [e["from"] for e in theirs]
        assert mine["to"] == [e["to"] for e in theirs]
        for key in ("success_probability", "uncertainty", "static_success_probability",
                    "duration_secs", "attempts"):
            np.testing.assert_array_equal(mine[key], [e[key] for e in theirs], err_msg=key)
        # The 90 % intervals of durations, bit for bit, around the expected duration.
        np.testing.assert_array_equal(mine["duration_lower_secs"],
                                      [e["duration_interval_secs"][0] for e in theirs])
        np.testing.assert_array_equal(mine["duration_upper_secs"],
                                      [e["duration_interval_secs"][1] for e in theirs])
        assert np.all(mine["duration_lower_secs"] <= mine["duration_secs"])
        assert np.all(mine["duration_secs"] <= mine["duration_upper_secs"])
    # Wider coverage, wider intervals; a coverage the quantiles cannot give is refused.
    wide = models.predict(time, coverage=0.99)
    assert np.all(wide["duration_upper_secs"] > mine["duration_upper_secs"])
    with pytest.raises(ValueError, match="coverage"):
        models.predict(time, coverage=0.999)
    # The door edge changes over the day; most edges hardly do.
    door = models.edges.index("LabDoor1_LabDoor2")
    assert 0.05 <= mine["success_probability"][door] < 0.9


@pytest.mark.parametrize("time", TIMES)
@pytest.mark.parametrize(("start", "task"), TASKS)
def test_plan_agrees_with_chronomap_plan(fitted, cli, start, task, time):
    models, py_file, _ = fitted
    mine = models.plan(start, task, time)
    theirs = cli("plan", "--model", py_file, "--from", start, "--task", task, "--time", time,
                 json_output=True)
    for key in ("task", "from", "time", "pmax", "expected_secs", "first_edge", "route",
                "route_success_probabilities", "product_states"):
        assert mine[key] == theirs[key], key
    assert 0.0 <= mine["pmax"] <= 1.0
    # The whole policy agrees with its summary: at the start, it takes the first edge with Pmax.
    policy = mine["policy"]
    assert len(policy["node"]) == len(policy["edge"]) == len(policy["pmax"]) <= mine["product_states"]
    if mine["first_edge"] is not None:
        at_start = [i for i, n in enumerate(policy["node"]) if n == start]
        assert mine["first_edge"] in [policy["edge"][i] for i in at_start]
        assert mine["pmax"] in [policy["pmax"][i] for i in at_start]
        # Following the policy along the route visits only edges it prescribes.
        assert set(mine["route"]) <= set(policy["edge"])


def test_now_or_later_agrees_with_the_day_table(fitted, cli):
    models, py_file, _ = fitted
    table = cli("plan", "--model", py_file, "--from", "Station", "--task", "F Kitchen",
                "--day-table", "--days", "1", "--step-mins", "120", json_output=True)
    times = np.array([p["time"] for p in table["plans"]])
    mine = models.now_or_later("Station", "F Kitchen", times)
    np.testing.assert_array_equal(mine["time"], times)
    np.testing.assert_array_equal(mine["pmax"], [p["pmax"] for p in table["plans"]])
    np.testing.assert_array_equal(mine["expected_secs"], [p["expected_secs"] for p in table["plans"]])
    assert mine["first_edge"] == [p["first_edge"] for p in table["plans"]]
    assert len(set(np.round(mine["pmax"], 6))) > 1  # it does depend on the time


def test_now_or_later_with_a_deadline_agrees_with_the_day_table(fitted, cli):
    models, py_file, _ = fitted
    table = cli("plan", "--model", py_file, "--from", "Kitchen", "--task", "F Station",
                "--day-table", "--days", "1", "--step-mins", "180", "--deadline", "100",
                json_output=True)
    plans = table["plans"]
    times = np.array([p["time"] for p in plans])
    mine = models.now_or_later("Kitchen", "F Station", times, deadline=100)
    assert mine["deadline_secs"] == table["deadline_secs"] == 100
    assert mine["bucket_secs"] == table["bucket_secs"] == 1.0
    for key in ("deadline_probability", "min_time_probability", "pmax"):
        np.testing.assert_array_equal(mine[key], [p[key] for p in plans], err_msg=key)
    assert mine["deadline_first_edge"] == [p["deadline_first_edge"] for p in plans]
    # The deadline plan is never less likely in time than the expected-time plan, nor than Pmax.
    assert np.all(mine["min_time_probability"] <= mine["deadline_probability"])
    assert np.all(mine["deadline_probability"] <= mine["pmax"])
    # One start time is the plan of that time alone.
    alone = models.plan("Kitchen", "F Station", float(times[4]), deadline=100)
    assert alone["probability"] == mine["deadline_probability"][4]
    assert "deadline_probability" not in models.now_or_later("Kitchen", "F Station", times)
    with pytest.raises(ValueError, match="bucket_secs: the bucket width 101 s is wider than the deadline 100 s"):
        models.now_or_later("Kitchen", "F Station", times, deadline=100, bucket_secs=101)
    with pytest.raises(ValueError, match="deadline: nan is not a finite number|deadline: NaN is not a finite number"):
        models.now_or_later("Kitchen", "F Station", times, deadline=float("nan"))
    with pytest.raises(ValueError, match="bucket_secs: only with deadline"):
        models.now_or_later("Kitchen", "F Station", times, bucket_secs=1.0)


def test_a_model_file_of_the_cli_loads(fitted):
    models, _, cli_file = fitted
    loaded = load_edge_models(cli_file)
    assert loaded.edges == models.edges and loaded.nodes == models.nodes
    for t in TIMES:
        np.testing.assert_array_equal(loaded.predict(t)["success_probability"],
                                      models.predict(t)["success_probability"])
        theirs, mine = loaded.plan("Station", "F Kitchen", t), models.plan("Station", "F Kitchen", t)
        their_policy, my_policy = theirs.pop("policy"), mine.pop("policy")
        assert theirs == mine
        for key in ("node", "automaton_state", "edge", "pmax"):
            assert np.array_equal(their_policy[key], my_policy[key]), key


def test_bad_input(fitted, tmp_path, repo):
    models, py_file, _ = fitted
    with pytest.raises(ValueError, match=r'start: unknown node "Statoin" \(did you mean "Station"\?\)'):
        models.plan("Statoin", "F Kitchen", TIMES[0])
    with pytest.raises(ValueError, match=r'task: .*"Kitchn"'):
        models.plan("Station", "F Kitchn", TIMES[0])
    with pytest.raises(ValueError, match="task: "):
        models.plan("Station", "F (Kitchen", TIMES[0])
    with pytest.raises(ValueError, match="time: nan is not a finite number|time: NaN is not a finite number"):
        models.predict(float("nan"))
    with pytest.raises(ValueError, match=r"times\[1\]: inf is not a finite number"):
        models.now_or_later("Station", "F Kitchen", [TIMES[0], float("inf")])
    with pytest.raises(ValueError, match=r"prior: 1.5 is not a probability in \[0, 1\]"):
        EdgeModels.fit(repo / EDGES, prior=1.5)
    with pytest.raises(ValueError, match="holdout: 1 is not a number strictly between 0 and 1"):
        EdgeModels.fit(repo / EDGES, holdout=1.0)
    with pytest.raises(FileNotFoundError, match="no-such-edges"):
        EdgeModels.fit(tmp_path / "no-such-edges")
    with pytest.raises(FileNotFoundError, match="missing.cmt"):
        load_edge_models(tmp_path / "missing.cmt")
    data = bytearray(py_file.read_bytes())
    data[len(data) // 2] ^= 0x55
    damaged = tmp_path / "damaged.cmt"
    damaged.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="damaged.cmt"):
        load_edge_models(damaged)
    edges = tmp_path / "edges"
    edges.mkdir()
    (edges / "A_B.data").write_text("100 5 1\n200 nan 1\n")
    with pytest.raises(ValueError, match=r"A_B.data"):
        EdgeModels.fit(edges)


# (start, task, hour of 2014-09-04 UTC, deadline, confidence, bucket_secs): the README's trip,
# trips of tests/cli/topo_deadline.rs, a two-step task in buckets of 2.5 s, and a deadline
# of a day (buckets of 144 s).
DEADLINES = [("Kitchen", "F Station", 14, 100, 0.5, None),
             ("LabDoor2", "F Kitchen", 14, 80, None, None),
             ("Station", "F (Printer & F Kitchen)", 10, 300, 0.9, 2.5),
             ("Station", "!Ramp1 U Kitchen", 3, 86400, None, None)]


@pytest.mark.parametrize(("start", "task", "hour", "deadline", "confidence", "bucket"), DEADLINES)
def test_deadline_plan_agrees_with_chronomap_plan_deadline(fitted, cli, start, task, hour,
                                                           deadline, confidence, bucket):
    models, py_file, _ = fitted
    time = 1409788800.0 + 3600.0 * hour
    options = {}
    args = ["plan", "--model", py_file, "--from", start, "--task", task, "--time", time,
            "--deadline", deadline]
    if confidence is not None:
        options["confidence"] = confidence
        args += ["--confidence", confidence]
    if bucket is not None:
        options["bucket_secs"] = bucket
        args += ["--bucket-secs", bucket]
    mine = models.plan(start, task, time, deadline=deadline, **options)
    theirs = cli(*args, json_output=True)
    assert set(mine) == set(theirs)
    for key in theirs:
        if key == "curve":
            np.testing.assert_array_equal(mine[key], np.array(theirs[key]))
        elif key != "seconds":  # the time spent planning
            assert mine[key] == theirs[key], key
    curve = mine["curve"]
    assert curve.dtype == np.float64 and curve.shape == (len(theirs["curve"]), 3)
    assert mine["bucket_secs"] == (bucket or max(deadline / 600, 1.0))
    # The deadline plan is never behind the expected-time plan, at any d up to the deadline
    # (the planner counts values within 1e-12 of 0 as 0: at 72 s of the README's trip the
    # expected-time plan has 1.01e-12 where the deadline plan has 0).
    assert np.all(curve[:, 1] >= curve[:, 2] - 1e-9)
    assert mine["probability"] == curve[-1, 1] and mine["min_time_probability"] == curve[-1, 2]
    assert mine["reaches_confidence"] == (mine["probability"] >= (confidence or 0.95))
    # Without a deadline: the plan as before, whose summary the deadline plan carries.
    plain = models.plan(start, task, time)
    assert (plain["pmax"], plain["expected_secs"], plain["first_edge"]) == (
        mine["pmax"], mine["expected_secs"], mine["min_time_first_edge"])


def test_a_short_deadline_takes_another_way(fitted):
    models, _, _ = fitted
    fast = models.plan("Kitchen", "F Station", 1409839200.0, deadline=100, confidence=0.5)
    assert fast["first_edge"] == "Kitchen_Ramp2"
    assert fast["min_time_first_edge"] == "Kitchen_GroundCentral"
    assert fast["reaches_confidence"] and fast["probability"] > 5 * fast["min_time_probability"]
    assert fast["shortest_deadline_secs"] <= 100
    # With time to spare both plans are the same.
    slow = models.plan("Kitchen", "F Station", 1409839200.0, deadline=600)
    assert slow["first_edge"] == slow["min_time_first_edge"]


def test_bad_deadlines(fitted):
    models, _, _ = fitted
    t = TIMES[2]
    for deadline in (0, -5.0, float("nan"), float("inf"), -0.0):
        with pytest.raises(ValueError, match=r"^deadline: .* is not a finite number of seconds > 0"):
            models.plan("Kitchen", "F Station", t, deadline=deadline)
    for confidence in (1.5, -0.1, float("nan")):
        with pytest.raises(ValueError, match=r"^confidence: .* is not a probability in \[0, 1\]"):
            models.plan("Kitchen", "F Station", t, deadline=100, confidence=confidence)
    for bucket in (0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match=r"^bucket_secs: .* is not a finite number of seconds > 0"):
            models.plan("Kitchen", "F Station", t, deadline=100, bucket_secs=bucket)
    with pytest.raises(ValueError, match=r"^confidence: only with deadline"):
        models.plan("Kitchen", "F Station", t, confidence=0.9)
    with pytest.raises(ValueError, match=r"^bucket_secs: only with deadline"):
        models.plan("Kitchen", "F Station", t, bucket_secs=1.0)
    # More than 10^6 cells: 18 product states × 100,001 buckets, refused before the work.
    with pytest.raises(ValueError, match=r"^bucket_secs: the deadline plan would need 18 states"):
        models.plan("Kitchen", "F Station", t, deadline=100, bucket_secs=0.001)
    with pytest.raises(ValueError, match=r'^start: unknown node "Kitchn"'):
        models.plan("Kitchn", "F Station", t, deadline=100)
    with pytest.raises(TypeError):
        models.plan("Kitchen", "F Station", t, deadline="100")


def test_observe_learns_the_later_weeks_as_topo_observe_does(repo, cli, tmp_path):
    """Fitted on the weeks before 2014-08-27 and taught the weeks after, as `chronomap topo
    split` + `topo fit` + `topo observe` do: the same file, bit for bit; the duration intervals
    adapted to every successful traversal, and these models unchanged."""
    before, after = tmp_path / "before", tmp_path / "after"
    cli("topo", "split", "--edges", repo / EDGES, "--at", "2014-08-27", "--before", before,
        "--after", after)
    models = EdgeModels.fit(before)
    cli_fitted, cli_observed = tmp_path / "fitted.cmt", tmp_path / "observed.cmt"
    models.save(cli_fitted)
    report = cli("topo", "observe", cli_fitted, "--edges", after, "-o", cli_observed,
                 json_output=True)
    learnt = models.observe(after)
    assert models.adapted_traversals == 0
    assert learnt.adapted_traversals == report["adapted_traversals"] == 5509
    assert learnt.edges == models.edges + ["Ramp1_WayPoint2"]
    learnt.save(tmp_path / "python.cmt")
    assert (tmp_path / "python.cmt").read_bytes() == cli_observed.read_bytes()
    # The later traversals ran longer than expected: the upper ends moved up.
    door = models.edges.index("LabDoor1_LabDoor2")
    fitted_upper = models.predict(TIMES[2])["duration_upper_secs"][door]
    learnt_upper = learnt.predict(TIMES[2])["duration_upper_secs"][door]
    assert learnt_upper > fitted_upper + 5.0
    # The same attempts again: refused, naming the file and the attempt.
    with pytest.raises(ValueError, match=r"\.data: attempt 1: .*earlier"):
        learnt.observe(after)
    with pytest.raises(FileNotFoundError):
        models.observe(tmp_path / "missing")
