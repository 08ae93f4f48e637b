"""The figure of a continuous world (:class:`~mitlc.worlds.plane.PlaneWorld`) and trajectories
in it: ``plane_figure(world, trajectories, title) -> Figure``.

The room is drawn in metres with the origin at its lower-left corner and y up (the world's
coordinates): obstacles black, each labelled region coloured and named, the start starred (a
start region outlined in gold), and each trajectory, a list of positions ``(x, y)``, as a line
through them with a dot at each position, a circle at its first and a square at its last.
Drawn on :class:`matplotlib.figure.Figure` directly (no pyplot, no display), like
:mod:`mitlc.learn.plots.grid`.
"""

from __future__ import annotations

from typing import Any

from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Rectangle

from mitlc.learn.learners.base import Policy
from mitlc.learn.setting import Setting, task_vector_of
from mitlc.worlds.plane import Box, PlaneWorld, Region

DPI = 100
SIZE = (9.5, 6.5)
"""Inches; at :data:`DPI`, a 950x650 PNG (as the grid's trajectory figure)."""
OBSTACLE, ROOM, START = "black", "0.25", "gold"
TRAJECTORY_COLOURS = "Dark2"
"""The qualitative colour map of the trajectories (the regions use matplotlib's ``C0``, ...)."""
MAX_LEGEND = 12
"""Trajectories named in the legend (the rest are drawn, not named)."""


def _patch(region: Region, **style: Any) -> Rectangle | Circle:
    if isinstance(region, Box):
        (x0, y0), (x1, y1) = region.low, region.high
        return Rectangle((x0, y0), x1 - x0, y1 - y0, **style)
    return Circle(region.center, region.radius, **style)


def _centre(region: Region) -> tuple[float, float]:
    if isinstance(region, Box):
        return ((region.low[0] + region.high[0]) / 2, (region.low[1] + region.high[1]) / 2)
    return region.center


def _draw_world(axes: Axes, world: PlaneWorld, font: float) -> None:
    """The room's edge, the labelled regions with their names, the obstacles, the start."""
    axes.add_patch(
        Rectangle(
            (0, 0), world.width, world.height, fill=False, edgecolor=ROOM, linewidth=2.5, zorder=4
        )
    )
    for i, name in enumerate(sorted(world.labels)):
        colour = f"C{i % 10}"
        for region in world.labels[name]:
            axes.add_patch(_patch(region, color=colour, alpha=0.25, linewidth=0, zorder=1))
            x, y = _centre(region)
            axes.text(
                x, y, name, ha="center", va="center", fontsize=font, fontweight="bold",
                color="0.15", zorder=6,
            )  # fmt: skip
    for obstacle in world.obstacles:
        axes.add_patch(_patch(obstacle, color=OBSTACLE, zorder=3))
    start = world.start
    if isinstance(start, tuple):
        axes.plot(
            *start, marker="*", markersize=font * 1.6, color=START, markeredgecolor="black",
            linewidth=0, zorder=10,
        )  # fmt: skip
    else:
        style = {"fill": False, "edgecolor": START, "linewidth": 2, "linestyle": "--"}
        axes.add_patch(_patch(start, zorder=5, **style))


def _colour(i: int) -> Any:
    from matplotlib import colormaps

    cmap = colormaps[TRAJECTORY_COLOURS]
    return cmap(i % cmap.N)


def _draw_trajectory(axes: Axes, points: list[tuple[float, float]], colour: Any) -> None:
    """A line through the positions, dots on them, a circle at the first, a square at the last."""
    if not points:
        return
    xs, ys = [p[0] for p in points], [p[1] for p in points]
    axes.plot(xs, ys, color=colour, linewidth=1.6, marker="o", markersize=3, alpha=0.85, zorder=7)
    axes.plot(
        xs[0], ys[0], marker="o", markersize=7, color=colour, markeredgecolor="black", zorder=8
    )
    axes.plot(
        xs[-1], ys[-1], marker="s", markersize=8, color=colour, markeredgecolor="black", zorder=9
    )


def _legend(axes: Axes, world: PlaneWorld, trajectories: list[list[tuple[float, float]]]) -> None:
    handles: list[Any] = []
    for i, points in enumerate(trajectories[:MAX_LEGEND]):
        label = f"#{i + 1}: {max(len(points) - 1, 0)} steps"
        handles.append(Line2D([], [], color=_colour(i), marker="o", markersize=5, label=label))
    if len(trajectories) > MAX_LEGEND:
        handles.append(Line2D([], [], linewidth=0, label=f"(and {len(trajectories) - MAX_LEGEND})"))
    if world.obstacles:
        handles.append(Patch(facecolor=OBSTACLE, label="obstacle"))
    start_marker = "*" if isinstance(world.start, tuple) else "s"
    handles.append(
        Line2D(
            [], [], color=START, marker=start_marker, markeredgecolor="black", markersize=12,
            linewidth=0, label="start" if start_marker == "*" else "start region",
        )
    )  # fmt: skip
    title = "trajectories\n(● first position, ■ last)"
    axes.legend(
        handles=handles, loc="center left", bbox_to_anchor=(1.04, 0.5), frameon=False,
        fontsize=9, title=title, title_fontsize=9,
    )  # fmt: skip


def plane_figure(
    world: PlaneWorld, trajectories: list[list[tuple[float, float]]], title: str
) -> Figure:
    """The room of ``world`` with ``trajectories`` (lists of positions ``(x, y)``) drawn in it."""
    figure = Figure(figsize=SIZE, dpi=DPI)
    axes = figure.add_axes((0.06, 0.06, 0.57, 0.8))
    side_points = 0.8 * SIZE[1] * 72 / max(world.width, world.height)
    font = float(min(max(side_points * 0.3, 9), 14))
    _draw_world(axes, world, font)
    for i, points in enumerate(trajectories):
        _draw_trajectory(axes, points, _colour(i))
    margin = 0.02 * max(world.width, world.height)
    axes.set_xlim(-margin, world.width + margin)
    axes.set_ylim(-margin, world.height + margin)
    axes.set_aspect("equal")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.spines[["top", "right"]].set_visible(False)
    _legend(axes, world, trajectories)
    figure.suptitle(title, fontsize=12, x=0.03, ha="left")
    return figure


def rollouts_plane(
    setting: Setting, policy: Policy, count: int, seed: int
) -> list[tuple[list[tuple[float, float]], bool]]:
    """``count`` greedy trajectories (positions) and whether each succeeded."""
    drawn = []
    for k in range(count):
        vector = task_vector_of(setting, 1, seed + k)
        policy.reset(1)
        x, y = vector.envs[0].unwrapped.position
        path = [(float(x), float(y))]
        while True:
            step = vector.step(policy.act(vector))
            policy.observe(step)
            x, y = vector.reached("position")[0]
            path.append((float(x), float(y)))
            if step.done[0]:
                drawn.append((path, bool(step.success[0])))
                break
    return drawn
