"""Grid geometry and the models built on it: motion (transitions) and observations.

A :class:`Layout` is a checked grid: its size, its blocked cells and the kind of each declared
side (wall, door, window). A side is keyed canonically (:func:`side_key`): the east or south
side of a cell between two cells of the grid, or the cell's own side on the grid's edge.
Up is north (towards row 0), left is west.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from mitlc.limits import MAX_GRID_CELLS
from mitlc.worlds.model import Observations, Sparse
from mitlc.worlds.schema import Motion, UncertainLabel, WeightedStart, WorldFile, label_cells, show

Cell = tuple[int, int]
SideKey = tuple[Cell, str]

DIRECTIONS = ("N", "W", "S", "E")
"""The compass directions, in the order of a local pattern."""
DELTA = {"N": (-1, 0), "W": (0, -1), "S": (1, 0), "E": (0, 1)}
OPPOSITE = {"N": "S", "S": "N", "W": "E", "E": "W"}
HEADING = {"up": "N", "down": "S", "left": "W", "right": "E"}
"""The direction of each move; ``stay`` has none."""
PERPENDICULAR = {"N": ("W", "E"), "S": ("W", "E"), "W": ("N", "S"), "E": ("N", "S")}
DIAGONALS = ((-1, -1), (-1, 1), (1, -1), (1, 1))
TOLERANCE = 1e-12


@dataclass(frozen=True, slots=True)
class Layout:
    """A grid with blocked cells and the kinds of its declared sides (by :func:`side_key`)."""

    rows: int
    cols: int
    blocked: frozenset[Cell]
    sides: Mapping[SideKey, str]

    def inside(self, cell: Cell) -> bool:
        """Whether ``cell`` is a cell of the grid."""
        return 0 <= cell[0] < self.rows and 0 <= cell[1] < self.cols

    def free(self, cell: Cell) -> bool:
        """Whether the robot can be in ``cell``: inside the grid and not blocked."""
        return self.inside(cell) and cell not in self.blocked

    def cells(self) -> tuple[Cell, ...]:
        """The free cells, row by row: the states of the world."""
        every = ((r, c) for r in range(self.rows) for c in range(self.cols))
        return tuple(cell for cell in every if cell not in self.blocked)

    def side(self, cell: Cell, direction: str) -> str | None:
        """The declared kind of a side of ``cell`` (``wall``, ``door``, ``window``), if any."""
        return self.sides.get(side_key(self, cell, direction))

    def step(self, cell: Cell, direction: str) -> Cell | None:
        """Where a move from ``cell`` goes, or ``None`` when it is infeasible (off the grid,
        into a blocked cell, or through a wall or a window)."""
        target = neighbour(cell, direction)
        if not self.free(target) or self.side(cell, direction) in ("wall", "window"):
            return None
        return target

    def pattern(self, cell: Cell) -> tuple[str, ...]:
        """What ``cell`` looks like from inside: N, W, S, E, each wall, hallway, door or window.
        The grid's edge and a blocked neighbour are walls unless a side says otherwise."""
        kinds = []
        for direction in DIRECTIONS:
            declared = self.side(cell, direction)
            if declared is not None:
                kinds.append(declared)
            else:
                kinds.append("hallway" if self.free(neighbour(cell, direction)) else "wall")
        return tuple(kinds)


@dataclass(frozen=True, slots=True)
class GridMap:
    """What a map of a grid world shows (a world's ``drawing``): its layout, the cells of each
    of its labels, and where its robots start."""

    layout: Layout
    labels: tuple[tuple[str, tuple[Cell, ...]], ...]
    starts: tuple[Cell, ...]


def neighbour(cell: Cell, direction: str) -> Cell:
    """The cell next to ``cell`` in ``direction`` (perhaps outside the grid)."""
    dr, dc = DELTA[direction]
    return (cell[0] + dr, cell[1] + dc)


def side_key(layout: Layout, cell: Cell, direction: str) -> SideKey:
    """The canonical key of a side: shared sides are named by the cell to their north or west."""
    other = neighbour(cell, direction)
    if direction in ("N", "W") and layout.inside(other):
        return (other, OPPOSITE[direction])
    return (cell, direction)


def direction_between(first: Cell, second: Cell) -> str | None:
    """The direction from ``first`` to an adjacent ``second``, or ``None`` if not adjacent."""
    for direction in DIRECTIONS:
        if neighbour(first, direction) == second:
            return direction
    return None


# --- the checks that need the whole file ------------------------------------------------------

FieldPath = tuple[str | int, ...]
Found = list[tuple[FieldPath, str]]
MAX_CELLS = MAX_GRID_CELLS


def check(world: WorldFile) -> tuple[Layout, Found]:
    """The layout of a world file, and what is wrong with its cells and sides: each problem as
    (the field's path, a message)."""
    checker, too_large = checked_layout(world)
    if too_large is not None:
        return checker.bare, too_large
    check_start(checker, world.start)
    return checker.layout(), checker.found


def check_start(checker: _Checker, start: Any) -> None:
    """The start's cells inside and free, each once, and one weight per cell
    (:data:`~mitlc.worlds.schema.Start`'s forms)."""
    if isinstance(start, str):  # uniform: every free cell
        return
    if isinstance(start, tuple):
        checker.cell(("start",), start)
        return
    cells, at = (
        (start, ("start",)) if isinstance(start, list) else (start.cells, ("start", "cells"))
    )
    for i, cell in enumerate(cells):
        checker.cell((*at, i), cell)
    checker.once(at, "cell", cells)
    if isinstance(start, WeightedStart) and len(start.weights) != len(start.cells):
        message = (
            f"{len(start.weights)} weights for {len(start.cells)} cells (one weight per cell, "
            "in the same order)"
        )
        checker.found.append((("start", "weights"), message))


class GridFile(Protocol):
    """What :func:`checked_layout` reads of a grid or team world file."""

    @property
    def grid(self) -> Any: ...
    @property
    def blocked(self) -> Sequence[Cell]: ...
    @property
    def labels(self) -> Mapping[str, Sequence[Cell] | UncertainLabel]: ...
    @property
    def actions(self) -> Sequence[str]: ...
    @property
    def walls(self) -> Sequence[Any]: ...
    @property
    def doors(self) -> Sequence[Any]: ...
    @property
    def windows(self) -> Sequence[Any]: ...


def checked_layout(world: GridFile) -> tuple[_Checker, Found | None]:
    """The checks every file on a grid shares (its size, blocked cells, labels' cells, actions
    and sides), in a checker that goes on collecting problems; the problem of a grid too large
    to check, which stops them."""
    rows, cols = world.grid.rows, world.grid.cols
    checker = _Checker(Layout(rows, cols, frozenset(world.blocked), {}))
    if rows * cols > MAX_CELLS:
        return checker, [
            (("grid",), f"a {rows}x{cols} grid is too large (at most {MAX_CELLS:,} cells)")
        ]
    for i, cell in enumerate(world.blocked):
        checker.cell(("blocked", i), cell, free=False)
    checker.once(("blocked",), "cell", world.blocked)
    for name, label in world.labels.items():
        cells, below = label_cells(label)
        for i, cell in enumerate(cells):
            checker.cell(("labels", name, *below, i), cell)
        checker.once(("labels", name, *below), "cell", cells)
    checker.once(("actions",), "action", world.actions)
    for kind, items in (("wall", world.walls), ("door", world.doors), ("window", world.windows)):
        for i, (first, second) in enumerate(items):
            checker.side((f"{kind}s", i), kind, first, second)
    return checker, None


class _Checker:
    """Collects the problems of a file's cells and sides against a grid without sides."""

    def __init__(self, bare: Layout) -> None:
        self.bare = bare
        self.found: Found = []
        self.sides: dict[SideKey, str] = {}
        self.declared: dict[SideKey, FieldPath] = {}

    def layout(self) -> Layout:
        """The grid with the sides declared so far."""
        return Layout(self.bare.rows, self.bare.cols, self.bare.blocked, self.sides)

    def cell(self, path: FieldPath, cell: Cell, free: bool = True) -> bool:
        """Whether ``cell`` is inside the grid (and free, if ``free``); a problem if not."""
        rows, cols = self.bare.rows, self.bare.cols
        if not self.bare.inside(cell):
            where = f"the {rows}x{cols} grid (rows 0 to {rows - 1}, columns 0 to {cols - 1})"
            self.found.append((path, f"cell {show(cell)} is outside {where}"))
        elif free and cell in self.bare.blocked:
            self.found.append((path, f"cell {show(cell)} is blocked"))
        else:
            return True
        return False

    def once(self, name: FieldPath, noun: str, items: Sequence[object]) -> None:
        """A problem for each item listed again."""
        first: dict[object, int] = {}
        for i, item in enumerate(items):
            if item in first:
                also = render((*name, first[item]))
                self.found.append(
                    ((*name, i), f"{noun} {show(item)} is listed twice (also {also})")
                )
            first.setdefault(item, i)

    def side(self, path: FieldPath, kind: str, first: Cell, second: Cell | str) -> None:
        """Check a side and record its kind: two adjacent cells, or a cell and a direction."""
        if not self.cell(path, first, free=False):
            return
        if isinstance(second, str):
            direction: str | None = second
        elif not self.cell(path, second, free=False):
            return
        else:
            direction = direction_between(first, second)
        if direction is None:
            self.found.append((path, f"cells {show(first)} and {show(second)} are not adjacent"))
            return
        key, other = side_key(self.bare, first, direction), neighbour(first, direction)
        what = _describe(self.bare, first, direction)
        if kind == "door" and not self.bare.inside(other):
            self.found.append((path, f"{what} is on the grid's edge: a door there leads nowhere"))
        elif kind == "door" and not (self.bare.free(first) and self.bare.free(other)):
            self.found.append((path, f"{what} has a blocked cell: a door must join two free cells"))
        elif key in self.declared:
            self.found.append((path, f"{what} is already declared in {render(self.declared[key])}"))
        else:
            self.declared[key], self.sides[key] = path, kind


def _describe(layout: Layout, cell: Cell, direction: str) -> str:
    other = neighbour(cell, direction)
    if layout.inside(other):
        return f"the side between {show(cell)} and {show(other)}"
    return f"the {direction} side of {show(cell)}"


def render(path: FieldPath) -> str:
    """``labels.a[0]``: keys joined by dots, indices in brackets."""
    text = ""
    for item in path:
        text += f"[{item}]" if isinstance(item, int) else (f".{item}" if text else str(item))
    return text


# --- motion ----------------------------------------------------------------------------------


def move(
    layout: Layout,
    cell: Cell,
    action: str,
    motion: Motion,
    steps: Mapping[str, Cell | None] | None = None,
) -> dict[Cell, float]:
    """The distribution of the next cell. With ``sideways``, each perpendicular way w.p.
    ``sideways``; with ``spread``, that mass split evenly over the other feasible directions;
    with ``stall``, in place w.p. ``stall``.
    Infeasible outcomes leave the robot in place; ``stay`` is certain. ``steps`` may give
    ``layout.step(cell, d)`` for every direction ``d``, computed once for all actions."""
    heading = HEADING.get(action)
    if heading is None:
        return {cell: 1.0}
    if steps is None:
        steps = {d: layout.step(cell, d) for d in DIRECTIONS}
    outcomes: list[tuple[Cell | None, float]] = [(steps[heading], motion.intended)]
    if motion.stall is not None:
        outcomes.append((None, motion.stall))
    elif motion.sideways is not None:
        outcomes += [(steps[d], motion.sideways) for d in PERPENDICULAR[heading]]
    else:
        spread = motion.spread or 0.0
        others = [steps[d] for d in DIRECTIONS if d != heading]
        feasible = [target for target in others if target is not None]
        share = [(t, spread / len(feasible)) for t in feasible]
        outcomes += share if feasible else [(None, spread)]
    dist: dict[Cell, float] = {}
    for target, p in outcomes:
        where = cell if target is None else target
        dist[where] = dist.get(where, 0.0) + p
    return dist


def transitions(layout: Layout, actions: Iterable[str], motion: Motion) -> Sparse:
    """The motion model as compressed rows ``s * len(actions) + a`` over state ids."""
    cells = layout.cells()
    index = {cell: s for s, cell in enumerate(cells)}
    chosen = tuple(actions)
    rows: list[dict[int, float]] = []
    for cell in cells:
        steps = {d: layout.step(cell, d) for d in DIRECTIONS}  # once for every action
        rows.extend(
            {index[t]: p for t, p in move(layout, cell, a, motion, steps).items()} for a in chosen
        )
    return _sparse(rows)


# --- observations ----------------------------------------------------------------------------


def noisy_cell(layout: Layout, correct: float, neighbourhood: int) -> Observations:
    """The true cell w.p. ``correct``, else one of the adjacent free cells (4 or 8 around)."""
    cells = layout.cells()
    index = {cell: s for s, cell in enumerate(cells)}
    offsets = [DELTA[d] for d in DIRECTIONS] + (list(DIAGONALS) if neighbourhood == 8 else [])
    rows: list[dict[int, float]] = []
    for cell in cells:
        around = [(cell[0] + dr, cell[1] + dc) for dr, dc in offsets]
        near = [index[n] for n in around if layout.free(n)]
        row = {index[cell]: correct if near else 1.0}
        row.update({n: (1.0 - correct) / len(near) for n in near})
        rows.append(row)
    names = tuple(f"r{r}c{c}" for r, c in cells)
    return Observations(names, _sparse(rows))


def local_pattern(layout: Layout) -> Observations:
    """Deterministic observations: a cell's (N, W, S, E) pattern; ids are the distinct patterns
    in sorted order, named like ``wall,wall,wall,door``."""
    patterns = [layout.pattern(cell) for cell in layout.cells()]
    distinct = sorted(set(patterns))
    ids = {pattern: i for i, pattern in enumerate(distinct)}
    names = tuple(",".join(pattern) for pattern in distinct)
    return Observations(names, _sparse([{ids[p]: 1.0} for p in patterns]))


def _sparse(rows: list[dict[int, float]]) -> Sparse:
    """:meth:`Sparse.from_rows`, after checking that every row sums to 1."""
    for r, row in enumerate(rows):
        total = sum(row.values())
        assert abs(total - 1.0) <= TOLERANCE, f"row {r} sums to {total}"
    return Sparse.from_rows(rows)
