"""Stable-Baselines3's SAC and TD3 (``--algo sb3-sac``, ``--algo sb3-td3``) on a world whose
env takes continuous actions (gymnasium's Pendulum): a run directory with checkpoints of the
policy, every optimiser and SAC's entropy coefficient (no pickle), resume, eval and plot, the
greedy policy against SB3's ``predict``, the refusal of discrete actions; and ``--device``."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

pytest.importorskip("stable_baselines3")

from mitlc.cli import app
from mitlc.learn.backends.sb3 import ModelState
from mitlc.learn.device import DeviceError, resolve_device
from mitlc.learn.rundir import checkpoint
from tests.conftest import ROOT
from tests.open_envs import PENDULUM

runner = CliRunner()
CASE1 = str(ROOT / "specs" / "paper" / "case1.yaml")
TINY = ["sb3.batch_size=32", "sb3.learning_starts=50", "sb3.buffer_size=1000", "sb3.hidden=16"]
PARTS = {  # what each checkpoint holds besides the settings, the policy and the counters
    "sb3-sac": {"actor_optimizer", "critic_optimizer", "ent_coef_optimizer", "log_ent_coef"},
    "sb3-td3": {"actor_optimizer", "critic_optimizer"},
}
NETWORKS = {
    "sb3-sac": {"actor", "critic", "critic_target"},
    "sb3-td3": {"actor", "actor_target", "critic", "critic_target"},
}


def train(world: Path, out: Path, algo: str | None, steps: int, *extra: str) -> Any:
    """``mitlc train`` on ``world`` with a tiny ``algo`` (None: the run's, on --resume);
    ``extra``: more settings (``KEY=VALUE``), or options."""
    given = [e for e in extra if "=" in e and not e.startswith("--")]
    sets = [item for s in [*TINY, f"sb3.steps={steps}", *given] for item in ("--set", s)]
    flags = [e for e in extra if e not in given] + (["--algo", algo] if algo else [])
    return runner.invoke(app, ["train", str(world), "--out", str(out), *sets, *flags,
                               "--quiet", "--no-eval"])  # fmt: skip


def same(a: Any, b: Any) -> bool:
    """Whether two states hold the same structure, numbers and tensors (the latter on any
    device)."""
    if isinstance(a, torch.Tensor):
        return isinstance(b, torch.Tensor) and torch.equal(a.cpu(), b.cpu())
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.dtype == b.dtype and np.array_equal(a, b)
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return type(a) is type(b) and len(a) == len(b) and all(map(same, a, b))
    return bool(a == b)


@pytest.fixture
def pendulum(tmp_path: Path) -> Path:
    """The world file."""
    path = tmp_path / "pendulum.yaml"
    path.write_text(PENDULUM)
    return path


@pytest.mark.parametrize("algo", ["sb3-sac", "sb3-td3"])
def test_each_trains_a_run_that_evaluates_and_acts_as_sb3_predicts(
    tmp_path: Path, pendulum: Path, algo: str
) -> None:
    from mitlc.learn.envs.envvec import task_vector
    from mitlc.learn.run import load_learner
    from mitlc.product.worlds import task_env

    out = tmp_path / "run"
    done = train(pendulum, out, algo, 200, "sb3.num_envs=2")
    assert done.exit_code == 0, done.output
    assert "(200 steps)" in done.output
    names = {p.name for p in out.iterdir()}
    assert {"config.json", "metrics.jsonl", "summary.json", "checkpoint.json"} < names
    assert not [n for n in names if n.endswith((".zip", ".pkl", ".pickle", ".pt"))]
    config = json.loads((out / "config.json").read_text())["train"]
    assert config["algo"] == algo and config["device"] == "auto"
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert rows[-1]["steps"] == 200 and rows[-1]["episodes"] >= 4
    model = checkpoint.load(out).state["model"]
    assert set(model) == {"settings", "policy", "counters", "replay"} | PARTS[algo]
    assert {key.partition(".")[0] for key in model["policy"]} == NETWORKS[algo]
    assert model["counters"]["num_timesteps"] == 200 and model["counters"]["n_updates"] > 0
    shown = runner.invoke(app, ["eval", str(out), "--episodes", "20", "--json"])
    assert shown.exit_code == 0, shown.output
    report = json.loads(shown.stdout)
    assert report["optimum"] is None and report["episodes"] == 20
    # the greedy policy eval runs: SB3's deterministic action on the wrapper's flat observation
    setting, learner = load_learner(out)
    policy, net = learner.policy(), learner.net  # type: ignore[attr-defined]
    flat = [task_env(setting.world, setting.automaton, flatten=True) for _ in range(3)]
    view = task_vector([task_env(setting.world, setting.automaton) for _ in range(3)], seed=7)
    observations = [env.reset(seed=7 + i)[0] for i, env in enumerate(flat)]
    rng = np.random.default_rng(0)
    for _ in range(20):
        chosen = policy.act(view)
        predicted = np.stack([net.predict(obs, deterministic=True)[0] for obs in observations])
        assert chosen.shape == (3, 1) and np.allclose(chosen, predicted, atol=1e-5)
        assert np.all(np.abs(chosen) <= 2.0)
        actions = rng.uniform(-2.0, 2.0, size=(3, 1)).astype(np.float32)
        view.step(actions)
        for i, env in enumerate(flat):
            obs, _, terminated, truncated, _ = env.step(actions[i])
            observations[i] = env.reset()[0] if terminated or truncated else obs


@pytest.mark.parametrize("algo", ["sb3-sac", "sb3-td3"])
def test_resume_loads_the_checkpoint_and_continues_its_steps(
    tmp_path: Path, pendulum: Path, algo: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An interrupted run (a smaller budget) resumed with a larger one: the model it goes on
    with holds the checkpoint's weights, optimisers and counters before it learns again; a
    config.json from before ``device`` existed loads (as ``auto``) and ``--device`` may change."""
    out = tmp_path / "run"
    assert train(pendulum, out, algo, 150).exit_code == 0
    saved = checkpoint.load(out).state["model"]
    path = out / "config.json"
    data = json.loads(path.read_text())
    del data["train"]["device"]  # as an older mitlc wrote it
    path.write_text(json.dumps(data))
    loaded: dict[str, Any] = {}
    load = ModelState.load_state_dict

    def spy(self: ModelState, state: dict[str, Any]) -> None:
        load(self, state)
        loaded.update(copy.deepcopy(self.state_dict()))  # before training changes them

    monkeypatch.setattr(ModelState, "load_state_dict", spy)
    more = train(pendulum, out, None, 260, "--resume", "--device", "cpu")
    assert more.exit_code == 0, more.output
    assert loaded.keys() == saved.keys() and same(loaded, saved)
    assert all(saved[key]["state"] for key in PARTS[algo] if key.endswith("optimizer"))
    if algo == "sb3-sac":
        assert float(saved["log_ent_coef"][0]) != 0.0  # it learned from log(1)
    assert loaded["counters"] == saved["counters"] and saved["counters"]["num_timesteps"] == 150
    state = checkpoint.load(out).state["model"]
    assert state["counters"]["num_timesteps"] == 260
    # a gradient step a step past learning_starts (50), and every step after the resume: the
    # replay memory was restored (its 150 rows), not refilled for 50 steps (that would be 160)
    assert (saved["counters"]["n_updates"], state["counters"]["n_updates"]) == (100, 210)
    assert saved["replay"]["kept"] and saved["replay"]["pos"] == 150
    assert loaded["replay"]["pos"] == 150 and state["replay"]["pos"] == 260
    assert not all(torch.equal(state["policy"][k], v) for k, v in saved["policy"].items())
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    steps = [row["steps"] for row in rows]
    assert steps == sorted(steps) and 150 in steps and steps[-1] == 260
    assert json.loads(path.read_text())["train"]["device"] == "cpu"
    other = train(pendulum, out, None, 400, "sb3.tau=0.01", "--resume")
    assert other.exit_code == 1 and "only sb3.steps may change" in other.output


@pytest.mark.parametrize("algo", ["sb3-sac", "sb3-td3"])
def test_discrete_actions_are_refused_in_one_line(tmp_path: Path, algo: str) -> None:
    out = tmp_path / "run"
    result = runner.invoke(app, ["train", CASE1, "--algo", algo, "--out", str(out), "-q"])
    assert result.exit_code == 1, result.output
    assert f"{algo} needs Box (continuous) actions" in result.output
    assert "use sb3-ppo, sb3-dqn" in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_the_plot_of_a_sac_run(tmp_path: Path, pendulum: Path) -> None:
    out = tmp_path / "run"
    assert train(pendulum, out, "sb3-sac", 100).exit_code == 0
    plotted = runner.invoke(app, ["plot", str(out), "--trajectories", "2"])
    assert plotted.exit_code == 0, plotted.output
    assert (out / "learning_curve.png").stat().st_size > 1000


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("sb3.tau=2", "training.sb3.tau: expected a value in [0, 1]"),
        ("sb3.noise_std=-1", "training.sb3.noise_std: expected a value in"),
        ("sb3.gradient_steps=1.5", "training.sb3.gradient_steps: expected an integer"),
    ],
)
def test_bad_settings_name_their_path(
    tmp_path: Path, pendulum: Path, setting: str, message: str
) -> None:
    result = train(pendulum, tmp_path / "run", "sb3-td3", 100, setting)
    assert result.exit_code == 1 and message in result.output, result.output


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
def test_the_devices_of_a_machine_without_cuda(tmp_path: Path, pendulum: Path) -> None:
    assert resolve_device("auto") == torch.device("cpu") == resolve_device("cpu")
    with pytest.raises(DeviceError, match="sees no CUDA device"):
        resolve_device("cuda")
    for algo in ("sb3-sac", "q"):  # every learner is refused before its set-up
        out = tmp_path / algo
        result = train(pendulum, out, algo, 100, "--device", "cuda")
        assert result.exit_code == 1 and "--device cuda:" in result.output, result.output
        assert "Traceback" not in result.output and result.exception is not None
        assert isinstance(result.exception, SystemExit) and not out.exists()
    wrong = train(pendulum, tmp_path / "gpu", "sb3-sac", 100, "--device", "gpu")
    assert wrong.exit_code == 1
    assert "training.device: expected one of auto, cpu, cuda, got 'gpu'" in wrong.output


def test_sac_and_td3_read_images_with_the_cnn() -> None:
    """SAC's and TD3's actor and critic read the images of the flat observation with the CNN
    (:mod:`mitlc.learn.backends.sb3_images`), as the other backends' policies do."""
    from gymnasium import spaces
    from stable_baselines3 import SAC, TD3

    from mitlc.learn.backends.sb3 import model_settings
    from mitlc.learn.config import SB3Config, TrainConfig
    from mitlc.learn.learners.nets import configure_torch
    from tests.test_observations import MINIGRID, Random, has_conv, wrapped

    class Steered(Random):
        """MiniGrid's observation (an image), steered by a Box action."""

        def __init__(self) -> None:
            super().__init__(MINIGRID)
            self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)  # type: ignore[assignment]

        def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
            return super().step(int(action[0] > 0))

    configure_torch()  # one thread, as in a run: two are many times slower on 2 cores
    env = wrapped(Steered(), flatten=True)
    tiny = SB3Config(hidden=16, batch_size=8, learning_starts=8, buffer_size=100)
    for algo, cls in (("sb3-sac", SAC), ("sb3-td3", TD3)):
        given = model_settings(TrainConfig(algo=algo, sb3=tiny), env)  # type: ignore[arg-type]
        assert ("action_noise" in given) == (algo == "sb3-td3")
        model = cls("MlpPolicy", env, device="cpu", seed=0, **given)
        assert has_conv(model.actor) and has_conv(model.critic)
        model.learn(16)
        assert model.num_timesteps == 16 and model._n_updates > 0
