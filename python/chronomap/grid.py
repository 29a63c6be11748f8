"""FreMEn occupancy grids: a FreMEn model in every cell, learnt from whole frames (numpy arrays
or Nav2 / ROS map files) and predicting the map at any time ([Krajník 2017] §III-C, §VI).

Grid files are those of ``chronomap grid build`` / ``chronomap grid predict``.
"""

from __future__ import annotations

from chronomap._native import Grid, load_grid, read_map

__all__ = ["Grid", "load_grid", "read_map"]
