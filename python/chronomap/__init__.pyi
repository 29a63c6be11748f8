"""Type stubs of the chronomap package (the classes live in the native module)."""

from __future__ import annotations

import datetime
import os
from typing import Any, Literal, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

from chronomap.client import Client as Client, ServiceError as ServiceError, read_token as read_token
from chronomap.grid import Grid as Grid, load_grid as load_grid, read_map as read_map
from chronomap.topo import EdgeModels as EdgeModels, load_edge_models as load_edge_models

__version__: str

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]
Path = Union[str, os.PathLike]
Order = Union[int, Literal["auto"]]
Criterion = Literal["brier", "absolute", "binary"]
RecentDays = Union[Sequence[int], None]
"""Memories in days of ``auto``'s drift candidates (``--recent-days``): whole days from 1 to
3650, by default ``(7, 14, 28, 56)``; ``None`` or ``()`` for no drift candidates."""
Time = Union[float, datetime.datetime, datetime.date, np.datetime64]
"""One time: unix seconds, a ``datetime`` (naive = UTC), ``numpy.datetime64`` (UTC) or
``pandas.Timestamp`` (a ``datetime``; zone-aware ones converted to UTC)."""
Times = ArrayLike
"""Times: float64 unix seconds, ``datetime64`` arrays of any unit, pandas ``Series`` /
``DatetimeIndex`` of datetimes, or lists of ``datetime``."""

class TemporalModel:
    """A model of one state over time ([Krajník 2017], [Santos 2017], [Krajník 2019]).

    It learns from observations made at irregular times and predicts p(t), the probability
    that the state is 1 (or its expected value for states in [0, 1]), at any time. The first
    ``observe`` fits it (choosing orders or families where the spec says ``auto``, on the most
    recent ``holdout`` of that batch, as ``chronomap fit`` does); later ones add to it.
    ``recent_days``: the memories in days of ``auto``'s drift candidates (the mean and
    histograms of the last that many days only; ``chronomap fit --recent-days``), each a whole
    number from 1 to 3650; ``None`` or ``()`` for none. Other values raise ``ValueError``.
    """

    def __init__(self, spec: str, *, periods: str = "week", holdout: float = 0.25,
                 max_order: int = 10, criterion: Criterion = "brier",
                 recent_days: RecentDays = (7, 14, 28, 56)) -> None: ...
    def observe(self, times: Times, values: ArrayLike) -> TemporalModel:
        """Adds observations: times (unix seconds, ``datetime64``, pandas datetimes) that never
        go backwards, values in [0, 1] (floats, ints or booleans, pandas Series too).

        A rejected batch raises ``ValueError`` naming the element
        (``observation 4 (times[3]): ...``) and leaves the model as it was. Contiguous float64
        arrays are read in place; the work runs without the GIL. Returns the model.
        """
    @overload
    def predict(self, times: Time, *, as_series: Literal[False] = ...) -> float: ...
    @overload
    def predict(self, times: Times, *, as_series: Literal[False] = ...) -> FloatArray: ...
    @overload
    def predict(self, times: Any, *, as_series: Literal[True]) -> Any: ...
    def predict(self, times: Any, *, as_series: bool = False) -> Any:
        """p(t) at ``times``; 0.5 for a model that has seen nothing. ``as_series=True``: a
        ``pandas.Series`` named ``p`` indexed by the times (a UTC ``DatetimeIndex``)."""
    @overload
    def entropy(self, times: Time, *, as_series: Literal[False] = ...) -> float: ...
    @overload
    def entropy(self, times: Times, *, as_series: Literal[False] = ...) -> FloatArray: ...
    @overload
    def entropy(self, times: Any, *, as_series: Literal[True]) -> Any: ...
    def entropy(self, times: Any, *, as_series: bool = False) -> Any:
        """Binary entropy of p(t) in bits (1 at p = 0.5, 0 when certain); ``as_series=True``:
        a ``pandas.Series`` named ``entropy``."""
    def anomalies(self, times: Times, values: ArrayLike, confidence: float = 0.99, *,
                  as_frame: bool = False) -> Any:
        """Observations contradicting a confident prediction ([Krajník 2017] §V, eq. (9)):
        arrays ``index``, ``time``, ``observed``, ``p`` (a dict), or with ``as_frame=True`` a
        ``pandas.DataFrame`` of them, ``time`` as UTC datetimes."""
    def save(self, path: Path) -> None:
        """Writes the model file ``chronomap fit -o`` writes (versioned, checksummed)."""
    def to_bytes(self) -> bytes:
        """The model file's bytes (what ``save`` writes; ``loads`` reads them; pickle uses them)."""
    @property
    def spec(self) -> str:
        """The spec as requested (``fremen:auto``)."""
    @property
    def fitted(self) -> str | None:
        """The spec as fitted, orders resolved (``fremen:2``)."""
    @property
    def kind(self) -> str | None:
        """The model family (``fremen``, ``hist``, ...)."""
    @property
    def order(self) -> int | None:
        """The order; settable for models that have one (``chronomap predict --order``)."""
    @order.setter
    def order(self, order: int) -> None: ...
    @property
    def observations(self) -> int:
        """Number of observations seen."""
    @property
    def span(self) -> Tuple[float, float] | None:
        """``(first, last)`` time observed."""
    @property
    def selection(self) -> dict[str, Any] | None:
        """How the order or family was chosen on held-back training data."""
    @property
    def components(self) -> dict[str, FloatArray]:
        """FreMEn: ``period``, ``amplitude`` (|γ|), ``phase``, ``mean``, so that
        p(t) = mean + Σ 2|γ| cos(2πt/period + phase), saturated to [0, 1]
        ([Krajník 2017] eq. (2)). PerGaM: ``weight``, ``mean``, ``sigma``. Hypertime:
        ``period``. Others: empty."""

class Fremen(TemporalModel):
    """Frequency Map Enhancement ([Krajník 2017] eq. (1)-(3))."""
    def __init__(self, order: Order | None = None, *, periods: str = "week",
                 holdout: float = 0.25, max_order: int = 10,
                 criterion: Criterion = "brier") -> None: ...

class Persistence(TemporalModel):
    """FreMEn with persistence ([Krajník 2017] eq. (12)-(13))."""
    def __init__(self, order: Order | None = None, *, periods: str = "week",
                 holdout: float = 0.25, max_order: int = 10,
                 criterion: Criterion = "brier") -> None: ...

class Mean(TemporalModel):
    """Long-term memory: the mean of all observations ([Santos 2017] §4.3.1)."""
    def __init__(self) -> None: ...

class Hist(TemporalModel):
    """The mean per bin of a period ([Santos 2017] §4.3.2)."""
    def __init__(self, bins: int = 24, period: float = 604800.0) -> None: ...

class Stm(TemporalModel):
    """Short-term memory: a two-state Markov chain ([Santos 2017] eq. (5)-(6))."""
    def __init__(self) -> None: ...

class PerGaM(TemporalModel):
    """Periodic Gaussian mixture ([Santos 2017] eq. (7)-(9))."""
    def __init__(self, components: Order | None = None, period: float = 86400.0, *,
                 holdout: float = 0.25) -> None: ...

class Fft(TemporalModel):
    """FFT FreMEn with an outlier set (uniformly sampled binary series only)."""
    def __init__(self, order: Order | None = None) -> None: ...

class Hypertime(TemporalModel):
    """Warped Hypertime ([Krajník 2019]): HyT-EM, or HyT-KM with ``clustering="kmeans"``."""
    def __init__(self, components: Order | None = None,
                 clustering: Literal["em", "kmeans"] = "em") -> None: ...

def model(spec: str, *, periods: str = "week", holdout: float = 0.25, max_order: int = 10,
          criterion: Criterion = "brier",
          recent_days: RecentDays = (7, 14, 28, 56)) -> TemporalModel:
    """The model a spec describes (``fremen:auto``, ``hist:24``, ``auto``...), typed; the
    settings are ``TemporalModel``'s."""

def load(path: Path) -> TemporalModel:
    """A model file (``chronomap fit -o``, ``TemporalModel.save``), checked, typed."""

def loads(data: bytes) -> TemporalModel:
    """A model from a model file's bytes (``TemporalModel.to_bytes``), checked, typed."""

@overload
def evaluate(train: Tuple[ArrayLike, ArrayLike], tests: Sequence[Tuple[ArrayLike, ArrayLike]],
             models: Union[str, Sequence[str]], *, as_frame: Literal[False] = ...,
             periods: str = ..., holdout: float = ..., max_order: int = ...,
             criterion: Criterion = ..., recent_days: RecentDays = ...,
             days_off: Path | None = ...) -> dict[str, np.ndarray]: ...
@overload
def evaluate(train: Tuple[ArrayLike, ArrayLike], tests: Sequence[Tuple[ArrayLike, ArrayLike]],
             models: Union[str, Sequence[str]], *, as_frame: Literal[True],
             periods: str = ..., holdout: float = ..., max_order: int = ...,
             criterion: Criterion = ..., recent_days: RecentDays = ...,
             days_off: Path | None = ...) -> Any: ...

def read_pairs(path: Path) -> Tuple[FloatArray, FloatArray]:
    """A ``time value`` file (plain, .xz, .gz) as ``(times, values)``, checked."""

def read_test_set(times_path: Path, values_path: Path) -> Tuple[FloatArray, FloatArray]:
    """A FreMEn test set (two line-aligned files)."""

class CopaMap:
    """CoPA-Map ([Stüde 2024] §4.2): the rate of people over space and time, with its
    uncertainty."""
    @staticmethod
    def fit(x: ArrayLike, t: ArrayLike, y: ArrayLike, *, inducing: int = 200,
            iterations: int = 300, period: float = 12.0,
            scale: Literal["rate", "log1p"] = "rate", seed: int = 0) -> CopaMap: ...
    def predict(self, x: ArrayLike, t: Union[float, ArrayLike]) -> Tuple[FloatArray, FloatArray]:
        """``(mean, std)`` of the rate at the ``(M, 2)`` positions, at one or ``M`` times."""
    @property
    def periods(self) -> FloatArray: ...
    @property
    def domain(self) -> Tuple[float, float, float, float]: ...
    @property
    def trace(self) -> FloatArray:
        """The ELBO after each iteration."""
    def save(self, path: Path) -> None: ...

def load_copa_map(path: Path) -> CopaMap:
    """A CoPA-Map model file (``chronomap activity fit -o``)."""

def read_rate_samples(path: Path) -> Tuple[FloatArray, FloatArray, FloatArray]:
    """A ``x1,x2,t,y`` CSV file as ``(x (N, 2), t, y)``."""

class HypertimeEvents:
    """Warped Hypertime for events ([Krajník 2019] §V-D): the intensity λ(t, x, y)."""
    @staticmethod
    def fit(events: ArrayLike, *, components: Order | None = None,
            gap: float = 3600.0) -> HypertimeEvents:
        """Fits to an ``(N, 3)`` array of detections ``t, x, y``."""
    @property
    def periods(self) -> FloatArray: ...
    @property
    def components(self) -> int: ...
    def rate(self, times: Times) -> FloatArray:
        """Expected events per second over the plane."""
    def intensity(self, t: Times, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """λ(t, x, y) in events per m² per second."""
    def density(self, times: Times, cell: float = 0.25) -> dict[str, Any]:
        """Detections per m² per hour on a grid over the training detections."""

def read_events(path: Path) -> FloatArray:
    """An event file (``t x y ...`` lines) as an ``(N, 3)`` array."""

def psbt_synthesize(map: Path, start: Tuple[float, float], time: Time, *,
                    tracks: Sequence[Path] | None = None, copa: CopaMap | None = None,
                    cell: float = 1.0, interval: float = 3600.0, planning_cell: float = 0.5,
                    clearance: float = 0.3, places: int = 6, seed: int = 0,
                    model_t: float | None = None, model_cell: float = 0.5) -> dict[str, Any]:
    """The person search behavior tree ([Stüde 2024] §5.4) as BehaviorTree.CPP 4 XML
    (``tree_xml``), with ``p_success``, ``expected_time_s``, ``candidates``, ``places``,
    ``choices`` — what ``chronomap psbt --json`` prints."""
