"""A blocking client of the chronomap world-model service (``chronomap serve``)."""

from __future__ import annotations

import pathlib

from chronomap._native import Client, ServiceError

__all__ = ["Client", "ServiceError", "read_token"]


def read_token(path) -> str:
    """The bearer token in a token file (``DATA/token`` of ``chronomap serve``), stripped.

    >>> client = Client("http://127.0.0.1:8470", token=read_token("chronomap-data/token"))  # doctest: +SKIP
    """
    return pathlib.Path(path).read_text(encoding="utf-8").strip()
