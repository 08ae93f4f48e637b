"""``ShapedReward`` (:mod:`mitlc.gym.shaping`): the task's shaping for learners that take the
env's reward as it is, by the one rule of :func:`mitlc.task.potential.shaped`."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from mitlc.gym import TaskWrapper
from mitlc.gym.shaping import ShapedReward, ShapedRewardError
from tests.test_clocks import LABELS, SPEC, Line


def test_the_reward_gains_gamma_phi_after_less_phi_before() -> None:
    inner = TaskWrapper(Line(), SPEC, LABELS, horizon=20, potential=0.0)
    plain = TaskWrapper(Line(), SPEC, LABELS, horizon=20)
    env = ShapedReward(inner, scale=2.0, gamma=0.9)
    rng = np.random.default_rng(1)
    for seed in range(10):
        _, info = env.reset(seed=seed)
        plain.reset(seed=seed)
        before = info["potential"]
        assert before > 0.0  # the task is pending at the start (and not at its farthest)
        done = False
        while not done:
            action = int(rng.integers(3))
            _, reward, terminated, truncated, info = env.step(action)
            _, base, *_ = plain.step(action)
            after = info["potential"]
            assert reward == pytest.approx(base + 2.0 * (0.9 * after - before))
            assert info["shaping"] == pytest.approx(reward - base)
            if terminated:
                assert after == 0.0
            before, done = after, terminated or truncated


def test_a_wrapper_without_a_potential_is_refused() -> None:
    env = ShapedReward(TaskWrapper(Line(), SPEC, LABELS, horizon=5), scale=1.0, gamma=0.9)
    with pytest.raises(ShapedRewardError, match="potential=REACH"):
        env.reset(seed=0)
    with pytest.raises(ShapedRewardError, match="gamma"):
        ShapedReward(gym.make("CartPole-v1"), scale=1.0, gamma=1.5)
