"""Continuous worlds (``plane:``): the motion and sensor models against their definitions
(moments of many seeded samples, and exact cases without noise), gymnasium's checker on the
env and on its task, the one-line error of each bad file through ``mitlc check``, the shipped
worlds (faithful to their grids, runnable), and their figures."""

from __future__ import annotations

import math
import subprocess
import sys
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml
from gymnasium.utils.env_checker import check_env
from matplotlib.figure import Figure
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.learn.plots.plane import plane_figure
from mitlc.worlds import WorldError, load_world, read_world_file
from mitlc.worlds.grid import HEADING, check
from mitlc.worlds.load import load_plane_world, read_any_world_file, read_world
from mitlc.worlds.plane import PlaneWorld
from mitlc.worlds.plane_env import PlaneEnv, PositionLabels, make_plane_env, plane_task
from mitlc.worlds.plane_schema import PlaneWorldFile
from tests.conftest import ROOT

CONTINUOUS = ROOT / "specs" / "continuous"
SHIPPED = {name: CONTINUOUS / f"{name}.yaml" for name in ("case1", "case2", "case3-office")}
GRIDS = {name: ROOT / "specs" / "paper" / f"{name}.yaml" for name in SHIPPED}
SAMPLES = 20_000

BASE: dict[str, Any] = {
    "name": "plane",
    "plane": {
        "room": {"width": 5.0, "height": 5.0},
        "start": [4.5, 0.5],
        "actions": {"headings": ["up", "down", "left", "right"], "stay": True, "step": 1.0},
        "noise": {"std": 0.1},
        "obstacles": [
            {"box": {"low": [2.0, 2.0], "high": [3.0, 3.0]}},
            {"disc": {"center": [1.5, 3.5], "radius": 0.4}},
        ],
    },
    "labels": {
        "a": {"box": {"low": [3.0, 4.0], "high": [4.0, 5.0]}},
        "b": [{"disc": {"center": [0.5, 1.5], "radius": 0.5}}],
    },
    "spec": {"formula": "(!a U[5,10] a) & (!b U[15,20] b)"},
    "horizon": 30,
}


BASE_BOX = {"low": [2.0, 2.0], "high": [3.0, 3.0]}


def write(tmp_path: Path, data: dict[str, Any], name: str = "world.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def plane(tmp_path: Path, **changes: Any) -> PlaneWorld:
    """The base world with ``changes`` to its ``plane:`` fields."""
    return load_plane_world(write(tmp_path, {**BASE, "plane": {**BASE["plane"], **changes}}))


def open_room(tmp_path: Path, noise: float = 0.1, sensor: float | None = None) -> PlaneWorld:
    """A 100 m room without obstacles, headings up, down, left, right and 30 degrees."""
    changes: dict[str, Any] = {
        "room": {"width": 100.0, "height": 100.0},
        "start": [50.0, 50.0],
        "actions": {"headings": ["up", "down", "left", "right", 30], "step": 1.0},
        "noise": {"std": noise},
        "obstacles": [],
    }
    if sensor is not None:
        changes["sensor"] = {"std": sensor}
    data = {**BASE, "plane": changes, "labels": {"a": {"box": {"low": [0, 0], "high": [1, 1]}}}}
    data["spec"] = {"formula": "F a"}
    return load_plane_world(write(tmp_path, data))


def checked(env: gym.Env[Any, Any]) -> None:
    """gymnasium's ``check_env``, every warning an error but the one about a wrapper."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", message=".*different from the unwrapped")
        warnings.filterwarnings("ignore", message=".*Not able to test alternative render")
        check_env(env)


def moments(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return samples.mean(axis=0), np.cov(samples.T)


def assert_gaussian(samples: np.ndarray, mean: tuple[float, float], std: float) -> None:
    """Mean within 4 standard errors, covariance std^2 I within 4 standard errors of the
    sample variances (sigma^2 sqrt(2/n)) and covariance (sigma^2 / sqrt(n))."""
    n = len(samples)
    m, cov = moments(samples)
    assert np.all(np.abs(m - np.asarray(mean)) <= 4 * std / math.sqrt(n)), (m, mean)
    var = std * std
    assert abs(cov[0, 0] - var) <= 4 * var * math.sqrt(2 / n), cov
    assert abs(cov[1, 1] - var) <= 4 * var * math.sqrt(2 / n), cov
    assert abs(cov[0, 1]) <= 4 * var / math.sqrt(n), cov


# --- the motion model ----------------------------------------------------------------------------


@pytest.mark.parametrize("action", ["up", "left", "30deg"])
def test_a_move_is_the_heading_plus_gaussian_noise(tmp_path: Path, action: str) -> None:
    world = open_room(tmp_path, noise=0.1)
    env = PlaneEnv(world)
    a = world.actions.index(action)
    start = (50.0, 50.0)
    env.reset(seed=7, options={"position": start})
    moved = np.empty((SAMPLES, 2))
    for i in range(SAMPLES):
        env.reset(options={"position": start})
        _, _, terminated, truncated, info = env.step(a)
        moved[i] = info["position"] - np.asarray(start)
        assert not terminated and not truncated
    angle = math.radians({"up": 90, "left": 180, "30deg": 30}[action])
    assert_gaussian(moved, (math.cos(angle), math.sin(angle)), 0.1)


def test_stay_is_certain(tmp_path: Path) -> None:
    world = open_room(tmp_path, noise=0.5)
    env = PlaneEnv(world)
    obs, info = env.reset(seed=0, options={"position": (10.25, 20.5)})
    for _ in range(100):
        obs, reward, _, _, info = env.step(world.actions.index("stay"))
        assert tuple(info["position"]) == (10.25, 20.5)
        assert obs.tolist() == [10.25, 20.5] and obs.dtype == np.float32
        assert reward == 0.0


def test_without_noise_moves_are_exact_and_blocked_moves_stay(tmp_path: Path) -> None:
    world = plane(tmp_path, noise={"std": 0.0}, start=[4.5, 0.5])
    rng = np.random.default_rng(0)
    up, down, left, right = (world.actions.index(n) for n in ("up", "down", "left", "right"))
    assert world.move((4.5, 0.5), up, rng) == (4.5, 1.5)
    assert world.move((4.5, 0.5), right, rng) == (4.5, 0.5)  # out of the room
    assert world.move((4.5, 0.5), down, rng) == (4.5, 0.5)  # out of the room
    assert world.move((4.5, 4.9), up, rng) == (4.5, 4.9)  # would end past the edge
    assert world.move((3.5, 2.5), left, rng) == (3.5, 2.5)  # into the box obstacle
    assert world.move((1.5, 2.5), up, rng) == (1.5, 2.5)  # into the disc obstacle
    assert world.move((0.5, 4.5), right, rng) == (1.5, 4.5)  # past the disc, not touching
    assert world.move((1.5, 4.5), down, rng) == (1.5, 4.5)  # into the disc from above
    assert world.move((3.2, 1.5), up, rng) == (3.2, 2.5)
    assert world.move((3.0, 1.5), up, rng) == (3.0, 1.5)  # touches the box's edge: closed


def test_a_thin_wall_is_not_jumped_over(tmp_path: Path) -> None:
    wall = {"box": {"low": [2.45, 0.0], "high": [2.55, 5.0]}}
    world = plane(tmp_path, noise={"std": 0.0}, obstacles=[wall], start=[2.0, 0.5])
    right = world.actions.index("right")
    assert world.move((2.0, 0.5), right, np.random.default_rng(0)) == (2.0, 0.5)


def test_the_move_reward_is_for_every_action_but_stay(tmp_path: Path) -> None:
    data = {**BASE, "reward": {"move": -5}}
    env = PlaneEnv(load_plane_world(write(tmp_path, data)))
    env.reset(seed=0)
    rewards = [env.step(a)[1] for a in range(env.action_space.n)]
    assert rewards == [-5.0, -5.0, -5.0, -5.0, 0.0]


def test_a_start_region_is_sampled_uniformly(tmp_path: Path) -> None:
    world = plane(tmp_path, start={"disc": {"center": [4.0, 1.0], "radius": 0.5}})
    env = PlaneEnv(world)
    env.reset(seed=3)
    points = np.array([env.reset()[1]["position"] for _ in range(4000)])
    assert np.all(np.hypot(points[:, 0] - 4.0, points[:, 1] - 1.0) <= 0.5)
    # uniform in a disc of radius r: each coordinate has variance r^2 / 4
    assert np.all(np.abs(points.mean(axis=0) - [4.0, 1.0]) <= 4 * 0.25 / math.sqrt(4000))


# --- the sensor model ----------------------------------------------------------------------------


def test_the_sensor_reads_the_position_plus_gaussian_noise(tmp_path: Path) -> None:
    world = open_room(tmp_path, noise=0.1, sensor=0.3)
    assert world.is_pomdp
    env = PlaneEnv(world)
    true = (40.0, 60.0)
    env.reset(seed=11, options={"position": true})
    seen = np.empty((SAMPLES, 2))
    for i in range(SAMPLES):
        obs, info = env.reset(options={"position": true})
        assert tuple(info["position"]) == true
        seen[i] = obs
    assert_gaussian(seen, true, 0.3)


def test_the_sensor_is_clipped_to_the_room(tmp_path: Path) -> None:
    world = plane(tmp_path, sensor={"std": 5.0})
    env = PlaneEnv(world)
    env.reset(seed=0)
    for _ in range(200):
        obs = env.step(env.action_space.sample())[0]
        assert env.observation_space.contains(obs)


def test_labels_read_the_true_position_in_a_pomdp(tmp_path: Path) -> None:
    world = plane(tmp_path, sensor={"std": 0.3})
    labels = PositionLabels.of(world)
    far = np.array([0.0, 0.0], dtype=np.float32)
    assert labels(far, {"position": np.array([3.5, 4.5])}) == {"a"}
    assert labels(far, {"position": np.array([0.5, 1.5])}) == {"b"}
    reader = labels.letter_reader(("a", "b"))
    assert reader(far, {"position": np.array([0.5, 1.5])}) == 0b10


# --- gymnasium -----------------------------------------------------------------------------------


@pytest.mark.parametrize("sensor", [None, {"std": 0.3}])
def test_check_env_on_the_env_and_on_its_task(tmp_path: Path, sensor: Any) -> None:
    world = plane(tmp_path, sensor=sensor)
    checked(PlaneEnv(world, render_mode="ansi"))
    checked(plane_task(world))
    checked(plane_task(world, flatten=True))


# --- bad worlds ----------------------------------------------------------------------------------

BAD: dict[str, tuple[dict[str, Any], dict[str, Any], str]] = {
    # name: (changes to plane:, changes to the file, the expected line after "file:line:col: ")
    "label outside the room": (
        {},
        {"labels": {"a": {"box": {"low": [3, 4], "high": [6, 5]}}, "b": BASE["labels"]["b"]}},
        "labels.a: the box from [3, 4] to [6, 5] is not inside the 5 m x 5 m room",
    ),
    "obstacle outside the room": (
        {"obstacles": [{"disc": {"center": [4.8, 4.0], "radius": 0.5}}]},
        {},
        "plane.obstacles[0]: the disc of radius 0.5 around [4.8, 4] is not inside the 5 m x 5 m",
    ),
    "obstacle overlapping the start region": (
        {"start": {"box": {"low": [2.5, 0.5], "high": [3.5, 2.5]}}},
        {},
        "plane.start: the start region overlaps the obstacle plane.obstacles[0]",
    ),
    "start inside an obstacle": (
        {"start": [1.5, 3.5]},
        {},
        "plane.start: the start [1.5, 3.5] is inside the obstacle plane.obstacles[1]",
    ),
    "start outside the room": (
        {"start": [5.5, 0.5]},
        {},
        "plane.start: the start [5.5, 0.5] is outside the 5 m x 5 m room",
    ),
    "negative noise": (
        {"noise": {"std": -0.1}},
        {},
        "plane.noise.std: expected a non-negative number, got -0.1",
    ),
    "negative sensor": (
        {"sensor": {"std": -1}},
        {},
        "plane.sensor.std: expected a non-negative number, got -1",
    ),
    "negative radius": (
        {},
        {"labels": {"a": BASE["labels"]["a"], "b": {"disc": {"center": [1, 1], "radius": -0.5}}}},
        "labels.b.disc.radius: expected a positive number, got -0.5",
    ),
    "low above high": (
        {"obstacles": [{"box": {"low": [3.0, 2.0], "high": [2.0, 3.0]}}]},
        {},
        "plane.obstacles[0].box: low [3, 2] is above high [2, 3] in x (3 > 2)",
    ),
    "unknown heading": (
        {"actions": {"headings": ["up", "dwn"]}},
        {},
        "plane.actions.headings[1]: unknown heading: expected up, down, left, right or an angle "
        "in degrees, got \"dwn\"; did you mean 'down'?",
    ),
    "heading twice": (
        {"actions": {"headings": ["up", 90]}},
        {},
        "plane.actions.headings[1]: heading 90 is the direction of plane.actions.headings[0] again",
    ),
    "empty actions": (
        {"actions": {"headings": [], "stay": True}},
        {},
        "plane.actions.headings: expected at least 1 item, got []",
    ),
    "zero step": (
        {"actions": {"step": 0}},
        {},
        "plane.actions.step: expected a positive number, got 0",
    ),
    "unknown plane field": (
        {"obstacle": []},
        {},
        "plane.obstacle: unknown field; did you mean 'obstacles'?",
    ),
    "unknown region field": (
        {"obstacles": [{"box": {"low": [2, 2], "high": [3, 3], "hihg": [3, 3]}}]},
        {},
        "plane.obstacles[0].box.hihg: unknown field; did you mean 'high'?",
    ),
    "unknown region kind": (
        {"obstacles": [{"square": {"low": [2, 2]}}]},
        {},
        "plane.obstacles[0]: expected a region {box: {low: [x, y], high: [x, y]}} or {disc: ",
    ),
    "bad point in a list of regions": (
        {},
        {
            "labels": {
                "a": BASE["labels"]["a"],
                "b": [BASE["labels"]["b"][0], {"box": {"low": [1], "high": [2, 2]}}],
            }
        },
        "labels.b[1].box.low: expected a point [x, y] of two numbers, got [1]",
    ),
    "box and disc": (
        {"obstacles": [{"disc": {"center": [1, 1], "radius": 0.2}, "box": BASE_BOX}]},
        {},
        "plane.obstacles[0].disc: a region has one of box: and disc:, not both",
    ),
    "no region": (
        {},
        {"labels": {"a": [], "b": BASE["labels"]["b"]}},
        "labels.a: expected at least 1 item, got []",
    ),
    "unknown top-level field": (
        {},
        {"horizn": 30},
        "horizn: unknown field; did you mean 'horizon'?",
    ),
    "grid beside plane": (
        {},
        {"grid": {"rows": 5, "cols": 5}},
        "grid: a world has one of grid:, env: or plane:, not two",
    ),
    "unlabelled proposition": (
        {},
        {"spec": {"formula": "F c"}},
        "spec: proposition 'c' labels no region (labels: a, b)",
    ),
}


@pytest.mark.parametrize("case", BAD)
def test_a_bad_world_is_one_line_with_the_field_path(case: str, tmp_path: Path) -> None:
    in_plane, in_file, expected = BAD[case]
    data = {**BASE, "plane": {**BASE["plane"], **in_plane}, **in_file}
    path = write(tmp_path, data)
    with pytest.raises(WorldError) as info:
        load_plane_world(path)
    text = info.value.render()
    assert len(text.splitlines()) == 1, text
    assert text.startswith(f"{path}:"), text
    assert text.split(": ", 1)[1].startswith(expected), (text, expected)
    result = CliRunner().invoke(app, ["check", str(path)])
    assert result.exit_code == 1
    assert "Traceback" not in result.output
    assert result.output.strip().splitlines() == [text]


def test_check_refuses_a_plane_world_in_one_line(tmp_path: Path) -> None:
    path = write(tmp_path, BASE)
    result = CliRunner().invoke(app, ["check", str(path)])
    assert result.exit_code == 1 and "Traceback" not in result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"{path}:2:1: plane: a continuous world is not a finite world")
    with pytest.raises(WorldError, match="plane: this is a continuous world, where a grid"):
        read_world_file(path)
    with pytest.raises(WorldError, match="this is a grid world, where a continuous world"):
        load_plane_world(GRIDS["case1"])
    assert isinstance(read_any_world_file(path), PlaneWorldFile)
    assert read_world(path).kind == "plane" and read_world(GRIDS["case1"]).kind == "grid"


def test_the_worlds_package_does_not_import_gymnasium() -> None:
    code = (
        "import sys; import mitlc.worlds, mitlc.worlds.plane, mitlc.worlds.load; "
        "assert 'gymnasium' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


# --- the shipped worlds --------------------------------------------------------------------------


@pytest.mark.parametrize("name", SHIPPED)
def test_a_shipped_world_is_its_grid_in_metres(name: str) -> None:
    """The same task and horizon; every grid cell's centre has the cell's labels; and without
    noise, a move from a free cell's centre succeeds exactly where the grid's intended move
    does, to the next cell's centre (walls, doors and blocked cells included)."""
    continuous = load_plane_world(SHIPPED[name])
    grid_file = read_world_file(GRIDS[name])
    grid = load_world(GRIDS[name])
    assert (continuous.spec, continuous.horizon) == (grid.spec, grid.horizon)
    assert continuous.is_pomdp == grid.is_pomdp
    layout, _ = check(grid_file)
    rows = layout.rows

    def centre(cell: tuple[int, int]) -> tuple[float, float]:
        return (cell[1] + 0.5, rows - 1 - cell[0] + 0.5)

    labels = PositionLabels.of(continuous)
    exact = replace(continuous, noise=0.0)
    rng = np.random.default_rng(0)
    for r in range(rows):
        for c in range(layout.cols):
            here = centre((r, c))
            assert exact.free(here) == layout.free((r, c)), (r, c)
            if not layout.free((r, c)):
                continue
            expected = {p for p, cells in grid_file.labels.items() if (r, c) in cells}
            assert labels(None, {"position": np.array(here)}) == expected, (r, c)
            for action, direction in HEADING.items():
                target = layout.step((r, c), direction)
                moved = exact.move(here, exact.actions.index(action), rng)
                assert moved == (here if target is None else centre(target)), (r, c, action)
    assert centre(grid_file.start) == continuous.start


@pytest.mark.parametrize("name", SHIPPED)
def test_a_shipped_world_runs_to_its_horizon(name: str) -> None:
    env = make_plane_env(SHIPPED[name])
    env.action_space.seed(0)
    horizon = env.unwrapped.world.horizon
    for episode in range(5):
        obs, info = env.reset(seed=episode)
        assert env.observation_space.contains(obs)
        steps, done = 0, False
        while not done:
            obs, _, terminated, truncated, info = env.step(env.action_space.sample())
            steps += 1
            done = terminated or truncated
        assert steps <= horizon and info["step"] == steps
        assert truncated == (steps == horizon and not terminated)
    stay = env.unwrapped.world.actions.index("stay")
    env.reset(seed=0)
    steps = 0
    while True:  # staying at the start: the task is violated when its first window closes
        _, _, terminated, truncated, info = env.step(stay)
        steps += 1
        if terminated or truncated:
            break
    assert info["verdict"] == "violated" or steps == horizon


@pytest.mark.parametrize("name", SHIPPED)
def test_a_shipped_world_is_drawn(name: str, tmp_path: Path) -> None:
    env = make_plane_env(SHIPPED[name])
    trajectories = []
    for episode in range(2):
        _, info = env.reset(seed=episode)
        points = [tuple(info["position"])]
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(env.action_space.sample())
            points.append(tuple(info["position"]))
            done = terminated or truncated
        trajectories.append(points)
    world = env.unwrapped.world
    figure = plane_figure(world, trajectories, world.name)
    assert isinstance(figure, Figure)
    png = tmp_path / f"{name}.png"
    figure.savefig(png, format="png", dpi=50)
    assert png.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
