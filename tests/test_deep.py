"""The deep learners (:mod:`mitlc.learn.learners.dqn`, :mod:`mitlc.learn.learners.drqn`): smoke
runs with tiny
budgets, exact resume, checkpoint round trips, masking of invalid actions, and the replay's
sequences."""

from __future__ import annotations

import dataclasses
import json
import pickle
from pathlib import Path
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from mitlc.learn.config import DQNConfig, TrainConfig  # noqa: E402
from mitlc.learn.envs.vec import Tables, VecProduct  # noqa: E402
from mitlc.learn.evaluation.evaluate import evaluate  # noqa: E402
from mitlc.learn.evaluation.exact import policy_success  # noqa: E402
from mitlc.learn.learners.base import Learner, Policy  # noqa: E402
from mitlc.learn.learners.dqn import DQNLearner, DQNPolicy  # noqa: E402
from mitlc.learn.learners.drqn import DRQNLearner  # noqa: E402
from mitlc.learn.learners.encoder import Encoder  # noqa: E402
from mitlc.learn.run import RunError, Setting, load_learner, make_learner, prepare, train  # noqa: E402
from mitlc.learn.rundir import checkpoint  # noqa: E402
from tests.conftest import TINY_DRQN  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CASE1 = ROOT / "specs" / "paper" / "case1.yaml"
CASE2 = ROOT / "specs" / "paper" / "case2.yaml"
CASE3 = ROOT / "specs" / "paper" / "case3-office.yaml"

TINY_DQN = DQNConfig(
    num_envs=4, hidden=16, batch_size=16, warmup_steps=32, target_update=10, initial_value=50.0
)


def label(value: object) -> str:
    """A test id: a world file's stem, or the value."""
    return value.stem if isinstance(value, Path) else str(value)


def tiny(algo: str, episodes: int, **changes: Any) -> TrainConfig:
    """A run of a few episodes that still learns (every step past a short warm-up)."""
    return TrainConfig(
        algo=algo,  # type: ignore[arg-type]
        seed=3,
        episodes=episodes,
        log_every=max(1, episodes // 4),
        checkpoint_every=max(1, episodes // 2),
        dqn=dataclasses.replace(TINY_DQN, **changes) if algo == "dqn" else TINY_DQN,
        drqn=dataclasses.replace(TINY_DRQN, **changes) if algo == "drqn" else TINY_DRQN,
    )


def learner_of(world: Path, config: TrainConfig, seed: int = 0) -> tuple[Setting, Learner]:
    setting = prepare(world, config)
    return setting, make_learner(setting, np.random.default_rng(seed))


def metrics(directory: Path) -> list[dict[str, Any]]:
    lines = (directory / "metrics.jsonl").read_text(encoding="utf-8").splitlines()
    rows = [json.loads(line) for line in lines]
    for row in rows:
        del row["seconds"]
    return rows


def weights(directory: Path) -> dict[str, Any]:
    saved: dict[str, Any] = checkpoint.load(directory).state["learner"]
    return saved["net"]  # type: ignore[no-any-return]


def same_weights(a: dict[str, Any], b: dict[str, Any]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def greedy_rollout(tables: Tables, policy: Policy, steps: int, num_envs: int = 8) -> None:
    """Run ``policy`` for ``steps`` steps; every action it picks must be valid."""
    env = VecProduct(tables, num_envs, np.random.default_rng(5))
    policy.reset(num_envs)
    for _ in range(steps):
        actions = policy.act(env)
        assert env.valid_actions()[np.arange(num_envs), actions].all()
        policy.observe(env.step(actions))


@pytest.mark.parametrize(
    ("world", "algo"), [(CASE1, "dqn"), (CASE3, "drqn"), (CASE2, "drqn")], ids=label
)
def test_smoke_run_learns_and_loads(world: Path, algo: str, tmp_path: Path) -> None:
    result = train(world, tiny(algo, 40), tmp_path / "run")
    assert result.episodes >= 40 and not result.stopped
    assert (tmp_path / "run" / "summary.json").is_file()
    assert metrics(tmp_path / "run")[-1]["episodes"] == result.episodes
    setting, learner = load_learner(tmp_path / "run")
    assert isinstance(learner, DQNLearner | DRQNLearner)
    assert learner.gradient_steps > 0
    greedy_rollout(setting.tables, learner.policy(), 50)


@pytest.mark.parametrize(("world", "algo"), [(CASE1, "dqn"), (CASE3, "drqn")], ids=label)
def test_resume_equals_uninterrupted_run(world: Path, algo: str, tmp_path: Path) -> None:
    config = tiny(algo, 60)
    whole = train(world, config, tmp_path / "whole")
    calls = iter(range(10**6))
    stopped = train(world, config, tmp_path / "cut", should_stop=lambda: next(calls) >= 120)
    assert stopped.stopped and 0 < stopped.episodes < 60
    resumed = train(world, config, tmp_path / "cut", resume=True)
    assert (resumed.episodes, resumed.steps) == (whole.episodes, whole.steps)
    assert metrics(tmp_path / "cut") == metrics(tmp_path / "whole")
    assert same_weights(weights(tmp_path / "cut"), weights(tmp_path / "whole"))


@pytest.mark.parametrize(("world", "algo"), [(CASE1, "dqn"), (CASE3, "drqn")], ids=label)
def test_the_device_may_change_on_resume_and_a_run_reads_back_anywhere(
    world: Path, algo: str, tmp_path: Path
) -> None:
    """A run resumed with another device (auto here, cpu before) ends as the uninterrupted
    one; a run whose config.json says cuda is read back on this CPU machine (eval, plot).
    Where auto is a GPU the two devices' arithmetic differs in the last bits, so the weights
    are compared only where auto is the CPU (``test_cuda`` has the GPU's side)."""
    config = tiny(algo, 60)
    whole = train(world, config, tmp_path / "whole")
    calls = iter(range(10**6))
    cpu = dataclasses.replace(config, device="cpu")
    stopped = train(world, cpu, tmp_path / "cut", should_stop=lambda: next(calls) >= 120)
    assert stopped.stopped
    resumed = train(world, config, tmp_path / "cut", resume=True)
    assert (resumed.episodes, resumed.steps) == (whole.episodes, whole.steps)
    if not torch.cuda.is_available():
        assert same_weights(weights(tmp_path / "cut"), weights(tmp_path / "whole"))
    saved = json.loads((tmp_path / "cut" / "config.json").read_text())
    saved["train"]["device"] = "cuda"
    (tmp_path / "cut" / "config.json").write_text(json.dumps(saved))
    _, learner = load_learner(tmp_path / "cut")
    here = "cuda" if torch.cuda.is_available() else "cpu"  # this machine's device, not the run's
    assert isinstance(learner, DQNLearner | DRQNLearner) and learner.device.type == here


@pytest.mark.parametrize(("world", "algo"), [(CASE1, "dqn"), (CASE3, "drqn")], ids=label)
def test_state_dict_round_trip(world: Path, algo: str) -> None:
    config = tiny(algo, 10)
    setting, first = learner_of(world, config, seed=1)
    env = VecProduct(setting.tables, first.num_envs, np.random.default_rng(2))
    for _ in range(60):
        first.train_step(env, 0.5)
    saved = pickle.loads(pickle.dumps(first.state_dict()))
    _, second = learner_of(world, config, seed=9)
    second.load_state_dict(saved)
    twin = VecProduct(setting.tables, first.num_envs, np.random.default_rng(0))
    twin.load_state_dict(env.state_dict())
    for _ in range(30):
        a, b = first.train_step(env, 0.6), second.train_step(twin, 0.6)
        assert np.array_equal(a.next_state, b.next_state)
    assert same_weights(first.state_dict()["net"], second.state_dict()["net"])
    assert first.rng.bit_generator.state == second.rng.bit_generator.state


def without_action(tables: Tables, action: int) -> Tables:
    """``tables`` where ``action`` is never valid."""
    choice = tables.choice.copy()
    choice[:, action] = -1
    return dataclasses.replace(tables, choice=choice, valid=choice >= 0)


@pytest.mark.parametrize(("world", "algo"), [(CASE1, "dqn"), (CASE3, "drqn")], ids=label)
def test_policy_never_picks_an_invalid_action(world: Path, algo: str) -> None:
    setting, learner = learner_of(world, tiny(algo, 10))
    assert isinstance(learner, DQNLearner | DRQNLearner)
    head = learner.net[-1] if isinstance(learner, DQNLearner) else learner.net.head
    with torch.no_grad():
        head.bias[2] = 1e6  # action 2 looks best everywhere
    tables = without_action(setting.tables, 2)
    env = VecProduct(tables, 6, np.random.default_rng(0))
    policy = learner.policy()
    policy.reset(6)
    for _ in range(40):
        actions = policy.act(env)
        assert (actions != 2).all()
        policy.observe(env.step(actions))


@pytest.mark.parametrize(("world", "algo"), [(CASE1, "dqn"), (CASE2, "drqn")], ids=label)
def test_untrained_policy_acts_validly(world: Path, algo: str) -> None:
    setting, learner = learner_of(world, tiny(algo, 10))
    greedy_rollout(setting.tables, learner.policy(), 100)


def test_dqn_is_refused_on_a_pomdp() -> None:
    setting = prepare(CASE2, tiny("dqn", 10))
    with pytest.raises(RunError, match="drqn"):
        make_learner(setting, np.random.default_rng(0))


def test_exact_success_of_dqn_policy_matches_monte_carlo() -> None:
    setting, learner = learner_of(CASE1, tiny("dqn", 10, initial_value=0.0), seed=4)
    policy = learner.policy()
    assert isinstance(policy, DQNPolicy)
    exact = policy_success(setting.product, policy.choices(), setting.tables.horizon)
    n = 4000
    env = VecProduct(setting.tables, n, np.random.default_rng(8))
    first = np.full(n, -1)
    while (first < 0).any():
        step = env.step(policy.act(env))
        new = step.done & (first < 0)
        first[new] = step.success[new]
    sigma = max(np.sqrt(exact * (1 - exact) / n), 1e-3)
    assert abs(first.mean() - exact) < 5 * sigma


def test_encoder_one_hot_blocks() -> None:
    tables = prepare(CASE3, tiny("drqn", 10)).tables
    encoder = Encoder(tables, previous_action=True)
    x = encoder(np.array([[2, 0]]), np.array([[1, 3]]), np.array([[1, 0]]), np.array([[-1, 4]]))
    assert x.shape == (1, 2, encoder.size)
    assert x.sum(dim=-1).tolist() == [[4.0, 3.0]]  # the mask bit only in the first
    assert x[0, 0, encoder.action_offset].item() == 1.0  # no previous action
    assert x[0, 1, encoder.action_offset + 5].item() == 1.0


def test_drqn_replay_covers_every_transition_once() -> None:
    config = tiny("drqn", 10, replay_size=10_000, warmup_sequences=10**6)
    setting, learner = learner_of(CASE3, config)
    assert isinstance(learner, DRQNLearner)
    env = VecProduct(setting.tables, learner.num_envs, np.random.default_rng(1))
    rewards = 0.0
    for _ in range(150):
        step = learner.train_step(env, 0.0)
        rewards += float(step.reward.sum())
    length = learner.streams.length
    emitted = learner.streams.length // TINY_DRQN.sequence_length * TINY_DRQN.sequence_length
    data = {k: v[: learner.replay.size] for k, v in learner.replay.data.items()}
    pending = int((length - emitted).sum())
    assert int(data["live"].sum()) == 150 * learner.num_envs - pending
    starts = ~data["burn"].any(axis=1)  # sequences from an episode's start: zero state
    assert starts.any() and not np.abs(data["state"][starts]).any()
    assert (data["previous"][starts, TINY_DRQN.burn_in] == -1).all()
    if pending == 0:
        live_reward = float((data["reward"] * data["live"]).sum())
        assert live_reward == pytest.approx(rewards * config.drqn.reward_scale, rel=1e-5)


def test_pomdp_evaluation_brackets_the_optimum(tmp_path: Path) -> None:
    train(CASE3, tiny("drqn", 20), tmp_path / "run")
    report = evaluate(tmp_path / "run", episodes=200)
    assert report.pomdp and report.exact is None
    assert report.lower is not None
    assert 0.99 < report.lower <= report.optimum + 1e-12  # the office loses ~nothing
    data = report.summary()
    assert data["lower_bound"] == report.lower
    assert data["lower_ratio"] == pytest.approx(report.success_rate / report.lower)


@pytest.mark.parametrize(
    ("algo", "device", "told"),
    [("dqn", "auto", True), ("sb3-ppo", "auto", True), ("dqn", "cpu", False), ("q", "auto", False)],
)
def test_a_network_that_auto_puts_on_cuda_is_told_the_cpu_may_be_quicker(
    algo: str, device: str, told: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where torch sees CUDA (made so here), ``train`` notes that the CPU may be quicker for a
    deep run on ``auto``; not for one given ``cpu``, nor for tabular Q."""
    from mitlc.learn.run import prepare
    from mitlc.learn.setting import SMALL_NETWORKS_ON_CUDA, setting_notes

    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    config = dataclasses.replace(tiny("dqn", 10), algo=algo, device=device)
    assert (SMALL_NETWORKS_ON_CUDA in setting_notes(prepare(CASE1, config))) == told
