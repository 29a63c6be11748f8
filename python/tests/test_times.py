"""Times as a notebook has them: numpy datetime64 (any unit, UTC), pandas Timestamps, Series
and DatetimeIndex (zone-aware ones converted to UTC), Python datetimes; states as booleans and
ints; pandas objects out with ``as_series`` / ``as_frame``. Every conversion is compared with
hand-computed unix seconds, and every model with the same model fed float seconds."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

import chronomap
from chronomap import _time

pd = pytest.importorskip("pandas")

# 2016-03-25T12:00Z: 16885 days after 1970-01-01 (46 years with 11 leap days, then 84 days
# of 2016) at 86400 s, plus 12 h.
NOON = 16885 * 86400 + 12 * 3600
assert NOON == 1458907200


@pytest.mark.parametrize("value, seconds", [
    (np.datetime64("2016-03-25T12:00", "m"), 1458907200.0),
    (np.datetime64("2016-03-25T12", "h"), 1458907200.0),
    (np.datetime64("2016-03-25", "D"), 1458864000.0),
    (np.datetime64("2016-03-25T12:00:00.250", "ms"), 1458907200.25),
    (np.datetime64("2016-03-25T12:00:00.000125", "us"), 1458907200.000125),
    (np.datetime64("2016-03-25T12:00:00.500000000", "ns"), 1458907200.5),
    (np.datetime64("2016-03", "M"), 1456790400.0),       # 2016-03-01: 16861 days
    (np.datetime64("2016", "Y"), 1451606400.0),          # 2016-01-01: 16801 days
    (np.datetime64("1970-01-08", "W"), 604800.0),        # one week
    (np.array(["2016-03-25T12:00"], dtype="datetime64[10s]")[0], 1458907200.0),
    (dt.datetime(2016, 3, 25, 12, 0), 1458907200.0),                     # naive: UTC
    (dt.datetime(2016, 3, 25, 13, 0, tzinfo=dt.timezone(dt.timedelta(hours=1))), 1458907200.0),
    (dt.datetime(2016, 3, 25, 12, 0, 0, 250000, tzinfo=dt.timezone.utc), 1458907200.25),
    (dt.date(2016, 3, 25), 1458864000.0),                                # midnight UTC
    (pd.Timestamp("2016-03-25 12:00"), 1458907200.0),                    # naive: UTC
    (pd.Timestamp("2016-03-25 13:00", tz="Europe/Prague"), 1458907200.0),  # CET, +01:00
    (pd.Timestamp("2016-03-28 14:00", tz="Europe/Prague"), 1459166400.0),  # CEST, +02:00
    (pd.Timestamp("2016-03-25 12:00:00.500000", tz="UTC").as_unit("ns"), 1458907200.5),
])
def test_one_time_is_its_unix_seconds(value, seconds):
    assert _time.seconds(value, "times") == seconds
    # The same number wherever one time is taken.
    model = chronomap.Fremen(order=2).observe([0.0, 600.0], [0.0, 1.0])
    assert model.predict(value) == model.predict(seconds)


def test_arrays_of_times_of_every_kind_are_the_same_seconds():
    expected = np.array([1458903600.0, 1458907200.0, 1458910800.0])  # 11:00, 12:00, 13:00 UTC
    prague = pd.date_range("2016-03-25 12:00", periods=3, freq="h", tz="Europe/Prague")
    for times in [
        expected.astype("datetime64[s]"),
        np.array(["2016-03-25T11:00", "2016-03-25T12:00", "2016-03-25T13:00"], "datetime64[m]"),
        prague,                                   # DatetimeIndex, zone-aware
        prague.tz_convert("UTC").tz_localize(None),   # DatetimeIndex, naive
        pd.Series(prague),                        # Series, zone-aware
        pd.Series(prague.tz_convert("America/New_York")),
        pd.Series(prague.astype("datetime64[s, Europe/Prague]")),
        [dt.datetime(2016, 3, 25, 11), dt.datetime(2016, 3, 25, 12), dt.datetime(2016, 3, 25, 13)],
        list(prague),                             # a list of zone-aware Timestamps
        np.array(list(prague), dtype=object),
    ]:
        np.testing.assert_array_equal(_time.seconds(times, "times"), expected, err_msg=repr(times))


def test_numbers_are_left_to_the_native_module():
    for numbers in [np.arange(3.0), [1.0, 2.0], (1, 2), 5.0]:
        assert _time.seconds(numbers, "times") is None
    # A pandas Series of numbers comes back as its numpy array.
    np.testing.assert_array_equal(_time.seconds(pd.Series([1.0, 2.5]), "times"), [1.0, 2.5])


def door_frame():
    """A door seen every 20 minutes for two weeks in Prague local time: open 08:00-18:00 UTC."""
    times = pd.date_range("2016-03-07", periods=14 * 72, freq="20min", tz="Europe/Prague")
    hour = (times.tz_convert("UTC").hour + times.minute / 60).to_numpy()
    return pd.DataFrame({"t": times, "open": (hour >= 8) & (hour < 18)})


def test_a_model_fed_pandas_predicts_as_one_fed_float_seconds():
    df = door_frame()
    seconds = (df["t"].dt.tz_convert("UTC").dt.tz_localize(None)
               - pd.Timestamp("1970-01-01")) // pd.Timedelta("1s")
    seconds = seconds.to_numpy().astype(np.float64)
    assert seconds[0] == 1457305200.0   # 2016-03-07T00:00+01:00 = 2016-03-06T23:00Z

    for spec in ["fremen:2", "hist:24", "pergam:2"]:
        from_pandas = chronomap.model(spec).observe(df["t"], df["open"])
        from_floats = chronomap.model(spec).observe(seconds, df["open"].to_numpy(np.float64))
        assert from_pandas.span == from_floats.span == (seconds[0], seconds[-1])
        later = pd.date_range("2016-03-21", periods=48, freq="h", tz="UTC")
        later_s = 1458518400.0 + 3600.0 * np.arange(48)
        np.testing.assert_array_equal(from_pandas.predict(later), from_floats.predict(later_s))
        np.testing.assert_array_equal(from_pandas.predict(later.to_numpy()),
                                      from_floats.predict(later_s))
        np.testing.assert_array_equal(from_pandas.entropy(later), from_floats.entropy(later_s))
        # One Timestamp: a float, as one number gives.
        noon = from_pandas.predict(pd.Timestamp("2016-03-21 12:00", tz="UTC"))
        assert isinstance(noon, float) and noon == from_floats.predict(1458561600.0)

    door = chronomap.Fremen(order=2).observe(df["t"], df["open"])
    assert door.predict(pd.Timestamp("2016-03-21 12:00", tz="UTC")) > 0.9
    assert door.predict(pd.Timestamp("2016-03-21 03:00", tz="UTC")) < 0.1


def test_states_may_be_booleans_ints_and_nullable_pandas():
    t = 600.0 * np.arange(6)
    as_floats = chronomap.Fremen(order=1).observe(t, [0.0, 1.0, 1.0, 0.0, 1.0, 0.0])
    for states in [[False, True, True, False, True, False],
                   np.array([0, 1, 1, 0, 1, 0], dtype=np.int8),
                   pd.Series([False, True, True, False, True, False]),
                   pd.Series([0, 1, 1, 0, 1, 0], dtype="Int64"),
                   pd.Series([False, True, True, False, True, False], dtype="boolean")]:
        model = chronomap.Fremen(order=1).observe(t, states)
        np.testing.assert_array_equal(model.predict(t), as_floats.predict(t))
    with pytest.raises(ValueError, match=r"^observation 2 \(values\[1\]\): value NaN is not"):
        chronomap.Fremen(order=1).observe(t[:3], pd.Series([True, None, False], dtype="boolean"))


def test_pandas_out():
    df = door_frame()
    door = chronomap.Fremen(order=2).observe(df["t"], df["open"])
    hours = pd.date_range("2016-03-21", periods=24, freq="h", tz="Europe/Prague")
    p = door.predict(hours, as_series=True)
    assert isinstance(p, pd.Series) and p.name == "p"
    assert p.index.name == "time" and str(p.index.tz) == "UTC"
    assert (p.index == hours).all()            # the same instants, shown in UTC
    np.testing.assert_array_equal(p.to_numpy(), door.predict(hours))
    h = door.entropy(1458561600.0, as_series=True)
    assert list(h.index) == [pd.Timestamp("2016-03-21 12:00", tz="UTC")]
    assert h.iloc[0] == door.entropy(1458561600.0)

    # A closed door at noon on a weekday contradicts a confident prediction.
    noon = pd.Timestamp("2016-03-21 12:00", tz="UTC")
    found = door.anomalies([noon, noon + pd.Timedelta("1h")], [False, True], 0.9, as_frame=True)
    assert list(found.columns) == ["index", "time", "observed", "p"]
    assert found["index"].tolist() == [0] and found["time"].tolist() == [noon]
    assert found["observed"].tolist() == [0.0]


def test_grid_prediction_times_may_be_timestamps():
    t = np.arange(0, 14 * 86400, 3600.0)
    frames = np.zeros((len(t), 2, 3), np.int8)
    frames[(t % 86400) < 6 * 3600, 1, 2] = 100
    grid = chronomap.Grid.from_frames(frames, t.astype("datetime64[s]"))
    same = chronomap.Grid.from_frames(frames, t)
    at = pd.Timestamp("1970-01-16 02:00", tz="UTC")
    np.testing.assert_array_equal(grid.predict_map(at), same.predict_map(15 * 86400 + 7200.0))
    np.testing.assert_array_equal(grid.predict_map(np.datetime64("1970-01-16T02:00")),
                                  grid.predict_map(15 * 86400 + 7200.0))


@pytest.mark.parametrize("times, error, message", [
    (np.array(["2016-03-25T12:00", "NaT"], dtype="datetime64[m]"), ValueError,
     r"^times\[1\]: NaT \(not a time\) where a time is needed"),
    (pd.Series([pd.Timestamp("2016-03-25"), pd.NaT]), ValueError,
     r"^times\[1\]: NaT \(not a time\)"),
    ([dt.datetime(2016, 3, 25), "2016-03-26"], TypeError,
     r"^times: mixed kinds of elements: times\[0\] is a time \(datetime\) but times\[1\] is "
     r"str \('2016-03-26'\)"),
    (np.array([pd.Timestamp("2016-03-25"), 1458907200.0], dtype=object), TypeError,
     r"^times: mixed kinds of elements: .* times\[1\] is number"),
    (np.array([1, 2], dtype="timedelta64[s]"), TypeError,
     r"^times: timedelta64 is a duration, not a time"),
    # Texts are not parsed (an ISO 8601 text without a zone would be ambiguous).
    ("2016-03-25T12:00", TypeError, r"^times: expected an array of numbers, got str$"),
    (pd.Timestamp("2016-03-25"), ValueError, r"^times: expected a 1-D array of times, got one "
                                             r"time \(Timestamp\)$"),
])
def test_bad_times_name_the_argument(times, error, message):
    model = chronomap.Fremen(order=2)
    with pytest.raises(error, match=message):
        model.observe(times, [0.0, 1.0])
    assert model.observations == 0


def test_bad_single_times_name_the_argument():
    door = chronomap.Fremen(order=2).observe([0.0, 600.0], [0.0, 1.0])
    with pytest.raises(ValueError, match=r"^times: NaT \(not a time\)"):
        door.predict(pd.NaT)
    with pytest.raises(ValueError, match=r"^times: NaT"):
        door.predict(np.datetime64("NaT"))
    grid = chronomap.Grid.from_frames(np.zeros((1, 1, 1), np.int8), [0.0])
    with pytest.raises(ValueError, match=r"^time: NaT"):
        grid.predict_map(pd.NaT)
    with pytest.raises(TypeError, match=r"^time: expected one time \(unix seconds, datetime, "
                                        r"numpy.datetime64 or pandas.Timestamp\), got str$"):
        grid.predict_map("2016-03-25T12:00Z")
    with pytest.raises(TypeError, match=r"^time: expected one time .* got DatetimeIndex$"):
        grid.predict_map(pd.date_range("2016-03-25", periods=2, freq="D"))
