"""Labels with a probability on a finite env world, made exact: ``{obs: [15], probability: 0.9}``.

The task wrapper perceives such a label with its probability where its form holds, drawn anew at
every position it reads (:mod:`mitlc.labels.chance`). A world's letters must be a function of
its state, so, as on a grid, the outcome goes into the state, through the grid's expansion
(:mod:`mitlc.worlds.uncertain`): a world state is an env state (an observation, or an
observation split by the events of the step into it: :mod:`mitlc.worlds.gym_events`) with the
set of its uncertain labels that hold now. A move enters each outcome of its target with the
probability the draw gives it (``p`` where a label holds, ``1 - p`` where it does not, the
labels independent), and so does the start.

**An ending is absorbing with its outcome.** Once the env has ended, the wrapper reads no new
position: the task keeps reading the last letter, the one drawn on arrival. So each action of an
ended state loops to the state itself, outcome included (where a grid cell would draw again).

Only the world's propositions (the task's and the costs') are read: a label with a probability
that nothing reads adds no state. Worlds whose labels are all certain are built as before, by
:mod:`mitlc.worlds.gym_world` alone.
"""

from __future__ import annotations

from collections.abc import Callable, Container, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.labels.chance import Chances
from mitlc.labels.values import Moment
from mitlc.worlds.model import IntArray, Sparse
from mitlc.worlds.uncertain import expand_outcomes, start_of

ChanceRead = Callable[[int, Moment], Chances]
"""``(observation, moment) -> chances`` over the world's propositions."""


def chance_read(declared: Mapping[str, Any], propositions: Sequence[str]) -> ChanceRead | None:
    """The chances of a discrete observation over ``propositions`` (bit ``i`` for
    ``propositions[i]``; one without a declaration holds nowhere), read through the labels'
    one definition (:meth:`mitlc.labels.Labeller.chance_reader`) from ``declared`` (plain
    declarations of some of them); ``None`` where every one of them is certain."""
    from mitlc.labels import compile_labels

    labeller = compile_labels(declared)
    named = tuple(declared)
    if not labeller.uncertain(named):
        return None
    read = labeller.chance_reader(named)
    moved = {1 << j: 1 << propositions.index(p) for j, p in enumerate(named)}

    def chances(obs: int, moment: Moment) -> Chances:
        certain, uncertain = read(obs, {}, moment)
        letter = sum(bit for own, bit in moved.items() if certain & own)
        return letter, tuple((moved[own], p) for own, p in uncertain)

    return chances


class Interned:
    """The chances of positions, each distinct ``(chances, ended)`` numbered once: what a
    state split by events keeps as its letter (:mod:`mitlc.worlds.gym_events`), ``ended``
    whether the step into it ended the env."""

    def __init__(self, read: ChanceRead) -> None:
        self.read = read
        self.kinds: list[tuple[Chances, bool]] = []
        self._index: dict[tuple[Chances, bool], int] = {}

    def __call__(self, obs: int, moment: Moment) -> int:
        """The number of the chances of ``obs`` at ``moment``."""
        key = (self.read(obs, moment), bool(moment.terminated))
        found = self._index.get(key)
        if found is None:
            found = self._index[key] = len(self.kinds)
            self.kinds.append(key)
        return found


@dataclass(frozen=True, slots=True)
class DrawnStates:
    """The world's parts over env states with outcomes (see the module docstring)."""

    base: IntArray
    """``base[s]``: the env state (an index into the states expanded) of world state ``s``."""
    letters: IntArray
    transitions: Sparse
    start: int
    start_distribution: tuple[tuple[int, float], ...]


def observation_kinds(interned: Interned, n: int, ending: Container[int]) -> list[int]:
    """The numbers of the chances of a finite env's observations ``0 .. n-1``, ``ending``
    those a step ends the episode in (no form reads the step's events here: labels that do
    are split by :mod:`mitlc.worlds.gym_events`)."""
    return [interned(s, Moment(terminated=s in ending)) for s in range(n)]


def drawn_states(
    interned: Interned,
    kinds: Sequence[int],
    rows: list[dict[int, float]],
    starts: Sequence[tuple[int, float]],
    m: int,
) -> DrawnStates:
    """The states of env states ``0 .. k-1`` whose chances are ``interned``'s ``kinds``, an
    ended one absorbing with its outcome, with next-state distributions ``rows`` (row
    ``s * m + a``) and start distribution ``starts``, each split by its outcomes."""
    chances = [interned.kinds[k][0] for k in kinds]
    states = expand_outcomes(
        [certain for certain, _ in chances],
        [[(bit.bit_length() - 1, p) for bit, p in uncertain] for _, uncertain in chances],
    )
    absorbing = np.array([interned.kinds[k][1] for k in kinds], dtype=np.bool_)
    transitions = states.transitions(Sparse.from_rows(rows), m, absorbing)
    start, distribution = start_of(states.starts(starts))
    return DrawnStates(states.cell, states.letter, transitions, start, distribution)
