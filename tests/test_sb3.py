"""Stable-Baselines3 as a backend (mitlc.learn.backends.sb3): train, eval, plot, checkpoints
without pickle,
resume, the greedy policy against the wrapped env, and the documented example."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

pytest.importorskip("stable_baselines3")
pytest.importorskip("sb3_contrib")

from mitlc.cli import app
from mitlc.gym.shaping import ShapedReward
from mitlc.learn.backends.sb3 import wrapped_env
from mitlc.learn.backends.sb3_policy import SB3Learner, SB3Policy
from mitlc.learn.run import load_learner
from tests.conftest import ROOT

runner = CliRunner()
CASE1 = str(ROOT / "specs" / "paper" / "case1.yaml")
TINY = {  # a few seconds per run
    "sb3-ppo": ["sb3.n_steps=128", "sb3.batch_size=64", "sb3.n_epochs=2"],
    "sb3-maskable-ppo": ["sb3.n_steps=128", "sb3.batch_size=64", "sb3.n_epochs=2"],
    "sb3-recurrent-ppo": ["sb3.n_steps=64", "sb3.batch_size=64", "sb3.n_epochs=2"],
    "sb3-dqn": ["sb3.learning_starts=64", "sb3.buffer_size=2000", "sb3.target_update_interval=100"],
}


def train(out: Path, algo: str, steps: int, *extra: str) -> Any:
    """``mitlc train`` case 1 with a tiny ``algo``; ``extra``: more settings, or flags."""
    settings = [*TINY[algo], f"sb3.steps={steps}", "sb3.num_envs=2"]
    settings += [e for e in extra if not e.startswith("--")]
    sets = [item for s in settings for item in ("--set", s)]
    flags = [e for e in extra if e.startswith("--")]
    return runner.invoke(app, ["train", CASE1, "--algo", algo, "--out", str(out), *sets,
                               *flags, "--quiet", "--no-eval"])  # fmt: skip


def checkpoint_files(out: Path) -> dict[str, str]:
    """The latest checkpoint's files by name, each checked against its SHA-256, read without
    pickle: JSON, and the tensors with safetensors."""
    import hashlib

    from safetensors.torch import load_file

    index = json.loads((out / "checkpoint.json").read_text())
    for name, digest in index["files"].items():
        assert hashlib.sha256((out / name).read_bytes()).hexdigest() == digest
        if name.endswith(".json"):
            assert json.loads((out / name).read_text())["steps"] == index["steps"]
        elif name.endswith(".npz"):  # the replay memory of the off-policy algorithms
            with np.load(out / name, allow_pickle=False) as arrays:
                assert arrays.files
        else:
            assert name.endswith(".safetensors") and load_file(out / name)
    return dict(index["files"])


@pytest.mark.parametrize("algo", ["sb3-ppo", "sb3-dqn", "sb3-maskable-ppo", "sb3-recurrent-ppo"])
def test_each_algorithm_trains_into_a_run_and_evaluates(tmp_path: Path, algo: str) -> None:
    out = tmp_path / "run"
    result = train(out, algo, 512)
    assert result.exit_code == 0, result.output
    assert re.search(r"trained [\d,]+ episodes \(5\d\d steps\)", result.output)
    names = {p.name for p in out.iterdir()}
    assert {"config.json", "metrics.jsonl", "summary.json", "checkpoint.json"} < names
    assert not [n for n in names if n.endswith((".zip", ".pkl", ".pickle", ".pt"))]
    listed = checkpoint_files(out)
    latest = json.loads((out / "checkpoint.json").read_text())["latest"]
    replay = {f"{latest}.npz"} if algo == "sb3-dqn" else set()
    assert {f"{latest}.json", f"{latest}.safetensors"} | replay == set(listed)
    config = json.loads((out / "config.json").read_text())["train"]
    assert config["algo"] == algo and config["sb3"]["steps"] == 512
    assert config["sb3"]["log_every"] == 5 and config["sb3"]["checkpoint_every"] == 51
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert rows[-1]["steps"] >= 512 and rows[-1]["episodes"] >= 512 // 31
    assert all({"success_rate", "return", "epsilon", "seconds"} <= row.keys() for row in rows)
    report = runner.invoke(app, ["eval", str(out), "--episodes", "200"])
    assert report.exit_code == 0, report.output
    assert re.search(r"learned success\s+\d\.\d{4}\s+95% \[", report.output)
    assert "optimum          0.974021" in report.output
    assert ("learned, exact" in report.output) == (algo != "sb3-recurrent-ppo")


def test_resume_continues_the_step_count_and_keeps_the_weights(tmp_path: Path) -> None:
    from safetensors.torch import load_file

    out = tmp_path / "run"
    assert train(out, "sb3-dqn", 256).exit_code == 0
    first = json.loads((out / "checkpoint.json").read_text())
    weights = load_file(out / f"{first['latest']}.safetensors")
    _, learner = load_learner(out)
    loaded = learner.state_dict()["policy"]
    assert all(np.array_equal(loaded[k].numpy(), weights[f"t{i}"].numpy())
               for i, k in enumerate(loaded))  # fmt: skip
    other = train(out, "sb3-dqn", 512, "sb3.hidden=32", "--resume")
    assert other.exit_code == 1 and "only sb3.steps may change" in other.output
    more = runner.invoke(app, ["train", CASE1, "--out", str(out), "--resume", "--set",
                               "sb3.steps=512", "--quiet", "--no-eval"])  # fmt: skip
    assert more.exit_code == 0, more.output
    second = json.loads((out / "checkpoint.json").read_text())
    assert first["steps"] == 256 and second["steps"] == 512
    state = json.loads((out / f"{second['latest']}.json").read_text())["state"]
    assert state["model"]["counters"]["num_timesteps"] == 512
    assert state["tally"]["steps"] == 512 and state["tally"]["episodes"] > 0
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    steps = [row["steps"] for row in rows]
    assert steps == sorted(steps) and steps[-1] == 512 and 256 in steps
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 512
    done = runner.invoke(app, ["train", CASE1, "--out", str(out), "--resume", "-q", "--no-eval"])
    assert done.exit_code == 1 and "already has 512 steps" in done.output


@pytest.mark.parametrize("extra", [(), ("task_obs=clocks", "shaping=1")])
def test_the_greedy_policy_is_the_one_sb3_predicts_on_the_wrapped_env(
    tmp_path: Path, extra: tuple[str, ...]
) -> None:
    """The policy that eval and plot run in the simulator acts as ``predict(obs,
    deterministic=True)`` does on the wrapped env, state by state: with the state's one-hot,
    and with the clocks observation under shaping (the encoder's layout is the wrapper's)."""
    out = tmp_path / "run"
    assert train(out, "sb3-ppo", 512, *extra).exit_code == 0
    setting, learner = load_learner(out)
    policy = learner.policy()
    assert isinstance(learner, SB3Learner) and isinstance(policy, SB3Policy)
    choices, t = policy.choices(), setting.tables
    index = {(int(s), int(q)): x for x, (s, q) in
             enumerate(zip(t.world_state, t.automaton_state, strict=True)) if s >= 0}  # fmt: skip
    env = wrapped_env(setting)
    rng = np.random.default_rng(0)
    compared = 0
    for episode in range(20):
        obs, _ = env.reset(seed=episode)
        done = False
        while not done:
            action, _ = learner.net.predict(obs, deterministic=True)
            product: Any = env.env if isinstance(env, ShapedReward) else env
            assert isinstance(env, ShapedReward) == bool(extra)
            x = index[(product.world_state, product.automaton_state)]
            assert t.choice[x, int(action)] == choices[int(product.frontier), x]
            compared += 1
            explore = rng.random() < 0.5  # visit states the greedy policy would not
            step = int(rng.integers(5)) if explore else int(action)
            obs, _, terminated, truncated, _ = env.step(step)
            done = terminated or truncated
    assert compared > 100


def test_plot_draws_an_sb3_run(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert train(out, "sb3-recurrent-ppo", 256).exit_code == 0
    result = runner.invoke(app, ["plot", str(out), "--trajectories", "3"])
    assert result.exit_code == 0, result.output
    assert {"learning_curve.png", "trajectories.png", "automaton.png"} <= {
        p.name for p in out.iterdir()
    }


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("sb3.exploration_fraction=2", "training.sb3.exploration_fraction: expected a value in"),
        ("sb3.steps=0", "training.sb3.steps: expected a positive value"),
        ("sb3.n_stepz=3", "training.sb3.n_stepz: unknown setting"),
        ("discount.mode=accepting", "SB3 learns with a constant discount"),
    ],
)
def test_bad_settings_name_their_path(tmp_path: Path, setting: str, message: str) -> None:
    result = runner.invoke(app, ["train", CASE1, "--algo", "sb3-ppo", "--set", setting,
                                 "--out", str(tmp_path / "run"), "-q"])  # fmt: skip
    assert result.exit_code == 1 and message in result.output, result.output


def test_the_example_trains_and_evaluates_through_is_success() -> None:
    path = ROOT / "examples" / "sb3_frozenlake.py"
    spec = importlib.util.spec_from_file_location("sb3_frozenlake", path)
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    figures = example.main(["--steps", "1024", "--episodes", "20"])
    assert 0.0 <= figures["success_rate"] <= 1.0 and figures["episodes"] == 20
    low, high = figures["interval95"]
    assert low <= figures["success_rate"] <= high
    assert figures["optimum"] == pytest.approx(0.744190, abs=1e-6)


def test_a_stopped_run_checkpoints_and_a_resumed_one_finishes(tmp_path: Path) -> None:
    """What Ctrl-C does in ``mitlc train``: the run checkpoints where it stopped."""
    from mitlc.learn.backends import sb3
    from mitlc.learn.config import SB3Config, TrainConfig

    tiny = SB3Config(steps=512, num_envs=2, n_steps=64, batch_size=64, n_epochs=2,
                     log_every=10, checkpoint_every=1000)  # fmt: skip
    config = TrainConfig(algo="sb3-ppo", sb3=tiny)
    calls = iter(range(10**6))
    out = tmp_path / "run"
    stopped = sb3.train(CASE1, config, out, should_stop=lambda: next(calls) >= 99)
    assert stopped.stopped and stopped.steps == 200 and not (out / "summary.json").exists()
    assert json.loads((out / "checkpoint.json").read_text())["steps"] == 200
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert rows[-1]["steps"] == 200
    done = sb3.train(CASE1, config, out, resume=True)
    assert not done.stopped and done.steps >= 512 and (out / "summary.json").exists()
    assert json.loads((out / "checkpoint.json").read_text())["steps"] == done.steps


@pytest.mark.parametrize("world", ["plane", "dict"])
def test_an_sb3_run_on_a_world_that_is_not_finite_acts_as_sb3_predicts(
    tmp_path: Path, world: str
) -> None:
    """``--algo sb3-ppo`` on a continuous world and on an env with a Dict observation: eval
    and plot run, and the policy mitlc evaluates (its features of the learners' view) chooses
    what ``predict(obs, deterministic=True)`` chooses on the wrapper's flat observation."""
    import tests.open_envs  # noqa: F401 - registers MitlcTest/DictChain-v0
    from mitlc.learn.envs.envvec import task_vector
    from mitlc.learn.run import load_learner
    from mitlc.product.worlds import task_env
    from tests.test_env_task import DICT_CHAIN
    from tests.test_envvec import CORRIDOR

    path = tmp_path / f"{world}.yaml"
    path.write_text(CORRIDOR if world == "plane" else DICT_CHAIN)
    out = tmp_path / "run"
    sets = [item for s in [*TINY["sb3-ppo"], "sb3.steps=512", "sb3.num_envs=2"]
            for item in ("--set", s)]  # fmt: skip
    done = runner.invoke(app, ["train", str(path), "--algo", "sb3-ppo", "--out", str(out),
                               *sets, "--quiet", "--no-eval"])  # fmt: skip
    assert done.exit_code == 0, done.output
    shown = runner.invoke(app, ["eval", str(out), "--episodes", "20", "--json"])
    assert shown.exit_code == 0 and json.loads(shown.output)["optimum"] is None, shown.output
    assert runner.invoke(app, ["plot", str(out)]).exit_code == 0
    setting, learner = load_learner(out)
    policy = learner.policy()
    flat = [task_env(setting.world, setting.automaton, flatten=True) for _ in range(3)]
    view = task_vector([task_env(setting.world, setting.automaton) for _ in range(3)], seed=7)
    observations = [env.reset(seed=7 + i)[0] for i, env in enumerate(flat)]
    rng = np.random.default_rng(0)
    for _ in range(30):
        chosen = policy.act(view)
        net: Any = learner.net  # type: ignore[attr-defined]
        for i in range(len(flat)):
            action, _ = net.predict(observations[i], deterministic=True)
            assert int(action) == int(chosen[i])
        actions = rng.integers(view.num_actions, size=3)
        view.step(actions)
        for i, env in enumerate(flat):
            obs, _, terminated, truncated, _ = env.step(int(actions[i]))
            observations[i] = env.reset()[0] if terminated or truncated else obs
