"""A team world's run, and any grid world's greedy episode as an animation.

* ``team_figure(setting, trajectories, title)``: the grid (as in :mod:`mitlc.learn.plots.grid`)
  with every robot's path of each greedy rollout drawn in the robot's colour, each robot's
  start starred in its colour and named, and a legend naming the robots. A joint trajectory is
  split into per-robot cells by :func:`~mitlc.learn.evaluation.trajectories.robot_cells`;
  later rollouts are drawn in paler shades of each robot's colour.
* ``episode_gif(setting, trajectory, title)``: one greedy episode as an animated GIF, one frame
  per world step (the last position of each step, after any epsilon jumps), the robots as
  discs in their colours with their ids, the step and the task's verdict so far in the title
  (*pending* until the episode's last frame, which shows how it ended). A single-robot grid
  world is drawn as a team of one. The frames are small (:data:`GIF_SIZE` at
  :data:`GIF_DPI`) and at most :data:`GIF_FRAMES`: a longer episode shows that many steps,
  evenly spaced, the first and the last among them. The same trajectory gives the same bytes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from io import BytesIO
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle
from PIL import Image

from mitlc.learn.evaluation.trajectories import Cell, Trajectory, robot_cells
from mitlc.learn.plots.common import DPI, PlotError
from mitlc.learn.plots.grid import (
    GRID_SIZE,
    _draw_cells,
    _draw_sides,
    _draw_start,
    _draw_trajectory,
    _map_handles,
)
from mitlc.learn.setting import Setting
from mitlc.worlds.grid import GridMap

ROBOT_COLOURS = (
    "#d62728",
    "#1f77b4",
    "#2ca02c",
    "#9467bd",
    "#ff7f0e",
    "#8c564b",
    "#e377c2",
    "#17becf",
)
"""Robot ``r``'s colour is ``ROBOT_COLOURS[r % 8]``."""
GIF_SIZE = (4.0, 4.4)
"""Inches; at :data:`GIF_DPI`, a 240x264 GIF."""
GIF_DPI = 60
GIF_FRAMES = 121
"""The most frames an episode's GIF has (the horizon + 1 when that is smaller)."""
FRAME_MS, LAST_FRAME_MS = 400, 2000
"""How long each frame shows, and the last one (the verdict)."""
_DISC = 0.2
"""A robot's disc radius, in cells."""


def robot_colour(robot: int) -> str:
    """Robot ``robot``'s colour (see :data:`ROBOT_COLOURS`)."""
    return ROBOT_COLOURS[robot % len(ROBOT_COLOURS)]


def _paler(colour: str, amount: float) -> tuple[float, float, float]:
    """``colour`` mixed with white: ``amount`` 0 keeps it, 1 is white."""
    return tuple(float(c + (1.0 - c) * amount) for c in to_rgb(colour))  # type: ignore[return-value]


def _robots(setting: Setting, trajectory: Trajectory) -> tuple[tuple[str, ...], list[Any]]:
    """The robots' ids and each robot's cells along ``trajectory`` (one robot named ``robot``
    for a single-robot world)."""
    team = setting.model()[0].team
    if team is None:
        return ("robot",), [trajectory.cells]
    return team.robots, list(robot_cells(trajectory, team))


def _grid(setting: Setting) -> GridMap:
    drawing = setting.world.drawing
    if not isinstance(drawing, GridMap):
        raise PlotError(f"{setting.world_path}: the world has no grid to draw on")
    return drawing


def _draw_map(axes: Axes, drawing: GridMap, font: float, width: float) -> None:
    """The grid's cells and sides, the axes fitted to it."""
    layout = drawing.layout
    _draw_cells(axes, layout, dict(drawing.labels), font)
    _draw_sides(axes, layout, width=width)
    axes.set_xlim(-0.05, layout.cols + 0.05)
    axes.set_ylim(layout.rows + 0.05, -0.05)
    axes.set_aspect("equal")
    axes.axis("off")


# --- the rollouts ------------------------------------------------------------------------------


def team_figure(setting: Setting, trajectories: list[Trajectory], title: str) -> Figure:
    """The world's grid with each robot's path of every one of ``trajectories`` over it."""
    drawing = _grid(setting)
    world = setting.model()[0]
    team = world.team
    if team is None:
        raise PlotError(f"{setting.world_path}: not a team world")
    layout = drawing.layout
    figure = Figure(figsize=GRID_SIZE, dpi=DPI)
    axes = figure.add_axes((0.03, 0.04, 0.6, 0.8))
    cell_points = 0.8 * GRID_SIZE[1] * 72 / max(layout.rows, layout.cols)
    font = float(np.clip(cell_points * 0.17, 6, 13))
    _draw_map(axes, drawing, font, width=float(np.clip(cell_points * 0.05, 2, 5)))
    for r, robot in enumerate(team.robots):
        start = team.cell_of(world.start, r)
        _draw_start(axes, start, font, colour=robot_colour(r), text=robot)
    count = len(trajectories) * team.num_robots
    spacing = min(0.07, 0.5 / max(count, 1))
    shades = np.linspace(0.0, 0.45, max(len(trajectories), 1)).tolist()
    for i, trajectory in enumerate(trajectories):
        for r, cells in enumerate(robot_cells(trajectory, team)):
            offset = (i * team.num_robots + r - (count - 1) / 2) * spacing
            colour = _paler(robot_colour(r), shades[i])
            _draw_trajectory(axes, replace(trajectory, cells=cells), offset, colour)
    _legend(axes, drawing, team.robots, trajectories)
    figure.suptitle(title, fontsize=12, x=0.03, ha="left")
    return figure


def _legend(
    axes: Axes, drawing: GridMap, robots: Sequence[str], trajectories: list[Trajectory]
) -> None:
    """The robots, the rollouts' outcomes, the kinds of sides and cells, the starts."""
    handles: list[Any] = [
        Line2D([], [], color=robot_colour(r), marker="o", markersize=5, label=robot)
        for r, robot in enumerate(robots)
    ]
    for i, t in enumerate(trajectories):
        outcome = "success" if t.success else "failure"
        handles.append(
            Line2D(
                [],
                [],
                color="0.35",
                marker="s" if t.success else "X",
                markersize=6,
                linewidth=0,
                label=f"#{i + 1} {outcome}: {t.verdict}, {t.length} steps",
            )
        )
    handles += _map_handles(drawing.layout)
    handles.append(
        Line2D(
            [],
            [],
            color="0.6",
            marker="*",
            markeredgecolor="black",
            markersize=12,
            linewidth=0,
            label="start (in the robot's colour)",
        )
    )
    title = (
        "greedy rollouts, each robot in its colour\n(paler: later rollouts; dot size: steps\n"
        "spent in a cell; ■ success, ✖ failure at the end)"
    )
    axes.legend(
        handles=handles,
        loc="center left",
        bbox_to_anchor=(1.04, 0.5),
        frameon=False,
        fontsize=9,
        title=title,
        title_fontsize=9,
    )


# --- the episode -------------------------------------------------------------------------------


def frame_positions(trajectory: Trajectory, limit: int = GIF_FRAMES) -> list[int]:
    """The positions of ``trajectory`` that the GIF shows: the last one of each world step,
    at most ``limit`` of them (evenly spaced, the first and the last kept)."""
    last: dict[int, int] = {}
    for i, step in enumerate(trajectory.steps):
        last[step] = i
    chosen = [last[step] for step in sorted(last)]
    if len(chosen) > limit:
        picks = np.linspace(0, len(chosen) - 1, max(limit, 2)).round().astype(np.int64)
        chosen = [chosen[int(i)] for i in np.unique(picks)]
    return chosen


def _spread(cells: Sequence[Cell]) -> list[tuple[float, float]]:
    """Disc centres (x, y) for robots in ``cells``: robots sharing a cell side by side."""
    centres = []
    for r, (row, col) in enumerate(cells):
        here = [s for s, other in enumerate(cells) if other == (row, col)]
        shift = (here.index(r) - (len(here) - 1) / 2) * _DISC * 1.1 if len(here) > 1 else 0.0
        centres.append((col + 0.5 + shift, row + 0.5))
    return centres


def episode_gif(setting: Setting, trajectory: Trajectory, title: str) -> bytes:
    """The GIF of ``trajectory`` on the world's grid (see the module docstring)."""
    drawing = _grid(setting)
    robots, paths = _robots(setting, trajectory)
    layout = drawing.layout
    figure = Figure(figsize=GIF_SIZE, dpi=GIF_DPI)
    axes = figure.add_axes((0.03, 0.02, 0.94, 0.8))
    cell_points = 0.8 * GIF_SIZE[1] * 72 / max(layout.rows, layout.cols)
    font = float(np.clip(cell_points * 0.15, 5, 10))
    _draw_map(axes, drawing, font, width=float(np.clip(cell_points * 0.04, 1.5, 3)))
    trails, discs, names = [], [], []
    for r, robot in enumerate(robots):
        colour = robot_colour(r)
        trails.append(axes.plot([], [], color=_paler(colour, 0.4), linewidth=2, zorder=7)[0])
        discs.append(Circle((0, 0), _DISC, color=colour, ec="black", zorder=8))
        axes.add_patch(discs[-1])
        names.append(
            axes.text(0, 0, robot, ha="center", va="top", fontsize=font, color=colour, zorder=9)
        )
    heading = figure.suptitle("", fontsize=9, x=0.03, ha="left")
    positions = frame_positions(trajectory)
    frames = []
    for n, i in enumerate(positions):
        cells = [path[i] for path in paths]
        for r, (x, y) in enumerate(_spread(cells)):
            discs[r].set_center((x, y))
            names[r].set_position((x, y + _DISC + 0.02))
            trails[r].set_data(
                [c + 0.5 for _, c in paths[r][: i + 1]], [row + 0.5 for row, _ in paths[r][: i + 1]]
            )
        verdict = "pending"
        if n == len(positions) - 1:
            outcome = "success" if trajectory.success else "failure"
            verdict = f"{trajectory.verdict} at the end: {outcome}"
        step = trajectory.steps[i]
        heading.set_text(f"{title}\nstep {step} of {setting.world.horizon}: {verdict}")
        frames.append(_pixels(figure))
    return _gif(frames)


def _pixels(figure: Figure) -> Image.Image:
    """``figure`` rendered at :data:`GIF_DPI`, as an RGB image."""
    buffer = BytesIO()
    figure.savefig(buffer, format="rgba", dpi=GIF_DPI)
    size = (round(GIF_SIZE[0] * GIF_DPI), round(GIF_SIZE[1] * GIF_DPI))
    return Image.frombytes("RGBA", size, buffer.getvalue()).convert("RGB")


def _gif(frames: list[Image.Image]) -> bytes:
    """``frames`` as a looping GIF, on one palette (64 colours of the first and the last
    frame, which between them show every robot, trail and text colour; no dithering), each
    shown :data:`FRAME_MS` and the last :data:`LAST_FRAME_MS`."""
    first, last = frames[0], frames[-1]
    both = Image.new("RGB", (first.width, first.height * 2))
    both.paste(first, (0, 0))
    both.paste(last, (0, first.height))
    palette = both.quantize(colors=64, method=Image.Quantize.MEDIANCUT)
    indexed = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    durations = [FRAME_MS] * (len(indexed) - 1) + [LAST_FRAME_MS]
    buffer = BytesIO()
    indexed[0].save(
        buffer,
        format="GIF",
        save_all=True,
        append_images=indexed[1:],
        duration=durations,
        loop=0,
    )
    return buffer.getvalue()
