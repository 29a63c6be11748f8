"""Topological maps whose edges know time, and the now-or-later planner ([Fentanes 2015]):
type stubs."""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy.typing as npt

_Path = Union[str, "os.PathLike[str]"]

class EdgeModels:
    """Success and duration models of every edge of a topological map ([Fentanes 2015] §IV)."""

    @staticmethod
    def fit(
        edges: _Path,
        *,
        static: bool = False,
        persistence: bool = True,
        min_attempts: int = 10,
        prior: float = 0.9,
        prior_attempts: float = 2.0,
        floor: float = 0.05,
        max_order: int = 10,
        success_order: Optional[int] = None,
        holdout: float = 0.25,
    ) -> EdgeModels:
        """Fits every edge from a directory of edge files ``<From>_<To>.data`` (lines
        ``t duration_s success``), as ``chronomap topo fit --edges`` does with the same
        options."""
    def predict(self, time: Any) -> Dict[str, Any]:
        """Every edge at ``time``, as ``chronomap topo predict --json``: ``edge``, ``from``,
        ``to`` (lists) and the arrays ``success_probability``, ``uncertainty``,
        ``static_success_probability``, ``duration_secs``, ``attempts``."""
    def plan(
        self,
        start: str,
        task: str,
        time: Any,
        *,
        deadline: Optional[float] = None,
        confidence: Optional[float] = None,
        bucket_secs: Optional[float] = None,
    ) -> Dict[str, Any]:
        """The plan of a co-safe LTL ``task`` from node ``start`` at ``time``, as
        ``chronomap plan --time --json``: ``pmax``, ``expected_secs``, ``first_edge``,
        ``route``, ``route_success_probabilities``, ``product_states``, ``task``, ``from``,
        ``time``; and ``policy``: for every undecided product state its ``node``,
        ``automaton_state``, the ``edge`` to take and its ``pmax``.

        With ``deadline`` (seconds > 0), the plan most likely to fulfil the task within it,
        as ``chronomap plan --time --deadline --json``: ``probability`` (a lower bound),
        ``first_edge``, ``median_route``, ``reaches_confidence`` and
        ``shortest_deadline_secs`` (``confidence``, default 0.95), ``min_time_probability``,
        ``min_time_first_edge``, ``pmax``, ``expected_secs``, ``curve`` (array of rows
        ``[d, deadline plan, expected-time plan]``), ``deadline_secs``, ``confidence``,
        ``bucket_secs`` (default ``max(deadline / 600, 1)``), ``duration_quantiles``,
        ``product_states``, ``seconds``, ``task``, ``from``, ``time``, ``utc``."""
    def now_or_later(self, start: str, task: str, times: npt.ArrayLike, *,
                     deadline: Optional[float] = None,
                     bucket_secs: Optional[float] = None) -> Dict[str, Any]:
        """The plan at each of ``times``: arrays ``time``, ``pmax``, ``expected_secs`` and the
        list ``first_edge``. With ``deadline`` (seconds), also the plan most likely to arrive
        in time at each: arrays ``deadline_probability``, ``min_time_probability``, the list
        ``deadline_first_edge``, and ``deadline_secs``, ``bucket_secs``."""
    def observe(self, edges: _Path) -> EdgeModels:
        """New models that have also learnt the later attempts of a directory of edge files,
        in time order, as ``chronomap topo observe`` does: success models, static rates and
        the online adaptation of the duration intervals; new edges from their priors."""
    def save(self, path: _Path) -> None:
        """Writes the edge-model file ``chronomap topo fit -o`` writes."""
    @property
    def nodes(self) -> List[str]:
        """Node names, in map order."""
    @property
    def edges(self) -> List[str]:
        """Edge ids, in map order (the order of ``predict``'s arrays)."""
    @property
    def last_time(self) -> Optional[float]:
        """Time of the latest attempt learnt from."""
    @property
    def adapted_traversals(self) -> int:
        """Successful traversals the duration intervals have adapted to since the fit."""

def load_edge_models(path: _Path) -> EdgeModels:
    """Reads an edge-model file (``chronomap topo fit``, ``EdgeModels.save``)."""

__all__: Sequence[str]
