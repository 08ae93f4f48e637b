"""Distances through free space: an occupancy grid and, per label region, the geodesic
distance from every free cell to it, for the shaping potential (:mod:`mitlc.task.potential`).

A straight line to a region points into walls in a maze; the distance here goes around them.
It is the discrete wavefront (grassfire) distance of robot path planning (Latombe, *Robot
Motion Planning*, 1991, ch. 7) computed by Dijkstra's algorithm (Dijkstra, "A note on two
problems in connexion with graphs", 1959) from the region's cells, once per region, so that a
step of the env only looks it up (a few array reads).

**The grid.** :class:`Occupancy` holds ``blocked[i, j]``, cell ``i`` along the first axis of
a position (x) and ``j`` along the second (y), each cell a square of side ``cell_size`` whose
least corner is ``origin + (i, j) * cell_size``. A position ``p`` is in cell
``floor((p - origin) / cell_size)``.

**The distance field** of a region (:meth:`Occupancy.field`): the cells that overlap the
region (a box, a disc, a point) and are free start at the straight distance from their centre
to the region (0 where the centre is inside); from them Dijkstra's algorithm runs over the free
cells, **8-connected** (a step to a side neighbour costs ``cell_size``, a diagonal one
``sqrt(2) * cell_size``, a diagonal step only where both side neighbours it passes are free,
so no wall corner is cut) or **4-connected** (side steps only: MiniGrid, whose agent moves
that way). A free cell from which no region cell can be reached is ``inf`` away.

**A position's distance** (:meth:`DistanceField.at`), in the env's units:

* in a free cell: the least, over that cell and its neighbours that a legal step reaches, of
  the neighbour's distance plus the straight gap from the position to the neighbour's centre
  (so the distance varies inside a cell, not only from cell to cell);
* in a blocked cell or outside the map: the distance of the nearest free cell (by a 8-connected
  search from the cell, clamped onto the map) plus the straight gap to that cell's centre.

:mod:`mitlc.labels.distance` takes the larger of this and the straight distance to the region
(the geodesic is never shorter than the straight line, and it stays 0 inside the region).
Paths run through cell centres, so the distance exceeds the shortest path by up to about a
cell's side in the open, and more along long diagonals around corners (a U of 1 m cells: 6 m
where the shortest path is 3.6 m; cells of 1/4 m: 4.25 m, of 1/8 m: 3.98 m).
"""

from __future__ import annotations

import heapq
import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt

from mitlc.errors import MitlcError

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]

SIDES = ((1, 0), (-1, 0), (0, 1), (0, -1))
DIAGONALS = ((1, 1), (1, -1), (-1, 1), (-1, -1))
MAX_CELLS = 1 << 20
"""The most cells an occupancy grid may have (a bound on the time of a field)."""


class OccupancyError(MitlcError, ValueError):
    """An occupancy grid that cannot be built as given; the message starts with the field's
    path where it comes from a file."""


@dataclass(frozen=True)
class Occupancy:
    """Which cells of a grid laid over the positions are free (module docstring)."""

    blocked: BoolArray
    """``blocked[i, j]``: cell ``i`` along x, ``j`` along y, is an obstacle."""
    cell_size: float
    origin: tuple[float, float]
    """The least corner (x, y) of cell ``(0, 0)``."""
    connectivity: int = 8
    """8 (side and diagonal steps) or 4 (side steps only)."""
    source: str = "declared"
    """Where the grid was read (for notes: ``maze_map``, ``MiniGrid grid``, ...)."""

    def __post_init__(self) -> None:
        blocked = np.asarray(self.blocked, dtype=np.bool_)
        if blocked.ndim != 2 or blocked.size == 0 or blocked.size > MAX_CELLS:
            raise OccupancyError(f"cells: expected a non-empty 2-D grid of at most {MAX_CELLS} "
                                 f"cells, got shape {blocked.shape}")  # fmt: skip
        if not (math.isfinite(self.cell_size) and self.cell_size > 0):
            raise OccupancyError(f"cell_size: expected a number > 0, got {self.cell_size!r}")
        if len(self.origin) != 2 or not all(math.isfinite(v) for v in self.origin):
            raise OccupancyError(f"origin: expected [x, y], got {list(self.origin)!r}")
        if self.connectivity not in (4, 8):
            raise OccupancyError(f"connectivity: expected 4 or 8, got {self.connectivity!r}")
        blocked.setflags(write=False)
        object.__setattr__(self, "blocked", blocked)
        object.__setattr__(self, "origin", (float(self.origin[0]), float(self.origin[1])))

    @staticmethod
    def from_rows(
        rows: Sequence[Sequence[int]],
        cell_size: float,
        origin: Sequence[float],
        *,
        refine: int = 1,
        connectivity: int = 8,
        source: str = "declared",
    ) -> Occupancy:
        """The grid of ``rows`` as a map prints it: ``rows[r][c]`` (1 blocked, 0 free) is the
        cell in column ``c`` from the left and row ``r`` from the *top*, y pointing up (a world
        file's ``occupancy:``, a maze map); ``origin`` is the map's lower-left corner. Each cell
        is cut into ``refine`` x ``refine`` cells (finer distances, the same free space)."""
        grid = np.asarray(rows, dtype=np.int64)
        if grid.ndim != 2 or grid.size == 0:
            raise OccupancyError("cells: expected a non-empty list of rows of equal length")
        blocked = np.flipud(grid != 0).T  # [column, row from the bottom]
        if refine > 1:
            blocked = np.repeat(np.repeat(blocked, refine, axis=0), refine, axis=1)
        size = float(cell_size) / refine
        return Occupancy(blocked, size, (float(origin[0]), float(origin[1])), connectivity,
                         source)  # fmt: skip

    @property
    def shape(self) -> tuple[int, int]:
        """Cells along x and along y."""
        nx, ny = self.blocked.shape
        return int(nx), int(ny)

    def cell_of(self, point: Sequence[float] | FloatArray) -> tuple[int, int]:
        """The cell ``(i, j)`` of a position (possibly outside the map)."""
        s = self.cell_size
        return (math.floor((float(point[0]) - self.origin[0]) / s),
                math.floor((float(point[1]) - self.origin[1]) / s))  # fmt: skip

    def centre(self, i: int, j: int) -> FloatArray:
        """The centre of cell ``(i, j)``."""
        s = self.cell_size
        return np.array([self.origin[0] + (i + 0.5) * s, self.origin[1] + (j + 0.5) * s])

    def free_at(self, point: Sequence[float] | FloatArray) -> bool:
        """Whether a position lies in a free cell of the map."""
        i, j = self.cell_of(point)
        nx, ny = self.shape
        return 0 <= i < nx and 0 <= j < ny and not self.blocked[i, j]

    @cached_property
    def nearest_free(self) -> IntArray:
        """``nearest_free[i, j]``: a free cell nearest to cell ``(i, j)`` (itself where it is
        free; 8-connected steps; ``(-1, -1)`` where the map has no free cell)."""
        nx, ny = self.shape
        found = np.full((nx, ny, 2), -1, dtype=np.int64)
        queue: deque[tuple[int, int]] = deque()
        for i, j in zip(*np.nonzero(~self.blocked), strict=True):
            found[i, j] = (i, j)
            queue.append((int(i), int(j)))
        while queue:
            i, j = queue.popleft()
            for di, dj in SIDES + DIAGONALS:
                a, b = i + di, j + dj
                if 0 <= a < nx and 0 <= b < ny and found[a, b, 0] < 0:
                    found[a, b] = found[i, j]
                    queue.append((a, b))
        return found

    def field(self, region: Target) -> DistanceField:
        """The distance field of ``region`` (module docstring); every cell ``inf`` where no
        free cell overlaps it."""
        start = self._start(region)
        return DistanceField(self, self._spread(start), region)

    def _start(self, region: Target) -> FloatArray:
        """Per free cell overlapping ``region``, the straight distance from its centre to the
        region; ``inf`` elsewhere."""
        nx, ny = self.shape
        s, (ox, oy) = self.cell_size, self.origin
        lo_x: FloatArray = ox + np.arange(nx, dtype=np.float64) * s
        lo_y: FloatArray = oy + np.arange(ny, dtype=np.float64) * s
        gx = _gap(lo_x, lo_x + s, region.low[0], region.high[0])
        gy = _gap(lo_y, lo_y + s, region.low[1], region.high[1])
        if region.radius >= 0.0:  # the disc: the nearest point of each cell to its centre
            cx = np.clip(region.center[0], lo_x, lo_x + s) - region.center[0]
            cy = np.clip(region.center[1], lo_y, lo_y + s) - region.center[1]
            overlaps = cx[:, None] ** 2 + cy[None, :] ** 2 <= region.radius**2
        else:
            overlaps = (gx[:, None] <= 0.0) & (gy[None, :] <= 0.0)
        overlaps &= ~self.blocked
        centres_x, centres_y = lo_x + s / 2, lo_y + s / 2
        start = np.full((nx, ny), np.inf)
        for i, j in zip(*np.nonzero(overlaps), strict=True):
            start[i, j] = region.straight(np.array([centres_x[i], centres_y[j]]))
        return start

    def _spread(self, start: FloatArray) -> FloatArray:
        """Dijkstra's algorithm from the finite entries of ``start`` over the free cells."""
        nx, ny = self.shape
        free, s = ~self.blocked, self.cell_size
        distance = start.copy()
        heap = [(float(distance[i, j]), int(i), int(j)) for i, j in zip(*np.nonzero(
            np.isfinite(distance)), strict=True)]  # fmt: skip
        heapq.heapify(heap)
        steps = [(di, dj, s) for di, dj in SIDES]
        if self.connectivity == 8:
            steps += [(di, dj, s * math.sqrt(2.0)) for di, dj in DIAGONALS]
        while heap:
            d, i, j = heapq.heappop(heap)
            if d > distance[i, j]:
                continue
            for di, dj, cost in steps:
                a, b = i + di, j + dj
                if not (0 <= a < nx and 0 <= b < ny and free[a, b]):
                    continue
                if di and dj and not (free[a, j] and free[i, b]):
                    continue  # no cutting of a wall's corner
                if d + cost < distance[a, b]:
                    distance[a, b] = d + cost
                    heapq.heappush(heap, (d + cost, a, b))
        return distance


def _gap(lo: FloatArray, hi: FloatArray, low: float, high: float) -> FloatArray:
    """Per interval ``[lo, hi]``: how far it is from ``[low, high]`` (negative: by how much
    they overlap; an interval that only touches overlaps where ``[low, high]`` is a point)."""
    gap = np.maximum(lo - high, low - hi)
    if high > low:
        return np.where(gap < 0.0, gap, np.where(gap == 0.0, 1.0, gap))
    return np.where(gap <= 0.0, -1.0, gap)


@dataclass(frozen=True, slots=True)
class Target:
    """A region of positions: a closed box ``low <= p <= high`` or, where ``radius >= 0``,
    the disc of ``center`` and ``radius`` (``low``/``high`` its bounding box)."""

    low: tuple[float, float]
    high: tuple[float, float]
    center: tuple[float, float] = (0.0, 0.0)
    radius: float = -1.0

    @staticmethod
    def box(low: Sequence[float] | FloatArray, high: Sequence[float] | FloatArray) -> Target:
        """The box ``low <= p <= high``."""
        return Target((float(low[0]), float(low[1])), (float(high[0]), float(high[1])))

    @staticmethod
    def disc(center: Sequence[float] | FloatArray, radius: float) -> Target:
        """The disc of ``center`` and ``radius``."""
        x, y, r = float(center[0]), float(center[1]), float(radius)
        return Target((x - r, y - r), (x + r, y + r), (x, y), r)

    @staticmethod
    def point(at: Sequence[float] | FloatArray) -> Target:
        """The one position ``at``."""
        return Target.box(at, at)

    def straight(self, p: FloatArray) -> float:
        """The straight distance from ``p`` to the region."""
        if self.radius >= 0.0:
            return max(float(np.hypot(p[0] - self.center[0], p[1] - self.center[1])) -
                       self.radius, 0.0)  # fmt: skip
        dx = max(self.low[0] - p[0], 0.0, p[0] - self.high[0])
        dy = max(self.low[1] - p[1], 0.0, p[1] - self.high[1])
        return float(math.hypot(dx, dy))


class DistanceField:
    """A region's geodesic distance over an occupancy grid (module docstring)."""

    def __init__(self, occupancy: Occupancy, distance: FloatArray, region: Target) -> None:
        self.occupancy, self.distance, self.region = occupancy, distance, region
        self.reachable = bool(np.isfinite(distance).any())
        """Whether some free cell reaches the region (else the field says nothing)."""
        s = occupancy.cell_size
        offsets = [(0, 0), *SIDES, *(DIAGONALS if occupancy.connectivity == 8 else ())]
        self._offsets = np.array(offsets, dtype=np.int64)
        self._shift = self._offsets.astype(np.float64) * s
        nx, ny = occupancy.shape
        padded = np.full((nx + 2, ny + 2), np.inf)
        padded[1:-1, 1:-1] = np.where(occupancy.blocked, np.inf, distance)
        free = np.zeros((nx + 2, ny + 2), dtype=np.bool_)
        free[1:-1, 1:-1] = ~occupancy.blocked
        near = np.empty((nx, ny, len(offsets)))
        for k, (di, dj) in enumerate(offsets):
            near[:, :, k] = padded[1 + di : nx + 1 + di, 1 + dj : ny + 1 + dj]
            if di and dj:  # a diagonal neighbour counts where a legal step reaches it
                passes = free[1 + di : nx + 1 + di, 1:-1] & free[1:-1, 1 + dj : ny + 1 + dj]
                near[:, :, k] = np.where(passes, near[:, :, k], np.inf)
        self._near = near

    def at(self, point: Sequence[float] | FloatArray) -> float:
        """The geodesic distance of a position (``inf`` where no path reaches the region)."""
        occupancy = self.occupancy
        p = np.asarray(point, dtype=np.float64)[:2]
        i, j = occupancy.cell_of(p)
        nx, ny = occupancy.shape
        if 0 <= i < nx and 0 <= j < ny and not occupancy.blocked[i, j]:
            gaps = np.hypot(*(p - occupancy.centre(i, j) - self._shift).T)
            return float(np.min(self._near[i, j] + gaps))
        a, b = occupancy.nearest_free[min(max(i, 0), nx - 1), min(max(j, 0), ny - 1)]
        if a < 0:
            return math.inf
        gap = float(np.hypot(*(p - occupancy.centre(int(a), int(b)))))
        return float(self.distance[a, b]) + gap


def as_target(region: Any) -> Target | None:
    """A 2-D region of a label form as a :class:`Target` (``None`` for another size):
    ``region`` has ``low``/``high`` (a box) or ``center``/``radius`` (a disc)."""
    radius = float(getattr(region, "radius", -1.0))
    if radius >= 0.0:
        center = tuple(getattr(region, "center", ()))
        return Target.disc(center, radius) if len(center) == 2 else None
    low, high = tuple(getattr(region, "low", ())), tuple(getattr(region, "high", ()))
    return Target.box(low, high) if len(low) == 2 == len(high) else None
