"""Continuous worlds: a point robot in a rectangular room (``plane:`` in a world file).

A world file may declare a room in the plane in place of a grid::

    name: case1-continuous
    plane:
      room: {width: 5.0, height: 5.0}
      start: [4.5, 0.5]                    # or a region, sampled uniformly: {box: ...}, {disc: ...}
      actions: {headings: [up, down, left, right], stay: true, step: 1.0}
      noise: {std: 0.1}
      obstacles:
        - {box: {low: [2.0, 2.0], high: [3.0, 3.0]}}
        - {disc: {center: [3.5, 1.5], radius: 0.4}}
      sensor: {std: 0.3}                   # optional: a POMDP
    labels:
      a: {box: {low: [3.0, 4.0], high: [4.0, 5.0]}}
      b: [{disc: {center: [0.5, 1.5], radius: 0.5}}]      # a region or a list of regions
    spec: {formula: "(!a U[5,10] a) & (!b U[15,20] b)"}
    horizon: 30

``reward``, ``discount`` and ``training`` are as for grids. The semantics, exactly:

* **Coordinates.** Metres; the room is the closed rectangle [0, width] x [0, height] with the
  origin at its *lower-left* corner and y pointing up (as the plots draw it). A grid's cell
  ``(row, col)`` of an ``R``-row grid is the 1 m square ``[col, col + 1] x [R - 1 - row, R - row]``.
* **Regions** (obstacles, labels, a start region) are closed: a box ``low <= p <= high``
  componentwise, a disc ``|p - center| <= radius``. Every region lies inside the room.
* **Actions.** ``Discrete``: one move per heading, in the listed order, then ``stay`` (last)
  when ``stay: true``. A heading is ``up`` (+y, 90 degrees), ``down`` (270), ``left`` (180),
  ``right`` (0), or an angle in degrees counter-clockwise from +x; its action is named by the
  heading's name, or ``<angle>deg``.
* **Motion.** A move from ``p`` with unit heading ``u`` proposes ``p' = p + step * u + e``,
  ``e ~ N(0, std^2 I)`` (``noise.std``; 0 is deterministic). The robot travels the straight
  segment from ``p`` to ``p'``: if ``p'`` is outside the room, or the segment touches an
  obstacle, the move fails and the robot stays at ``p`` (as a grid's move into a wall or a
  blocked cell leaves the agent in place; so a thin wall is never jumped over). ``stay`` is
  certain: no noise. The robot is therefore always in the room and outside every obstacle.
* **Start.** A point (inside the room, in no obstacle), or a region whose interior meets no
  obstacle's, sampled uniformly (a draw on an obstacle's boundary is drawn again).
* **Observation.** ``Box(low=[0, 0], high=[width, height], float32)``: the true position for an
  MDP; with a ``sensor``, the position plus ``N(0, sensor.std^2 I)``, clipped to the room (a
  POMDP). ``info["position"]`` is always the true position (float64): labels are observable
  and read it (:class:`mitlc.worlds.plane_env.PositionLabels`).
* **Reward** ``reward.move`` for each action other than ``stay``; the task's terms are the
  wrapper's. Episodes never end by themselves (the task's horizon ends them).

A plane world is not finite: ``mitlc check`` refuses it; it is learned through
:func:`mitlc.worlds.plane_env.make_plane_env` (a :class:`mitlc.gym.TaskWrapper`). This module
imports no gymnasium; the environment is :class:`mitlc.worlds.plane_env.PlaneEnv`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mitlc.worlds.model import Rewards
from mitlc.worlds.plane_schema import (
    HEADINGS,
    BoxRegion,
    DiscRegion,
    PlaneWorldFile,
    heading_angle,
)

Vec = tuple[float, float]

MAX_START_DRAWS = 10_000
"""Draws of a start region before giving up (only its boundary may be blocked)."""


@dataclass(frozen=True, slots=True)
class Box:
    """The closed rectangle ``low <= p <= high``."""

    low: Vec
    high: Vec

    def contains(self, p: Vec) -> bool:
        """Whether ``p`` is in the box."""
        return self.low[0] <= p[0] <= self.high[0] and self.low[1] <= p[1] <= self.high[1]

    def hits(self, p: Vec, q: Vec) -> bool:
        """Whether the segment from ``p`` to ``q`` touches the box (Liang-Barsky clipping)."""
        t0, t1 = 0.0, 1.0
        for k in (0, 1):
            d = q[k] - p[k]
            if d == 0.0:
                if p[k] < self.low[k] or p[k] > self.high[k]:
                    return False
                continue
            a, b = (self.low[k] - p[k]) / d, (self.high[k] - p[k]) / d
            if a > b:
                a, b = b, a
            t0, t1 = max(t0, a), min(t1, b)
            if t0 > t1:
                return False
        return True

    def sample(self, rng: np.random.Generator) -> Vec:
        """A uniform point of the box."""
        u = rng.random(2)
        return (
            self.low[0] + float(u[0]) * (self.high[0] - self.low[0]),
            self.low[1] + float(u[1]) * (self.high[1] - self.low[1]),
        )

    def declaration(self) -> dict[str, Any]:
        """The box as a :mod:`mitlc.labels` form over a position ``[x, y]``."""
        return {"box": {"index": [0, 1], "low": list(self.low), "high": list(self.high)}}


@dataclass(frozen=True, slots=True)
class Disc:
    """The closed disc ``|p - center| <= radius``."""

    center: Vec
    radius: float

    def contains(self, p: Vec) -> bool:
        """Whether ``p`` is in the disc."""
        dx, dy = p[0] - self.center[0], p[1] - self.center[1]
        return dx * dx + dy * dy <= self.radius * self.radius

    def hits(self, p: Vec, q: Vec) -> bool:
        """Whether the segment from ``p`` to ``q`` touches the disc (its closest point)."""
        dx, dy = q[0] - p[0], q[1] - p[1]
        fx, fy = p[0] - self.center[0], p[1] - self.center[1]
        length = dx * dx + dy * dy
        t = 0.0 if length == 0.0 else min(max(-(fx * dx + fy * dy) / length, 0.0), 1.0)
        nx, ny = fx + t * dx, fy + t * dy
        return nx * nx + ny * ny <= self.radius * self.radius

    def sample(self, rng: np.random.Generator) -> Vec:
        """A uniform point of the disc."""
        u = rng.random(2)
        r, angle = self.radius * math.sqrt(float(u[0])), 2 * math.pi * float(u[1])
        return (self.center[0] + r * math.cos(angle), self.center[1] + r * math.sin(angle))

    def declaration(self) -> dict[str, Any]:
        """The disc as a :mod:`mitlc.labels` form over a position ``[x, y]``."""
        return {"disc": {"index": [0, 1], "center": list(self.center), "radius": self.radius}}


Region = Box | Disc


def region_of(region: BoxRegion | DiscRegion) -> Region:
    """A file's region as a :class:`Box` or :class:`Disc`."""
    if isinstance(region, BoxRegion):
        return Box(region.box.low, region.box.high)
    return Disc(region.disc.center, region.disc.radius)


def unit(angle: float) -> Vec:
    """The unit vector of a heading in degrees (exact on the four axes)."""
    exact = {0.0: (1.0, 0.0), 90.0: (0.0, 1.0), 180.0: (-1.0, 0.0), 270.0: (0.0, -1.0)}
    a = angle % 360.0
    if a in exact:
        return exact[a]
    return (math.cos(math.radians(a)), math.sin(math.radians(a)))


@dataclass(frozen=True, slots=True)
class PlaneWorld:
    """A validated continuous world and its task (see the module docstring)."""

    name: str
    width: float
    height: float
    start: Vec | Region
    """A point, or a region sampled uniformly."""
    actions: tuple[str, ...]
    moves: tuple[Vec | None, ...]
    """``moves[a]``: the displacement ``step * heading`` of action ``a``; ``None`` for stay."""
    step: float
    noise: float
    """The motion noise's standard deviation per axis (0: deterministic)."""
    obstacles: tuple[Region, ...]
    sensor: float | None
    """The sensor noise's standard deviation per axis; ``None`` for an MDP."""
    labels: dict[str, tuple[Region, ...]]
    """Every label of the file: a proposition holds in any of its regions."""
    propositions: tuple[str, ...]
    """The task's propositions, sorted."""
    spec: str
    spec_source: str
    horizon: int
    discount: float
    rewards: Rewards = field(default_factory=Rewards)
    training: Mapping[str, Any] = field(default_factory=dict)
    """The file's ``training`` settings."""

    @property
    def default_algo(self) -> str:
        """The learner a run takes unless told: the recurrent DQN with a sensor, else DQN."""
        return "drqn" if self.is_pomdp else "dqn"

    @property
    def drawing(self) -> PlaneWorld:
        """The room is its own map."""
        return self

    def task_env(self, automaton: Any, *, flatten: bool = False, **options: Any) -> Any:
        """A fresh gymnasium env of the world under its task
        (:func:`mitlc.worlds.plane_env.plane_task`), with the task ``automaton`` compiled
        once for many envs."""
        from mitlc.worlds.plane_env import plane_task

        return plane_task(self, automaton=automaton, flatten=flatten, **options)

    @property
    def num_actions(self) -> int:
        """The number of actions."""
        return len(self.actions)

    @property
    def is_pomdp(self) -> bool:
        """Whether the agent sees a noisy position rather than its position."""
        return self.sensor is not None

    def label_declarations(self) -> dict[str, list[dict[str, Any]]]:
        """The labels as :mod:`mitlc.labels` declarations over a position ``[x, y]``."""
        return {p: [r.declaration() for r in regions] for p, regions in self.labels.items()}

    def inside(self, p: Vec) -> bool:
        """Whether ``p`` is in the room."""
        return 0.0 <= p[0] <= self.width and 0.0 <= p[1] <= self.height

    def free(self, p: Vec) -> bool:
        """Whether the robot can be at ``p``: in the room and in no obstacle."""
        return self.inside(p) and not any(o.contains(p) for o in self.obstacles)

    def passable(self, p: Vec, q: Vec) -> bool:
        """Whether the robot can travel straight from ``p`` to ``q`` (``q`` in the room, the
        segment touching no obstacle)."""
        return self.inside(q) and not any(o.hits(p, q) for o in self.obstacles)

    def move(self, p: Vec, action: int, rng: np.random.Generator) -> Vec:
        """Where ``action`` takes the robot from ``p`` (the motion model)."""
        d = self.moves[action]
        if d is None:
            return p
        x, y = p[0] + d[0], p[1] + d[1]
        if self.noise > 0.0:
            e = rng.normal(0.0, self.noise, 2)
            x, y = x + float(e[0]), y + float(e[1])
        q = (x, y)
        return q if self.passable(p, q) else p

    def sense(self, p: Vec, rng: np.random.Generator) -> Vec:
        """What the sensor reads at ``p`` (``p`` itself for an MDP)."""
        if self.sensor is None:
            return p
        e = rng.normal(0.0, self.sensor, 2)
        x = min(max(p[0] + float(e[0]), 0.0), self.width)
        y = min(max(p[1] + float(e[1]), 0.0), self.height)
        return (x, y)

    def sample_start(self, rng: np.random.Generator) -> Vec:
        """The start point, or a uniform free point of the start region."""
        start = self.start
        if isinstance(start, tuple):
            return start
        for _ in range(MAX_START_DRAWS):
            p = start.sample(rng)
            if self.free(p):
                return p
        raise RuntimeError("no free point drawn from the start region")  # pragma: no cover


def action_name(heading: str | float) -> str:
    """An action's name: the heading's name, or ``<angle>deg``."""
    return heading if isinstance(heading, str) else f"{heading:g}deg"


def build_plane_world(
    file: PlaneWorldFile,
    *,
    name: str,
    spec: str,
    spec_source: str,
    propositions: tuple[str, ...],
) -> PlaneWorld:
    """The world of a validated plane world file (shape and :func:`check_file` passed)."""
    plane = file.plane
    actions = plane.actions
    names = [action_name(h) for h in actions.headings]
    moves: list[Vec | None] = []
    for heading in actions.headings:
        ux, uy = unit(heading_angle(heading))
        moves.append((actions.step * ux, actions.step * uy))
    if actions.stay:
        names.append("stay")
        moves.append(None)
    start = plane.start
    labels = {
        p: tuple(region_of(r) for r in (label if isinstance(label, list) else [label]))
        for p, label in file.labels.items()
    }
    reward = file.reward
    return PlaneWorld(
        name=name,
        width=plane.room.width,
        height=plane.room.height,
        start=start if isinstance(start, tuple) else region_of(start),
        actions=tuple(names),
        moves=tuple(moves),
        step=actions.step,
        noise=plane.noise.std,
        obstacles=tuple(region_of(o) for o in plane.obstacles),
        sensor=None if plane.sensor is None else plane.sensor.std,
        labels=labels,
        propositions=propositions,
        spec=spec,
        spec_source=spec_source,
        horizon=file.horizon,
        discount=file.discount,
        rewards=reward.rewards(),
    )


__all__ = [
    "HEADINGS",
    "Box",
    "Disc",
    "PlaneWorld",
    "Region",
    "build_plane_world",
    "region_of",
    "unit",
]
