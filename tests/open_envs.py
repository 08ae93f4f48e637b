"""Small gymnasium envs without a transition table, registered for the tests of worlds that
are not finite: a slippery chain with a Discrete observation, and the same chain with a Dict
observation (its position and a Box of the steps taken)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

LENGTH = 6
PENDULUM = """
name: pendulum-up
env: {id: Pendulum-v1}
labels:
  up: {box: {index: [0], low: [0.9], high: [1.0]}}
spec: {formula: "F[0,40] up"}
horizon: 50
discount: 0.99
reward: {satisfied: 1, accept: 1, violated: 0, move: 0}
"""
"""A world file of gymnasium's Pendulum: swing it up (cos of its angle above 0.9) within 40
steps; Box(-2, 2, (1,)) actions, a Box observation."""


class Chain(gym.Env[Any, int]):
    """Cells 0..5, start at 0; action 0 moves left, 1 right; a move slips (stays) w.p. 0.1."""

    def __init__(self) -> None:
        self.observation_space: spaces.Space[Any] = spaces.Discrete(LENGTH)
        self.action_space = spaces.Discrete(2)
        self.position, self.steps = 0, 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        self.position, self.steps = 0, 0
        return self._obs(), {}

    def step(self, action: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        self.steps += 1
        if self.np_random.random() >= 0.1:
            self.position = int(np.clip(self.position + (1 if action == 1 else -1), 0, LENGTH - 1))
        return self._obs(), 0.0, False, False, {"at_end": self.position == LENGTH - 1}

    def _obs(self) -> Any:
        return self.position


class DictChain(Chain):
    """The chain, observed as ``{"pos": Discrete(6), "clock": Box(0, 50, (1,))}``."""

    def __init__(self) -> None:
        super().__init__()
        self.observation_space = spaces.Dict(
            {"pos": spaces.Discrete(LENGTH), "clock": spaces.Box(0.0, 50.0, (1,), np.float32)}
        )

    def _obs(self) -> Any:
        return {"pos": self.position, "clock": np.array([min(self.steps, 50)], np.float32)}


for name, cls in (("Chain", Chain), ("DictChain", DictChain)):
    if f"MitlcTest/{name}-v0" not in gym.registry:
        gym.register(id=f"MitlcTest/{name}-v0", entry_point=cls, max_episode_steps=200)
