"""``TaskGuide``: what a :class:`~mitlc.gym.TaskWrapper` made with ``potential=REACH`` keeps
for the task's shaping potential (:mod:`mitlc.task.potential`) on an env.

It measures, at each position the wrapper reads, how far the position is from each of the
automaton's propositions (:mod:`mitlc.labels.distance`: the labels' regions and positions; a
labelling object with a ``distances`` method, such as a plane's, measures its own), keeps the
last, and evaluates the potential of
any task state at any such distances. The reach, the env distance past which a label's pull is
flat, is the one given, or else the largest distance measured at the first position. Where the
task is decided the potential is 0 (the wrapper says which states those are).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from mitlc.labels import Labeller
from mitlc.labels.distance import distances
from mitlc.labels.values import Moment
from mitlc.task.potential import TaskPotential
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

Found = list[float | None]
"""Per proposition, its distance, ``None`` where it has none."""


class TaskGuide:
    """The potential's state on an env: the reach and the distances of the last positions."""

    def __init__(self, shaping: TaskPotential, propositions: Sequence[str], reach: float) -> None:
        """``reach`` 0: the largest distance measured at the first position."""
        self.shaping, self.propositions = shaping, tuple(propositions)
        self.reach = float(reach)
        self.now: Found = []
        """The distances of the position now."""

    def measure(self, labels: Any, obs: Any, info: Mapping[str, Any], moment: Moment) -> None:
        """Measure a position newly reached (its distances become :attr:`now`); the first sets
        the reach, where none was given."""
        if isinstance(labels, Labeller):
            found = distances(labels, self.propositions, obs, info, moment)
        elif hasattr(labels, "distances"):  # labels read elsewhere than obs (a plane's)
            found = labels.distances(self.propositions, obs, info, moment)
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
