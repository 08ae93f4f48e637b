"""What a team world knows of its robots, beside the joint arrays of its
:class:`~mitlc.worlds.model.World` (:mod:`mitlc.worlds.team` builds both).

Joint indices are mixed-radix numbers with robot 0 the most significant digit: joint action
``a = sum(parts[r] * prod(len(actions[s]) for s > r))``, and the same for a joint observation
over the robots' observation counts.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

from mitlc.worlds.model import BoolArray, IntArray, Observations

Cell = tuple[int, int]


def radix_parts(radices: tuple[int, ...]) -> IntArray:
    """Every mixed-radix number over ``radices`` (the first most significant) as its digits:
    row ``i`` holds the digits of ``i``."""
    digits = list(product(*(range(k) for k in radices)))
    return np.asarray(digits, dtype=np.int64).reshape(len(digits), len(radices))


def radix_weights(radices: tuple[int, ...]) -> IntArray:
    """The place value of each digit: ``number = digits @ weights``."""
    weights = np.ones(len(radices), dtype=np.int64)
    for r in range(len(radices) - 2, -1, -1):
        weights[r] = weights[r + 1] * radices[r + 1]
    return weights


@dataclass(frozen=True, slots=True, eq=False)
class Team:
    """The robots of a team world and how its joint states, actions and observations split
    into per-robot ones."""

    robots: tuple[str, ...]
    """The robots' ids, in joint order."""
    cells: tuple[Cell, ...]
    """The free cells, row by row: every robot's cell index points here (the robots share one
    grid, so one tuple serves all of them)."""
    actions: tuple[tuple[str, ...], ...]
    """Each robot's actions, in order."""
    positions: IntArray
    """``positions[s, r]``: robot ``r``'s cell (an index into ``cells``) in joint state ``s``;
    shape ``(num_states, robots)``."""
    swapped: BoolArray
    """``swapped[s]``: joint state ``s`` was reached by a step on which two robots swapped
    cells (always false without a collision label, or with blocking)."""
    action_parts: IntArray
    """``action_parts[a, r]``: robot ``r``'s action index in joint action ``a``; shape
    ``(num_joint_actions, robots)``."""
    observations: tuple[Observations | None, ...]
    """Each robot's observation model over its cell index (``None``: it sees its cell)."""
    collision: str | None = None
    """The collision label, if the file declares one."""
    block: bool = False
    """Whether colliding moves are blocked (the robots stay)."""

    @property
    def num_robots(self) -> int:
        """The number of robots."""
        return len(self.robots)

    def observation_counts(self) -> tuple[int, ...]:
        """How many observations each robot has (its cells, for one that sees its cell)."""
        return tuple(
            len(self.cells) if model is None else len(model.names) for model in self.observations
        )

    def joint_action(self, parts: tuple[int, ...] | list[int]) -> int:
        """The joint action of per-robot action indices."""
        weights = radix_weights(tuple(len(a) for a in self.actions))
        return int(np.dot(np.asarray(parts, dtype=np.int64), weights))

    def split_action(self, action: int) -> tuple[int, ...]:
        """The per-robot action indices of a joint action."""
        return tuple(int(x) for x in self.action_parts[action])

    def split_observation(self, observation: int) -> tuple[int, ...]:
        """The per-robot observation ids of a joint observation id."""
        parts = []
        for count in reversed(self.observation_counts()):
            observation, digit = divmod(observation, count)
            parts.append(digit)
        return tuple(reversed(parts))

    def cell_of(self, state: int, robot: int) -> Cell:
        """Robot ``robot``'s cell in joint state ``state``."""
        return self.cells[int(self.positions[state, robot])]

    def state_of(self, cells: tuple[Cell, ...], swapped: bool = False) -> int:
        """The joint state with these per-robot cells (and swap flag); a ``ValueError`` if
        there is none (a blocked cell, or two robots in one cell where collisions block)."""
        index = {cell: i for i, cell in enumerate(self.cells)}
        want = np.asarray([index[c] for c in cells], dtype=np.int64)
        hits = np.flatnonzero((self.positions == want).all(axis=1) & (self.swapped == swapped))
        if len(hits) == 0:
            raise ValueError(f"no joint state has cells {cells} (swapped: {swapped})")
        return int(hits[0])
