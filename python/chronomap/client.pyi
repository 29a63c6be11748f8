"""A blocking client of the chronomap world-model service (``chronomap serve``): type stubs."""

from __future__ import annotations

import datetime
import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

Time = Union[float, datetime.datetime, datetime.date, np.datetime64]

class ServiceError(RuntimeError):
    """The service answered with an error: ``str(e)`` is ``"404 Not Found: no model ..."``."""

    status: int
    """The HTTP status."""
    kind: str
    """``bad_request``, ``unauthorized``, ``not_found``, ``conflict``, ``payload_too_large``,
    ``unavailable`` or ``internal``."""
    reason: str
    """The service's message, naming the field (and element) at fault."""

class Client:
    """A client of ``chronomap serve`` at ``url``; ``token`` is the bearer token writes need.
    Calls block (without the GIL) until the service answers. No answer at all is a
    ``ConnectionError``; an error answer a ``ServiceError``."""

    def __init__(self, url: str = "http://127.0.0.1:8470", token: Optional[str] = None) -> None: ...
    def health(self) -> Dict[str, Any]:
        """``status``, ``models``, ``store``, ``seq``, ``auth``."""
    def list(self) -> List[Dict[str, Any]]:
        """Every model's description (``id``, ``model``, ``observations``, ...)."""
    def ids(self) -> List[str]:
        """The ids of all models."""
    def view(self, id: str) -> Dict[str, Any]:
        """A model's description, with ``mean`` and ``components`` for spectral models."""
    def create(
        self, id: str, model: str = "fremen:2", *, range: Optional[Tuple[float, float]] = None
    ) -> Dict[str, int]:
        """Creates a model; returns ``{"observations": 0, "seq": ...}``."""
    def remove(self, id: str) -> Dict[str, int]:
        """Removes a model."""
    def add(
        self, id: str, times: npt.ArrayLike, values: npt.ArrayLike, *, model: Optional[str] = None
    ) -> Dict[str, int]:
        """Adds observations (created as ``model`` if missing); returns
        ``{"observations": n, "seq": ...}`` once durable."""
    @overload
    def predict(self, id: str, times: Time, *, order: Optional[int] = None,
                as_series: bool = False) -> float: ...
    @overload
    def predict(self, id: str, times: npt.ArrayLike, *, order: Optional[int] = None,
                as_series: bool = False) -> np.ndarray: ...
    def predict(self, id: str, times: Any, *, order: Optional[int] = None,
                as_series: bool = False) -> Any:
        """p(t) at ``times`` (seconds, ``datetime64``, pandas datetimes); ``as_series=True``:
        a ``pandas.Series`` named ``p`` indexed by the times (UTC)."""
    def interval(self, id: str, times: Any, *, coverage: float = 0.9,
                 order: Optional[int] = None, as_frame: bool = False) -> Any:
        """The central prediction interval of ``coverage`` (strictly between 0 and 1) of a
        model of continuous values (created with a ``range``) at ``times``: ``(lower, upper)``
        in its range (two arrays, or two floats for one time); ``as_frame=True``: a
        ``pandas.DataFrame`` with columns ``time``, ``lower``, ``upper``. A model without
        intervals (binary, ``auto`` before its first fit, or another spec fitted on a whole
        series) is a ``ValueError``."""
    @overload
    def entropy(self, id: str, times: Time, *, order: Optional[int] = None,
                as_series: bool = False) -> float: ...
    @overload
    def entropy(self, id: str, times: npt.ArrayLike, *, order: Optional[int] = None,
                as_series: bool = False) -> np.ndarray: ...
    def entropy(self, id: str, times: Any, *, order: Optional[int] = None,
                as_series: bool = False) -> Any:
        """Entropy (bits) of p(t) at ``times``; ``as_series=True``: a ``pandas.Series``."""
    def forecast(self, ids: Sequence[str], time: Time, *, order: Optional[int] = None) -> np.ndarray:
        """p(t) of many models at one time, in the order of ``ids``."""
    def observations(self, id: str, *, as_frame: bool = False) -> Any:
        """Every observation the model holds: ``(times, values)``, or with ``as_frame=True`` a
        ``pandas.DataFrame`` with columns ``time`` (UTC datetimes) and ``value``."""
    @property
    def url(self) -> str:
        """The service's address."""

def read_token(path: Union[str, "os.PathLike[str]"]) -> str:
    """The token in a token file, stripped."""

__all__: Sequence[str]
