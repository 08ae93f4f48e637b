"""``TaskGuide``: what a :class:`~mitlc.gym.TaskWrapper` made with ``potential=REACH`` keeps
for the task's shaping potential (:mod:`mitlc.task.potential`) on an env.

It measures, at each position the wrapper reads, how far the position is from each of the
automaton's propositions (:mod:`mitlc.labels.distance`: the labels' regions and positions; a
labelling object with a ``distances`` method, such as a plane's, measures its own), keeps the
last, and evaluates the potential of
any task state at any such distances. The reach, the env distance past which a label's pull is
flat, is the one given, or else the largest distance measured at the first position. Where the
task is decided the potential is 0 (the wrapper says which states those are).

Where the env's occupancy is known (:mod:`mitlc.labels.geodesic`: a maze's ``maze_map``, a
MiniGrid grid, a plane's obstacles, or one declared), the distances of 2-D regions are
geodesic, through free space (:mod:`mitlc.labels.occupancy`); the occupancy is read again at
each reset (a MiniGrid layout changes with the episode).

**The way** (the wrapper's ``guide=True``): the unit vector, in the space of the position the
labels read, along which the distance to the proposition the potential pulls toward falls
fastest (:meth:`TaskGuide.way`: the nearest that advances the task state,
:meth:`mitlc.task.potential.TaskPotential.leading`; its direction,
:func:`mitlc.labels.distance.form_direction`), through free space where the occupancy is known:
the gradient of the potential's pull, shown to the policy so that it can follow the pull the
shaping rewards (zeros where no proposition pulls or the position is in its region).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np

from mitlc.gym.arguments import TaskWrapperTypeError
from mitlc.labels import Labeller
from mitlc.labels.distance import Point, form_direction, nearest_forms
from mitlc.labels.forms import Guided, InBox, InDisc
from mitlc.labels.geodesic import Geodesic, has_region, occupancy_source
from mitlc.labels.occupancy import Occupancy
from mitlc.labels.values import Equals, Moment, Region, Value, vector
from mitlc.task.potential import TaskPotential
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

Found = list[float | None]
"""Per proposition, its distance, ``None`` where it has none."""

OccupancyChoice = Occupancy | Literal["auto", "none"]
"""The task wrapper's ``occupancy``: a grid, ``"auto"`` (the env's own where it has one) or
``"none"`` (straight lines)."""


class StraightDistanceWarning(UserWarning):
    """The shaping measures straight lines to the labels' regions: nothing is known of the
    env's obstacles (no occupancy grid), so the pull may point into walls."""


def geodesic_of(
    env: Any, labels: Any, occupancy: OccupancyChoice, stacklevel: int = 4
) -> Geodesic | None:
    """The geodesic distances of the ``labels`` on ``env`` (``env.unwrapped``): over the
    occupancy given, or the env's own (``"auto"``, :func:`mitlc.labels.geodesic.occupancy_source`);
    ``None`` with ``"none"``, or where nothing is known, which is warned about once
    (:class:`StraightDistanceWarning`) if some label has a 2-D region."""
    if not (isinstance(occupancy, Occupancy) or occupancy in ("auto", "none")):
        raise TaskWrapperTypeError(
            f"occupancy: expected an Occupancy, 'auto' or 'none', got {occupancy!r}"
        )
    if isinstance(occupancy, str) and occupancy == "none":
        return None
    declared = occupancy if isinstance(occupancy, Occupancy) else None
    source = occupancy_source(env, declared)
    if source is not None:
        return Geodesic(source)
    labeller = labels if isinstance(labels, Labeller) else getattr(labels, "labeller", None)
    if isinstance(labeller, Labeller) and has_region(labeller.forms):
        warnings.warn(
            "shaping: the labels' distances are straight lines (no occupancy grid is known for "
            f"{type(env).__name__}; declare one with occupancy: in the world file)",
            StraightDistanceWarning,
            stacklevel=stacklevel,
        )
    return None


class TaskGuide:
    """The potential's state on an env: the reach and the distances of the last positions."""

    def __init__(
        self,
        shaping: TaskPotential,
        propositions: Sequence[str],
        reach: float,
        geodesic: Geodesic | None = None,
        env: Any = None,
    ) -> None:
        """``reach`` 0: the largest distance measured at the first position; ``geodesic``:
        the env's occupancy (``None``: straight lines), read from ``env`` (``env.unwrapped``)
        at each reset."""
        self.shaping, self.propositions = shaping, tuple(propositions)
        self.reach = float(reach)
        self.geodesic, self._env = geodesic, env
        self.now: Found = []
        """The distances of the position now."""
        self.pointing = 0
        """The size of :meth:`way` (0: not measured; :meth:`point`)."""
        self.toward: list[Point | None] = []
        """With :attr:`pointing`, the directions of the position now (:meth:`way`)."""

    def point(self, labels: Any) -> int:
        """Measure the directions too, from now on (:meth:`way`), and return their size: the
        largest position a label's region or point reads (a guide's ``from``: 2);
        a :class:`TaskWrapperTypeError` where no label has one."""
        size = max((position_size(f) for fs in getattr(labels, "forms", ()) for f in fs), default=0)
        if not isinstance(labels, Labeller) or size == 0:
            raise TaskWrapperTypeError(
                "guide: no declared label has a region or a position to point toward"
            )
        self.pointing = size
        return size

    def way(self, q: int) -> FloatArray:
        """The way (module docstring) in automaton state ``q`` from the position now."""
        return self.way_at(q, self.array(self.now), self.ways())

    def ways(self) -> FloatArray:
        """The directions of the position now, a row per proposition (zero-padded to
        :attr:`pointing`; ``nan`` where the proposition has none): what :meth:`way_at` reads,
        and ``info["ways"]`` holds."""
        result = np.full((len(self.propositions), self.pointing), np.nan)
        for i, found in enumerate(self.toward):
            if found is None:
                continue
            if found.size > self.pointing:
                raise TaskWrapperTypeError(
                    f"guide: a label's position has {found.size} values, more than the "
                    f"{self.pointing} its declaration gave"
                )
            result[i] = 0.0
            result[i, : found.size] = found
        return result

    def way_at(self, q: int, distances: FloatArray, ways: FloatArray) -> FloatArray:
        """The way in automaton state ``q`` at a position ``distances`` (:meth:`array`) from
        the propositions with their directions ``ways`` (:meth:`ways`): the direction of the
        one the potential pulls toward (:meth:`TaskPotential.leading`), zeros where none does
        or it has no direction. The one rule of the way: the observation's, and that of a
        counterfactual task state in the replay (:mod:`mitlc.learn.backends.sb3_crm`)."""
        result = np.zeros(self.pointing, dtype=np.float64)
        leading = self.shaping.leading(q, distances) if len(ways) else None
        if leading is not None and not np.isnan(ways[leading]).any():
            result[:] = ways[leading]
        return result

    def measure(
        self, labels: Any, obs: Any, info: Mapping[str, Any], moment: Moment, reset: bool = False
    ) -> None:
        """Measure a position newly reached (its distances become :attr:`now`; ``reset``: the
        position a reset gives, where the occupancy is read again); the first sets the reach,
        where none was given."""
        geodesic = self.geodesic
        if geodesic is not None and (reset or geodesic.occupancy is None):
            geodesic.refresh(self._env)
        if isinstance(labels, Labeller):
            near = nearest_forms(labels, self.propositions, obs, info, moment, geodesic)
            found = [None if n is None else n[0] for n in near]
            if self.pointing:
                self.toward = [
                    None if n is None else form_direction(n[1], obs, info, moment, geodesic)
                    for n in near
                ]
        elif hasattr(labels, "distances"):  # labels read elsewhere than obs (a plane's)
            more = {} if geodesic is None else {"geodesic": geodesic}
            found = labels.distances(self.propositions, obs, info, moment, **more)
        else:
            found = []
        if found and not self.reach:
            known = [d for d in found if d is not None and d > 0.0]
            self.reach = max(known, default=1.0)
        self.now = found

    def array(self, found: Found) -> FloatArray:
        """``found`` as an array, ``nan`` where a proposition has no distance."""
        if not found:
            return np.full(len(self.propositions), np.nan)
        return np.array([np.nan if d is None else d for d in found], dtype=np.float64)

    def at(self, q: IntArray, found: FloatArray, pending: BoolArray) -> FloatArray:
        """The potential (unscaled) of automaton state ``q[r]`` at distances ``found[r]``; 0
        where ``pending[r]`` is False (the task is decided)."""
        phi = self.shaping.at(np.asarray(q, dtype=np.int64), found, self.reach or 1.0)
        result: FloatArray = np.where(pending, phi, 0.0)
        return result

    def state_dict(self) -> dict[str, Any]:
        """The reach and the distances of the position now (for a checkpoint)."""
        return {"reach": self.reach, "distances": list(self.now)}

    def load_state_dict(self, saved: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` (entries missing from an older checkpoint are kept)."""
        self.reach = float(saved.get("reach", self.reach))
        self.now = [None if d is None else float(d) for d in saved.get("distances", [])]


def position_size(form: Any) -> int:
    """The number of values of the position ``form`` reads (0: none; a guide's: 2)."""
    if isinstance(form, InBox | InDisc):
        return len(form.index)
    if isinstance(form, Guided):
        return 2
    if isinstance(form, Value) and isinstance(form.test, Region):
        return form.test.size
    if isinstance(form, Value) and isinstance(form.test, Equals):
        expected = vector(form.test.expected)
        return 0 if expected is None else int(expected.size)
    return 0
