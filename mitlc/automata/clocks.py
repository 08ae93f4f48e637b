"""The clock view of a digital automaton: each state as its T-LDGBA location and clock values.

The digital automaton counts time in its states: ``!a U[0,100] (a & F[0,100] b)`` has some 200
states that differ only in the time left. Its folding (:mod:`mitlc.automata.fold`, the paper's
T-LDGBA) writes each state as a *location* and the values of a few *clocks*; a learner that
sees the location and the clocks (scaled by their bound) sees in a handful of numbers what the
one-hot of the state spreads over hundreds, and states that differ only in time share their
location. :func:`clock_view` gives, per digital state, that point ``(location, clocks)``;
:meth:`ClockView.features` the learners' encoding of it: a one-hot of the location, then each
clock's value divided by its bound (0 for the clocks a location does not use).

The view is injective: two digital states never share a point (a location and a valuation name
one state of the folding), so an agent that sees the features knows the task's state exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from mitlc.automata.digital import DigitalAutomaton
from mitlc.automata.fold import fold_points
from mitlc.automata.ldba import Translation, translate_terms
from mitlc.limits import Deadline
from mitlc.syntax import parse

FloatArray = npt.NDArray[np.float32]


class ClockViewError(ValueError):
    """An automaton whose clock view cannot be made (not one translated from its source)."""


@dataclass(frozen=True, slots=True)
class ClockView:
    """Per digital state, its location and clock values (see the module docstring)."""

    location: tuple[int, ...]
    """``location[s]``: the T-LDGBA location of digital state ``s``."""
    clocks: tuple[tuple[int, ...], ...]
    """``clocks[s][c]``: the value of clock ``c`` in state ``s`` (0 where its location does
    not use ``c``)."""
    num_locations: int
    bounds: tuple[int, ...]
    """Each clock's bound (it stops counting there)."""

    @property
    def num_clocks(self) -> int:
        """The T-LDGBA's clocks."""
        return len(self.bounds)

    @property
    def width(self) -> int:
        """The length of a state's features: locations plus clocks."""
        return self.num_locations + self.num_clocks

    def features(self) -> FloatArray:
        """One row per digital state: the one-hot of its location, then its clocks scaled to
        [0, 1] by their bounds (float32)."""
        count = len(self.location)
        table = np.zeros((count, self.width), dtype=np.float32)
        table[np.arange(count), np.asarray(self.location, dtype=np.int64)] = 1.0
        if self.num_clocks:
            values = np.asarray(self.clocks, dtype=np.float32).reshape(count, self.num_clocks)
            table[:, self.num_locations :] = values / np.asarray(self.bounds, dtype=np.float32)
        return table


def clock_view(translation: Translation, *, deadline: Deadline | None = None) -> ClockView:
    """The clock view of a translation's digital automaton, from its folding."""
    timed, points = fold_points(translation, deadline=deadline)
    bounds = timed.clock_bounds
    clocks = []
    for _, valuation in points:
        values = [0] * len(bounds)
        for clock, value in valuation:
            values[clock] = value
        clocks.append(tuple(values))
    return ClockView(
        tuple(loc for loc, _ in points), tuple(clocks), len(timed.locations), tuple(bounds)
    )


def clock_view_of(automaton: DigitalAutomaton) -> ClockView:
    """The clock view of ``automaton``, translated again from its source (the translation is
    deterministic; an automaton that differs from its source's translation is refused with
    :class:`ClockViewError`). Memoised per automaton source."""
    view, states = _view_of_source(automaton.source)
    if states != automaton:
        raise ClockViewError(
            f"the automaton of {automaton.formula!r} is not its formula's translation, so its "
            "clocks are unknown (use the digital state's observation)"
        )
    return view


@lru_cache(maxsize=8)
def _view_of_source(source: str) -> tuple[ClockView, DigitalAutomaton]:
    translation = translate_terms(parse(source, "<spec>"))
    return clock_view(translation), translation.automaton


AUTO_CLOCKS = 1000
"""``task_obs: auto`` shows the clocks of automata with more states than this, where a one-hot
grows too wide to learn on. Below it the one-hot learned as well or better wherever the two
were compared (seed 0): case 1's DQN, 0.957 with the one-hot and 0.909 with the clocks; the
noisy corridor's recurrent DQN, 0.8 or more and 0; MiniGrid DoorKey's PPO (73 states), 1.00
with the one-hot and 0 with the clocks at 300,000 steps (0.90 with the clocks and shaping)."""


def clocks_shown(automaton: DigitalAutomaton, task_obs: str) -> bool:
    """Whether a learner with the setting ``task_obs`` (``state``, ``clocks`` or ``auto``) sees
    the task's state by its clock view: ``clocks``; ``auto`` where the automaton has more than
    :data:`AUTO_CLOCKS` states and its folding has clocks."""
    if task_obs == "auto":
        return len(automaton.states) > AUTO_CLOCKS and clock_view_of(automaton).num_clocks > 0
    return task_obs == "clocks"
