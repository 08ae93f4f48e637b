"""Counterfactual experience with shaping on envs (:mod:`mitlc.learn.learners.crm_env`,
:meth:`EnvCounterfactuals.potentials`): a counterfactual's shaped reward is what the wrapper,
under :class:`mitlc.gym.shaping.ShapedReward`, pays for the same step taken in that task state.

The oracle is the wrapper itself, run: on the line of ``tests/test_crm_env.py`` (deterministic,
``a`` at cell 1 and ``b`` at cell 2, read from the env's ``position`` so that both have a
distance), random episodes from every start record what each (task state, cell, action) is paid
and where it leads; every counterfactual that names a recorded triple must agree with it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mitlc.gym import TaskWrapper
from mitlc.gym.shaping import ShapedReward
from mitlc.learn.envs.envvec import task_vector
from mitlc.learn.learners.base import EnvShaping
from mitlc.learn.learners.crm_env import EnvCounterfactuals
from mitlc.task import MonitorState, TaskMonitor
from mitlc.task.potential import shaped
from tests.test_crm_env import PENDULUM, REWARDS, RIGHT, SPEC, TINY, Line, learner

LABELS = {"a": {"attr": "position", "equals": 1}, "b": {"attr": "position", "equals": 2}}
SCALE, GAMMA, REACH = 2.0, 0.9, 3.0
Truth = dict[tuple[int, int, int], tuple[float, int, bool]]


def wrapped(start: int) -> TaskWrapper:
    return TaskWrapper(Line(start), SPEC, LABELS, rewards=REWARDS, horizon=8, reward_mode="add",
                       potential=REACH)  # fmt: skip


def paid(episodes: int = 400) -> Truth:
    """``(task state, cell, action) -> (shaped reward, next task state, terminated)`` of the
    steps random episodes took (the env stepping, not yet ended), each seen the same every time."""
    rng = np.random.default_rng(0)
    truth: Truth = {}
    for episode in range(episodes):
        env = ShapedReward(wrapped(int(rng.integers(4))), scale=SCALE, gamma=GAMMA)
        inner = env.unwrapped
        assert isinstance(inner, Line)
        env.reset(seed=episode)
        done = False
        while not done:
            q, cell, action = env.env.automaton_state, inner.position, int(rng.integers(2))  # type: ignore[attr-defined]
            _, reward, terminated, truncated, info = env.step(action)
            if info["letter"] >= 0 and not info["env_ended"]:
                seen = (round(float(reward), 9), int(info["automaton_state"]), terminated)
                assert truth.setdefault((q, cell, action), seen) == seen
            done = terminated or truncated
    return truth


def test_shaped_counterfactuals_are_what_the_wrapper_pays_in_their_own_state() -> None:
    """Steps of episodes from every start: each counterfactual's reward shaped with
    :meth:`EnvCounterfactuals.potentials` (at the experienced step's distances) is the shaped
    reward the wrapper pays when its own episode takes that step in that task state."""
    truth = paid()
    rng = np.random.default_rng(1)
    checked = 0
    for start in range(4):
        env = wrapped(start)
        crm = EnvCounterfactuals.of(env)
        env.reset(seed=0)
        for action in (RIGHT, 0, RIGHT, RIGHT):
            q, cell = env.automaton_state, env.unwrapped.position  # type: ignore[attr-defined]
            _, _, terminated, truncated, info = env.step(action)
            told = crm.tells(np.array([info["letter"]]), np.array([info["env_ended"]]))
            rows = crm.rows(np.array([q]), np.array([0]), np.array([info["letter"]]),
                            np.array([info["env_reward"]]), told, rng)  # fmt: skip
            left, reached = info["distances_left"][None, :], info["distances"][None, :]
            before, after = crm.potentials(rows, left, reached)
            gammas = np.full(len(rows.q), GAMMA)
            reward = shaped(rows.reward, gammas, SCALE * before, SCALE * after)
            for r in range(len(rows.q)):
                key = (int(rows.q[r]), cell, action)
                if key in truth:
                    want, next_q, ended = truth[key]
                    assert (round(float(reward[r]), 9), int(rows.next_q[r])) == (want, next_q)
                    assert bool(rows.terminated[r]) == ended
                    checked += 1
            if terminated or truncated:
                break
    assert checked >= 20  # the oracle covered many counterfactuals


def test_potentials_need_a_wrapper_made_with_one() -> None:
    from mitlc.learn.learners.crm_env import CounterfactualError

    plain = TaskWrapper(Line(0), SPEC, LABELS, rewards=REWARDS, horizon=8)
    crm = EnvCounterfactuals.of(plain)
    plain.reset(seed=0)
    _, _, _, _, info = plain.step(RIGHT)
    assert "distances" not in info
    rows = crm.rows(np.array([0]), np.array([0]), np.array([info["letter"]]), np.array([0.0]),
                    np.array([True]), np.random.default_rng(0))  # fmt: skip
    with pytest.raises(CounterfactualError, match="potential"):
        crm.potentials(rows, np.zeros((1, 2)), np.zeros((1, 2)))


def test_dqn_stores_shaped_counterfactuals_of_an_env_step() -> None:
    """mitlc's DQN with shaping and ``dqn.crm`` on envs: the stored counterfactual rows of a
    step from cell 1 to cell 2 carry the wrapper's shaped rewards of their own task states."""
    truth = paid()
    envs = [wrapped(1), wrapped(1)]
    vector = task_vector(envs, seed=0)
    dqn = learner(vector, EnvCounterfactuals.of(envs[0]), **{"dqn.epsilon_start": 0.0,
                                                             "dqn.epsilon_end": 0.0})  # fmt: skip
    dqn.shaping = EnvShaping(SCALE)
    dqn.net[-1].bias.data[:] = torch_row([0.0, 1.0])  # greedy: right
    dqn.train_step(vector, 0.0)
    data = {k: v[: dqn.replay.size] for k, v in dqn.replay.data.items()}
    assert dqn.replay.size == 2 + 2 * 5
    scale = dqn.settings.reward_scale
    checked = 0
    for row in range(10):  # the counterfactuals first (a task state some run reaches at cell 1)
        key = (int(data["automaton"][row]), 1, RIGHT)
        if key in truth:
            want, next_q, ended = truth[key]
            assert float(data["reward"][row]) / scale == pytest.approx(want, abs=1e-6)
            assert (int(data["next_automaton"][row]), bool(data["terminated"][row])) == (
                next_q, ended)  # fmt: skip
            checked += 1
    assert checked >= 4


def torch_row(values: list[float]) -> Any:
    import torch

    return torch.tensor(values)


def test_sb3_shapes_its_counterfactuals_as_the_wrapper_would(tmp_path: Path) -> None:
    """SB3's SAC with ``sb3.crm`` and shaping (Pendulum, ``up`` a box over the observation's
    first value): every counterfactual row's reward is the monitor's, plus ``k (gamma Phi(q',
    s') - Phi(q, s))`` of the wrapper's potential at the distances its observations show."""
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    from mitlc.learn.backends.sb3 import algorithm, model_settings, wrapped_env
    from mitlc.learn.backends.sb3_crm import CounterfactualReplay
    from mitlc.learn.config import resolve
    from mitlc.learn.setting import prepare

    path = tmp_path / "pendulum.yaml"
    path.write_text(PENDULUM)
    given = {"algo": "sb3-sac", **TINY, "shaping": SCALE}
    config = resolve({}, given, discount=0.95, pomdp=False)
    setting = prepare(path, config)
    assert setting.config.shaping_reach > 0  # resolved once, for every env
    venv = make_vec_env(lambda: wrapped_env(setting), 2, seed=0, vec_env_cls=DummyVecEnv)
    cls, policy = algorithm("sb3-sac")
    model = cls(policy, venv, seed=0, device="cpu", **model_settings(config, venv.envs[0]))
    model.learn(300)
    memory = model.replay_buffer
    assert isinstance(memory, CounterfactualReplay)
    wrapper = venv.envs[0].env.env  # Monitor(ShapedReward(TaskWrapper))
    assert isinstance(wrapper, TaskWrapper) and wrapper.reach == setting.config.shaping_reach
    monitor = TaskMonitor(setting.automaton, setting.world.rewards)
    num_q = len(setting.automaton.states)
    made = np.argwhere(memory.counterfactual[: memory.size()])
    assert len(made) > 100
    for pos, env in made[:: max(1, len(made) // 200)]:
        obs, after = memory.observations[pos, env], memory.next_observations[pos, env]
        q, reached = (int(np.argmax(o[3 : 3 + num_q])) for o in (obs, after))
        out = monitor.step(MonitorState(q, 0, 0, 0), int(0.9 <= obs[0] <= 1.0))
        assert out.state.q == reached
        gap = [[max(0.9 - float(o[0]), float(o[0]) - 1.0, 0.0)] for o in (obs, after)]
        phi = wrapper.potential_at(np.array([q, reached]), np.array(gap))
        want = out.reward + SCALE * (0.95 * phi[1] - phi[0])
        assert float(memory.rewards[pos, env]) == pytest.approx(want, abs=1e-5)
