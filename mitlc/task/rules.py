"""The rules of a task during an episode, each written once for a single episode and a batch.

Every function here reads only ``|``, ``&``, ``~``, ``==``, ``*``, ``+`` and indexing, so the same
code runs on Python ints (one episode, the gymnasium wrapper's per-step path) and on numpy
integer arrays (a batch of episodes, the simulator, the exact recursions). They are the single
definition of:

* the **frontier** of a generalized Büchi condition (Baier and Katoen, *Principles of Model
  Checking*, 2008, Sect. 4.3: a run is accepting when it sees every acceptance set infinitely
  often; the frontier is the sets seen in the current round, emptied when the round completes);
* the **verdict** codes of an automaton state, and when an episode **terminates** (the task is
  decided);
* **success** of an episode (:func:`success`), judged where it stops (docs/episodes.md): it
  never reaches *violated*, and it reaches *satisfied*, or it stops in a state whose end code
  (:attr:`mitlc.automata.DigitalState.end`, :mod:`mitlc.automata.ends`) says that the finite
  trace it read satisfies the task: every obligation still open is met at the end (a deadline
  still open fails, a safety window still open holds, a request not yet answered fails, a
  recurrence ``G F β`` owes one ``β``), and, after an epsilon jump, a round of the acceptance
  sets was completed. A completed round never excuses an open obligation;
* the task's **reward**: ``accept`` for each acceptance set new in the round, ``satisfied`` and
  ``violated`` on entering those states (a world's own terms, such as a cost per move, are the
  world's and are added by whoever steps it).
"""

from __future__ import annotations

from typing import Any, Protocol, TypeVar

import numpy as np
import numpy.typing as npt

PENDING, VIOLATED, SATISFIED = 0, 1, 2
"""Verdict codes."""

VERDICT_NAMES = ("pending", "violated", "satisfied")
"""``VERDICT_NAMES[code]``."""

VERDICT_CODES = {name: code for code, name in enumerate(VERDICT_NAMES)}


class TaskRewards(Protocol):
    """The task's reward terms (:class:`mitlc.worlds.model.Rewards` has them)."""

    @property
    def accept(self) -> float: ...
    @property
    def satisfied(self) -> float: ...
    @property
    def violated(self) -> float: ...


T = TypeVar("T", int, Any)
"""An int (one episode) or a numpy integer array (a batch)."""


def popcounts(num_sets: int) -> tuple[int, ...]:
    """``popcounts(k)[m]``: the number of sets in mask ``m`` (a table: indexable by an int or,
    as ``numpy.asarray``, by an array)."""
    return tuple(m.bit_count() for m in range(1 << num_sets))


def account(frontier: T, marks: T, all_sets: int, popcount: Any) -> tuple[T, T, T]:
    """Add a transition's ``marks`` to the ``frontier``: ``(frontier after, sets new in this
    round, round completed)``. A completed round empties the frontier; with no acceptance sets
    (``all_sets == 0``) no round ever completes."""
    new = popcount[marks & ~frontier]
    seen = frontier | marks
    complete = (seen == all_sets) & (all_sets > 0)
    return seen - seen * complete, new, complete


def saturate(done_mask: T, marks: T, all_sets: int) -> T:
    """The frontier of the finite-horizon recursions, where ``all_sets`` stands for "a round was
    completed" (after which only a violation matters): ``mask | marks``, kept at ``all_sets``
    once reached. It is :func:`account`'s frontier with the completed round remembered."""
    return done_mask | marks


def terminated(verdict: T) -> T:
    """The task is decided: the episode ends (``terminated``). An episode that stops while
    pending, at the task's horizon or in a world that can no longer move, is ``truncated``."""
    return verdict != PENDING


def seen_sets(frontier: T, rounds: T, all_sets: int) -> T:
    """The acceptance sets an episode has seen so far: its frontier, or every set once it has
    completed a round (the frontier of the recursions, :func:`saturate`)."""
    return frontier | all_sets * (rounds > 0)


def success(verdict: T, seen: T, end: T) -> T:
    """The success of an episode that stops here (see the module docstring): in a state of
    ``verdict`` whose end code is ``end``, having seen the acceptance sets ``seen``
    (:func:`seen_sets`). The end code ``e`` of a pending state fails (0), or holds once the
    sets of the mask ``e - 1`` have been seen (1: at once). The one definition of success: the
    monitor, the wrapper, the simulators, the exact evaluation and the checker's recursions
    all read it."""
    needed = (end - 1) * (end > 0)
    holds = (end > 0) & ((seen & needed) == needed)
    return (verdict != VIOLATED) & ((verdict == SATISFIED) | holds)


def reward(new: T, verdict: T, rewards: TaskRewards) -> Any:
    """The task's reward for a transition that added ``new`` sets to the frontier and entered a
    state of ``verdict``."""
    return (
        rewards.accept * new
        + rewards.satisfied * (verdict == SATISFIED)
        + rewards.violated * (verdict == VIOLATED)
    )


def recursion_ends(
    verdict: npt.NDArray[np.int64], end: npt.NDArray[np.int64], num_sets: int
) -> npt.NDArray[np.float64]:
    """The finite-horizon recursions' values when the horizon ends: ``values[mask, x]`` is the
    :func:`success` of an episode ending in a state of ``verdict[x]`` and end code ``end[x]``
    with the frontier ``mask``, the sets seen (:func:`saturate`: the mask of all sets once a
    round is completed)."""
    seen = np.arange(1 << num_sets, dtype=np.int64)
    ends: npt.NDArray[np.float64] = success(
        verdict[None, :], seen[:, None], end[None, :].astype(np.int64)
    ).astype(np.float64)
    return ends
