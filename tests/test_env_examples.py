"""The shipped examples of real env packages (``specs/envs/``), each driven through ``mitlc
train``, ``eval`` and ``plot`` from its YAML alone on a tiny budget. A test is skipped only where
its package cannot be imported (``pip install 'mitlc[envs]'`` installs them all; ``make test``
does)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from mitlc.cli import app

ROOT = Path(__file__).resolve().parent.parent
ENVS = ROOT / "specs" / "envs"

EXAMPLES = {
    # file: (the package it imports, settings for a tiny run, eval episodes)
    "cliffwalking.yaml": (None, ["q.episodes=300"], 200),
    "minigrid-doorkey.yaml": ("minigrid", ["sb3.steps=256", "sb3.n_steps=32"], 3),
    "minigrid-empty.yaml": ("minigrid", ["sb3.steps=256", "sb3.n_steps=32"], 3),
    "highway.yaml": ("highway_env", ["dqn.episodes=2", "dqn.warmup_steps=16"], 2),
    "pointmaze.yaml": ("gymnasium_robotics", ["sb3.steps=256"], 2),
    "pointmaze-medium.yaml": ("gymnasium_robotics", ["sb3.steps=256"], 2),
    "pointmaze-large.yaml": ("gymnasium_robotics", ["sb3.steps=256"], 2),
}


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_each_example_trains_evaluates_and_plots_from_its_file(name: str, tmp_path: Path) -> None:
    package, settings, episodes = EXAMPLES[name]
    if package is not None:
        pytest.importorskip(package)
    runner = CliRunner()
    out = tmp_path / "run"
    sets = [arg for s in settings for arg in ("--set", s)]
    trained = runner.invoke(
        app, ["train", str(ENVS / name), "--out", str(out), "--no-eval", "-q", *sets]
    )
    assert trained.exit_code == 0, trained.output
    assert "trained" in trained.output and (out / "summary.json").is_file()
    evaluated = runner.invoke(app, ["eval", str(out), "--episodes", str(episodes), "--json"])
    assert evaluated.exit_code == 0, evaluated.output
    report = json.loads(evaluated.stdout)
    assert report["episodes"] == episodes and 0.0 <= report["success_rate"] <= 1.0
    if name == "cliffwalking.yaml":  # finite: the exact optimum beside the estimate
        assert report["optimum"] == pytest.approx(1.0)
    else:
        assert report["optimum"] is None
    plotted = runner.invoke(app, ["plot", str(out)])
    assert plotted.exit_code == 0, plotted.output
    assert (out / "learning_curve.png").stat().st_size > 1000


def test_every_shipped_example_is_driven_here() -> None:
    assert {path.name for path in ENVS.glob("*.yaml")} == set(EXAMPLES)
