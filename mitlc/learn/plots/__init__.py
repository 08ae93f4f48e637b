"""Figures of a training run, of any world: ``plot_run(directory) -> [paths]``.

* ``learning_curve.png``: the success rate and the mean return of each ``metrics.jsonl`` window
  against the episodes (the paper's cumulative-reward figure), with the exploration rate
  (:mod:`mitlc.learn.plots.common`);
* ``trajectories.png``: a few greedy rollouts of the learned policy where the world has a map to
  draw them on: a grid world's cells (:mod:`mitlc.learn.plots.grid`), a team world's grid with
  every robot's path in its colour (:mod:`mitlc.learn.plots.team`), a continuous world's room
  (:mod:`mitlc.learn.plots.plane`); a gymnasium env has none;
* ``episode.gif`` (team worlds): the first of those rollouts animated, one frame per step, the
  robots as discs in their colours (:func:`mitlc.learn.plots.team.episode_gif`);
* ``automaton.png``: the run's task compiled to its timed LDGBA, drawn by Graphviz
  (:mod:`mitlc.automata.dot`).

One route for every world: the run's setting is loaded once and asked what its world is. Each
file is written atomically.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

from mitlc.automata import compile_formula
from mitlc.automata.dot import render, to_dot
from mitlc.files import write_atomically
from mitlc.learn.evaluation.trajectories import rollouts
from mitlc.learn.learners.base import Policy
from mitlc.learn.plots.common import (
    AUTOMATON,
    CURVE_SIZE,
    DPI,
    EPISODE,
    LEARNING_CURVE,
    TRAJECTORIES,
    PlotError,
    learning_curve,
    png_bytes,
    read_metrics,
)
from mitlc.learn.plots.grid import GRID_SIZE, trajectory_figure
from mitlc.learn.plots.plane import plane_figure, rollouts_plane
from mitlc.learn.plots.team import episode_gif, team_figure
from mitlc.learn.run import load_learner
from mitlc.learn.setting import Setting, read_config
from mitlc.limits import Deadline
from mitlc.syntax import parse
from mitlc.worlds.grid import GridMap
from mitlc.worlds.plane import PlaneWorld

__all__ = [
    "AUTOMATON",
    "CURVE_SIZE",
    "DPI",
    "EPISODE",
    "GRID_SIZE",
    "LEARNING_CURVE",
    "TRAJECTORIES",
    "PlotError",
    "plot_run",
    "read_metrics",
]


def plot_run(
    directory: Path,
    out: Path | None = None,
    *,
    trajectories: int = 5,
    seed: int = 0,
    deadline: Deadline | None = None,
) -> list[Path]:
    """Draw the run in ``directory`` (see the module docstring) into ``out`` (default: the run
    directory); ``trajectories`` greedy rollouts with ``seed``. The paths written, in order.
    Setting the run up (its task and product) stops at ``deadline`` (by default a minute)."""
    directory = Path(directory)
    out = directory if out is None else Path(out)
    data, config = read_config(directory)
    metrics = read_metrics(directory)
    setting, learner = load_learner(directory, deadline=deadline)
    name = data.get("world_name", Path(str(data.get("world", "?"))).stem)
    curve = out / LEARNING_CURVE
    write_atomically(curve, png_bytes(learning_curve(metrics, f"{name} — {config.algo}")))
    written = [curve]
    for file, drawn in _trajectories(setting, learner.policy(), name, trajectories, seed):
        write_atomically(out / file, drawn)
        written.append(out / file)
    automaton = out / AUTOMATON
    timed = compile_formula(
        parse(setting.world.spec, setting.world.spec_source), deadline=deadline
    ).timed
    render(to_dot(timed).replace("{\n", "{\n  dpi=120;\n", 1), automaton, deadline=deadline)
    return [*written, automaton]


def _trajectories(
    setting: Setting, policy: Policy, name: str, count: int, seed: int
) -> list[tuple[str, bytes]]:
    """The PNG of ``count`` greedy rollouts on the world's map (and a team world's GIF of the
    first), as (file name, bytes); none where the world has no map (a gymnasium env, finite or
    not)."""
    formula = textwrap.fill(setting.automaton.formula, 95)
    algo = setting.config.algo
    world = setting.world
    if isinstance(world.drawing, PlaneWorld):  # a room: the world is its own map
        paths = rollouts_plane(setting, policy, count, seed)
        wins = sum(success for _, success in paths)
        title = (
            f"{name} — {algo}: {wins} of {len(paths)} greedy rollouts succeed (seed {seed})\n"
            f"{formula}"
        )
        return [
            (TRAJECTORIES, png_bytes(plane_figure(world.drawing, [p for p, _ in paths], title)))
        ]
    if not setting.finite or not isinstance(world.drawing, GridMap):  # no grid to draw on
        return []
    drawn = rollouts(setting, policy, count, seed)
    wins = sum(t.success for t in drawn)
    title = (
        f"{name} — {algo}: {wins} of {len(drawn)} greedy rollouts succeed (seed {seed})\n{formula}"
    )
    if setting.model()[0].team is None:
        return [(TRAJECTORIES, png_bytes(trajectory_figure(setting, drawn, title)))]
    episode = drawn[0] if drawn else rollouts(setting, policy, 1, seed)[0]
    return [
        (TRAJECTORIES, png_bytes(team_figure(setting, drawn, title))),
        (EPISODE, episode_gif(setting, episode, f"{name} — {algo}, greedy (seed {seed})")),
    ]
