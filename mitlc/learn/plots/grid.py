"""The trajectories of a grid world's run: ``trajectory_figure(setting, trajectories, title)``.

The grid (blocked cells black, labelled cells coloured and named, the start starred, walls thick
black, doors brown, windows light blue) with a few greedy rollouts of the learned policy drawn
through the cell centres (green: success, red: failure).
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from mitlc.learn.evaluation.trajectories import Trajectory
from mitlc.learn.plots.common import DPI, PlotError
from mitlc.learn.setting import Setting
from mitlc.worlds.grid import GridMap, Layout

GRID_SIZE = (9.5, 6.5)
"""Inches; at :data:`DPI`, a 950x650 PNG."""
WALL, DOOR, WINDOW = "black", "#8b5a2b", "#8ecae6"
SUCCESS, FAILURE = "Greens", "Reds"


_SEGMENTS = {
    "N": ((0, 0), (1, 0)),
    "S": ((0, 1), (1, 1)),
    "W": ((0, 0), (0, 1)),
    "E": ((1, 0), (1, 1)),
}
"""A cell's side as (x, y) offsets from its top-left corner (y grows downwards)."""


def _side_line(cell: tuple[int, int], direction: str) -> tuple[list[float], list[float]]:
    (x0, y0), (x1, y1) = _SEGMENTS[direction]
    row, col = cell
    return [col + x0, col + x1], [row + y0, row + y1]


def _draw_sides(axes: Axes, layout: Layout, width: float) -> None:
    """Thin hallway lines, the grid's edge, and each declared wall, door and window."""
    for r in range(1, layout.rows):
        axes.plot([0, layout.cols], [r, r], color="0.85", linewidth=0.8, zorder=1)
    for c in range(1, layout.cols):
        axes.plot([c, c], [0, layout.rows], color="0.85", linewidth=0.8, zorder=1)
    axes.add_patch(
        Rectangle(
            (0, 0), layout.cols, layout.rows, fill=False, edgecolor=WALL, linewidth=width, zorder=3
        )
    )
    for (cell, direction), kind in sorted(layout.sides.items()):
        xs, ys = _side_line(cell, direction)
        if kind == "wall":
            axes.plot(xs, ys, color=WALL, linewidth=width, solid_capstyle="projecting", zorder=3)
        elif kind == "window":
            axes.plot(xs, ys, color=WALL, linewidth=width * 1.8, solid_capstyle="butt", zorder=3)
            axes.plot(xs, ys, color=WINDOW, linewidth=width * 1.0, solid_capstyle="butt", zorder=4)
        else:  # a door: wall stubs at both ends, the door leaf in brown between them
            x = np.asarray(xs)
            y = np.asarray(ys)
            for a, b in ((0.0, 0.2), (0.8, 1.0)):
                axes.plot(
                    x[0] + (x[1] - x[0]) * np.array([a, b]),
                    y[0] + (y[1] - y[0]) * np.array([a, b]),
                    color=WALL,
                    linewidth=width,
                    solid_capstyle="butt",
                    zorder=3,
                )
            axes.plot(
                x[0] + (x[1] - x[0]) * np.array([0.2, 0.8]),
                y[0] + (y[1] - y[0]) * np.array([0.2, 0.8]),
                color=DOOR,
                linewidth=width * 0.6,
                solid_capstyle="butt",
                zorder=3,
            )


def _draw_cells(
    axes: Axes,
    layout: Layout,
    labels: dict[str, tuple[tuple[int, int], ...]],
    font: float,
) -> None:
    """Blocked cells black, labelled cells coloured with their names."""
    for row, col in sorted(layout.blocked):
        axes.add_patch(Rectangle((col, row), 1, 1, color="black", zorder=2))
    palette = [f"C{i}" for i in range(10)]
    names: dict[tuple[int, int], list[str]] = {}
    for i, name in enumerate(sorted(labels)):
        for cell in labels[name]:
            names.setdefault(cell, []).append(name)
            if len(names[cell]) == 1:
                axes.add_patch(
                    Rectangle(
                        (cell[1], cell[0]),
                        1,
                        1,
                        color=palette[i % 10],
                        alpha=0.22,
                        linewidth=0,
                        zorder=0,
                    )
                )
    for (row, col), here in sorted(names.items()):
        axes.text(
            col + 0.5,
            row + 0.06,
            ", ".join(here),
            ha="center",
            va="top",
            fontsize=font,
            fontweight="bold",
            color="0.15",
            zorder=6,
        )


def _draw_start(
    axes: Axes,
    start: tuple[int, int],
    font: float,
    *,
    colour: Any = "gold",
    text: str = "start",
    shift: float = 0.0,
) -> None:
    """A star at ``start``'s centre (moved right by ``shift``) with ``text`` below it."""
    axes.plot(
        start[1] + 0.5 + shift,
        start[0] + 0.5,
        marker="*",
        markersize=font * 1.6,
        color=colour,
        markeredgecolor="black",
        zorder=5,
    )
    axes.text(
        start[1] + 0.5 + shift,
        start[0] + 0.94,
        text,
        ha="center",
        va="bottom",
        fontsize=font * 0.85,
        color="0.3",
        zorder=6,
    )


def _draw_trajectory(axes: Axes, trajectory: Trajectory, offset: float, colour: Any) -> None:
    """Arrows from cell centre to cell centre (shifted by ``offset``), a dot at each stop
    growing with the steps spent there, and a square (success) or a cross (failure) at the
    end."""
    stops = trajectory.stops()
    points = [(col + 0.5 + offset, row + 0.5 + offset) for (row, col), _, _ in stops]
    for before, after in itertools.pairwise(points):
        axes.annotate(
            "",
            xy=after,
            xytext=before,
            zorder=7,
            arrowprops={
                "arrowstyle": "-|>",
                "color": colour,
                "linewidth": 1.8,
                "shrinkA": 3,
                "shrinkB": 3,
                "mutation_scale": 11,
                "alpha": 0.9,
                "connectionstyle": "arc3,rad=0.1",
            },
        )
    for (x, y), (_, first, last) in zip(points, stops, strict=True):
        axes.plot(
            x,
            y,
            marker="o",
            markersize=4 + 2 * np.sqrt(last - first),
            color=colour,
            alpha=0.85,
            markeredgecolor="white",
            markeredgewidth=0.6,
            zorder=8,
        )
    x, y = points[-1]
    axes.plot(
        x,
        y,
        marker="s" if trajectory.success else "X",
        markersize=9,
        color=colour,
        markeredgecolor="black",
        markeredgewidth=0.8,
        zorder=9,
    )


def _colours(trajectories: list[Trajectory]) -> list[Any]:
    """Shades of green for successes and of red for failures, darker for later ones."""
    from matplotlib import colormaps

    counts = {True: sum(t.success for t in trajectories)}
    counts[False] = len(trajectories) - counts[True]
    seen = {True: 0, False: 0}
    colours = []
    for t in trajectories:
        shades = np.linspace(0.55, 0.9, max(counts[t.success], 1))
        colours.append(colormaps[SUCCESS if t.success else FAILURE](shades[seen[t.success]]))
        seen[t.success] += 1
    return colours


def _legend(axes: Axes, layout: Layout, trajectories: list[Trajectory], colours: list[Any]) -> None:
    """The rollouts, then the kinds of sides and cells this grid has."""
    handles: list[Any] = []
    for i, (t, colour) in enumerate(zip(trajectories, colours, strict=True)):
        outcome = "success" if t.success else "failure"
        label = f"#{i + 1} {outcome}: {t.verdict}, {t.length} steps"
        handles.append(Line2D([], [], color=colour, marker="o", markersize=5, label=label))
    handles += _map_handles(layout)
    handles.append(
        Line2D(
            [],
            [],
            color="gold",
            marker="*",
            markeredgecolor="black",
            markersize=12,
            linewidth=0,
            label="start",
        )
    )
    title = "greedy rollouts\n(dot size: steps spent in a cell;\n■ success, ✖ failure at the end)"
    axes.legend(
        handles=handles,
        loc="center left",
        bbox_to_anchor=(1.04, 0.5),
        frameon=False,
        fontsize=9,
        title=title,
        title_fontsize=9,
    )


def _map_handles(layout: Layout) -> list[Any]:
    """Legend entries for the kinds of sides and cells this grid has."""
    kinds = set(layout.sides.values())
    features = [("wall", WALL, 4.0), ("door", DOOR, 3.0), ("window", WINDOW, 4.0)]
    handles: list[Any] = [
        Line2D([], [], color=colour, linewidth=width, label=kind)
        for kind, colour, width in features
        if kind == "wall" or kind in kinds
    ]
    if layout.blocked:
        handles.append(Patch(facecolor="black", label="blocked"))
    return handles


def trajectory_figure(setting: Setting, trajectories: list[Trajectory], title: str) -> Figure:
    """The world's grid with ``trajectories`` drawn over it."""
    drawing = setting.world.drawing
    if not isinstance(drawing, GridMap):
        raise PlotError(f"{setting.world_path}: the world has no grid to draw on")
    layout = drawing.layout
    figure = Figure(figsize=GRID_SIZE, dpi=DPI)
    axes = figure.add_axes((0.03, 0.04, 0.6, 0.8))
    cell_points = 0.8 * GRID_SIZE[1] * 72 / max(layout.rows, layout.cols)
    font = float(np.clip(cell_points * 0.17, 6, 13))
    _draw_cells(axes, layout, dict(drawing.labels), font)
    _draw_start(axes, drawing.starts[0], font)
    _draw_sides(axes, layout, width=float(np.clip(cell_points * 0.05, 2, 5)))
    colours = _colours(trajectories)
    spacing = min(0.07, 0.5 / max(len(trajectories), 1))
    for i, (trajectory, colour) in enumerate(zip(trajectories, colours, strict=True)):
        offset = (i - (len(trajectories) - 1) / 2) * spacing
        _draw_trajectory(axes, trajectory, offset, colour)
    axes.set_xlim(-0.05, layout.cols + 0.05)
    axes.set_ylim(layout.rows + 0.05, -0.05)
    axes.set_aspect("equal")
    axes.axis("off")
    _legend(axes, layout, trajectories, colours)
    figure.suptitle(title, fontsize=12, x=0.03, ha="left")
    return figure


# --- the run -----------------------------------------------------------------------------------
