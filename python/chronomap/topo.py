"""Topological maps whose edges know time, and the now-or-later planner ([Fentanes 2015]).

Edge files and edge-model files are those of ``chronomap topo fit``, ``chronomap topo predict``
and ``chronomap plan``.
"""

from __future__ import annotations

from chronomap._native import EdgeModels, load_edge_models

__all__ = ["EdgeModels", "load_edge_models"]
