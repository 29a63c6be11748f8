"""FreMEn occupancy grids ([Krajník 2017] §III-C, §VI): type stubs."""

from __future__ import annotations

import os
from typing import Any, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "os.PathLike[str]"]

class Grid:
    """A FreMEn occupancy grid: a FreMEn model of every cell's occupancy, learnt from whole
    frames at irregular times, predicting the map at any time.

    Frames follow ``nav_msgs/OccupancyGrid``: int8, -1 unknown, 0..100 occupancy in percent,
    ``frames[t, y, x]`` with row ``y = 0`` at the bottom (at the map's origin).
    """

    @staticmethod
    def from_frames(
        frames: npt.ArrayLike,
        times: npt.ArrayLike,
        *,
        resolution: float = 1.0,
        origin: Tuple[float, float] = (0.0, 0.0),
        periods: str = "week",
        order: int = 2,
        keep_history: bool = False,
    ) -> Grid:
        """A grid learnt from ``frames`` (a ``(T, H, W)`` int8 array) observed at ``times``
        (``T`` float64 seconds, never going backwards).

        ``resolution`` is metres per cell, ``origin`` the (x, y) of the lower-left corner of
        cell (0, 0); ``periods`` and ``order`` are those of ``chronomap grid build``;
        ``keep_history`` keeps what ``save(store="lossless")`` needs.

        Raises ``TypeError`` for float frames, ``ValueError`` for a wrong shape, a bad time
        (``frame 3 (times[2]): time NaN is not a finite number``) or cell value
        (``frames[2, 0, 7]: occupancy 101 is not -1 (unknown) or 0..=100``).
        """
    @staticmethod
    def from_nav2(
        frame_list: _Path,
        *,
        ros1: bool = False,
        periods: str = "week",
        order: int = 2,
        keep_history: bool = False,
    ) -> Grid:
        """A grid learnt from the maps of a frame list (lines ``<unix time> <map.yaml>``),
        as ``chronomap grid build --frames`` builds it. ``FileNotFoundError`` for a missing
        list or map, ``ValueError`` for a malformed one (naming the list, line and map)."""
    def observe(self, frames: npt.ArrayLike, times: npt.ArrayLike) -> Grid:
        """Observes more ``(T, H, W)`` frames (learning-state grids only); a rejected batch
        leaves the grid as it was. Returns the grid."""
    def predict_map(self, time: Any, *, order: Optional[int] = None) -> np.ndarray:
        """Occupancy probabilities at ``time``: float32 ``(H, W)`` (``(D, H, W)`` for 3-D
        grids), NaN where never observed; ``chronomap grid predict`` writes ``round(100 p)``."""
    def compact(self, order: Optional[int] = None) -> Grid:
        """The compact (lossy) model with ``order`` components per cell: predicts the same
        maps without refitting on every call."""
    def save(
        self,
        path: _Path,
        *,
        store: Optional[Literal["state", "lossy", "lossless"]] = None,
        order: Optional[int] = None,
    ) -> None:
        """Writes the grid file ``chronomap grid build -o`` writes (``store`` as its
        ``--store``; default ``"state"``)."""
    @property
    def shape(self) -> Tuple[int, ...]:
        """``(H, W)``, or ``(D, H, W)`` for a 3-D grid."""
    @property
    def resolution(self) -> float:
        """Metres per cell."""
    @property
    def origin(self) -> Tuple[float, ...]:
        """(x, y) of the lower-left corner of cell (0, 0) in metres ((x, y, z) in 3-D)."""
    @property
    def frames(self) -> int:
        """Number of frames learnt from."""
    @property
    def span(self) -> Optional[Tuple[float, float]]:
        """(first, last) frame time."""
    @property
    def kind(self) -> str:
        """``grid-state``, ``grid-lossy`` or ``grid-lossless``."""
    @property
    def order(self) -> Optional[int]:
        """Default order of a learning-state grid (None for fitted grids)."""

def load_grid(path: _Path) -> Grid:
    """Reads a grid file (``chronomap grid build``, ``Grid.save``). ``FileNotFoundError`` if
    missing, ``ValueError`` if damaged or not a grid file."""

def read_map(
    yaml: _Path, *, ros1: bool = False
) -> Tuple[np.ndarray, float, Tuple[float, float, float]]:
    """A ROS map_server / Nav2 map as ``(data, resolution, origin)``: int8 ``(H, W)``
    occupancies (row 0 at the bottom), metres per cell, ``(x, y, yaw)``."""

__all__: Sequence[str]
