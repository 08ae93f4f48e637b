"""A small env package for the tests: importing it registers ``MitlcTest/Probe-v0``, an env
whose state lives on the env (attributes), in nested ``info`` and in its rewards, as
MiniGrid's and highway-env's do; and it defines a wrapper, :class:`Recorder`."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

IMPORTED = True


class Item:
    """Something the agent may carry (MiniGrid's ``carrying``)."""

    def __init__(self, kind: str) -> None:
        self.kind = kind


class Probe(gym.Env[int, int]):
    """A walk on a line of ``size`` cells, from 0: action 1 moves right, 0 left. The env
    keeps ``pos`` (a pair of numpy ints), ``carrying`` (``None``, then an :class:`Item` at cell
    2), ``speed`` and ``_secret``; ``info`` has ``rewards.arrived`` (1.0 at the last cell) and
    ``vec`` (the position as a float vector); stepping left from 0 is a fall (reward -100, back
    to 0); reaching the last cell terminates."""

    def __init__(self, size: int = 5) -> None:
        self.size = size
        self.observation_space = spaces.Discrete(size)
        self.action_space = spaces.Discrete(2)
        self.x = 0
        self.pos = (np.int64(0), np.int64(0))
        self.carrying: Item | None = None
        self.speed = 0.0
        self._secret = 1

    def _info(self) -> dict[str, Any]:
        arrived = 1.0 if self.x == self.size - 1 else 0.0
        return {"rewards": {"arrived": arrived}, "vec": np.array([self.x, 0.0])}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.x, self.carrying, self.speed = 0, None, 0.0
        self.pos = (np.int64(0), np.int64(0))
        return self.x, self._info()

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        reward = 0.0
        if int(action) == 1:
            self.x += 1
            self.speed = 1.0
        elif self.x == 0:
            reward = -100.0
            self.speed = 0.0
        else:
            self.x -= 1
            self.speed = -1.0
        self.pos = (np.int64(self.x), np.int64(0))
        if self.x == 2 and self.carrying is None:
            self.carrying = Item("key")
        return self.x, reward, self.x == self.size - 1, False, self._info()


class Recorder(gym.Wrapper[int, int, int, int]):
    """A wrapper that records the order it was applied in (``tag``) on the env's ``wrapped``
    list."""

    def __init__(self, env: gym.Env[int, int], tag: str = "") -> None:
        super().__init__(env)
        order = getattr(env.unwrapped, "wrapped", [])
        env.unwrapped.wrapped = [*order, tag]  # type: ignore[attr-defined]


NOT_A_WRAPPER = 3

if "MitlcTest/Probe-v0" not in gym.registry:
    gym.register(id="MitlcTest/Probe-v0", entry_point=Probe, max_episode_steps=100)
