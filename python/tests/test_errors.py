"""Bad input raises ValueError or TypeError naming the argument and element, never crashes the
interpreter, and leaves the model as it was."""

from __future__ import annotations

import numpy as np
import pytest

import chronomap

NAN, INF = float("nan"), float("inf")


@pytest.fixture
def door():
    return chronomap.Fremen(order=2).observe([0.0, 600.0, 1200.0], [0.0, 1.0, 1.0])


@pytest.mark.parametrize("times, values, message", [
    ([0, 600, NAN], [0, 1, 0], "observation 3 (times[2]): time NaN is not a finite number"),
    ([0, INF], [0, 1], "observation 2 (times[1]): time inf is not a finite number"),
    ([-5, 0], [0, 1], "observation 1 (times[0]): time -5 is negative (times are seconds >= 0)"),
    ([0, 10, 5], [0, 1, 0],
     "observation 3 (times[2]): time 5 is earlier than the previous observation at 10"),
    ([0, 10], [0, 1.5], "observation 2 (values[1]): value 1.5 is outside [0, 1]"),
    ([0, 10], [0, -0.1], "observation 2 (values[1]): value -0.1 is outside [0, 1]"),
    ([0, 10], [NAN, 0], "observation 1 (values[0]): value NaN is not a finite number"),
    ([0, 10, 20], [0, 1], "3 times but 2 values"),
])
def test_bad_observations_name_the_element(times, values, message):
    model = chronomap.Fremen(order=2)
    with pytest.raises(ValueError) as error:
        model.observe(times, values)
    assert str(error.value) == message
    assert model.observations == 0


def test_a_rejected_batch_changes_nothing(door):
    before = door.predict(np.arange(0, 86400, 3600.0))
    # Times must not go backwards across batches either.
    with pytest.raises(ValueError, match=r"observation 1 \(times\[0\]\): time 100 is earlier "
                                         r"than the previous observation at 1200"):
        door.observe([100.0, 5000.0], [1.0, 0.0])
    with pytest.raises(ValueError, match=r"observation 2 \(values\[1\]\)"):
        door.observe([2000.0, 3000.0], [1.0, 2.0])
    assert door.observations == 3
    assert np.array_equal(door.predict(np.arange(0, 86400, 3600.0)), before)


@pytest.mark.parametrize("bad, error, message", [
    (np.array(["a", "b"]), TypeError,
     "times: expected an array of real numbers (float64), got dtype <U1"),
    (np.array([1 + 2j, 3j]), TypeError,
     "times: expected an array of real numbers (float64), got dtype complex128"),
    (None, TypeError, "times: expected an array of numbers, got NoneType"),
    ("12", TypeError, "times: expected an array of numbers, got str"),
    (np.zeros((2, 2)), ValueError, "times: expected a 1-D array, got shape (2, 2)"),
    (np.float64(3.0), ValueError, "times: expected a 1-D array, got shape ()"),
])
def test_wrong_dtypes_and_shapes(bad, error, message):
    with pytest.raises(error) as raised:
        chronomap.Fremen(order=2).observe(bad, [0.0, 1.0])
    assert str(raised.value) == message


def test_predict_rejects_times_that_are_not_times(door):
    with pytest.raises(ValueError, match=r"^times\[1\]: time NaN is not a finite number$"):
        door.predict(np.array([0.0, NAN]))
    with pytest.raises(ValueError, match=r"^times\[0\]: time -1 is negative"):
        door.predict(-1.0)
    with pytest.raises(ValueError, match=r"^times\[0\]: time inf is not a finite number$"):
        door.entropy([INF])
    with pytest.raises(TypeError, match="^times: expected an array of real numbers"):
        door.predict(np.array(["noon"]))


def test_other_dtypes_and_layouts_are_converted_not_refused(door):
    t = np.arange(0, 7 * 86400, 600, dtype=np.int64)
    expected = door.predict(t.astype(np.float64))
    assert np.array_equal(door.predict(t), expected)                       # int64
    assert np.array_equal(door.predict(t.astype(np.float32)), expected)    # exact for these
    assert np.array_equal(door.predict(t.astype(">f8")), expected)         # big-endian
    strided = np.repeat(t.astype(np.float64), 2)[::2]                      # not contiguous
    assert not strided.flags["C_CONTIGUOUS"]
    assert np.array_equal(door.predict(strided), expected)
    assert door.predict(np.array([], dtype=np.float64)).shape == (0,)
    # Booleans are states.
    m = chronomap.Mean().observe(np.array([0.0, 1.0, 2.0]), np.array([True, False, True]))
    assert m.predict(3.0) == pytest.approx(2 / 3)


def test_empty_input():
    assert chronomap.Fremen(order=2).observe([], []).observations == 0
    with pytest.raises(ValueError, match="not enough data: no observations"):
        chronomap.Fremen().observe([], [])          # `auto` needs data to choose on
    with pytest.raises(ValueError, match="has observed nothing yet"):
        chronomap.model("auto").save("never-written.cmm")


def test_settings_are_checked():
    with pytest.raises(ValueError, match='cannot parse model "fremen:x": order "x" is not a '
                                         "whole number or 'auto'"):
        chronomap.model("fremen:x")
    with pytest.raises(ValueError, match="^order: -1 is negative$"):
        chronomap.Fremen(order=-1)
    with pytest.raises(TypeError, match="^order: expected an int or \"auto\", got float$"):
        chronomap.Fremen(order=2.5)
    with pytest.raises(ValueError, match=r"^holdout: 1.5 is not a fraction in \(0, 1\)$"):
        chronomap.Fremen(holdout=1.5)
    with pytest.raises(ValueError, match="^criterion: 'mse' is not one of"):
        chronomap.Fremen(criterion="mse")
    with pytest.raises(ValueError, match="^periods: "):
        chronomap.Fremen(periods="fortnight")
    with pytest.raises(ValueError, match="^confidence: "):
        chronomap.Fremen(order=2).observe([0.0], [1.0]).anomalies([1.0], [0.0], confidence=0.2)


def test_the_cli_gives_the_same_message_for_a_bad_spec(cli, tmp_path):
    train = tmp_path / "train.txt"
    train.write_text("0 0\n600 1\n")
    done = cli("fit", "--train", train, "--model", "fremen:x", "-o", tmp_path / "m.cmm",
               check=False)
    assert done.returncode == 2
    with pytest.raises(ValueError) as error:
        chronomap.model("fremen:x")
    assert str(error.value) in done.stderr


def test_files_that_are_not_models(tmp_path, door):
    with pytest.raises(FileNotFoundError, match="missing.cmm: cannot read"):
        chronomap.load(tmp_path / "missing.cmm")
    path = tmp_path / "door.cmm"
    door.save(path)
    data = bytearray(path.read_bytes())
    data[-3] ^= 0x40
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="checksum mismatch .*: the file is corrupted"):
        chronomap.load(path)
    path.write_bytes(b"not a model\n")
    with pytest.raises(ValueError, match="door.cmm: "):
        chronomap.load(path)
    with pytest.raises(OSError, match="not a regular file"):
        chronomap.load("/dev/zero")          # bounded: refused, not read to exhaustion
    with pytest.raises(FileNotFoundError, match="nope.txt"):
        chronomap.read_pairs(tmp_path / "nope.txt")
    bad = tmp_path / "bad.txt"
    bad.write_text("0 0\n10 1\n5 0\n")
    with pytest.raises(ValueError, match=r"bad.txt:3: time: \"5\" is earlier than the time 10"):
        chronomap.read_pairs(bad)
