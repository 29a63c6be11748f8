"""chronomap.Client against a `chronomap serve` started for the tests (temporary data
directory, a free loopback port, a token), with the bundled Greg door data (Lincoln, 2016)."""

from __future__ import annotations

import re
import socket
import subprocess

import numpy as np
import pytest

import chronomap._native as native
from chronomap.client import Client, ServiceError, read_token

TRAINING = "data/door_greg_2016/training_data.txt.xz"
TOKEN = "python-tests-0123456789abcdef-0123456789"
# The first test week, every hour (as `chronomap client predict --from --to --step` asks).
FROM, TO, STEP = 1458518400.0, 1459123200.0, 3600.0


@pytest.fixture(scope="module")
def service(cli, tmp_path_factory):
    """A running service: its URL and token file; stopped (SIGTERM) at the end."""
    folder = tmp_path_factory.mktemp("service")
    token_file = folder / "token"
    token_file.write_text(TOKEN + "\n")
    token_file.chmod(0o600)  # the service refuses a token file others can read
    process = subprocess.Popen(
        [str(cli.binary), "serve", "--data", str(folder / "data"), "--listen", "127.0.0.1:0",
         "--token-file", str(token_file)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        line = process.stdout.readline()
        found = re.search(r"listening on (http://127\.0\.0\.1:\d+)", line)
        assert found, f"chronomap serve did not start: {line!r} {process.stderr.read() if process.poll() is not None else ''}"
        yield found.group(1), token_file
    finally:
        process.terminate()
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:  # pragma: no cover - a hung service
            process.kill()
            process.wait()
        process.stdout.close()
        process.stderr.close()


@pytest.fixture(scope="module")
def client(service):
    url, token_file = service
    return Client(url, token=read_token(token_file))


@pytest.fixture(scope="module")
def door(repo):
    return native.read_pairs(repo / TRAINING)


def hours():
    n = int(np.floor((TO - FROM) / STEP)) + 1
    return FROM + STEP * np.arange(n)


def test_observations_added_from_python_predict_as_the_cli_and_a_local_model(
        client, service, door, cli, repo):
    url, token_file = service
    times, values = door
    ack = client.add("greg-door", times, values, model="fremen:2")
    assert ack["observations"] == len(times) == 96_480
    assert client.health()["status"] == "ok" and client.health()["auth"] is True

    t = hours()
    p = client.predict("greg-door", t)
    assert isinstance(p, np.ndarray) and p.shape == t.shape
    # The command-line client asks the same service the same question.
    theirs = cli("client", "--url", url, "--token-file", token_file, "predict", "greg-door",
                 "--from", FROM, "--to", TO, "--step", STEP, json_output=True)
    np.testing.assert_array_equal(theirs["times"], t)
    np.testing.assert_array_equal(p, theirs["probability"])
    np.testing.assert_array_equal(client.entropy("greg-door", t), theirs["entropy"])
    # And a model fitted here on the same observations predicts the same.
    local = native.model("fremen:2").observe(times, values)
    np.testing.assert_allclose(p, local.predict(t), rtol=0, atol=1e-12)
    assert isinstance(client.predict("greg-door", float(t[10])), float)
    assert client.predict("greg-door", float(t[10])) == pytest.approx(p[10], rel=1e-12)
    # Order 0 is the mean of the observations.
    np.testing.assert_allclose(client.predict("greg-door", t, order=0), values.mean(), rtol=1e-9)

    # Observations the command line adds are predicted the same in Python.
    cli("client", "--url", url, "--token-file", token_file, "add", "greg-cli", "--file",
        repo / TRAINING, "--model", "fremen:2", json_output=True)
    np.testing.assert_array_equal(client.predict("greg-cli", t), p)
    np.testing.assert_array_equal(client.forecast(["greg-door", "greg-cli"], float(t[5])),
                                  [p[5], p[5]])
    theirs = cli("client", "--url", url, "forecast", "--ids", "greg-door,greg-cli", "--at",
                 t[5], json_output=True)
    assert theirs["probability"] == [p[5], p[5]]

    got_t, got_v = client.observations("greg-door")
    np.testing.assert_array_equal(got_t, times)
    np.testing.assert_array_equal(got_v, values)
    listed = {m["id"]: m for m in client.list()}
    assert listed["greg-door"]["observations"] == 96_480 and listed["greg-door"]["model"] == "fremen:2"
    assert set(client.ids()) >= {"greg-door", "greg-cli"}
    view = client.view("greg-door")
    assert view["first_time"] == times[0] and view["last_time"] == times[-1]
    assert len(view["components"]) == 2


def test_create_remove_and_service_errors(client, service):
    url, _ = service
    assert client.create("kitchen", "hist:24")["observations"] == 0
    assert client.create("kitchen", "hist:24")["observations"] == 0  # the same again: no-op
    with pytest.raises(ServiceError) as error:
        client.create("kitchen", "stm")
    assert error.value.status == 409 and error.value.kind == "conflict"
    assert isinstance(error.value, RuntimeError)
    client.remove("kitchen")
    with pytest.raises(ServiceError, match=r'^404 Not Found: .*"kitchen"') as error:
        client.predict("kitchen", [0.0])
    assert error.value.status == 404 and error.value.kind == "not_found"
    assert "kitchen" in error.value.reason
    # Bad observations are refused by the service, naming the element at fault.
    with pytest.raises(ServiceError, match=r"^400 Bad Request: model \"lab\", observation 1: value 1.5 is outside \[0, 1\]") as error:
        client.add("lab", [0.0, 60.0], [0.0, 1.5], model="fremen:2")
    assert error.value.kind == "bad_request"
    with pytest.raises(ServiceError, match=r"^400 Bad Request: model \"lab\", .*time 30 is earlier"):
        client.add("lab", [0.0, 60.0, 30.0], [0.0, 1.0, 1.0], model="fremen:2")
    # Writes need the token; reads do not.
    anonymous = Client(url)
    with pytest.raises(ServiceError, match="^401 Unauthorized") as error:
        anonymous.add("lab", [0.0], [1.0], model="fremen:2")
    assert error.value.kind == "unauthorized"
    assert anonymous.health()["status"] == "ok"
    with pytest.raises(ServiceError, match="^401"):
        Client(url, token="wrong-token-wrong-token").remove("greg-door")


def test_arguments_are_checked_before_sending(client):
    with pytest.raises(ValueError, match="2 times but 1 values"):
        client.add("lab", [0.0, 1.0], [1.0])
    with pytest.raises(TypeError, match=r"values: expected an array of"):
        client.add("lab", [0.0], ["x"])
    with pytest.raises(ValueError, match=r"times: expected a 1-D array, got shape \(2, 2\)"):
        client.predict("greg-door", np.zeros((2, 2)))
    with pytest.raises(TypeError, match="ids: expected a list of model ids, got one str"):
        client.forecast("greg-door", 0.0)
    with pytest.raises(ValueError, match='is not an http:// URL'):
        Client("https://robot:8470")


def test_no_service_is_a_connection_error():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ConnectionError, match=rf"http://127.0.0.1:{port}/v1/health"):
        Client(f"http://127.0.0.1:{port}").health()


def test_pandas_times_and_states_go_to_the_service_as_seconds(client):
    pd = pytest.importorskip("pandas")
    # A door seen every hour for a week from 2016-03-21T00:00+01:00 (Prague), open 08-18 UTC.
    times = pd.date_range("2016-03-21", periods=7 * 24, freq="h", tz="Europe/Prague")
    seconds = 1458514800.0 + 3600.0 * np.arange(7 * 24)          # 2016-03-20T23:00Z onwards
    is_open = pd.Series(((seconds % 86400) >= 8 * 3600) & ((seconds % 86400) < 18 * 3600))
    assert client.add("pandas-door", pd.Series(times), is_open, model="fremen:2")[
        "observations"] == 7 * 24
    client.add("float-door", seconds, is_open.to_numpy(np.float64), model="fremen:2")

    got_t, got_v = client.observations("pandas-door")
    np.testing.assert_array_equal(got_t, seconds)
    np.testing.assert_array_equal(got_v, is_open.to_numpy(np.float64))
    frame = client.observations("pandas-door", as_frame=True)
    assert list(frame.columns) == ["time", "value"]
    assert (pd.DatetimeIndex(frame["time"]) == times).all()

    later = pd.date_range("2016-03-28", periods=24, freq="h", tz="UTC")
    later_s = 1459123200.0 + 3600.0 * np.arange(24)
    p = client.predict("pandas-door", later, as_series=True)
    assert isinstance(p, pd.Series) and p.name == "p" and (p.index == later).all()
    np.testing.assert_array_equal(p.to_numpy(), client.predict("float-door", later_s))
    np.testing.assert_array_equal(client.entropy("pandas-door", later.to_numpy()),
                                  client.entropy("float-door", later_s))
    noon = pd.Timestamp("2016-03-28 14:00", tz="Europe/Prague")   # 12:00 UTC (CEST)
    assert client.predict("pandas-door", noon) == client.predict("float-door", 1459166400.0)
    np.testing.assert_array_equal(client.forecast(["pandas-door", "float-door"], noon),
                                  [p.iloc[12], p.iloc[12]])
    with pytest.raises(ValueError, match=r"^times\[1\]: NaT"):
        client.predict("pandas-door", pd.Series([noon, pd.NaT]))


def test_intervals_of_a_continuous_state_hold_fresh_values_and_match_the_service(client, service):
    import json
    import urllib.request

    url, _ = service
    # A temperature in [10, 30]: a Beta law whose mean follows the time of day, one value
    # every two minutes for six weeks, learnt online by fremen:2 with its second moment.
    rng = np.random.default_rng(7)
    day = 86_400.0

    def draw(t):
        mean = 0.5 + 0.3 * np.cos(2 * np.pi * t / day)
        k = 12.0
        return 10.0 + 20.0 * rng.beta(mean * k, (1 - mean) * k)

    t = 1_700_000_000.0 + 120.0 * np.arange(6 * 7 * 720)
    client.create("temperature", "fremen:2", range=(10.0, 30.0))
    client.add("temperature", t, draw(t))
    fresh = t[-1] + 60.0 + day * rng.random(4000)
    fresh.sort()
    lower, upper = client.interval("temperature", fresh)
    assert lower.shape == upper.shape == fresh.shape
    assert np.all((10.0 <= lower) & (lower <= upper) & (upper <= 30.0))
    inside = np.mean((lower <= (v := draw(fresh))) & (v <= upper))
    print(f"90 % intervals hold {inside:.4f} of 4,000 fresh values")
    assert 0.87 <= inside <= 0.93, inside  # 4,000 draws: 2 SE ≈ 0.01

    # The same numbers as the service's JSON answer.
    request = urllib.request.Request(
        f"{url}/v1/predict", method="POST", headers={"Content-Type": "application/json"},
        data=json.dumps({"id": "temperature", "times": fresh[:5].tolist(),
                         "coverage": 0.5}).encode())
    with urllib.request.urlopen(request) as response:
        answer = json.load(response)
    lo50, hi50 = client.interval("temperature", fresh[:5], coverage=0.5)
    assert lo50.tolist() == answer["lower"] and hi50.tolist() == answer["upper"]
    assert np.all((lower[:5] <= lo50) & (hi50 <= upper[:5]))  # narrower at 50 %

    one = client.interval("temperature", float(fresh[0]))
    assert one == (lower[0], upper[0])
    frame = client.interval("temperature", fresh[:3], as_frame=True)
    assert list(frame.columns) == ["time", "lower", "upper"]
    np.testing.assert_array_equal(frame["lower"].to_numpy(), lower[:3])
    assert str(frame["time"].dt.tz) == "UTC"

    with pytest.raises(ValueError, match="coverage: 1.5 is not strictly between 0 and 1"):
        client.interval("temperature", fresh, coverage=1.5)
    with pytest.raises(ValueError, match="coverage: NaN is not"):
        client.interval("temperature", fresh, coverage=float("nan"))
    client.create("door-state", "fremen:2")
    client.add("door-state", t[:100], np.zeros(100))
    with pytest.raises(ValueError, match='model "door-state" has no prediction intervals'):
        client.interval("door-state", fresh)
