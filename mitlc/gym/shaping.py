"""``ShapedReward``: the task's potential-based shaping as a gymnasium wrapper, for learners
that take the env's reward as it is (Stable-Baselines3's, any other).

It wraps a :class:`mitlc.gym.TaskWrapper` made with ``potential=REACH`` (which reports the
task's potential in ``info["potential"]``: :mod:`mitlc.task.potential`) and adds
``scale * (gamma * Phi(s') - Phi(s))`` to each step's reward (:func:`mitlc.task.potential.shaped`,
the rule mitlc's own learners apply), ``Phi(s)`` being the potential the previous ``reset`` or
``step`` reported. ``gamma`` must be the learner's discount (Ng, Harada and Russell, ICML 1999:
with it, the optimal policies of the shaped task are the task's). The potential is 0 where the
task is decided; at a truncation the learner bootstraps from the state reached, whose
potential counts as it should. ``info["shaping"]`` holds the term added.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from mitlc.errors import MitlcError
from mitlc.task.potential import shaped


class ShapedRewardError(MitlcError, ValueError):
    """A ``ShapedReward`` that cannot be built as asked."""


class ShapedReward(gym.Wrapper[Any, Any, Any, Any]):
    """Potential-based shaping of a task wrapper's reward (see the module docstring)."""

    def __init__(self, env: gym.Env[Any, Any], *, scale: float, gamma: float) -> None:
        """``scale`` times the task's potential, under the learner's discount ``gamma``."""
        super().__init__(env)
        if not 0.0 <= gamma <= 1.0:
            raise ShapedRewardError(f"gamma: expected a value in [0, 1], got {gamma!r}")
        if not scale >= 0.0:
            raise ShapedRewardError(f"scale: expected a value >= 0, got {scale!r}")
        self.scale, self.gamma = float(scale), float(gamma)
        self._before = 0.0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset, and remember the start's potential."""
        obs, info = self.env.reset(seed=seed, options=options)
        self._before = self._potential(info)
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Step, and add the shaping term to the reward."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        after = self._potential(info)
        total = shaped(
            np.array([float(reward)]), np.array([self.gamma]), np.array([self._before]),
            np.array([after]),
        )  # fmt: skip
        self._before = after
        info["shaping"] = float(total[0]) - float(reward)
        return obs, float(total[0]), terminated, truncated, info

    def _potential(self, info: dict[str, Any]) -> float:
        if "potential" not in info:
            raise ShapedRewardError(
                "the wrapped env reports no info['potential']: wrap a TaskWrapper made with "
                "potential=REACH"
            )
        return self.scale * float(info["potential"])
