"""Figures of a team world's run (``mitlc.learn.plots.team``): every robot's path on one map and
an animated GIF of a greedy episode, on a tiny tabular Q run trained and drawn through the CLI."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

pytest.importorskip("matplotlib")

from PIL import Image, ImageSequence
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.learn.evaluation.trajectories import Trajectory, robot_cells, rollouts
from mitlc.learn.plots import (
    AUTOMATON,
    DPI,
    EPISODE,
    GRID_SIZE,
    LEARNING_CURVE,
    TRAJECTORIES,
    plot_run,
)
from mitlc.learn.plots.team import GIF_FRAMES, episode_gif, frame_positions
from mitlc.learn.run import load_learner
from mitlc.worlds.model import World
from tests.conftest import ROOT

runner = CliRunner()
HORIZON = 8
TEAM = f"""
name: two-on-three
grid: {{rows: 3, cols: 3}}
labels: {{a: [[0, 2]], b: [[2, 0]]}}
actions: [up, down, left, right, stay]
motion: {{intended: 1.0, sideways: 0.0}}
robots:
  robot_0: {{start: [0, 0]}}
  robot_1: {{start: [2, 2]}}
collisions: {{label: collide, block: false}}
spec: {{formula: "F[0,6] a_robot_0 & F[0,6] b_robot_1 & G !collide"}}
reward: {{satisfied: 100, accept: 100, violated: 0, move: 0}}
horizon: {HORIZON}
discount: 0.99
"""
TRAIN = ["--episodes", "1500", "--set", "q.num_envs=64", "--quiet", "--no-eval"]


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny tabular Q run of two robots on a 3x3 grid."""
    folder = tmp_path_factory.mktemp("team")
    world = folder / "team.yaml"
    world.write_text(TEAM, encoding="utf-8")
    result = runner.invoke(app, ["train", str(world), "--out", str(folder / "run"), *TRAIN])
    assert result.exit_code == 0, result.output
    return folder / "run"


def test_plot_writes_the_team_map_and_an_episode_gif(run: Path, tmp_path: Path) -> None:
    result = runner.invoke(app, ["plot", str(run), "--out", str(tmp_path), "--trajectories", "3"])
    assert result.exit_code == 0, result.output
    names = [LEARNING_CURVE, TRAJECTORIES, EPISODE, AUTOMATON]
    assert result.output.split() == [str(tmp_path / name) for name in names]
    with Image.open(tmp_path / TRAJECTORIES) as png:
        assert png.format == "PNG"
        assert png.size == (round(GRID_SIZE[0] * DPI), round(GRID_SIZE[1] * DPI))
    with Image.open(tmp_path / EPISODE) as gif:
        assert gif.format == "GIF"
        frames = [frame.convert("RGB") for frame in ImageSequence.Iterator(gif)]
        assert 1 < len(frames) <= HORIZON + 1
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries


def test_plotting_twice_gives_the_same_bytes(run: Path, tmp_path: Path) -> None:
    first = plot_run(run, tmp_path / "first", trajectories=2, seed=4)
    second = plot_run(run, tmp_path / "second", trajectories=2, seed=4)
    assert [p.name for p in first] == [LEARNING_CURVE, TRAJECTORIES, EPISODE, AUTOMATON]
    for one, other in zip(first, second, strict=True):
        assert one.read_bytes() == other.read_bytes(), f"{one.name} differs between runs"


def _check_robot_moves(world: World, trajectory: Trajectory) -> None:
    """The per-robot split is ``team.positions`` read along the trajectory; each robot starts
    at its start and moves to the same or an adjacent cell at each position; the joint moves
    are successors under some joint action."""
    team = world.team
    assert team is not None
    split = robot_cells(trajectory, team)
    assert len(split) == team.num_robots == 2
    for r, cells in enumerate(split):
        assert len(cells) == len(trajectory.world_states)
        for s, cell in zip(trajectory.world_states, cells, strict=True):
            assert cell == team.cells[int(team.positions[s, r])] == team.cell_of(s, r)
            assert world.cells[s][2 * r : 2 * r + 2] == cell  # the flat joint tuple agrees
        assert cells[0] == team.cell_of(world.start, r)
        for (r0, c0), (r1, c1) in itertools.pairwise(cells):
            assert abs(r0 - r1) + abs(c0 - c1) <= 1, f"{team.robots[r]}: {cells}"
    for s, t in itertools.pairwise(trajectory.world_states):
        successors = {
            int(x)
            for a in range(world.num_actions)
            for x in world.transitions.row(s * world.num_actions + a)[0]
        }
        assert t in successors
    assert trajectory.length <= world.horizon


def test_rollouts_split_into_each_robots_walk(run: Path) -> None:
    setting, learner = load_learner(run)
    world = setting.model()[0]
    drawn = rollouts(setting, learner.policy(), 6, seed=2)
    for trajectory in drawn:
        _check_robot_moves(world, trajectory)
    positions = frame_positions(drawn[0])
    assert len(positions) == drawn[0].length + 1 <= HORIZON + 1
    assert [drawn[0].steps[i] for i in positions] == list(range(drawn[0].length + 1))


def test_a_long_episode_is_capped(run: Path) -> None:
    setting, learner = load_learner(run)
    short = rollouts(setting, learner.policy(), 1, seed=0)[0]
    steps = tuple(range(500))
    long = Trajectory(
        world_states=(short.world_states[0],) * 500,
        cells=(short.cells[0],) * 500,
        automaton_states=(0,) * 500,
        steps=steps,
        success=False,
        verdict="pending",
        episode_return=0.0,
    )
    positions = frame_positions(long)
    assert len(positions) <= GIF_FRAMES
    assert positions[0] == 0 and positions[-1] == 499
    assert positions == sorted(set(positions))


def test_a_single_robot_episode_gif(tmp_path: Path) -> None:
    out = tmp_path / "run"
    world = str(ROOT / "specs" / "paper" / "case1.yaml")
    result = runner.invoke(app, ["train", world, "--out", str(out), *TRAIN])
    assert result.exit_code == 0, result.output
    setting, learner = load_learner(out)
    trajectory = rollouts(setting, learner.policy(), 1, seed=1)[0]
    data = episode_gif(setting, trajectory, "case1")
    assert data == episode_gif(setting, trajectory, "case1")
    (tmp_path / "episode.gif").write_bytes(data)
    with Image.open(tmp_path / "episode.gif") as gif:
        assert 1 < sum(1 for _ in ImageSequence.Iterator(gif)) <= setting.model()[0].horizon + 1
