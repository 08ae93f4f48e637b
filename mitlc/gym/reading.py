"""How a task on an environment reads its letters and ends its run, shared by the gymnasium
wrapper (:class:`mitlc.gym.TaskWrapper`) and the PettingZoo team wrapper
(:class:`mitlc.pettingzoo.TeamTaskWrapper`), so that both read a position the same way.

* :class:`LetterTaker` reads the letter of a position: the labels on ``(obs, info)`` and, where
  a label reads a value, the :class:`~mitlc.labels.Moment` (``env.unwrapped``, the reward and
  termination of the step that reached the position; :mod:`mitlc.labels.values`). A labelling
  function's result is checked once, at the first position; declared labels' ``attr`` paths
  are checked on the env at the first reset and their ``info`` paths in the first reset's info
  or, where one is missing there, the first step's (:mod:`mitlc.labels.probe`). A label with
  ``probability: p`` (:mod:`mitlc.labels.chance`) is drawn at each position read, from the env's
  own generator (``env.unwrapped.np_random``, which ``reset(seed=...)`` seeds), so a run is
  reproducible from its seed; an env without one (some PettingZoo envs) is read with a
  generator of the reader's own, seeded from the operating system.
* :func:`run_out` is the rest of a run whose world has ended (the inner env terminated or
  truncated): as in a finite world, whose terminal states are absorbing, the world stays on
  its last position and the task (:class:`mitlc.task.TaskMonitor`) reads its last letter, one
  step of the horizon at a time, until it is decided or the horizon is reached.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from mitlc.labels import LabelDeclarationError, LabelFunction, Labeller, Labels, letter_reader
from mitlc.labels.chance import ChanceReader, perceive
from mitlc.labels.function import call_checked
from mitlc.labels.probe import attr_problems, info_paths_found, info_problems
from mitlc.labels.values import NO_MOMENT, Moment
from mitlc.task import Outcome, TaskMonitor


class LetterTaker:
    """The letters over ``propositions`` that ``labels`` read on an env whose
    ``env.unwrapped`` is ``env`` (see the module docstring)."""

    def __init__(
        self, labels: Labels | LabelFunction, propositions: Sequence[str], env: Any
    ) -> None:
        self.labels = labels
        self._function_unchecked = not isinstance(labels, Labels)
        """A labelling function's result is checked once, at the first position."""
        drawn = isinstance(labels, Labeller) and bool(labels.uncertain(propositions))
        self._chances: ChanceReader | None = None
        """The chances of a position, where a label is perceived with a probability."""
        if drawn:
            assert isinstance(labels, Labeller)
            self._chances = labels.chance_reader(propositions)
        else:
            self._read = letter_reader(labels, propositions)
        self._env = env
        self._own_rng: np.random.Generator | None = None
        values = labels.values() if isinstance(labels, Labeller) else ()
        guides = labels.guides() if isinstance(labels, Labeller) else ()
        self.reads_moment = bool(values or guides)
        """Whether the labels read the :class:`~mitlc.labels.Moment` beside ``(obs, info)``."""
        self._probe: list[dict[str, Any]] | None = [] if self.reads_moment else None

    def moment(self, reward: float | None, terminated: bool) -> Moment:
        """The moment of a position reached by a step of ``reward`` that ``terminated`` (or
        not) the env; ``reward`` ``None``: the position ``reset`` gives."""
        return Moment(self._env, reward, terminated) if self.reads_moment else NO_MOMENT

    def take(self, obs: Any, info: dict[str, Any], moment: Moment) -> int:
        """The letter of ``(obs, info)`` at ``moment`` (:meth:`moment`)."""
        if self._function_unchecked:
            self._function_unchecked = False
            call_checked(self.labels, obs, info)
        if self._chances is None and not self.reads_moment:
            return self._read(obs, info)
        if self._probe is not None:
            self._check_labels(info, reset=moment.reward is None)
        if self._chances is not None:
            return perceive(self._chances(obs, info, moment), self.generator())
        return self._read(obs, info, moment)

    def generator(self) -> np.random.Generator:
        """The generator of the draws of labels with a probability: the env's own
        (``np_random``, seeded by its ``reset(seed=...)``), else one of this reader's."""
        rng = getattr(self._env, "np_random", None)
        if isinstance(rng, np.random.Generator):
            return rng
        if self._own_rng is None:
            self._own_rng = np.random.default_rng()
        return self._own_rng

    def _check_labels(self, info: dict[str, Any], *, reset: bool) -> None:
        """Check the labels' ``attr`` paths on the env at the first reset, and their ``info``
        paths in the first reset's info or, where one is missing there, the first step's
        (:mod:`mitlc.labels.probe`); a :class:`~mitlc.labels.LabelDeclarationError` naming
        each path that is not there."""
        assert isinstance(self.labels, Labeller) and self._probe is not None
        seen = self._probe
        seen.append(info)
        problems = attr_problems(self.labels, self._env) if reset and len(seen) == 1 else []
        if not reset or info_paths_found(self.labels, info):
            problems += info_problems(self.labels, seen)
            self._probe = None
        if problems:
            raise LabelDeclarationError("\n".join(problems))


def run_out(monitor: TaskMonitor, last: Outcome, letter: int, horizon: int) -> Outcome:
    """The rest of a run after ``last``, the step whose world ended: ``monitor`` reads
    ``letter`` (that of the world's last position) until the task is decided or ``horizon``
    steps are taken. The rewards are added to ``last.reward`` one by one, the marks or-ed and
    the new sets counted; the state, verdict, decision and success are the last step's."""
    state, marks, new, reward, verdict, decided, success = last
    while not decided and state.steps < horizon:
        state, more, fresh, gain, verdict, decided, success = monitor.step(state, letter)
        reward += gain
        marks |= more
        new += fresh
    return Outcome(state, marks, new, reward, verdict, decided, success)
