"""Env steps per second of each deep learner and SB3 backend on ``--device cuda`` beside
``--device cpu``, one short run of each with its world's default settings, in the same minutes
on one machine (run by ``bench/device_check.sh`` on a lent GPU machine). Prints a table: the
training's own seconds (``summary.json``, set-up left out) and the ratio cpu / cuda.

    python bench/device_speed.py [--quick] [--only=WORLD_OR_ALGO ...]
"""

from __future__ import annotations

import json
import sys
import tempfile
import warnings
from pathlib import Path

from mitlc.learn.config import config_for
from mitlc.learn.run import train
from mitlc.worlds.door import open_world

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from tests.open_envs import PENDULUM  # noqa: E402 - the tests' Pendulum world

RUNS = [  # (world, algo, the budget's setting)
    ("specs/paper/case1.yaml", "dqn", {"episodes": 300}),
    ("specs/paper/case3-office.yaml", "drqn", {"episodes": 200}),
    ("specs/paper/case1.yaml", "sb3-dqn", {"sb3.steps": 8_000}),
    ("specs/paper/case1.yaml", "sb3-ppo", {"sb3.steps": 8_192}),
    ("pendulum", "sb3-sac", {"sb3.steps": 1_500}),
    ("pendulum", "sb3-td3", {"sb3.steps": 1_500}),
    ("specs/envs/minigrid-doorkey.yaml", "sb3-ppo", {"sb3.steps": 16_384}),  # the CNN
    ("specs/envs/minigrid-doorkey.yaml", "dqn", {"episodes": 100}),
]


def rate(world: Path, algo: str, budget: dict[str, int], device: str, where: Path) -> float:
    """Env steps per second of one run's training."""
    config, _ = config_for(open_world(world), {"algo": algo, "device": device, **budget})
    result = train(world, config, where)
    summary = json.loads((where / "summary.json").read_text())
    return float(summary["steps"]) / max(result.seconds, 1e-9)


def main() -> None:
    warnings.filterwarnings("ignore")
    quick = "--quick" in sys.argv
    only = [a.removeprefix("--only=") for a in sys.argv if a.startswith("--only=")]
    print("| world | algo | cpu steps/s | cuda steps/s | cpu / cuda |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        pendulum = Path(tmp) / "pendulum.yaml"
        pendulum.write_text(PENDULUM)
        for world, algo, budget in RUNS:
            if only and not any(o in f"{world}:{algo}" for o in only):
                continue
            path = pendulum if world == "pendulum" else ROOT / world
            if quick:
                budget = {k: max(v // 10, 256) for k, v in budget.items()}
            figures = {
                device: rate(path, algo, budget, device, Path(tmp) / f"{algo}-{device}")
                for device in ("cpu", "cuda")
            }
            ratio = figures["cpu"] / figures["cuda"]
            print(f"| {path.stem} | {algo} | {figures['cpu']:,.0f} | {figures['cuda']:,.0f} | "
                  f"{ratio:.2f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
