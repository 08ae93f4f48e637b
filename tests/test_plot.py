"""Figures of a run (``mitlc.learn.plots``) and the greedy rollouts they draw
(``mitlc.learn.evaluation.trajectories``), on tiny tabular Q-learning runs of the paper's worlds."""

from __future__ import annotations

import itertools
import re
import struct
from pathlib import Path

import pytest

pytest.importorskip("matplotlib")

from mitlc.learn.config import resolve
from mitlc.learn.evaluation.trajectories import Trajectory, rollouts
from mitlc.learn.plots import (
    AUTOMATON,
    CURVE_SIZE,
    DPI,
    GRID_SIZE,
    LEARNING_CURVE,
    TRAJECTORIES,
    PlotError,
    plot_run,
    read_metrics,
)
from mitlc.learn.run import METRICS, RunError, load_learner, train
from mitlc.worlds.model import World
from tests.conftest import ROOT

WORLDS = {"case1": "case1.yaml", "office": "case3-office.yaml"}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A 2,000-episode tabular Q run of each world."""
    made = {}
    for name, file in WORLDS.items():
        config = resolve(
            {
                "algo": "q",
                "episodes": 2000,
                "log_every": 500,
                "q": {"initial_value": 100, "alpha": 0.3, "alpha_end": 0.01},
            },
            {},
            discount=0.99,
            pomdp=False,
        )
        made[name] = tmp_path_factory.mktemp(name)
        train(fully_observed(ROOT / "specs" / "paper" / file, made[name]), config, made[name])
    return made


def fully_observed(path: Path, directory: Path) -> Path:
    """The world file at ``path`` as an MDP (tabular Q refuses POMDPs), written in
    ``directory``."""
    text = path.read_text(encoding="utf-8")
    text = re.sub(r"(?m)^observation: .*$", "observation: null", text)
    spec = re.search(r"(?m)^spec: (\S+)$", text)
    if spec:  # beside the copy: a world file reads no file outside its folder
        (directory / spec[1]).write_bytes((path.parent / spec[1]).read_bytes())
    copy = directory / f"mdp-{path.name}"
    copy.write_text(text, encoding="utf-8")
    return copy


def png_size(path: Path) -> tuple[int, int]:
    """The width and height in a PNG's header (after checking the signature and IHDR)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path.name} is not a PNG"
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    assert data.endswith(b"IEND\xaeB`\x82"), f"{path.name} is cut short"
    return width, height


def pixels(size: tuple[float, float]) -> tuple[int, int]:
    return round(size[0] * DPI), round(size[1] * DPI)


@pytest.mark.parametrize("name", sorted(WORLDS))
def test_plot_run_writes_three_pngs(runs: dict[str, Path], name: str, tmp_path: Path) -> None:
    written = plot_run(runs[name], tmp_path, trajectories=3, seed=1)
    assert written == [tmp_path / LEARNING_CURVE, tmp_path / TRAJECTORIES, tmp_path / AUTOMATON]
    assert png_size(written[0]) == pixels(CURVE_SIZE)
    assert png_size(written[1]) == pixels(GRID_SIZE)
    width, height = png_size(written[2])
    assert width > 100 and height > 50
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries


def test_plot_run_defaults_to_the_run_directory_and_is_deterministic(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    written = plot_run(runs["office"])
    assert all(path.parent == runs["office"] for path in written)
    again = plot_run(runs["office"], tmp_path)
    for first, second in zip(written, again, strict=True):
        assert first.read_bytes() == second.read_bytes(), f"{first.name} differs between runs"


def _check_moves(world: World, trajectory: Trajectory) -> None:
    """Each position is the start or a successor of the one before under some action (so a
    neighbour or the same cell); steps start at 0 and grow by at most one."""
    assert trajectory.world_states[0] == world.start
    assert trajectory.cells[0] == world.cells[world.start]
    assert trajectory.steps[0] == 0
    for s, t in itertools.pairwise(trajectory.world_states):
        (r0, c0), (r1, c1) = world.cells[s], world.cells[t]
        assert abs(r0 - r1) + abs(c0 - c1) <= 1, f"{world.cells[s]} -> {world.cells[t]}"
        successors = {
            int(x)
            for a in range(world.num_actions)
            for x in world.transitions.row(s * world.num_actions + a)[0]
        }
        assert t in successors
    assert all(0 <= b - a <= 1 for a, b in itertools.pairwise(trajectory.steps))
    assert trajectory.length <= world.horizon
    assert len(trajectory.automaton_states) == len(trajectory.cells)


@pytest.mark.parametrize("name", sorted(WORLDS))
def test_rollouts_walk_the_grid(runs: dict[str, Path], name: str) -> None:
    setting, learner = load_learner(runs[name])
    drawn = rollouts(setting, learner.policy(), 20, seed=3)
    assert len(drawn) == 20
    for trajectory in drawn:
        _check_moves(setting.world, trajectory)
        assert trajectory.verdict in ("satisfied", "violated", "pending")
        if trajectory.verdict == "satisfied":
            assert trajectory.success
        if trajectory.verdict == "violated":
            assert not trajectory.success
        if trajectory.verdict == "pending":
            assert trajectory.length == setting.world.horizon


def test_rollouts_are_deterministic_for_a_seed(runs: dict[str, Path]) -> None:
    setting, learner = load_learner(runs["case1"])
    first = rollouts(setting, learner.policy(), 8, seed=5)
    assert first == rollouts(setting, learner.policy(), 8, seed=5)
    assert rollouts(setting, learner.policy(), 0, seed=5) == []


def test_missing_or_empty_metrics_are_typed_errors(runs: dict[str, Path], tmp_path: Path) -> None:
    for file in runs["case1"].glob("checkpoint*"):
        (tmp_path / file.name).write_bytes(file.read_bytes())
    (tmp_path / "config.json").write_bytes((runs["case1"] / "config.json").read_bytes())
    with pytest.raises(PlotError, match=r"no metrics\.jsonl"):
        plot_run(tmp_path)
    (tmp_path / METRICS).write_text("", encoding="utf-8")
    with pytest.raises(PlotError, match="no metrics yet"):
        plot_run(tmp_path)
    (tmp_path / METRICS).write_text('{"episodes": 10, "success', encoding="utf-8")
    with pytest.raises(RunError):
        read_metrics(tmp_path)
    assert not list(tmp_path.glob("*.png"))


def test_a_run_cut_short_keeps_its_complete_lines(runs: dict[str, Path], tmp_path: Path) -> None:
    lines = (runs["case1"] / METRICS).read_text(encoding="utf-8").splitlines()
    (tmp_path / METRICS).write_text("\n".join([*lines[:2], lines[2][:10]]), encoding="utf-8")
    metrics = read_metrics(tmp_path)
    assert len(metrics.episodes) == 2


def test_not_a_run_directory(tmp_path: Path) -> None:
    with pytest.raises(RunError, match="not a run directory"):
        plot_run(tmp_path)


def test_a_recurring_tasks_rounds_are_read_beside_its_success(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    """A window's ``rounds`` (a patrol's completed rounds per episode) reach the learning curve
    where some window has any; a task without recurrences has none to draw."""
    import json

    from mitlc.learn.plots.common import learning_curve

    lines = (runs["case1"] / METRICS).read_text(encoding="utf-8").splitlines()
    assert read_metrics(runs["case1"]).rounds is None  # case 1's deadlines: no rounds
    rows = [json.loads(line) for line in lines]
    for i, row in enumerate(rows):
        row["rounds"] = 0.5 * i
    (tmp_path / METRICS).write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    metrics = read_metrics(tmp_path)
    assert metrics.rounds is not None and list(metrics.rounds) == [
        0.5 * i for i in range(len(rows))
    ]
    figure = learning_curve(metrics, "patrol")
    assert f"rounds {0.5 * (len(rows) - 1):.2f}" in figure.get_suptitle()
    assert len(figure.axes) == 4  # success, its rounds axis, return, violations
