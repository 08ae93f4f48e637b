"""Distances through free space (mitlc/labels/occupancy.py, mitlc/labels/geodesic.py): the
wavefront distances on hand-made mazes, the occupancy read from gymnasium-robotics' mazes and
MiniGrid's grids against the envs themselves, a world file's ``occupancy:`` section, and the
task wrapper's ``info["distances"]`` on a maze."""

from __future__ import annotations

import math
import textwrap
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.gym import TaskWrapper
from mitlc.gym.guide import StraightDistanceWarning
from mitlc.labels.geodesic import maze_occupancy, minigrid_occupancy, plane_occupancy
from mitlc.labels.occupancy import Occupancy, OccupancyError, Target
from mitlc.syntax import parse
from mitlc.worlds import WorldError
from mitlc.worlds.door import open_world

U_MAZE = [[0, 0, 0], [1, 1, 0], [0, 0, 0]]
"""A U: the straight line from the top-left cell to the bottom-left one crosses the wall."""


def test_u_maze_geodesic_is_long_where_the_straight_line_is_short() -> None:
    grid = Occupancy.from_rows(U_MAZE, 1.0, (0.0, 0.0))
    region = Target.box((0.0, 0.0), (1.0, 1.0))  # the bottom-left cell
    field = grid.field(region)
    start = np.array([0.5, 2.5])  # the top-left cell's centre
    assert region.straight(start) == 1.5
    # centre to centre, no corner of the wall cut: right 2, down 2, left 2
    assert field.at(start) == pytest.approx(6.0)
    assert field.at([2.5, 0.5]) == pytest.approx(2.0)  # the bottom of the U's right arm
    assert field.at([2.5, 1.5]) == pytest.approx(3.0)  # its middle
    assert field.at([2.5, 1.2]) == pytest.approx(2.0 + 0.7)  # varies inside a cell
    assert field.at([0.5, 0.5]) == 0.0
    # 4-connected: the same here (no diagonal step is legal next to the wall)
    four = Occupancy.from_rows(U_MAZE, 1.0, (0.0, 0.0), connectivity=4)
    assert four.field(region).at(start) == pytest.approx(6.0)
    # finer cells: closer to the shortest path around the wall's corners (3.58)
    fine = Occupancy.from_rows(U_MAZE, 1.0, (0.0, 0.0), refine=8).field(region)
    assert fine.at(start) == pytest.approx(3.978, abs=1e-3) and fine.at(start) > 3.58


def test_positions_in_walls_and_outside_take_the_nearest_free_cell() -> None:
    grid = Occupancy.from_rows(U_MAZE, 1.0, (0.0, 0.0))
    field = grid.field(Target.box((0.0, 0.0), (1.0, 1.0)))
    # in the wall cell (0, 1) (row 1, column 0): the nearest free cell is the one above or
    # below; below is the region's own cell (distance 0) at 1 m
    assert field.at([0.5, 1.5]) == pytest.approx(1.0)
    # outside the map, left of the top-left cell: its distance plus the gap to its centre
    assert field.at([-1.5, 2.5]) == pytest.approx(6.0 + 2.0)


def test_a_closed_region_is_unreachable_and_a_disc_overlaps_its_cells() -> None:
    walled = Occupancy.from_rows([[0, 1, 0]], 1.0, (0.0, 0.0))
    field = walled.field(Target.point((2.5, 0.5)))
    assert math.isinf(field.at([0.5, 0.5])) and field.at([2.2, 0.5]) == pytest.approx(0.3)
    disc = Occupancy.from_rows([[0, 0, 0, 0]], 1.0, (0.0, 0.0)).field(Target.disc((3.5, 0.5), 0.6))
    assert disc.distance[2, 0] < math.inf and disc.distance[1, 0] == pytest.approx(1.0 + 0.4)


def test_bad_grids_are_refused() -> None:
    with pytest.raises(OccupancyError, match="cell_size"):
        Occupancy.from_rows(U_MAZE, 0.0, (0.0, 0.0))
    with pytest.raises(OccupancyError, match="connectivity"):
        Occupancy.from_rows(U_MAZE, 1.0, (0.0, 0.0), connectivity=6)


# -- gymnasium-robotics' mazes ------------------------------------------------------------------


def _point_maze(**kwargs: Any) -> Any:
    gymnasium_robotics = pytest.importorskip("gymnasium_robotics")
    gym.register_envs(gymnasium_robotics)
    return gym.make("PointMaze_Medium-v3", **kwargs)


def test_point_maze_cells_are_where_the_env_puts_the_ball() -> None:
    env = _point_maze()
    maze = env.unwrapped.maze
    grid = maze_occupancy(maze)
    refine = 4
    assert grid.shape == (maze.map_width * refine, maze.map_length * refine)
    free = [(i, j) for i, row in enumerate(maze.maze_map) for j, v in enumerate(row) if v != 1]
    for k, (row, col) in enumerate(free):
        obs, _ = env.reset(seed=k, options={"reset_cell": np.array([row, col])})
        ball = obs["achieved_goal"]
        i, j = grid.cell_of(ball)
        assert (i // refine, maze.map_length - 1 - j // refine) == (col, row)
        assert tuple(maze.cell_xy_to_rowcol(ball)) == (row, col)
        assert grid.free_at(ball) and grid.free_at(maze.cell_rowcol_to_xy(np.array([row, col])))
    walls = [(i, j) for i, row in enumerate(maze.maze_map) for j, v in enumerate(row) if v == 1]
    for row, col in walls:
        assert not grid.free_at(maze.cell_rowcol_to_xy(np.array([row, col])))
    env.close()


MAZE_FILE = Path(__file__).parent.parent / "specs" / "envs" / "pointmaze-medium.yaml"


def test_wrapper_distances_are_geodesic_on_a_maze() -> None:
    world = open_world(MAZE_FILE)
    automaton = translate(parse(world.spec, world.spec_source))
    found = {}
    for occupancy in ("auto", "none"):
        env = world.task_env(automaton, potential=0.0, occupancy=occupancy)
        _, info = env.reset(seed=0)
        found[occupancy] = info["distances"]
        env.close()
    a, b = found["auto"], found["none"]
    # b (bottom-right) from the start (top-left): around the walls, far longer than straight
    assert b[1] == pytest.approx(6.67, abs=0.01) and a[1] > b[1] + 0.7
    assert a[0] >= b[0]
    env = world.task_env(automaton, potential=0.0)
    assert env.unwrapped is not None and env._guide.geodesic.source.name == "maze_map"
    obs, info = env.reset(seed=1)
    for _ in range(20):  # the geodesic is never shorter than the straight line
        obs, _, terminated, truncated, info = env.step(env.action_space.sample())
        ball = obs["env"]["achieved_goal"]
        assert info["distances"][1] >= np.hypot(*(ball - [2.5, -2.5])) - 0.4 - 1e-9
        if terminated or truncated:
            break
    env.close()


# -- MiniGrid ----------------------------------------------------------------------------------


def test_minigrid_walls_block_and_doors_are_free() -> None:
    pytest.importorskip("minigrid")
    env = gym.make("MiniGrid-DoorKey-6x6-v0")
    env.reset(seed=3)
    grid = getattr(env.unwrapped, "grid")  # noqa: B009 (typed as Env)
    occupancy = minigrid_occupancy(grid)
    assert occupancy.shape == (6, 6) and occupancy.connectivity == 4
    for x in range(6):
        for y in range(6):
            cell = grid.get(x, y)
            wall = cell is not None and cell.type == "wall"
            assert occupancy.blocked[x, y] == wall
            assert occupancy.free_at((x, y)) == (not wall)  # agent_pos (x, y) is its cell
    door = next(c for c in grid.grid if c is not None and c.type == "door")
    assert not occupancy.blocked[door.cur_pos[0], door.cur_pos[1]]
    env.close()


def test_minigrid_goal_distance_goes_through_the_door() -> None:
    pytest.importorskip("minigrid")
    labels = {"goal": {"attr": "agent_pos", "equals": [4, 4]}}
    env = TaskWrapper(gym.make("MiniGrid-DoorKey-6x6-v0"), "F[0,50] goal", labels,
                      horizon=60, potential=0.0)  # fmt: skip
    _, info = env.reset(seed=3)
    inner: Any = env.unwrapped
    x, y = inner.agent_pos
    door = next(c for c in inner.grid.grid if c is not None and c.type == "door")
    dx, dy = door.cur_pos
    through = abs(x - dx) + abs(y - dy) + abs(4 - dx) + abs(4 - dy)  # 4-connected via the door
    assert info["distances"][0] == pytest.approx(through)
    assert info["distances"][0] > math.hypot(4 - x, 4 - y)
    env.close()


# -- plane worlds and declared grids ---------------------------------------------------------


def test_plane_obstacles_are_rasterised() -> None:
    class Box:
        low, high = (2.0, 0.0), (3.0, 4.0)

    class Room:
        width, height, obstacles = 5.0, 5.0, (Box(),)

    grid = plane_occupancy(Room())
    assert grid.cell_size == pytest.approx(0.1) and grid.shape == (50, 50)
    assert not grid.free_at((2.5, 1.0)) and grid.free_at((2.5, 4.5)) and grid.free_at((1.95, 1))
    field = grid.field(Target.disc((4.5, 0.5), 0.3))
    assert field.at((0.5, 0.5)) > 2 * 3.5  # up and over the wall, then down


def _world(tmp_path: Path, occupancy: str) -> Path:
    path = tmp_path / "w.yaml"
    path.write_text(textwrap.dedent(f"""\
        env: {{id: CartPole-v1}}
        labels:
          a: {{box: {{index: [0, 2], low: [1.0, 0.0], high: [2.0, 0.1]}}}}
        spec: {{formula: "F[0,10] a"}}
        horizon: 20
        occupancy: {occupancy}
        """))  # fmt: skip
    return path


@pytest.mark.parametrize(
    ("occupancy", "where"),
    [
        ("{cells: [[0, 2]], cell_size: 1, origin: [0, 0]}", r"occupancy\.cells\[0\]\[1\]"),
        ("{cells: [[0, 1]], cell_size: -1, origin: [0, 0]}", r"occupancy\.cell_size"),
        ("{cells: [[0, 1]], cell_size: 1, origin: [0]}", r"occupancy\.origin\[1\]"),
        ("{cells: [[0, 1], [0]], cell_size: 1, origin: [0, 0]}", r"occupancy\.cells\[1\]: a row"),
        ("{cells: [[0]], cell_size: 1, origin: [0, 0], size: 3}", r"occupancy\.size"),
        ("straight", r"occupancy: expected a mapping"),
    ],
)
def test_occupancy_errors_name_the_field(tmp_path: Path, occupancy: str, where: str) -> None:
    with pytest.raises(WorldError, match=where):
        open_world(_world(tmp_path, occupancy))


def test_a_declared_occupancy_reaches_the_wrapper(tmp_path: Path) -> None:
    world = open_world(
        _world(tmp_path, "{cells: [[0, 0], [0, 0]], cell_size: 5, origin: [-5, -5]}")
    )
    automaton = translate(parse(world.spec, world.spec_source))
    with warnings.catch_warnings():
        warnings.simplefilter("error", StraightDistanceWarning)
        env = world.task_env(automaton, potential=1.0)
    assert env._guide.geodesic.source.name == "declared"
    _, info = env.reset(seed=0)
    assert np.isfinite(info["distances"][0])
    env.close()


def test_straight_lines_are_noted_where_nothing_is_known() -> None:
    labels = {"a": {"box": {"index": [0, 2], "low": [1.0, 0.0], "high": [2.0, 0.1]}}}
    with pytest.warns(StraightDistanceWarning, match="straight lines"):
        TaskWrapper(gym.make("CartPole-v1"), "F[0,10] a", labels, horizon=20, potential=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StraightDistanceWarning)
        TaskWrapper(gym.make("CartPole-v1"), "F[0,10] a", labels, horizon=20, potential=1.0,
                    occupancy="none")  # fmt: skip


PLANE = Path(__file__).parent.parent / "specs" / "continuous" / "case1.yaml"


def test_a_plane_world_measures_around_its_obstacles() -> None:
    world = open_world(PLANE)
    automaton = translate(parse(world.spec, world.spec_source))
    env = world.task_env(automaton, potential=0.0)
    assert env._guide.geodesic.source.name == "plane obstacles"
    _, info = env.reset(seed=0, options={"position": [3.5, 2.5]})  # right of the obstacle
    b = world.propositions.index("b")
    straight = math.hypot(3.5 - 1.0, 2.5 - 2.0)  # to the corner (1, 2) of b, across it
    around = math.hypot(0.5, 0.5) + 2.0  # by the obstacle's corner (3, 2)
    assert around <= info["distances"][b] < around + 0.2 and straight < around
    _, info = env.reset(seed=0, options={"position": [4.5, 4.5]})  # in sight of a
    # straight 0.5; the grid's own error is within a cell (0.1 m here)
    assert 0.5 <= info["distances"][world.propositions.index("a")] <= 0.5 + 0.1
    env.close()


def test_only_the_forms_over_the_maps_positions_are_geodesic() -> None:
    env = _point_maze()
    labels = {
        "fast": {"box": {"key": "observation", "index": [2, 3], "low": [1, 1], "high": [2, 2]}},
        "b": {"disc": {"key": "achieved_goal", "index": [0, 1], "center": [2.5, -2.5],
                       "radius": 0.4}},
    }  # fmt: skip
    wrapper = TaskWrapper(env, "F[0,50] (fast | b)", labels, horizon=60, potential=0.0)
    obs, info = wrapper.reset(seed=0, options={"reset_cell": np.array([1, 1])})  # top-left
    at = {p: info["distances"][i] for i, p in enumerate(wrapper.automaton.propositions)}
    velocity = obs["env"]["observation"][2:]
    straight = math.hypot(*np.maximum(np.array([1.0, 1.0]) - velocity, 0.0))
    assert at["fast"] == pytest.approx(straight)  # a velocity: straight
    ball = obs["env"]["achieved_goal"]
    assert at["b"] > math.hypot(*(ball - [2.5, -2.5])) - 0.4 + 0.7  # around the walls
    wrapper.close()
