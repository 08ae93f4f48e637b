"""Counterfactual experience on worlds that are not finite (:mod:`mitlc.learn.learners.crm_env`)
and in SB3's replay memory (:mod:`mitlc.learn.backends.sb3_crm`), against a hand-worked
example and the task monitor.

The hand-worked example: a line of cells 0..4 (actions 0 left, 1 right; the env pays -0.1 a
step and ends at cell 4), ``a`` at cell 1, ``b`` at cell 2, the task ``!a U[0,3] (a & F[0,2]
b)`` with rewards satisfied 1, violated -1, the env's reward added (``reward_mode="add"``). Its
digital automaton (letters: 0 none, 1 ``a``, 2 ``b``; ``mitlc compile``):

    state  obligation                       on a        on b
    0      !a U[0,3] (a & F[0,2] b)         2           1
    1      !a U[0,2] (a & F[0,2] b)         2           4
    2      F[0,1] b                         5           3 satisfied
    4      !a U[0,1] (a & F[0,2] b)         2           6
    5      F[0,0] b                         7 violated  3 satisfied
    6      !a U[0,0] (a & F[0,2] b)         2           7 violated

(3 is *satisfied*, 7 *violated*; no acceptance sets, so the frontier is always 0.)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

import tests.open_envs  # noqa: F401 - registers MitlcTest/Chain-v0
from mitlc.gym import TaskWrapper
from mitlc.learn.config import resolve
from mitlc.learn.envs.envvec import task_vector
from mitlc.learn.learners.crm_env import EnvCounterfactuals
from mitlc.learn.learners.dqn import DQNLearner
from mitlc.learn.learners.encoder import Encoder
from mitlc.task import MonitorState, TaskMonitor
from mitlc.worlds.model import Rewards
from tests.open_envs import PENDULUM

SPEC = "!a U[0,3] (a & F[0,2] b)"
LABELS = {"a": {"obs": [1]}, "b": {"obs": [2]}}
REWARDS = Rewards(accept=0.0, satisfied=1.0, violated=-1.0, move=0.0)
STEP = -0.1
RIGHT = 1
A, B = 1, 2
Table = dict[int, tuple[int, float, bool]]


class Line(gym.Env[int, int]):
    """Cells 0..4 from ``start``; 0 moves left, 1 right; -0.1 a step; it ends at cell 4."""

    def __init__(self, start: int = 0) -> None:
        self.observation_space = spaces.Discrete(5)
        self.action_space = spaces.Discrete(2)
        self.start, self.position = start, start

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.position = self.start
        return self.position, {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        self.position = int(np.clip(self.position + (1 if action == 1 else -1), 0, 4))
        return self.position, STEP, self.position == 4, False, {}


def line(start: int = 1, **options: Any) -> TaskWrapper:
    return TaskWrapper(Line(start), SPEC, LABELS, rewards=REWARDS, horizon=8, reward_mode="add",
                       **options)  # fmt: skip


def by_hand(letter: int, experienced: int) -> Table:
    """The table of the module docstring: ``q -> (next q, reward, terminated)`` on ``letter``
    for every pending state but the experienced one, the env's -0.1 added."""
    table = {
        A: {0: (2, STEP, False), 1: (2, STEP, False), 2: (5, STEP, False),
            4: (2, STEP, False), 5: (7, -1 + STEP, True), 6: (2, STEP, False)},
        B: {0: (1, STEP, False), 1: (4, STEP, False), 2: (3, 1 + STEP, True),
            4: (6, STEP, False), 5: (3, 1 + STEP, True), 6: (7, -1 + STEP, True)},
    }  # fmt: skip
    return {q: row for q, row in table[letter].items() if q != experienced}


def as_table(q: Any, next_q: Any, reward: Any, terminated: Any) -> Table:
    """``q -> (next q, reward, terminated)`` of some transitions."""
    return {int(s): (int(n), round(float(r), 5), bool(t))
            for s, n, r, t in zip(q, next_q, reward, terminated, strict=True)}  # fmt: skip


def test_the_counterfactuals_of_two_steps_by_hand_and_by_the_monitor() -> None:
    """From cell 1 (``a``) right to cell 2, then from cell 2 (``b``) right to cell 3: each
    step's counterfactuals are the table's rows of its letter, and ``TaskMonitor.step`` run
    directly agrees with every one."""
    env = line()
    crm = EnvCounterfactuals.of(env)
    assert crm.pair_q.tolist() == [0, 1, 2, 4, 5, 6] and crm.num_frontiers == 1
    monitor = TaskMonitor(env.automaton, REWARDS)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    for letter, before, after in ((A, 0, 2), (B, 2, 3)):
        _, reward, terminated, _, info = env.step(RIGHT)
        assert (info["letter"], info["automaton_state"]) == (letter, after)
        assert info["env_reward"] == STEP and not info["env_ended"]
        one = np.array([0])
        rows = crm.rows(np.array([before]), one * 0, np.array([letter]), np.array([STEP]),
                        np.array([True]), rng)  # fmt: skip
        assert rows.source.tolist() == [0] * 5 and rows.frontier.tolist() == [0] * 5
        assert not rows.accepting.any() and rows.next_frontier.tolist() == [0] * 5
        found = as_table(rows.q, rows.next_q, rows.reward, rows.terminated)
        assert found == by_hand(letter, before)
        for q, (next_q, r, t) in found.items():
            out = monitor.step(MonitorState(q, 0, 0, 1), letter)
            assert (out.state.q, out.reward + STEP, out.terminated) == pytest.approx((next_q, r, t))
        # the experienced step itself is what the table says of its state
        assert (after, reward, terminated) == pytest.approx(by_hand(letter, -1)[before])


def test_jumps_and_ended_envs_give_none_and_the_sample_is_bounded() -> None:
    crm = EnvCounterfactuals.of(line())
    told = crm.tells(np.array([A, -1, B, B]), np.array([False, False, True, False]))
    assert told.tolist() == [True, False, False, True]
    rows = crm.rows(np.array([0, 0, 0, 2]), np.zeros(4, np.int64), np.array([A, -1, B, B]),
                    np.full(4, STEP), told, np.random.default_rng(0))  # fmt: skip
    assert rows.source.tolist() == [0] * 5 + [3] * 5
    # the env ends at cell 4: that step (and the wrapper's rest of the episode) tells nothing
    env = line(start=3)
    env.reset(seed=0)
    *_, info = env.step(RIGHT)
    assert info["env_ended"] and not crm.tells(np.array([info["letter"]]),
                                               np.array([info["env_ended"]])).any()  # fmt: skip
    small = EnvCounterfactuals.of(line(), limit=3)
    rows = small.rows(np.array([0, 2]), np.zeros(2, np.int64), np.array([A, B]),
                      np.zeros(2), np.array([True, True]), np.random.default_rng(1))  # fmt: skip
    assert rows.source.tolist() == [0, 0, 0, 1, 1, 1]
    assert 0 not in rows.q[:3].tolist() and 2 not in rows.q[3:].tolist()
    assert len(set(rows.q[:3].tolist())) == 3


def test_the_frontiers_of_a_round_are_counterfactual_too() -> None:
    """``G F a & G F b``: one state, ``a`` marks set 0 and ``b`` set 1, so a round's frontier
    is 0, 1 or 2. A step reading ``a`` with the frontier 0 tells what it does from 1 (nothing
    new) and from 2 (the round completes: the frontier empties, ``accept`` is paid)."""
    rewards = Rewards(accept=10.0, satisfied=0.0, violated=0.0, move=0.0)
    env = TaskWrapper(Line(1), "G F a & G F b", LABELS, rewards=rewards, horizon=8)
    crm = EnvCounterfactuals.of(env)
    assert crm.pair_q.tolist() == [0, 0, 0] and crm.pair_frontier.tolist() == [0, 1, 2]
    rows = crm.rows(np.array([0]), np.array([0]), np.array([A]), np.array([STEP]),
                    np.array([True]), np.random.default_rng(0))  # fmt: skip
    assert rows.frontier.tolist() == [1, 2] and rows.next_frontier.tolist() == [1, 0]
    assert rows.accepting.tolist() == [False, True] and rows.reward.tolist() == [0.0, 10.0]
    monitor = TaskMonitor(env.automaton, rewards)
    for f, after, reward in ((1, 1, 0.0), (2, 0, 10.0)):
        out = monitor.step(MonitorState(0, f, 0, 0), A)
        assert (out.state.frontier, out.reward, out.new > 0) == (after, reward, bool(reward))


def learner(vector: Any, crm: EnvCounterfactuals | None, **overrides: Any) -> DQNLearner:
    settings = {"algo": "dqn", "dqn.num_envs": vector.num_envs, "dqn.warmup_steps": 64,
                "dqn.crm": crm is not None, **overrides}  # fmt: skip
    config = resolve({}, settings, discount=0.9, pomdp=False)
    space = vector.observation_space
    encoder = Encoder.of_spaces(space[vector.env_key], int(space["automaton"].n), 0,
                                vector.num_actions)  # fmt: skip
    return DQNLearner(None, config, np.random.default_rng(0), None, crm, encoder=encoder,
                      num_actions=vector.num_actions)  # fmt: skip


def test_dqn_stores_the_counterfactuals_of_an_env_step() -> None:
    """One vector step of two episodes at cell 1, both moving right: the replay holds the two
    experienced transitions and the table's five counterfactual rows of each."""
    envs = [line(), line()]
    vector = task_vector(envs, seed=0)
    dqn = learner(vector, EnvCounterfactuals.of(envs[0]), **{"dqn.epsilon_start": 0.0,
                                                             "dqn.epsilon_end": 0.0})  # fmt: skip
    dqn.net[-1].bias.data[:] = torch_row([0.0, 1.0])  # greedy: right
    step = dqn.train_step(vector, 0.0)
    assert step.letter is not None and step.letter.tolist() == [A, A]
    data = {k: v[: dqn.replay.size] for k, v in dqn.replay.data.items()}
    assert dqn.replay.size == 2 + 2 * 5
    assert data["observation"].tolist() == [1] * 12
    assert data["next_observation"].tolist() == [2] * 12
    assert data["action"].tolist() == [RIGHT] * 12
    scale = dqn.settings.reward_scale
    for k in range(2):
        part = slice(5 * k, 5 * k + 5)  # the counterfactuals first, as on a finite product
        found = as_table(data["automaton"][part], data["next_automaton"][part],
                         data["reward"][part] / scale, data["terminated"][part])  # fmt: skip
        assert found == by_hand(A, 0)
    assert data["automaton"][10:].tolist() == [0, 0]  # the experienced ones
    assert data["next_automaton"][10:].tolist() == [2, 2]
    assert data["next_valid"].all() and (data["gamma"] == np.float32(0.9)).all()


def torch_row(values: list[float]) -> Any:
    import torch

    return torch.tensor(values)


CHAIN = """
name: chain
env: {id: MitlcTest/Chain-v0}
labels:
  goal: {obs: [5]}
spec: {formula: "F[0,12] goal"}
horizon: 15
discount: 0.95
reward: {satisfied: 1, accept: 1, violated: 0, move: 0}
"""


def test_a_dqn_run_with_counterfactuals_on_an_env_world_trains_and_evaluates(
    tmp_path: Path,
) -> None:
    """``dqn.crm`` on an env world (no product): the run learns the slippery chain's task
    and ``eval`` measures it without an optimum; with shaping too."""
    from mitlc.learn.evaluation.evaluate import evaluate
    from mitlc.learn.run import train

    path = tmp_path / "chain.yaml"
    path.write_text(CHAIN)
    overrides = {"algo": "dqn", "episodes": 200, "dqn.num_envs": 4, "dqn.warmup_steps": 64,
                 "dqn.crm": True, "dqn.initial_value": 1.0}  # fmt: skip
    config = resolve({}, overrides, discount=0.95, pomdp=False)
    done = train(path, config, tmp_path / "run")
    assert done.episodes >= 200 and not done.stopped
    report = evaluate(tmp_path / "run", episodes=100)
    assert report.optimum is None and report.successes >= 90
    shaped = resolve({}, {**overrides, "shaping": 1.0}, discount=0.95, pomdp=False)
    assert not train(path, shaped, tmp_path / "shaped").stopped


# --- SB3's replay ------------------------------------------------------------------------------

TINY = {"sb3.batch_size": 32, "sb3.learning_starts": 50, "sb3.buffer_size": 50_000,
        "sb3.hidden": 16, "sb3.crm": True}  # fmt: skip
LETTERS = {  # the letter of a flat observation's env part, and that part's width
    "chain": (lambda env: int(np.argmax(env) == 5), 6),
    "pendulum": (lambda env: int(0.9 <= env[0] <= 1.0), 3),
}


@pytest.mark.parametrize(("algo", "world"), [("sb3-dqn", "chain"), ("sb3-sac", "pendulum")])
def test_sb3_stores_counterfactuals_with_the_monitors_rewards(
    tmp_path: Path, algo: str, world: str
) -> None:
    """A few hundred steps of SB3's DQN (the slippery chain) and SAC (Pendulum) with
    ``sb3.crm``: the memory grows by more than a row a step, and every counterfactual row is
    the monitor's step from its task state on its letter (read from its observation)."""
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    from mitlc.learn.backends.sb3 import algorithm, model_settings, wrapped_env
    from mitlc.learn.backends.sb3_crm import CounterfactualReplay
    from mitlc.learn.setting import prepare

    path = tmp_path / f"{world}.yaml"
    path.write_text(CHAIN if world == "chain" else PENDULUM)
    config = resolve({}, {"algo": algo, **TINY}, discount=0.95, pomdp=False)
    setting = prepare(path, config)
    venv = make_vec_env(lambda: wrapped_env(setting), 2, seed=0, vec_env_cls=DummyVecEnv)
    cls, policy = algorithm(algo)
    model = cls(policy, venv, seed=0, device="cpu", **model_settings(config, venv.envs[0]))
    model.learn(300)
    memory = model.replay_buffer
    assert isinstance(memory, CounterfactualReplay)
    made = memory.counterfactual[: memory.size()]
    steps = model.num_timesteps  # env steps: SB3 adds them a row (an env each) at a time
    assert made.sum() + steps == memory.size() * 2 and memory.size() > 2 * steps
    assert memory.made >= made.sum() > 0
    assert all(run is not None for run in memory.runs)  # it followed every episode
    letter_of, width = LETTERS[world]
    monitor = TaskMonitor(setting.automaton, setting.world.rewards)
    num_q = len(setting.automaton.states)
    rows = np.argwhere(made)
    for pos, env in rows[:: max(1, len(rows) // 200)]:
        obs, after = memory.observations[pos, env], memory.next_observations[pos, env]
        q, reached = (int(np.argmax(o[width : width + num_q])) for o in (obs, after))
        out = monitor.step(MonitorState(q, 0, 0, 0), letter_of(obs[:width]))
        assert out.state.q == reached
        assert memory.rewards[pos, env] == pytest.approx(out.reward)
        ended = bool(memory.dones[pos, env])
        assert ended == (out.terminated or bool(memory.timeouts[pos, env]))
    dones = memory.dones[: memory.size()][made]
    assert 0 < dones.sum() < len(dones)  # some counterfactuals end the task, most do not


def test_sb3_crm_from_the_command_line_and_its_refusals(tmp_path: Path) -> None:
    """``--set sb3.crm=true`` trains an sb3-dqn run, with shaping too; sb3-ppo (no replay) is
    refused."""
    pytest.importorskip("stable_baselines3")
    from typer.testing import CliRunner

    from mitlc.cli import app

    path = tmp_path / "chain.yaml"
    path.write_text(CHAIN)
    sets = ["sb3.steps=200", "sb3.learning_starts=50", "sb3.hidden=16", "sb3.crm=true"]

    def run(algo: str, *more: str) -> Any:
        given = [item for s in [*sets, *more] for item in ("--set", s)]
        return CliRunner().invoke(app, ["train", str(path), "--algo", algo, "--out",
                                        str(tmp_path / f"{algo}{len(more)}"), *given,
                                        "--quiet", "--no-eval"])  # fmt: skip

    done = run("sb3-dqn")
    assert done.exit_code == 0, done.output
    refused = run("sb3-ppo")
    assert refused.exit_code == 1 and "replay memory" in refused.output
    shaped = run("sb3-dqn", "shaping=1")
    assert shaped.exit_code == 0, shaped.output
