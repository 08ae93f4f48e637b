"""A mitlc :class:`~mitlc.worlds.model.World` as a plain gymnasium environment, and its labels.

:class:`GridEnv` is the world alone, with no task: the task is put on it by
:class:`mitlc.gym.TaskWrapper` (and :class:`mitlc.product.env.ProductEnv` is exactly that).

* **Observation**: the state id for an MDP; for a POMDP, an observation id drawn from
  ``world.observations.model.row(s)``. ``info["state"]`` is the true state ``s``.
* **Actions**: ``Discrete(num_actions)``; ``s'`` is drawn from the world's row
  ``s * num_actions + a``.
* **Reward**: ``world.rewards.move`` for each action other than ``stay`` (the task's terms are
  the wrapper's).
* **Episodes** never end by themselves (the task's horizon ends them). The start is
  ``world.start``, or drawn from the world's ``start_distribution`` when it has a non-empty one.

:class:`WorldLabels` labels a GridEnv by the world's letters of the *true* state
(``info["state"]``: labels are observable, also in a POMDP), read by proposition name.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import accumulate
from typing import Any

import gymnasium as gym
from gymnasium import spaces

from mitlc.labels import undeclared
from mitlc.worlds.model import Sparse, World


class Sampler:
    """Draws from the rows of a :class:`Sparse` by inverting their cumulative sums."""

    def __init__(self, sparse: Sparse) -> None:
        self._rows: list[tuple[list[int], list[float]]] = []
        for r in range(sparse.num_rows):
            targets, probs = sparse.row(r)
            self._rows.append((targets.tolist(), list(accumulate(probs.tolist()))))

    def draw(self, r: int, u: float) -> int:
        """The target of row ``r`` that the uniform number ``u`` in [0, 1) selects."""
        targets, cumulative = self._rows[r]
        i = bisect_right(cumulative, u * cumulative[-1])
        return targets[min(i, len(targets) - 1)]


class GridEnv(gym.Env[Any, Any]):
    """A world as a gymnasium environment (see the module docstring)."""

    metadata: dict[str, Any] = {"render_modes": ["ansi"], "render_fps": 4}  # noqa: RUF012
    observation_space: spaces.Discrete
    action_space: spaces.Discrete

    def __init__(self, world: World, *, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} is not one of 'ansi' or None")
        self.world, self.render_mode = world, render_mode
        self._num_actions = world.num_actions
        self._move = world.rewards.move
        self._moves = [name != "stay" for name in world.actions]
        self._motion = Sampler(world.transitions)
        obs = world.observations
        self._sensor = None if obs is None else Sampler(obs.model)
        num_obs = world.num_states if obs is None else len(obs.names)
        self.observation_space = spaces.Discrete(num_obs)
        self.action_space = spaces.Discrete(world.num_actions)
        starts: Sequence[tuple[int, float]] = getattr(world, "start_distribution", ()) or ()
        self._starts = None
        if starts:
            ids = [int(s) for s, _ in starts]
            self._starts = (ids, list(accumulate(float(p) for _, p in starts)))
        self._s = world.start

    @property
    def state(self) -> int:
        """The true state ``s``."""
        return self._s

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        """Start at ``world.start`` (or a draw from the start distribution)."""
        super().reset(seed=seed)
        if self._starts is None:
            self._s = self.world.start
        else:
            ids, cumulative = self._starts
            i = bisect_right(cumulative, self.np_random.random() * cumulative[-1])
            self._s = ids[min(i, len(ids) - 1)]
        return self._observe(), {"state": self._s}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        """One action of the world."""
        a = int(action)
        if not 0 <= a < self._num_actions:
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        self._s = s = self._motion.draw(self._s * self._num_actions + a, self.np_random.random())
        return self._observe(), self._move if self._moves[a] else 0.0, False, False, {"state": s}

    def render(self) -> str | None:
        """With ``render_mode="ansi"``: the grid (``@`` the robot, ``#`` blocked, labels by
        their first letter)."""
        if self.render_mode != "ansi":
            return None
        world = self.world
        grid = [["#"] * world.cols for _ in range(world.rows)]
        for s, (row, col) in enumerate(world.cells):
            props = [p for i, p in enumerate(world.propositions) if world.letters[s] >> i & 1]
            grid[row][col] = "@" if s == self._s else props[0][0] if props else "."
        return "\n".join("".join(line) for line in grid)

    def _observe(self) -> int:
        if self._sensor is None:
            return self._s
        return self._sensor.draw(self._s, self.np_random.random())


@dataclass(frozen=True, slots=True)
class StateLetters:
    """Letters from a table indexed by ``info["state"]``."""

    table: tuple[int, ...]

    def __call__(self, obs: Any, info: Mapping[str, Any]) -> int:
        """The letter of the true state."""
        state: int = info["state"]
        return self.table[state]


@dataclass(frozen=True, slots=True)
class WorldLabels:
    """A world's labels of the true state, by proposition name (see the module docstring)."""

    propositions: tuple[str, ...]
    letters: tuple[int, ...]
    """``letters[s]``: the world's letter of state ``s`` over :attr:`propositions`."""

    @staticmethod
    def of(world: World) -> WorldLabels:
        """The labels of ``world``."""
        return WorldLabels(tuple(world.propositions), tuple(world.letters.tolist()))

    def __call__(self, obs: Any, info: Mapping[str, Any]) -> frozenset[str]:
        """The propositions true in the true state ``info["state"]``."""
        letter = self.letters[info["state"]]
        return frozenset(p for i, p in enumerate(self.propositions) if letter >> i & 1)

    def letter_reader(self, propositions: Sequence[str]) -> StateLetters:
        """Letters over ``propositions`` (each must be the world's)."""
        index = {p: i for i, p in enumerate(self.propositions)}
        missing = [p for p in propositions if p not in index]
        if missing:
            raise undeclared(missing, self.propositions)
        bits = [(index[p], j) for j, p in enumerate(propositions)]
        return StateLetters(tuple(sum(((w >> i) & 1) << j for i, j in bits) for w in self.letters))


__all__ = ["GridEnv", "Sampler", "StateLetters", "WorldLabels"]
