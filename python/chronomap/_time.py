"""Times as chronomap takes them, and pandas objects out.

chronomap computes with unix seconds (float64, UTC). Wherever a time or an array of times is
taken, the native module passes anything that is not already numbers through ``seconds``:

* numpy ``datetime64`` arrays and scalars of any unit (they carry no zone: read as UTC);
* pandas ``Timestamp``, ``Series``, ``Index`` / ``DatetimeIndex`` (zone-aware ones converted
  to UTC, naive ones read as UTC);
* Python ``datetime`` (naive read as UTC) and ``date`` (midnight UTC);
* lists and object arrays of those (one kind of element only).

Observed states (``values``) may be pandas Series of floats, ints or booleans, including the
nullable ``boolean`` / ``Int64`` dtypes (a missing value is NaN and refused by name).

Texts are not parsed (an ISO 8601 text without a zone is ambiguous): parse them first, e.g.
``pd.to_datetime(texts, utc=True)``. ``NaT``, timedeltas and object arrays mixing kinds are
errors naming the argument and element.
"""

from __future__ import annotations

import datetime as _dt

import numpy as np

_EPOCH = _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc)
# Ticks per second of the sub-second units, seconds per tick of the coarse fixed ones.
_TICKS = {"s": 1, "ms": 10**3, "us": 10**6, "ns": 10**9, "ps": 10**12, "fs": 10**15,
          "as": 10**18}
_COARSE = {"W": 604800, "D": 86400, "h": 3600, "m": 60}


def _is_pandas(obj) -> bool:
    return type(obj).__module__.split(".", 1)[0] == "pandas"


def _is_nat(obj) -> bool:
    return type(obj).__name__ == "NaTType" or (isinstance(obj, np.datetime64) and np.isnat(obj))


def _is_time_scalar(obj) -> bool:
    """A datetime, date, numpy datetime64 or pandas Timestamp / NaT (not a number or text)."""
    return isinstance(obj, (_dt.date, np.datetime64)) or type(obj).__name__ == "NaTType"


def _nat_error(name: str) -> ValueError:
    return ValueError(f"{name}: NaT (not a time) where a time is needed; drop or fill the "
                      f"missing times first")


def _datetime64_seconds(array: np.ndarray, name: str) -> np.ndarray:
    """float64 unix seconds of a datetime64 array of any unit (its values are UTC)."""
    unit, count = np.datetime_data(array.dtype)
    if unit not in _TICKS and unit not in _COARSE or count != 1:
        # Years and months have no fixed length and `[10ms]`-style units are multiples:
        # numpy rescales them (exactly) to a plain unit first.
        unit = unit if unit in _TICKS else "s"
        array = array.astype(f"datetime64[{unit}]")
    missing = np.isnat(array)
    if missing.any():
        if array.ndim == 0:
            raise _nat_error(name)
        raise _nat_error(f"{name}[{int(np.flatnonzero(missing)[0])}]")
    if not array.dtype.isnative:
        array = array.astype(array.dtype.newbyteorder("="))
    ticks = array.view(np.int64)
    if unit in _COARSE:
        # Whole seconds: exact below 2**53 s.
        return ticks.astype(np.float64) * _COARSE[unit]
    per_second = _TICKS[unit]
    # Whole seconds exactly, then the fraction: one rounding instead of rounding the huge tick
    # count first (1458907200123456789 ns has no exact float64).
    whole, fraction = np.divmod(ticks, per_second)
    return whole.astype(np.float64) + fraction / per_second


def _scalar_seconds(obj, name: str) -> float:
    """Unix seconds of one datetime / date / datetime64 / Timestamp."""
    if _is_nat(obj):
        raise _nat_error(name)
    if isinstance(obj, np.datetime64):
        return float(_datetime64_seconds(np.asarray(obj), name))
    if hasattr(obj, "to_datetime64"):  # a pandas Timestamp (nanoseconds, maybe a zone)
        if obj.tzinfo is not None:
            obj = obj.tz_convert("UTC").tz_localize(None)
        return float(_datetime64_seconds(np.asarray(obj.to_datetime64()), name))
    if isinstance(obj, _dt.datetime):
        if obj.tzinfo is None or obj.utcoffset() is None:
            obj = obj.replace(tzinfo=_dt.timezone.utc)
        delta = obj - _EPOCH
    else:  # a date: its midnight, UTC
        delta = _dt.datetime(obj.year, obj.month, obj.day, tzinfo=_dt.timezone.utc) - _EPOCH
    return float(delta.days * 86400 + delta.seconds) + delta.microseconds / 1e6


def _kind(obj) -> str:
    if _is_time_scalar(obj):
        return "time"
    if isinstance(obj, (int, float, np.integer, np.floating)):
        return "number"
    return type(obj).__name__


def _object_seconds(array: np.ndarray, name: str):
    """float64 seconds of an object array whose elements are all times (None if none is)."""
    flat = array.ravel()
    kinds = [_kind(item) for item in flat]
    if "time" not in kinds:
        return None
    for i, kind in enumerate(kinds):
        if kind != "time":
            first = kinds.index("time")
            raise TypeError(f"{name}: mixed kinds of elements: {name}[{first}] is a time "
                            f"({type(flat[first]).__name__}) but {name}[{i}] is {kind} "
                            f"({flat[i]!r}); give times of one kind")
    out = np.fromiter((_scalar_seconds(item, f"{name}[{i}]") for i, item in enumerate(flat)),
                      dtype=np.float64, count=len(flat))
    return out.reshape(array.shape)


def _from_pandas(obj, name: str):
    """A pandas Series / Index / array as a numpy array: datetimes as naive UTC datetime64,
    nullable numbers and booleans as float64 (a missing value as NaN)."""
    dtype = getattr(obj, "dtype", None)
    if dtype is None:
        return np.asarray(obj)
    if getattr(dtype, "tz", None) is not None:
        # Zone-aware: the same instants in UTC, then without the zone.
        values = obj.dt.tz_convert(None) if hasattr(obj, "dt") else obj.tz_convert(None)
        return np.asarray(values.to_numpy())
    if getattr(dtype, "kind", None) in ("b", "i", "u", "f") and not isinstance(dtype, np.dtype):
        # Nullable extension dtypes (boolean, Int64, Float64): pd.NA becomes NaN.
        return obj.to_numpy(dtype=np.float64, na_value=np.nan)
    return np.asarray(obj)


def seconds(obj, name: str):
    """Unix seconds of ``obj`` if it holds times: a float for one time, a float64 array for
    an array of times; None if it holds no times (numbers, or anything the native module
    then refuses with its own message). ``name`` names the argument in errors."""
    if _is_time_scalar(obj):
        return _scalar_seconds(obj, name)
    if _is_pandas(obj):
        array = _from_pandas(obj, name)
    elif isinstance(obj, np.ndarray):
        array = obj
    elif isinstance(obj, (list, tuple)):
        # Only lists that start with a time are converted here; lists of numbers go to
        # numpy once, in the native module.
        if not obj or not _is_time_scalar(obj[0]):
            return None
        array = np.empty(len(obj), dtype=object)
        array[:] = obj
    else:
        return None
    kind = array.dtype.kind
    if kind == "M":
        out = _datetime64_seconds(array, name)
        return float(out) if out.ndim == 0 else out
    if kind == "m":
        raise TypeError(f"{name}: timedelta64 is a duration, not a time; add it to a start "
                        f"time (np.datetime64('2016-03-25T12:00') + delta)")
    if kind == "O":
        out = _object_seconds(array, name)
        if out is not None:
            return out
    return array if array is not obj else None


def values(obj, name: str):
    """``obj`` (observed states) as a numpy array if it is a pandas object, else None."""
    if _is_pandas(obj):
        return _from_pandas(obj, name)
    return None


def _index(times) -> object:
    """A UTC ``DatetimeIndex`` of float64 unix seconds, exact to the nanosecond for whole
    seconds."""
    import pandas as pd

    times = np.asarray(times, dtype=np.float64)
    whole = np.floor(times)
    ns = whole.astype(np.int64) * 10**9 + np.round((times - whole) * 1e9).astype(np.int64)
    return pd.DatetimeIndex(ns.view("datetime64[ns]"), name="time").tz_localize("UTC")


def _pandas():
    try:
        import pandas as pd
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("as_series / as_frame need pandas: pip install pandas") from e
    return pd


def series(times, data, name: str):
    """``pandas.Series(data, index=times as a UTC DatetimeIndex named "time", name=name)``."""
    pd = _pandas()
    return pd.Series(np.asarray(data), index=_index(times), name=name)


def frame(columns: dict, time_columns=("time",)):
    """``pandas.DataFrame(columns)`` with the ``time_columns`` as UTC datetimes."""
    pd = _pandas()
    table = pd.DataFrame(columns)
    for column in time_columns:
        if column in table:
            table[column] = _index(table[column].to_numpy()).to_series(index=table.index)
    return table
