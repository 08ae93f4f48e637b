"""Small hand-made POMDP worlds shared by the tests."""

from __future__ import annotations

import numpy as np

from mitlc.worlds.model import Observations, Sparse, World


def guessing_world() -> World:
    """Start 0 moves to room 1 or room 2 w.p. 1/2 each, whatever the action. In room 1 action
    ``a0`` reaches the goal 3 and ``a1`` the trap 4; in room 2 the other way round. Room 1 always
    shows ``x``; room 2 shows ``x`` or ``y`` w.p. 1/2 each. Goal and trap are absorbing.

    Fully observable: 1. Observation-based: on ``y`` the room is 2 (win); on ``x`` (w.p. 3/4)
    room 1 has posterior 2/3, so the best is 1/4 + 3/4 * 2/3 = 3/4."""
    rows: list[dict[int, float]] = [
        {1: 0.5, 2: 0.5},
        {1: 0.5, 2: 0.5},
        {3: 1.0},
        {4: 1.0},
        {4: 1.0},
        {3: 1.0},
        {3: 1.0},
        {3: 1.0},
        {4: 1.0},
        {4: 1.0},
    ]
    return World(
        name="guessing",
        rows=1,
        cols=5,
        cells=tuple((0, c) for c in range(5)),
        actions=("a0", "a1"),
        start=0,
        transitions=Sparse.from_rows(rows),
        propositions=("g",),
        letters=np.array([0, 0, 0, 1, 0], dtype=np.int64),
        spec="F g",
        spec_source="<inline>",
        horizon=5,
        discount=0.99,
        observations=Observations(
            names=("start", "x", "y", "goal", "trap"),
            model=Sparse.from_rows([{0: 1.0}, {1: 1.0}, {1: 0.5, 2: 0.5}, {3: 1.0}, {4: 1.0}]),
        ),
    )
