"""Where an env's occupancy grid comes from, and the geodesic distances of a labeller's forms
over it (:mod:`mitlc.labels.occupancy`), for the shaping potential.

**Sources** (:func:`occupancy_source`), tried in this order on ``env.unwrapped``:

* **declared**: an :class:`~mitlc.labels.occupancy.Occupancy` given to the task wrapper (an
  env world file's ``occupancy:`` section: ``{cells: [[...]], cell_size: ..., origin: [x, y]}``,
  rows printed top first, ``origin`` the lower-left corner);
* **gymnasium-robotics' mazes** (PointMaze, AntMaze): ``env.unwrapped.maze``'s ``maze_map``
  (``1`` a wall; ``0``, ``r``, ``g``, ``c`` free), each cell ``maze_size_scaling`` wide, the map
  centred on the origin (``Maze.cell_rowcol_to_xy``: column ``j`` of row ``i`` has its centre at
  ``x = (j + 0.5) s - x_map_center``, ``y = y_map_center - (i + 0.5) s``, so the lower-left
  corner is ``(-x_map_center, -y_map_center)``); each maze cell is cut into
  :data:`MAZE_REFINE` x :data:`MAZE_REFINE` cells (the walls are whole maze cells, so this is
  exact); 8-connected; positions are the ball's (or the ant's) ``(x, y)``, what ``achieved_goal``
  holds: the geodesic applies to a ``box`` or ``disc`` over ``achieved_goal`` (or
  ``desired_goal``) at ``index: [0, 1]``;
* **MiniGrid**: ``env.unwrapped.grid``, read again at each reset (DoorKey moves its wall every
  episode): a wall or lava blocks its cell; doors (open, closed or locked: the task is to go
  through them), keys, balls, boxes and goals are free; cell ``(x, y)`` of ``agent_pos`` is the
  unit square centred on it; 4-connected, as the agent moves; the geodesic applies to the forms
  that read ``attr: agent_pos`` (an ``equals``, a ``box``) and to guides from it;
* **mitlc's plane worlds** (:class:`mitlc.worlds.plane_env.PlaneEnv`): the room, its obstacles
  rasterised on cells of :data:`PLANE_RESOLUTION` of the room's shorter side (a cell is
  blocked where an obstacle's interior meets it); 8-connected; every label (each reads the
  position).

A map with no blocked cell (a plane world without obstacles) measures straight lines, which
are then exact. Anything else has no occupancy: the distance stays the straight line (the
task wrapper says so once, :class:`mitlc.gym.guide.StraightDistanceWarning`).

The geodesic applies to a form over a 2-D position that reads the positions the map is over
(above; with a declared grid, every such form) and whose region lies in the map (its box or
disc meets a free cell): ``box`` and ``disc`` (over the observation or a value), a value's
``equals`` of a pair, and a guide's ``toward`` (the field of its target, per target cell).
Every other form keeps the straight line.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from typing import Any

import numpy as np

from mitlc.labels.forms import Form, Guided, InBox, InDisc
from mitlc.labels.occupancy import DistanceField, Occupancy, Target, as_target
from mitlc.labels.values import AttrPath, Equals, Region, Value, vector

MAZE_REFINE = 4
"""Cells per side of a gymnasium-robotics maze cell (0.25 m at the default scaling of 1)."""
PLANE_RESOLUTION = 1 / 50
"""A plane world's cell side, as a share of the room's shorter side."""
MAX_GUIDED = 256
"""The most target cells a guide keeps fields for (more: the oldest is dropped)."""
BLOCKING = frozenset({"wall", "lava"})
"""MiniGrid's object types that block a cell."""


def maze_occupancy(maze: Any) -> Occupancy:
    """The occupancy of a gymnasium-robotics ``Maze`` (module docstring)."""
    rows = [[1 if str(v) == "1" else 0 for v in row] for row in maze.maze_map]
    origin = (-float(maze.x_map_center), -float(maze.y_map_center))
    return Occupancy.from_rows(rows, float(maze.maze_size_scaling), origin,
                               refine=MAZE_REFINE, source="maze_map")  # fmt: skip


def minigrid_occupancy(grid: Any) -> Occupancy:
    """The occupancy of a MiniGrid ``Grid`` (module docstring)."""
    width, height = int(grid.width), int(grid.height)
    blocked = np.zeros((width, height), dtype=np.bool_)
    for k, cell in enumerate(grid.grid):
        if cell is not None and getattr(cell, "type", None) in BLOCKING:
            blocked[k % width, k // width] = True
    return Occupancy(blocked, 1.0, (-0.5, -0.5), connectivity=4, source="MiniGrid grid")


def plane_occupancy(world: Any) -> Occupancy:
    """The occupancy of a plane world's room and obstacles (module docstring)."""
    width, height = float(world.width), float(world.height)
    size = min(width, height) * PLANE_RESOLUTION
    nx, ny = max(int(np.ceil(width / size - 1e-9)), 1), max(int(np.ceil(height / size - 1e-9)), 1)
    lo_x, lo_y = np.arange(nx) * size, np.arange(ny) * size
    blocked = np.zeros((nx, ny), dtype=np.bool_)
    for obstacle in world.obstacles:
        if hasattr(obstacle, "radius"):  # a disc meets a cell's interior
            cx, cy = obstacle.center
            dx = np.clip(cx, lo_x, lo_x + size) - cx
            dy = np.clip(cy, lo_y, lo_y + size) - cy
            blocked |= dx[:, None] ** 2 + dy[None, :] ** 2 < obstacle.radius**2
        else:
            (ax, ay), (bx, by) = obstacle.low, obstacle.high
            inside_x = (lo_x < bx) & (lo_x + size > ax)
            inside_y = (lo_y < by) & (lo_y + size > ay)
            blocked |= inside_x[:, None] & inside_y[None, :]
    return Occupancy(blocked, size, (0.0, 0.0), source="plane obstacles")


def reads_maze_position(form: Form) -> bool:
    """Whether a form reads a maze's position: a ``box`` or ``disc`` over ``achieved_goal``
    (or ``desired_goal``) at ``[0, 1]``."""
    return (
        isinstance(form, InBox | InDisc)
        and form.key in ("achieved_goal", "desired_goal")
        and tuple(form.index) == (0, 1)
    )


def reads_agent_pos(form: Form) -> bool:
    """Whether a form reads MiniGrid's ``agent_pos`` (a value's test, or a guide's origin)."""
    source = form.origin if isinstance(form, Guided) else getattr(form, "source", None)
    return isinstance(source, AttrPath) and source.steps == ("agent_pos",)


def reads_anything(form: Form) -> bool:
    """Every 2-D form reads the positions of the grid (a plane's, a declared one)."""
    return True


class OccupancySource:
    """Reads an env's occupancy: once (a maze, a plane, a declared grid) or at every reset (a
    MiniGrid grid); ``reads`` says which forms read the positions it maps (the others keep the
    straight line)."""

    def __init__(
        self,
        name: str,
        occupancy: Occupancy | None = None,
        reads: Callable[[Form], bool] = reads_anything,
    ) -> None:
        self.name, self.fixed, self.reads = name, occupancy, reads

    def read(self, unwrapped: Any) -> Occupancy | None:
        """The occupancy now."""
        if self.fixed is not None:
            return self.fixed
        grid = getattr(unwrapped, "grid", None)
        return None if grid is None or not hasattr(grid, "grid") else minigrid_occupancy(grid)


def occupancy_source(unwrapped: Any, declared: Occupancy | None = None) -> OccupancySource | None:
    """Where ``unwrapped``'s occupancy comes from (module docstring), ``None`` where nothing
    is known."""
    if declared is not None:
        return OccupancySource(declared.source, declared)
    maze = getattr(unwrapped, "maze", None)
    if all(hasattr(maze, a) for a in ("maze_map", "maze_size_scaling", "x_map_center")):
        return OccupancySource("maze_map", maze_occupancy(maze), reads_maze_position)
    minigrid = sys.modules.get("minigrid.minigrid_env")
    if minigrid is not None and isinstance(unwrapped, minigrid.MiniGridEnv):
        return OccupancySource("MiniGrid grid", reads=reads_agent_pos)
    world = getattr(unwrapped, "world", None)
    if all(hasattr(world, a) for a in ("obstacles", "width", "height", "free")):
        return OccupancySource("plane obstacles", plane_occupancy(world))
    return None


class Geodesic:
    """The geodesic distances of label forms over an env's occupancy, each form's field
    computed once per occupancy (module docstring)."""

    def __init__(self, source: OccupancySource) -> None:
        self.source = source
        self.occupancy: Occupancy | None = None
        self._fields: dict[int, tuple[Any, DistanceField | None]] = {}
        self._guided: dict[tuple[int, int], DistanceField] = {}
        self._key: bytes = b""
        self._walled = False

    def refresh(self, unwrapped: Any) -> None:
        """Read the occupancy again (at a reset); the fields are kept where it is the same."""
        occupancy = self.source.read(unwrapped)
        if occupancy is None:
            self.occupancy, self._key = None, b""
            return
        if occupancy is not self.occupancy:
            key = occupancy.blocked.tobytes() + repr((occupancy.shape, occupancy.cell_size,
                                                      occupancy.origin)).encode()  # fmt: skip
            if key != self._key:
                self._fields.clear()
                self._guided.clear()
                self._key = key
            self.occupancy, self._walled = occupancy, bool(occupancy.blocked.any())

    def field(self, form: Form) -> DistanceField | None:
        """The field of a form's fixed region (``None``: none, or not in the map, or a map
        with no obstacle, where the straight line is the distance)."""
        if self.occupancy is None or not self._walled:
            return None
        found = self._fields.get(id(form))
        if found is None or found[0] is not form:
            target = _target(form) if self.source.reads(form) else None
            made = None if target is None else self.occupancy.field(target)
            found = (form, made if made is not None and made.reachable else None)
            self._fields[id(form)] = found
        return found[1]

    def toward(self, form: Guided, target: np.ndarray[Any, Any]) -> DistanceField | None:
        """The field of a guide's target position (per target cell)."""
        occupancy = self.occupancy
        if occupancy is None or target.size != 2 or not self._walled or not self.source.reads(form):
            return None
        cell = occupancy.cell_of(target)
        found = self._guided.get(cell)
        if found is None:
            if len(self._guided) >= MAX_GUIDED:
                self._guided.pop(next(iter(self._guided)))
            found = occupancy.field(Target.point(target))
            self._guided[cell] = found
        return found if found.reachable else None

    def form_distance(self, form: Form, point: Any, straight: float) -> float:
        """The geodesic distance of ``point`` (the 2-D position the form reads) from the form's
        region, never below ``straight``; ``straight`` where the form has no field."""
        if straight == 0.0:
            return 0.0
        found = self.field(form)
        x = vector(point)
        if found is None or x is None or x.size != 2:
            return straight
        return max(found.at(x), straight)


def _target(form: Form) -> Target | None:
    """A form's 2-D region (``None``: not a 2-D box, disc or point)."""
    if isinstance(form, InBox | InDisc):
        return as_target(form) if len(form.index) == 2 else None
    if isinstance(form, Value):
        if isinstance(form.test, Region):
            return as_target(form.test) if form.test.size == 2 else None
        if isinstance(form.test, Equals):
            point = vector(form.test.expected)
            return Target.point(point) if point is not None and point.size == 2 else None
    return None


def has_region(forms: Sequence[Sequence[Form]]) -> bool:
    """Whether some form has a 2-D region or a guide (what a geodesic would measure)."""
    return any(isinstance(f, Guided) or _target(f) is not None for fs in forms for f in fs)


def declared_occupancy(section: Any) -> Occupancy | None:
    """A world file's ``occupancy:`` section (validated by its schema: ``cells``, ``cell_size``,
    ``origin``, as a mapping or attributes) as a grid; ``None`` for none."""
    if section is None:
        return None
    read: Any = section.get if isinstance(section, Mapping) else partial(getattr, section)
    return Occupancy.from_rows(read("cells"), float(read("cell_size")),
                               [float(v) for v in read("origin")])  # fmt: skip
