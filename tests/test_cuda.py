"""``--device cuda`` and ``auto`` on a machine with a GPU (:mod:`mitlc.learn.device`): every
deep learner and SB3 backend trains on it, checkpoints CPU tensors, resumes on the CPU and is
evaluated on a machine without CUDA. Skipped where torch sees no CUDA device (CI, this
project's CPU machines); the CPU side of the same rules is in ``test_deep`` and
``test_sb3_continuous``. Run them with ``pytest tests/test_cuda.py`` on a machine with one."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest

torch = pytest.importorskip("torch")
pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="torch sees no CUDA")

from typer.testing import CliRunner  # noqa: E402

import mitlc.learn.run as run_module  # noqa: E402
from mitlc.cli import app  # noqa: E402
from mitlc.learn.device import resolve_device  # noqa: E402
from mitlc.learn.learners.dqn import DQNLearner  # noqa: E402
from mitlc.learn.learners.drqn import DRQNLearner  # noqa: E402
from mitlc.learn.rundir import checkpoint  # noqa: E402
from tests.open_envs import PENDULUM  # noqa: E402
from tests.test_deep import CASE1, CASE3, greedy_rollout, tiny  # noqa: E402
from tests.test_envvec import CORRIDOR  # noqa: E402

runner = CliRunner()
TINY_SB3 = {
    "sb3-dqn": ["sb3.learning_starts=64", "sb3.buffer_size=2000", "sb3.target_update_interval=100"],
    "sb3-ppo": ["sb3.n_steps=128", "sb3.batch_size=64", "sb3.n_epochs=2"],
    "sb3-recurrent-ppo": ["sb3.n_steps=64", "sb3.batch_size=64", "sb3.n_epochs=2"],
    "sb3-sac": ["sb3.batch_size=32", "sb3.learning_starts=50", "sb3.buffer_size=1000"],
    "sb3-td3": ["sb3.batch_size=32", "sb3.learning_starts=50", "sb3.buffer_size=1000"],
}


def tensors(state: Any) -> list[Any]:
    """Every tensor in a nested checkpoint state."""
    if isinstance(state, torch.Tensor):
        return [state]
    if isinstance(state, dict):
        return [t for value in state.values() for t in tensors(value)]
    if isinstance(state, list | tuple):
        return [t for value in state for t in tensors(value)]
    return []


def test_auto_and_cuda_are_the_gpu() -> None:
    assert resolve_device("auto").type == "cuda" == resolve_device("cuda").type
    assert resolve_device("cpu").type == "cpu"


@pytest.mark.parametrize(
    ("world", "algo", "changes"),
    [("case1", "dqn", {}), ("case3", "drqn", {}), ("corridor", "dqn", {"crm": True})],
)
def test_a_deep_learner_trains_on_the_gpu_and_resumes_on_the_cpu(
    world: str, algo: str, changes: dict[str, Any], tmp_path: Path, monkeypatch: Any
) -> None:
    """The learner's network and its batches are on the GPU while it trains; the checkpoint
    holds CPU tensors; the run resumes with ``--device cpu`` and is read back on the GPU, and
    on a machine without CUDA, where the greedy policy acts."""
    path = {"case1": CASE1, "case3": CASE3}.get(world)
    if path is None:
        path = tmp_path / "corridor.yaml"
        path.write_text(CORRIDOR)
    made: list[Any] = []
    make = run_module.make_learner

    def recorded(*args: Any) -> Any:
        made.append(make(*args))
        return made[-1]

    monkeypatch.setattr(run_module, "make_learner", recorded)
    config = dataclasses.replace(tiny(algo, 60), device="cuda")
    if changes:
        config = dataclasses.replace(config, dqn=dataclasses.replace(config.dqn, **changes))
    calls = iter(range(10**6))
    out = tmp_path / "run"
    stopped = run_module.train(path, config, out, should_stop=lambda: next(calls) >= 40)
    assert stopped.stopped and made and made[0].device.type == "cuda"
    assert all(p.is_cuda for p in made[0].net.parameters())
    assert all(t.device.type == "cpu" for t in tensors(checkpoint.load(out).state))
    resumed = run_module.train(path, dataclasses.replace(config, device="cpu"), out, resume=True)
    assert not resumed.stopped and resumed.episodes >= 60
    assert made[-1].device.type == "cpu"
    setting, learner = run_module.load_learner(out)
    assert isinstance(learner, DQNLearner | DRQNLearner) and learner.device.type == "cuda"
    if setting.tables is not None:
        greedy_rollout(setting.tables, learner.policy(), 30)
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    setting, learner = run_module.load_learner(out)
    assert isinstance(learner, DQNLearner | DRQNLearner) and learner.device.type == "cpu"
    if setting.tables is not None:
        greedy_rollout(setting.tables, learner.policy(), 30)


def test_the_same_seed_on_the_gpu_gives_the_same_run(tmp_path: Path) -> None:
    """A DQN run on CUDA, twice with one seed: the same metrics and weights (mitlc's networks
    use no CUDA operation that is not deterministic)."""
    config = dataclasses.replace(tiny("dqn", 40), device="cuda")
    for name in ("a", "b"):
        run_module.train(CASE1, config, tmp_path / name)
    rows = [
        [{k: v for k, v in json.loads(line).items() if k != "seconds"}
         for line in (tmp_path / name / "metrics.jsonl").read_text().splitlines()]
        for name in ("a", "b")
    ]  # fmt: skip
    assert rows[0] == rows[1]
    a, b = (checkpoint.load(tmp_path / name).state["learner"]["net"] for name in ("a", "b"))
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize(
    ("world", "algo", "extra"),
    [
        ("case1", "sb3-dqn", ["sb3.crm=true"]),
        ("case1", "sb3-ppo", ["task_obs=clocks", "shaping=1"]),
        ("case1", "sb3-recurrent-ppo", []),
        ("pendulum", "sb3-sac", ["sb3.crm=true"]),
        ("pendulum", "sb3-td3", []),
    ],
)
def test_an_sb3_backend_trains_on_the_gpu(
    world: str, algo: str, extra: list[str], tmp_path: Path, monkeypatch: Any
) -> None:
    """``--device cuda``: SB3's model and policy are on the GPU; resumed with ``--device cpu``,
    the run goes on from its checkpoint (its replay memory too); eval reads it back."""
    import mitlc.learn.backends.sb3 as sb3

    path = Path(CASE1)
    if world == "pendulum":
        path = tmp_path / "pendulum.yaml"
        path.write_text(PENDULUM)
    models: list[Any] = []

    class Recorded(sb3.ModelState):
        def __init__(self, model: Any, config: Any) -> None:
            models.append(model)
            super().__init__(model, config)

    monkeypatch.setattr(sb3, "ModelState", Recorded)
    out = tmp_path / "run"

    def train(steps: int, *flags: str) -> Any:
        settings = [*TINY_SB3[algo], *extra, f"sb3.steps={steps}", "sb3.num_envs=2"]
        sets = [item for s in settings for item in ("--set", s)]
        return runner.invoke(app, ["train", str(path), "--algo", algo, "--out", str(out), *sets,
                                   *flags, "--quiet", "--no-eval"])  # fmt: skip

    first = train(256, "--device", "cuda")
    assert first.exit_code == 0, first.output
    assert models[0].device.type == "cuda"
    assert all(p.is_cuda for p in models[0].policy.parameters())
    index = json.loads((out / "checkpoint.json").read_text())
    off_policy = algo in ("sb3-dqn", "sb3-sac", "sb3-td3")
    assert any(name.endswith(".npz") for name in index["files"]) == off_policy
    second = train(512, "--device", "cpu", "--resume")
    assert second.exit_code == 0, second.output
    assert "refill" not in second.output  # the replay memory came back from the checkpoint
    assert models[-1].device.type == "cpu"
    assert json.loads((out / "checkpoint.json").read_text())["steps"] >= 512
    shown = runner.invoke(app, ["eval", str(out), "--episodes", "20", "--json"])
    assert shown.exit_code == 0, shown.output
    report = json.loads(shown.output)
    assert report["episodes"] == 20 and 0.0 <= report["success_rate"] <= 1.0
