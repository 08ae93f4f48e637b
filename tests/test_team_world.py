"""Team worlds (mitlc.worlds.team): several robots on a grid as one joint World.

Collisions on hand-worked moves with certain motion, the joint table against the product of the
robots' own grid tables, the exact checker against Storm on random two-robot worlds, the file's
errors at their fields and lines, and the PettingZoo env of the raw team world.
"""

from __future__ import annotations

import json
import random
from pathlib import Path

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.check.drn import storm_label, storm_property, to_drn
from mitlc.check.solve import pmax, pmax_horizon
from mitlc.product.explicit import SATISFIED, build_product
from mitlc.syntax import parse
from mitlc.worlds.grid import Layout, transitions
from mitlc.worlds.kinds.team import load_team_world
from mitlc.worlds.load import WorldError
from mitlc.worlds.model import World
from mitlc.worlds.schema import Motion
from tests.conftest import ROOT

CERTAIN = "{intended: 1.0, sideways: 0.0}"


def team_file(tmp_path: Path, body: str, name: str = "team.yaml") -> Path:
    path = tmp_path / name
    path.write_text(body, encoding="utf-8")
    return path


def row_world(tmp_path: Path, cols: int, starts: list[int], block: bool | None) -> World:
    """A 1 x ``cols`` corridor with certain moves, robots r0, r1, ... at the given columns."""
    robots = "\n".join(f"  r{i}: {{start: [0, {c}]}}" for i, c in enumerate(starts))
    collisions = "" if block is None else f"collisions: {{block: {json.dumps(block)}}}\n"
    body = (
        f"grid: {{rows: 1, cols: {cols}}}\nlabels: {{a: [[0, 0]]}}\nmotion: {CERTAIN}\n"
        f"robots:\n{robots}\n{collisions}spec: {{formula: 'F a'}}\nhorizon: 5\n"
    )
    spec = "F collide" if block is not None else "F a"
    return load_team_world(team_file(tmp_path, body), spec=spec)


def step(world: World, state: int, action: str) -> dict[int, float]:
    """The distribution of the next state under the joint action named ``action``."""
    targets, probs = world.transitions.row(state * world.num_actions + world.actions.index(action))
    return {int(t): float(p) for t, p in zip(targets, probs, strict=True)}


def certain(world: World, state: int, action: str) -> int:
    (target, p), *rest = step(world, state, action).items()
    assert not rest and p == pytest.approx(1.0)
    return target


def cells(world: World, state: int) -> list[tuple[int, int]]:
    assert world.team is not None
    return [world.team.cell_of(state, r) for r in range(world.team.num_robots)]


def collides(world: World, state: int) -> bool:
    return bool(world.letters[state] & (1 << world.propositions.index("collide")))


# --- collisions, hand-worked ------------------------------------------------------------------


def test_same_cell_and_swap_are_labelled(tmp_path: Path) -> None:
    world = row_world(tmp_path, 3, [0, 2], block=False)
    assert world.actions[0] == "up|up" and world.num_actions == 25
    s = world.start
    assert cells(world, s) == [(0, 0), (0, 2)] and not collides(world, s)
    met = certain(world, s, "right|left")
    assert cells(world, met) == [(0, 1), (0, 1)] and collides(world, met)
    # from adjacent cells, a swap: distinct cells, but the step swapped them
    near = world.team.state_of(((0, 0), (0, 1)))  # type: ignore[union-attr]
    swapped = certain(world, near, "right|left")
    assert cells(world, swapped) == [(0, 1), (0, 0)] and collides(world, swapped)
    assert world.team.swapped[swapped]  # type: ignore[union-attr]
    apart = world.team.state_of(((0, 1), (0, 0)))  # type: ignore[union-attr]
    assert apart != swapped and not collides(world, apart)
    # staying after a swap: the same cells, no longer colliding
    assert certain(world, swapped, "stay|stay") == apart
    # one robot moving into the other's cell while it stays
    assert collides(world, certain(world, near, "right|stay"))
    # following: robot 1 leaves the cell robot 0 enters, no collision
    follow = certain(world, near, "right|right")
    assert cells(world, follow) == [(0, 1), (0, 2)] and not collides(world, follow)


def test_block_keeps_colliding_robots_in_place(tmp_path: Path) -> None:
    world = row_world(tmp_path, 3, [0, 2], block=True)
    s = world.start
    assert certain(world, s, "right|left") == s  # both would enter (0, 1)
    near = world.team.state_of(((0, 0), (0, 1)))  # type: ignore[union-attr]
    assert certain(world, near, "right|left") == near  # a swap is blocked
    assert certain(world, near, "right|stay") == near  # into a robot that stays
    follow = certain(world, near, "right|right")  # following is no conflict
    assert cells(world, follow) == [(0, 1), (0, 2)]
    assert not world.letters.any()  # blocking never lets collide hold
    # no joint state has two robots in one cell
    positions = world.team.positions  # type: ignore[union-attr]
    assert (positions[:, 0] != positions[:, 1]).all()


def test_a_chain_of_blocks(tmp_path: Path) -> None:
    """r1 and r2 both want (0, 2) and stay; then r0, moving into r1's cell, stays too."""
    world = row_world(tmp_path, 4, [0, 1, 3], block=True)
    s = world.start
    assert certain(world, s, "right|right|left") == s
    # without the conflict at (0, 2) the whole line moves on
    moved = certain(world, s, "right|right|stay")
    assert cells(world, moved) == [(0, 1), (0, 2), (0, 3)]
    # r2 cannot go right (the edge), so it stays; r1 would enter its cell and stays; r0 would
    # enter r1's cell and stays: a chain of three
    world = row_world(tmp_path, 3, [0, 1, 2], block=True)
    assert certain(world, world.start, "right|right|right") == world.start
    unblocked = row_world(tmp_path, 3, [0, 1, 2], block=False)
    both = certain(unblocked, unblocked.start, "right|right|right")
    assert cells(unblocked, both) == [(0, 1), (0, 2), (0, 2)] and collides(unblocked, both)


def test_a_rotation_is_no_collision(tmp_path: Path) -> None:
    """Three robots going round a 2x2 square, each into the cell the next one leaves."""
    body = (
        f"grid: {{rows: 2, cols: 2}}\nmotion: {CERTAIN}\nrobots:\n"
        "  r0: {start: [0, 0]}\n  r1: {start: [0, 1]}\n  r2: {start: [1, 1]}\n"
        "collisions: {block: true}\nspec: {formula: 'G !collide'}\nhorizon: 4\n"
    )
    world = load_team_world(team_file(tmp_path, body))
    after = certain(world, world.start, "right|down|left")
    assert cells(world, after) == [(0, 1), (1, 1), (1, 0)]


# --- the joint table ---------------------------------------------------------------------------


NOISY = "{intended: 0.7, sideways: 0.15}"
SPREAD = "{intended: 0.8, spread: 0.2}"


@pytest.mark.parametrize("collisions", ["", "collisions: {block: false}\n"])
def test_unblocked_joint_table_is_the_product_of_the_robots(
    tmp_path: Path, collisions: str
) -> None:
    body = (
        "grid: {rows: 3, cols: 3}\nblocked: [[1, 1]]\nwalls: [[[0, 0], [0, 1]]]\n"
        "labels: {a: [[0, 2]]}\n"
        f"motion: {NOISY}\nrobots:\n  r0: {{start: [0, 0]}}\n"
        f"  r1: {{start: [2, 2], motion: {SPREAD}, actions: [left, stay, up]}}\n"
        f"{collisions}spec: {{formula: 'F a'}}\nhorizon: 5\n"
    )
    world = load_team_world(team_file(tmp_path, body))
    team = world.team
    assert team is not None and world.num_actions == 15
    layout = Layout(3, 3, frozenset({(1, 1)}), {((0, 0), "E"): "wall"})
    assert layout.cells() == team.cells
    own = [
        transitions(layout, team.actions[0], Motion(intended=0.7, sideways=0.15)),
        transitions(layout, team.actions[1], Motion(intended=0.8, spread=0.2)),
    ]
    sums = np.add.reduceat(world.transitions.probs, world.transitions.indptr[:-1])
    assert np.abs(sums - 1).max() < 1e-12
    for s in range(world.num_states):
        for a in range(world.num_actions):
            parts = team.split_action(a)
            assert team.joint_action(parts) == a
            mine: dict[tuple[int, ...], float] = {}
            for t, p in step(world, s, world.actions[a]).items():
                key = tuple(int(x) for x in team.positions[t])
                mine[key] = mine.get(key, 0.0) + p  # the swap flag summed out
            rows = [
                own[r].row(int(team.positions[s, r]) * len(team.actions[r]) + parts[r])
                for r in range(2)
            ]
            theirs = {
                (int(t0), int(t1)): float(p0 * p1)
                for t0, p0 in zip(*rows[0], strict=True)
                for t1, p1 in zip(*rows[1], strict=True)
            }
            assert mine.keys() == theirs.keys()
            assert all(abs(mine[k] - theirs[k]) < 1e-12 for k in mine)


def test_propositions_of_robots_and_of_the_team(tmp_path: Path) -> None:
    body = (
        f"grid: {{rows: 2, cols: 2}}\nlabels: {{a: [[0, 1]]}}\nmotion: {CERTAIN}\nrobots:\n"
        "  r0: {start: [0, 0], labels: {home: [[0, 0]], a: [[1, 1]]}}\n  r1: {start: [0, 1]}\n"
        "spec: {formula: 'F a & F a_r0 & F a_r1 & F home_r0'}\nhorizon: 3\n"
    )
    world = load_team_world(team_file(tmp_path, body))
    assert world.propositions == ("a", "a_r0", "a_r1", "home_r0")
    assert world.team is not None
    for s in range(world.num_states):
        c0, c1 = cells(world, s)
        want = {
            "a": (0, 1) in (c0, c1),
            "a_r0": c0 in ((0, 1), (1, 1)),
            "a_r1": c1 == (0, 1),
            "home_r0": c0 == (0, 0),
        }
        got = {p: bool(world.letters[s] >> i & 1) for i, p in enumerate(world.propositions)}
        assert got == want
        assert world.cells[s] == (*c0, *c1)
    with pytest.raises(WorldError) as err:
        load_team_world(team_file(tmp_path, body), spec="F home_r1")
    assert "proposition 'home_r1' labels no cell" in str(err.value)


def test_joint_observations(tmp_path: Path) -> None:
    body = (
        f"grid: {{rows: 2, cols: 3}}\nmotion: {CERTAIN}\nlabels: {{a: [[0, 0]]}}\nrobots:\n"
        "  r0: {start: [0, 0]}\n"
        "  r1: {start: [1, 2], observation: {type: noisy-cell, correct: 0.7}}\n"
        "  r2: {start: [0, 2], observation: {type: local-pattern}}\n"
        "spec: {formula: 'F a'}\nhorizon: 3\n"
    )
    world = load_team_world(team_file(tmp_path, body))
    team, obs = world.team, world.observations
    assert team is not None and obs is not None and world.is_pomdp
    counts = team.observation_counts()
    assert counts[:2] == (6, 6) and len(obs.names) == int(np.prod(counts))
    models = team.observations
    assert models[0] is None and models[1] is not None and models[2] is not None
    for s in range(0, world.num_states, 7):
        ids, probs = obs.model.row(s)
        assert abs(probs.sum() - 1) < 1e-12 and (np.diff(ids) > 0).all()
        for o, p in zip(ids, probs, strict=True):
            parts = team.split_observation(int(o))
            assert parts[0] == team.positions[s, 0]  # robot 0 sees its own cell
            want = 1.0
            for r in (1, 2):
                own_ids, own_probs = models[r].model.row(int(team.positions[s, r]))  # type: ignore[union-attr]
                want *= float(own_probs[list(own_ids).index(parts[r])])
            assert p == pytest.approx(want)
            assert obs.names[o].split("|")[0] == "r{}c{}".format(*team.cell_of(s, 0))


# --- the exact checker against Storm on random two-robot worlds -------------------------------

TEAM_SPECS = [
    "F[{lo},{hi}] a_r0 & F[{lo},{hi}] b_r1",
    "!collide U a_r0",
    "(!a_r0 U[{lo},{hi}] a_r0) & G[0,{hi}] !collide",
    "F (a_r0 & b_r1)",
    "G F a & G !collide",
    "F G b_r1",
    "G (a_r0 -> F b_r1) & F a_r0",
    "F[{lo},{hi}] a & F[{lo},{hi2}] b",
    "G[0,{hi}] !collide & F b",
]


def random_team_yaml(rng: random.Random, formula: str) -> str:
    rows, cols = rng.choice([(2, 3), (3, 2), (3, 3)])
    every = [(r, c) for r in range(rows) for c in range(cols)]
    starts = rng.sample(every, 2)
    others = [c for c in every if c not in starts]
    blocked = rng.sample(others, rng.randint(0, 1))
    free = [c for c in every if c not in blocked]
    labels = {p: rng.sample(free, rng.randint(1, 2)) for p in "ab"}
    motions = [CERTAIN, "{intended: 0.8, sideways: 0.1}", "{intended: 0.7, spread: 0.3}"]
    block = rng.choice([True, False])
    return "\n".join(
        [
            f"grid: {{rows: {rows}, cols: {cols}}}",
            f"blocked: {json.dumps([list(c) for c in blocked])}",
            f"labels: {json.dumps({p: [list(c) for c in cs] for p, cs in labels.items()})}",
            f"motion: {rng.choice(motions)}",
            "robots:",
            f"  r0: {{start: {list(starts[0])}}}",
            f"  r1: {{start: {list(starts[1])}, motion: {rng.choice(motions)}}}",
            f"collisions: {{block: {json.dumps(block)}}}",
            f"spec: {{formula: {json.dumps(formula)}}}",
            f"horizon: {rng.randint(4, 8)}",
        ]
    )


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_joint_optimum_agrees_with_storm(seed: int, tmp_path: Path) -> None:
    pytest.importorskip("stormpy")
    from tests.test_check import _state_marks, storm_value
    from tests.test_check_grids import storm_pmax

    rng = random.Random(seed)
    values: list[float] = []
    compared = 0
    for i in range(7):
        lo, hi = sorted(rng.sample(range(0, 5), 2))
        template = TEAM_SPECS[(i + seed) % len(TEAM_SPECS)]  # each seed a spread of them
        text = template.format(lo=lo, hi=hi, hi2=hi + rng.randint(1, 3))
        path = team_file(tmp_path, random_team_yaml(rng, text), f"team{i}.yaml")
        world = load_team_world(path)
        automaton = translate(parse(world.spec))
        product = build_product(world, automaton)
        mine = float(pmax(product).values[product.initial])
        theirs = storm_pmax(to_drn(product), storm_property(product), tmp_path)
        case = (path.read_text(encoding="utf-8"), mine, theirs)
        assert abs(mine - theirs) < 1e-6, case
        within, _ = pmax_horizon(product, world.horizon)
        values += [mine, within]
        if automaton.epsilon or (
            automaton.num_sets
            and not all(m == 0 or x == SATISFIED for x, m in _state_marks(product))
        ):
            continue
        # success within the horizon is a reachability event here (tests/test_check_grids.py)
        h, end = world.horizon, storm_label(product, "end")
        storm_within = storm_value(to_drn(product), f"Pmax=? [F[{h},{h}] {end}]", tmp_path)
        assert abs(within - storm_within) < 1e-9, (case, within, storm_within)
        compared += 1
    assert compared >= 3
    assert len({round(v, 6) for v in values}) >= 3  # the instances are not all alike


# --- errors at their fields and lines -------------------------------------------------------


GOOD = """\
grid: {rows: 3, cols: 3}
blocked: [[1, 1]]
labels: {a: [[0, 2]]}
motion: {intended: 0.8, sideways: 0.1}
robots:
  r0: {start: [0, 0]}
  r1: {start: [2, 2]}
spec: {formula: "F a_r0"}
horizon: 5
"""


def problem(tmp_path: Path, body: str, **kwargs: object) -> str:
    with pytest.raises(WorldError) as err:
        load_team_world(team_file(tmp_path, body), **kwargs)  # type: ignore[arg-type]
    return str(err.value)


def test_the_good_file_loads(tmp_path: Path) -> None:
    world = load_team_world(team_file(tmp_path, GOOD))
    assert world.num_states == 64 and world.team is not None
    assert world.team.robots == ("r0", "r1")


def test_errors_name_fields_and_lines(tmp_path: Path) -> None:
    same = GOOD.replace("r1: {start: [2, 2]}", "r1: {start: [0, 0]}")
    text = problem(tmp_path, same)
    assert ":7:" in text and "robots.r1.start: cell [0, 0] is robot 'r0''s start too" in text
    text = problem(tmp_path, GOOD.replace("r0: {start: [0, 0]}", "r0: {strat: [0, 0]}"))
    assert ":6:" in text and "robots.r0.strat: unknown field; did you mean 'start'?" in text
    text = problem(tmp_path, GOOD.replace("r1: {start: [2, 2]}", "r1: {start: [1, 1]}"))
    assert ":7:" in text and "robots.r1.start: cell [1, 1] is blocked" in text
    text = problem(tmp_path, GOOD.replace("F a_r0", "F c_r0 & F a"))
    assert ":8:" in text and "spec: proposition 'c_r0' labels no cell" in text
    assert "(labels: a, a_r0, a_r1)" in text
    text = problem(tmp_path, GOOD.replace("robots:", "start: [0, 0]\nrobots:"))
    assert "start: unknown field: a team world gives each robot its start" in text
    text = problem(tmp_path, GOOD.replace("r1: {start: [2, 2]}", "R1: {start: [2, 2]}"))
    assert "robots.R1: expected a robot id" in text
    obs = GOOD.replace("r1: {start: [2, 2]}", "r1: {start: [2, 2], observation: {type: x}}")
    assert "robots.r1.observation.type: expected 'noisy-cell' or 'local-pattern'" in problem(
        tmp_path, obs
    )
    clash = GOOD.replace("labels: {a: [[0, 2]]}", "labels: {a: [[0, 2]], a_r0: [[2, 0]]}")
    text = problem(tmp_path, clash)
    assert "robots.r0: proposition 'a_r0' would be both label 'a_r0' on any robot and " in text


def test_the_size_limit_is_an_error_at_robots(tmp_path: Path) -> None:
    text = problem(tmp_path, GOOD, limit=1000)  # 64 joint states x 25 joint actions
    assert ":5:1: robots: 2 robots on 8 free cells make at least 64 joint states x 25 " in text
    text = problem(tmp_path, GOOD, limit=2000)  # counted exactly
    assert (
        ":5:1: robots: 2 robots on 8 free cells make 64 joint states x 25 joint actions, " in text
    )
    assert "more than mitlc's limit of 2,000" in text and "fewer robots" in text
    assert load_team_world(team_file(tmp_path, GOOD), limit=10_000).num_states == 64
    many = GOOD.replace("rows: 3, cols: 3", "rows: 30, cols: 30").replace(
        "  r1: {start: [2, 2]}", "\n".join(f"  r{i}: {{start: [2, {i}]}}" for i in range(1, 5))
    )
    text = problem(tmp_path, many)
    assert "robots: 5 robots on 899 free cells make at least" in text


def test_the_shipped_team_world_loads(capsys: pytest.CaptureFixture[str]) -> None:
    world = load_team_world(ROOT / "specs" / "teams" / "two-robots.yaml")
    assert world.team is not None and world.team.robots == ("robot_0", "robot_1")
    assert world.cells[world.start] == (0, 0, 4, 4) and not world.is_pomdp
    noisy = load_team_world(ROOT / "specs" / "teams" / "two-robots-noisy.yaml")
    assert noisy.is_pomdp and noisy.name == "two-robots-noisy"
    assert "collide" in world.propositions and world.horizon == 30
    assert capsys.readouterr() == ("", "")


def test_the_team_declaration(tmp_path: Path) -> None:
    from mitlc.worlds.kinds.team import TeamDeclaration, read_team_file
    from mitlc.worlds.load import read_mapping

    path = ROOT / "specs" / "teams" / "two-robots.yaml"
    declaration = TeamDeclaration.read(path, read_mapping(path))
    assert declaration.kind == "team" and declaration.name == "two-robots"
    world = declaration.finite("F a_robot_1")
    assert world.propositions == ("a_robot_1",) and world.spec_source == "<spec>"
    grid = ROOT / "specs" / "paper" / "case1.yaml"
    with pytest.raises(WorldError, match="this is not a team world"):
        read_team_file(grid)


# --- the PettingZoo env ------------------------------------------------------------------------


def test_team_grid_env_passes_pettingzoo_tests() -> None:
    pytest.importorskip("pettingzoo")
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    from mitlc.worlds.team_env import TeamGridEnv

    world = load_team_world(ROOT / "specs" / "teams" / "two-robots.yaml")
    env = TeamGridEnv(world)
    parallel_api_test(env, num_cycles=60)
    parallel_seed_test(lambda: TeamGridEnv(world), num_cycles=60)
    assert env.observation_space("robot_1").n == 24 and env.action_space("robot_0").n == 5


def test_team_grid_env_steps_by_the_joint_world(tmp_path: Path) -> None:
    pytest.importorskip("pettingzoo")
    from mitlc.worlds.team_env import TeamGridEnv

    world = row_world(tmp_path, 3, [0, 2], block=False)
    env = TeamGridEnv(world)
    obs, infos = env.reset(seed=3)
    assert obs == {"r0": 0, "r1": 2}
    assert infos["r0"] == {"cell": [0, 0], "collide": False, "state": world.start}
    obs, _, _, _, infos = env.step({"r0": 3, "r1": 4})  # right, stay
    assert obs == {"r0": 1, "r1": 2} and not infos["r1"]["collide"]
    obs, _, _, _, infos = env.step({"r0": 3, "r1": 2})  # right, left: a swap
    assert obs == {"r0": 2, "r1": 1} and infos["r0"]["collide"] and infos["r1"]["collide"]
    # a noisy world: the next states drawn follow World.transitions
    noisy = load_team_world(team_file(tmp_path, GOOD))
    env = TeamGridEnv(noisy)
    env.reset(seed=0)
    start = noisy.start
    seen: dict[int, int] = {}
    for _ in range(2000):
        env.reset()
        _, _, _, _, infos = env.step({"r0": 3, "r1": 0})  # right, up
        state = noisy.team.state_of(tuple(tuple(infos[r]["cell"]) for r in ("r0", "r1")))  # type: ignore[union-attr]
        seen[state] = seen.get(state, 0) + 1
    want = step(noisy, start, "right|up")
    assert set(seen) == set(want)
    assert all(abs(seen[t] / 2000 - p) < 0.05 for t, p in want.items())
