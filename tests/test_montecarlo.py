"""The one Monte-Carlo estimate (:mod:`mitlc.learn.evaluation.montecarlo`): unbiased in a world
that is
not finite, where counting the first episodes to end over parallel envs is not; reproducible
whatever its batches. (On a finite world it agrees with the exact success of a memoryless
policy: ``tests/test_learn.py::test_simulator_success_matches_the_exact_value``.)"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from mitlc.learn.config import resolve
from mitlc.learn.evaluation.montecarlo import Estimate, first_episodes, monte_carlo, wilson
from mitlc.learn.learners.base import Episodes, Policy
from mitlc.learn.setting import batches, prepare
from mitlc.worlds.model import IntArray

START, SAFE, BAD = 0, 1, 2
SAFE_ON_RIGHT = 0.2
TRUE_SUCCESS = 0.5 * SAFE_ON_RIGHT
"""A uniform policy's success in the gamble: it goes right w.p. 1/2, then lands safe w.p.
0.2; going left always lands on the bad cell."""
GAMBLE = """
name: gamble
env: {id: MitlcTest/Gamble-v0}
labels:
  bad: {obs: [2]}
spec: {formula: "G !bad"}
horizon: 20
discount: 0.95
reward: {satisfied: 1, accept: 1, violated: -1, move: 0}
"""


class Gamble(gym.Env[int, int]):
    """Cells start, safe and bad; the first move (0: left, 1: right) leaves the start for good:
    left lands on bad, right on safe w.p. 0.2 and on bad otherwise. A failure shows at once
    (the task reads bad on the second step), a success only at the horizon: the episodes that
    end first are failures."""

    def __init__(self) -> None:
        self.observation_space = spaces.Discrete(3)
        self.action_space = spaces.Discrete(2)
        self.cell = START

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.cell = START
        return self.cell, {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        if self.cell == START:
            lucky = action == 1 and self.np_random.random() < SAFE_ON_RIGHT
            self.cell = SAFE if lucky else BAD
        return self.cell, 0.0, False, False, {}


if "MitlcTest/Gamble-v0" not in gym.registry:
    gym.register(id="MitlcTest/Gamble-v0", entry_point=Gamble, max_episode_steps=100)


class Uniform(Policy):
    """Each valid action with equal probability."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def act(self, env: Episodes) -> IntArray:
        valid = env.valid_actions()
        chosen: IntArray = (self.rng.random(valid.shape) * valid).argmax(axis=1)
        return chosen


@pytest.fixture(scope="module")
def gamble(tmp_path_factory: pytest.TempPathFactory) -> Any:
    path = tmp_path_factory.mktemp("gamble") / "gamble.yaml"
    path.write_text(GAMBLE)
    return prepare(path, resolve({}, {"algo": "dqn"}, discount=0.95, pomdp=False))


def first_to_end(setting: Any, policy: Policy, episodes: int, seed: int) -> Estimate:
    """The estimate this module replaced: the first ``episodes`` episodes to *end* over 64
    parallel envs (length-biased: quick failures are over-counted)."""
    vector = batches(setting, seed)(min(64, episodes), 0)
    policy.reset(vector.num_envs)
    wins, returns, ended = 0, 0.0, 0
    while ended < episodes:
        step = vector.step(policy.act(vector))
        done = np.flatnonzero(step.done)[: episodes - ended]
        wins += int(step.success[done].sum())
        returns += float(step.episode_return[done].sum())
        ended += len(done)
    return Estimate(wins, ended, returns / ended)


def covers(estimate: Estimate, value: float) -> bool:
    low, high = estimate.interval
    return low <= value <= high


@pytest.mark.parametrize("episodes", [100, 1000])
def test_a_uniform_policy_in_an_open_world_is_estimated_without_bias(
    gamble: Any, episodes: int
) -> None:
    """The gamble's true success is 0.1 (by hand); the estimate's Wilson interval holds it
    at 100 and 1,000 episodes, where the first episodes to end say about 0.00 and 0.06."""
    estimate = monte_carlo(batches(gamble, 7), Uniform(3), episodes)
    assert estimate.trials == episodes and covers(estimate, TRUE_SUCCESS), estimate
    assert estimate.mean_return == pytest.approx(estimate.rate - 1)  # violated pays -1
    biased = first_to_end(gamble, Uniform(3), episodes, 7)
    assert biased.rate < TRUE_SUCCESS and not covers(biased, TRUE_SUCCESS), biased


def test_the_estimate_is_reproducible_and_independent_of_the_batch_width(gamble: Any) -> None:
    """Episode ``j`` is seeded the same whatever the batches (the policy here ignores the
    episodes, so only the envs' draws matter): equal counts; another seed draws others."""

    class Right(Policy):
        def act(self, env: Episodes) -> IntArray:
            return np.ones(env.num_envs, dtype=np.int64)

    one = monte_carlo(batches(gamble, 5), Right(), 300)
    assert one == monte_carlo(batches(gamble, 5), Right(), 300, width=64)
    assert covers(one, SAFE_ON_RIGHT)
    assert monte_carlo(batches(gamble, 6), Right(), 300) != one


def test_progress_counts_the_episodes_of_every_batch_as_they_end(gamble: Any) -> None:
    """``progress`` is told a rising count of ended episodes across batches of 64, ending at
    the estimate's 300; the estimate is the one made without it."""
    told: list[int] = []
    estimate = monte_carlo(batches(gamble, 5), Uniform(3), 300, width=64, progress=told.append)
    assert estimate == monte_carlo(batches(gamble, 5), Uniform(3), 300, width=64)
    assert told == sorted(told) and told[-1] == 300 and len(set(told)) == len(told) > 5
    assert {64, 128, 192, 256} <= set(told)  # each batch's last episode ends its count


def test_first_episodes_counts_each_slot_once(gamble: Any) -> None:
    success, returns, costs, _ = first_episodes(batches(gamble, 1)(50, 0), Uniform(0))
    assert costs is None  # a world without costs
    assert success.shape == returns.shape == (50,)
    assert (returns == np.where(success, 0.0, -1.0)).all()


def test_wilson_interval_is_the_score_interval() -> None:
    """Wilson (JASA 1927): at 5 of 10 the interval is 0.5 -+ 0.2366 (to 4 places)."""
    low, high = wilson(5, 10)
    assert (round(low, 4), round(high, 4)) == (0.2366, 0.7634)
    assert wilson(0, 0) == (0.0, 1.0)
    with pytest.raises(ValueError, match="width"):
        monte_carlo(lambda count, first: None, Uniform(0), 1, width=0)  # type: ignore[arg-type,return-value]
