"""DQN on any wrapped environment (``TaskVector``): a Discrete-observation toy-text env and a
Box-observation continuous world, beside the simulator's interface it shares."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from mitlc.gym import TaskWrapper
from mitlc.learn.config import resolve
from mitlc.learn.envs.envvec import VectorTask, task_vector
from mitlc.learn.learners.dqn import DQNLearner
from mitlc.learn.learners.encoder import Encoder
from mitlc.worlds.load import load_plane_world
from mitlc.worlds.plane_env import make_plane_env

LAKE = {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 11, 12]}}
CORRIDOR = """
name: corridor
plane:
  room: {width: 4.0, height: 1.0}
  start: [0.5, 0.5]
  actions: {headings: [left, right], stay: true, step: 1.0}
labels:
  goal: {box: {low: [3.0, 0.0], high: [4.0, 1.0]}}
spec: {formula: "F[0,6] goal"}
reward: {satisfied: 1, accept: 1, violated: 0, move: 0}
horizon: 10
discount: 0.9
"""


def learner_for(vector: VectorTask, episodes_hint: int) -> DQNLearner:
    overrides = {"algo": "dqn", "dqn.num_envs": vector.num_envs, "dqn.warmup_steps": 64,
                 "dqn.initial_value": 1.0, "dqn.epsilon_decay": 0.5,
                 "episodes": episodes_hint}  # fmt: skip
    config = resolve({}, overrides, discount=0.9, pomdp=False)
    space = vector.observation_space
    encoder = Encoder.of_spaces(
        space[vector.env_key], int(space["automaton"].n),
        vector.envs[0].monitor.num_sets, vector.num_actions,
    )  # fmt: skip
    return DQNLearner(None, config, np.random.default_rng(0), encoder=encoder,
                      num_actions=vector.num_actions)  # fmt: skip


def train(learner: DQNLearner, vector: VectorTask, episodes: int) -> None:
    done = 0
    while done < episodes:
        done += int(learner.train_step(vector, done / episodes).done.sum())  # type: ignore[arg-type]


def greedy_success(learner: DQNLearner, vector: VectorTask, episodes: int) -> float:
    policy, wins, ended = learner.policy(), 0, 0
    while ended < episodes:
        step = vector.step(policy.act(vector))  # type: ignore[arg-type]
        wins += int((step.success & step.done).sum())
        ended += int(step.done.sum())
    return wins / ended


def test_the_vector_steps_the_wrappers_with_same_step_restarts() -> None:
    envs = [TaskWrapper(gym.make("FrozenLake-v1", is_slippery=False), "F[0,8] goal", LAKE,
                        horizon=10) for _ in range(3)]  # fmt: skip
    vector = task_vector(envs, seed=0)
    assert vector.observation.tolist() == [0, 0, 0] and vector.automaton.tolist() == [0, 0, 0]
    right, down = 2, 1
    path = [down, down, right, right, down, right]  # 0 -> 4 -> 8 -> 9 -> 10 -> 14 -> 15
    for k, action in enumerate(path):
        step = vector.step(np.full(3, action))
        if k < len(path) - 1:
            assert not step.done.any()
    assert step.done.all() and step.success.all() and (step.next_observation == 15).all()
    # FrozenLake ends at the goal; the task reads the goal's letter once more (a stutter step)
    assert (vector.observation == 0).all() and (step.episode_steps == len(path) + 1).all()
    assert step.next_valid is not None and step.next_automaton is not None


def test_dqn_learns_a_discrete_toy_text_env() -> None:
    """A 3x3 lake (holes at 1 and 5, the goal at 8): reach it within 6 steps, avoiding holes."""
    desc = ["SHF", "FFH", "FFG"]
    labels = {"goal": {"obs": [8]}, "hole": {"obs": [1, 5]}}
    envs = [TaskWrapper(gym.make("FrozenLake-v1", desc=desc, is_slippery=False),
                        "!hole U[0,6] goal", labels, horizon=8) for _ in range(4)]  # fmt: skip
    vector = task_vector(envs, seed=0)
    assert vector.observation_space["env"].n == 9
    learner = learner_for(vector, 800)
    train(learner, vector, 800)
    assert greedy_success(learner, vector, 40) >= 0.95


def test_dqn_learns_a_box_observation_continuous_world(tmp_path: Path) -> None:
    path = tmp_path / "corridor.yaml"
    path.write_text(CORRIDOR)
    assert load_plane_world(path).width == 4.0
    vector = task_vector([make_plane_env(path) for _ in range(4)], seed=0)
    assert vector.observation.shape == (4, 2)
    encoder = learner_for(vector, 1).encoder
    features = encoder(vector.observation, vector.automaton, vector.mask)
    assert float(features[:, :2].min()) >= 0.0 and float(features[:, :2].max()) <= 1.0
    learner = learner_for(vector, 400)
    train(learner, vector, 400)
    assert greedy_success(learner, vector, 40) >= 0.95


def test_an_unbounded_axis_is_read_as_it_is_and_refused_tiles() -> None:
    box = gym.spaces.Box(np.array([-np.inf, 0.0], np.float32), np.array([np.inf, 4.0], np.float32))
    encoder = Encoder.of_spaces(box, 3, 0, 2)
    x = encoder(np.array([[-7.5, 1.0]]), np.array([0]), np.array([0]))
    assert x[0, :2].tolist() == [-7.5, 0.25]
    with pytest.raises(ValueError, match="bounded Box"):
        Encoder.of_spaces(box, 3, 0, 2, tiles=4)


# --- a continuous world from the command line ------------------------------------------------


def test_a_continuous_world_trains_evaluates_plots_and_resumes_exactly(tmp_path: Path) -> None:
    """``mitlc train`` on a ``plane:`` world (DQN on its wrapped envs), interrupted and resumed,
    ends exactly where an uninterrupted run does (the same metrics, the same evaluation);
    ``eval`` says there is no exact optimum; ``plot`` draws the room."""
    from mitlc.learn.config import resolve as resolve_config
    from mitlc.learn.evaluation.evaluate import evaluate
    from mitlc.learn.plots import plot_run
    from mitlc.learn.run import train as train_run

    path = tmp_path / "corridor.yaml"
    path.write_text(CORRIDOR)
    overrides = {"algo": "dqn", "episodes": 300, "dqn.num_envs": 4, "dqn.warmup_steps": 64,
                 "dqn.initial_value": 1.0, "log_every": 50, "checkpoint_every": 100}  # fmt: skip
    settings = resolve_config({}, overrides, discount=0.9, pomdp=False)
    straight = train_run(path, settings, tmp_path / "straight")
    calls = iter(range(100_000))
    stopped = train_run(path, settings, tmp_path / "split", should_stop=lambda: next(calls) == 30)
    assert stopped.stopped and 0 < stopped.episodes < 300
    resumed = train_run(path, settings, tmp_path / "split", resume=True)
    assert resumed.episodes == straight.episodes and resumed.steps == straight.steps
    metrics = [(tmp_path / run / "metrics.jsonl").read_text().splitlines()
               for run in ("straight", "split")]  # fmt: skip
    strip = [[line.split('"seconds"')[0] for line in lines] for lines in metrics]
    assert strip[0] == strip[1]
    a, b = (evaluate(tmp_path / run, episodes=100) for run in ("straight", "split"))
    assert a.successes == b.successes and a.optimum is None
    assert a.summary()["optimum_kind"].startswith("none")
    written = plot_run(tmp_path / "straight", trajectories=2)
    assert [p.name for p in written] == ["learning_curve.png", "trajectories.png",
                                         "automaton.png"]  # fmt: skip
    assert all(p.stat().st_size > 0 for p in written)


def test_the_recurrent_dqn_learns_a_continuous_world_with_a_noisy_sensor(tmp_path: Path) -> None:
    """The corridor with a noisy position sensor (a POMDP): ``mitlc train`` picks the
    recurrent DQN, which reads the Box observations through its sequences and learns the task;
    ``eval`` measures it without an optimum."""
    from typer.testing import CliRunner

    from mitlc.cli import app

    noisy = CORRIDOR.replace("  start: [0.5, 0.5]\n", "  start: [0.5, 0.5]\n  sensor: {std: 0.3}\n")
    path = tmp_path / "noisy.yaml"
    path.write_text(noisy)
    runner = CliRunner()
    settings = ["--episodes", "2000", "--set", "drqn.num_envs=8", "--quiet", "--no-eval",
                "--set", "drqn.warmup_sequences=32", "--set", "drqn.initial_value=1.0"]  # fmt: skip
    done = runner.invoke(app, ["train", str(path), "--out", str(tmp_path / "run"), *settings])
    assert done.exit_code == 0, done.output
    config = (tmp_path / "run" / "config.json").read_text()
    assert '"algo": "drqn"' in config
    shown = runner.invoke(app, ["eval", str(tmp_path / "run"), "--episodes", "200", "--json"])
    assert shown.exit_code == 0, shown.output
    import json

    report = json.loads(shown.output)
    assert report["optimum"] is None and report["success_rate"] >= 0.8


def test_tabular_q_learns_any_env_with_a_discrete_observation() -> None:
    """Tabular Q-learning over (frontier, observation, automaton state) on wrapped toy-text
    envs (the 3x3 lake with a deadline)."""
    from mitlc.learn.learners.qlearning_env import ObservedQLearner

    desc = ["SHF", "FFH", "FFG"]
    labels = {"goal": {"obs": [8]}, "hole": {"obs": [1, 5]}}
    envs = [TaskWrapper(gym.make("FrozenLake-v1", desc=desc, is_slippery=False),
                        "!hole U[0,6] goal", labels, horizon=8) for _ in range(16)]  # fmt: skip
    vector = task_vector(envs, seed=0)
    config = resolve({}, {"q.num_envs": 16, "episodes": 2000}, discount=0.9, pomdp=False)
    space = vector.observation_space
    learner = ObservedQLearner(9, int(space["automaton"].n), envs[0].monitor.num_sets,
                               vector.num_actions, config, np.random.default_rng(0))  # fmt: skip
    done = 0
    while done < 2000:
        done += int(learner.train_step(vector, done / 2000).done.sum())
    policy, wins, ended = learner.policy(), 0, 0
    while ended < 64:
        step = vector.step(policy.act(vector))
        wins += int((step.success & step.done).sum())
        ended += int(step.done.sum())
    assert wins / ended >= 0.95


def test_tile_coding_adds_the_one_hot_of_the_tile() -> None:
    """With ``tiles``, a Box observation also gives the one-hot of its tile (row-major over
    the axes), beside its scaled values."""
    box = gym.spaces.Box(np.zeros(2, np.float32), np.array([10.0, 5.0], np.float32))
    encoder = Encoder.of_spaces(box, 2, 0, 3, tiles=5)
    x = encoder(np.array([[9.9, 0.1], [0.0, 5.0]]), np.array([0, 1]), np.array([0, 0]))
    assert x.shape == (2, 2 + 25 + 2)
    assert x[0, :2].tolist() == pytest.approx([0.99, 0.02])
    tiles = x[:, 2:27]
    assert tiles.sum(dim=1).tolist() == [1.0, 1.0]
    assert int(tiles[0].argmax()) == 4 * 5 + 0 and int(tiles[1].argmax()) == 0 * 5 + 4
    assert encoder.observation_field == ((2,), np.float32)


def test_shaping_reads_the_wrappers_potential_without_a_product(tmp_path: Path) -> None:
    """Without product states the shaping reads the potential the task wrapper reports (0 at
    an episode's end where the task is decided): the reward is shaped by the one rule."""
    from mitlc.learn.learners.base import EnvShaping, learning_signal
    from mitlc.worlds.plane_env import plane_task

    path = tmp_path / "corridor.yaml"
    path.write_text(CORRIDOR)
    world = load_plane_world(path)
    vector = task_vector([plane_task(world, potential=0.0) for _ in range(3)], seed=0)
    config = resolve({}, {"shaping": 2.0}, discount=0.9, pomdp=False)
    shaping = EnvShaping(2.0)
    right, seen = 1, 0
    for _ in range(8):
        before = shaping.before(vector)
        assert (before > 0).all()  # still pending, and not at the farthest a task can be
        step = vector.step(np.full(3, right))
        reward, gammas = learning_signal(step, before, config, shaping)
        assert step.next_potential is not None
        expected = step.reward + gammas * 2.0 * step.next_potential - before
        assert reward.tolist() == pytest.approx(expected.tolist())
        assert (step.next_potential[step.terminated] == 0.0).all()
        seen += int(step.terminated.sum())
    assert seen > 0


def test_the_learners_read_an_async_vector_env_as_a_sync_one() -> None:
    """``VectorTask`` over gymnasium's ``AsyncVectorEnv`` (envs in subprocesses) gives the same
    steps as over ``SyncVectorEnv`` for the same seeds and actions."""
    from gymnasium.vector import AutoresetMode

    from mitlc.learn.envs.envvec import VectorTask

    def make() -> TaskWrapper:
        return TaskWrapper(gym.make("FrozenLake-v1", is_slippery=True), "!hole U[0,20] goal",
                           LAKE, horizon=25)  # fmt: skip

    sync = task_vector([make() for _ in range(3)], seed=4)
    venv = gym.vector.AsyncVectorEnv([make] * 3, autoreset_mode=AutoresetMode.SAME_STEP)
    try:
        async_ = VectorTask(venv, seed=4)
        rng, ended = np.random.default_rng(0), 0
        for _ in range(80):
            assert (sync.valid_actions() == async_.valid_actions()).all()
            actions = rng.integers(4, size=3)
            a, b = sync.step(actions), async_.step(actions)
            for field in ("reward", "terminated", "truncated", "accepting", "next_observation",
                          "next_automaton", "next_mask", "episode_steps"):  # fmt: skip
                assert np.array_equal(getattr(a, field), getattr(b, field)), field
            assert np.array_equal(a.success[a.done], b.success[a.done])
            ended += int(a.done.sum())
        assert ended > 5
    finally:
        venv.close()
