"""Worlds made from gymnasium envs: FrozenLake's and Taxi's transition tables, labels and starts
as the env has them, the exact optimum against Storm, and the one-line error of each bad file."""

from __future__ import annotations

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
from typer.testing import CliRunner

from mitlc.automata import translate
from mitlc.check.drn import storm_label, storm_property, to_drn
from mitlc.check.solve import pmax, pmax_horizon
from mitlc.cli import app
from mitlc.product.explicit import build_product
from mitlc.syntax import parse
from mitlc.worlds import World, WorldError, load_world, read_world_file
from mitlc.worlds.env_schema import EnvWorldFile
from mitlc.worlds.gym_world import GymWorldError, NotFiniteError, build_world, letters_of
from mitlc.worlds.load import read_any_world_file
from tests.conftest import ROOT

GYM = ROOT / "specs" / "gym"
FROZEN_HOLES = [5, 7, 11, 12]
TOLERANCE = 1e-12


def make(env_id: str, **kwargs: Any) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gym.make(env_id, **kwargs).unwrapped


def merged(entries: list[tuple[float, int, float, bool]]) -> dict[int, float]:
    """A row of toy-text ``P`` as a distribution, repeated next states summed."""
    row: dict[int, float] = {}
    for prob, target, _, _ in entries:
        row[int(target)] = row.get(int(target), 0.0) + float(prob)
    return {t: p for t, p in row.items() if p > 0}


def world_row(world: World, s: int, a: int) -> dict[int, float]:
    targets, probs = world.transitions.row(s * world.num_actions + a)
    return {int(t): float(p) for t, p in zip(targets, probs, strict=True)}


def write(tmp_path: Path, data: dict[str, Any], name: str = "world.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


FROZEN: dict[str, Any] = {
    "name": "fl",
    "env": {"id": "FrozenLake-v1", "kwargs": {"map_name": "4x4", "is_slippery": True}},
    "labels": {"goal": {"obs": [15]}, "hole": {"obs": FROZEN_HOLES}},
    "spec": {"formula": "!hole U[0,12] goal"},
    "horizon": 14,
}


# --- FrozenLake ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def frozen() -> World:
    return load_world(GYM / "frozenlake4x4.yaml")


def test_frozenlake_transitions_are_the_envs(frozen: World) -> None:
    env = make("FrozenLake-v1", map_name="4x4", is_slippery=True)
    assert (frozen.num_states, frozen.num_actions) == (16, 4)
    assert frozen.actions == ("left", "down", "right", "up")
    absorbing = {*FROZEN_HOLES, 15}
    for s in range(16):
        for a in range(4):
            row = world_row(frozen, s, a)
            assert abs(sum(row.values()) - 1.0) <= TOLERANCE
            if s in absorbing:
                assert row == {s: 1.0}, (s, a)
            else:
                assert row == pytest.approx(merged(env.P[s][a]), abs=TOLERANCE), (s, a)
    # spot checks, by hand: from the start, 'left' stays put w.p. 2/3 or slips down
    assert world_row(frozen, 0, 0) == pytest.approx({0: 2 / 3, 4: 1 / 3})
    assert world_row(frozen, 14, 2) == pytest.approx({10: 1 / 3, 14: 1 / 3, 15: 1 / 3})
    assert world_row(frozen, 6, 1) == pytest.approx({5: 1 / 3, 7: 1 / 3, 10: 1 / 3})


def test_frozenlake_letters_start_and_map(frozen: World) -> None:
    assert frozen.propositions == ("goal", "hole")
    expected = [2 if s in FROZEN_HOLES else 1 if s == 15 else 0 for s in range(16)]
    assert frozen.letters.tolist() == expected
    assert frozen.start == 0 and frozen.start_distribution == ()  # one start state: certain
    assert (frozen.rows, frozen.cols) == (4, 4)
    assert frozen.cells == tuple((r, c) for r in range(4) for c in range(4))
    assert frozen.name == "frozenlake-4x4" and frozen.horizon == 110


def test_frozenlake_8x8_uses_its_map() -> None:
    world = load_world(GYM / "frozenlake8x8.yaml")
    desc = make("FrozenLake-v1", map_name="8x8").desc.reshape(-1)
    assert (world.rows, world.cols, world.num_states) == (8, 8, 64)
    holes = [s for s, c in enumerate(desc) if c == b"H"]
    assert [s for s in range(64) if world.letters[s] & 2] == holes
    for s in [*holes, 63]:
        assert all(world_row(world, s, a) == {s: 1.0} for a in range(4))


def storm_value(drn: str, prop: str, tmp: Path) -> float:
    stormpy = pytest.importorskip("stormpy")
    path = tmp / "product.drn"
    path.write_text(drn, encoding="utf-8")
    model = stormpy.build_model_from_drn(str(path))
    result = stormpy.model_checking(model, stormpy.parse_properties(prop)[0])
    return float(result.get_value_vector()[model.initial_states[0]])


@pytest.mark.parametrize(
    "formula", ["!hole U[0,12] goal", "(!hole U[0,6] goal) | G F goal", "F goal & G !hole"]
)
def test_frozenlake_optimum_agrees_with_storm(formula: str, tmp_path: Path) -> None:
    world = load_world(write(tmp_path, {**FROZEN, "spec": {"formula": formula}}))
    product = build_product(world, translate(parse(formula)))
    mine = float(pmax(product).values[product.initial])
    drn = to_drn(product)
    theirs = storm_value(drn, storm_property(product), tmp_path)
    assert abs(mine - theirs) < 1e-6, (formula, mine, theirs)
    if formula == "F goal & G !hole":
        assert abs(mine - 14 / 17) < 1e-6  # FrozenLake 4x4's known optimum, 0.8235
    if formula.startswith("!hole U"):
        within, _ = pmax_horizon(product, world.horizon)
        bad = storm_label(product, "violated")
        storm_within = 1 - storm_value(drn, f"Pmin=? [F<={world.horizon} {bad}]", tmp_path)
        assert abs(within - storm_within) < 1e-9
        assert 0.05 < mine < 0.5


# --- Taxi ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def taxi() -> World:
    return load_world(GYM / "taxi.yaml")


def test_taxi_decoded_labels_agree_with_decode(taxi: World) -> None:
    env = make("Taxi-v4", is_rainy=True)
    assert taxi.propositions == ("carrying", "delivered")
    assert taxi.actions == ("south", "north", "east", "west", "pickup", "dropoff")
    assert (taxi.rows, taxi.cols, taxi.num_states) == (1, 500, 500)
    for s in range(500):
        _, _, passenger, destination = env.decode(s)
        expected = (passenger == 4) | (passenger == destination) << 1
        assert taxi.letters[s] == expected, s


def test_taxi_start_distribution_is_the_envs(taxi: World) -> None:
    env = make("Taxi-v4", is_rainy=True)
    dist = env.initial_state_distrib
    pairs = taxi.start_distribution
    assert len(pairs) == 300 and [s for s, _ in pairs] == sorted(s for s, _ in pairs)
    assert abs(sum(p for _, p in pairs) - 1.0) < 1e-9
    assert pairs == tuple((int(s), float(dist[s])) for s in np.flatnonzero(dist))
    assert taxi.start == 1  # all equally likely: the lowest id


def test_taxi_drop_off_is_absorbing(taxi: World) -> None:
    env = make("Taxi-v4", is_rainy=True)
    ends = set()
    for s in range(500):
        row, col, passenger, destination = env.decode(s)
        if passenger == destination and (row, col) == env.locs[destination]:
            ends.add(s)  # the four states a successful drop-off enters
    assert len(ends) == 4
    for s in ends:
        assert all(world_row(taxi, s, a) == {s: 1.0} for a in range(6))
    # elsewhere the rows are P's: a rainy move, and a pick-up
    s = env.encode(2, 2, 0, 1)
    for a in range(6):
        assert world_row(taxi, s, a) == pytest.approx(merged(env.P[s][a]), abs=TOLERANCE)


def test_decoded_label_with_values_and_equal_fields() -> None:
    env = make("Taxi-v4")
    file = EnvWorldFile.model_validate(
        {
            "env": {"id": "Taxi-v4"},
            "labels": {
                "corner": {
                    "decoded": {
                        "radices": [5, 5, 5, 4],
                        "fields": ["row", "col", "p", "d"],
                        "where": {"row": [0], "col": [0, 4], "p": "d"},
                    }
                }
            },
            "spec": {"formula": "F corner"},
            "horizon": 5,
        }
    )
    mask = letters_of(file.labels, ("corner",), 500) == 1
    for s in range(500):
        row, col, p, d = env.decode(s)
        assert mask[s] == (row == 0 and col in (0, 4) and p == d), s


# --- conversion of other tables --------------------------------------------------------------


class FakeEnv:
    """A made env's surface: a toy-text table, spaces and a start distribution."""

    def __init__(self, table: Any, start: list[float], n: int, m: int) -> None:
        self.P = table
        self.initial_state_distrib = np.asarray(start)
        self.observation_space = gym.spaces.Discrete(n)
        self.action_space = gym.spaces.Discrete(m)
        self.spec = None

    @property
    def unwrapped(self) -> FakeEnv:
        return self


def convert(env: FakeEnv, formula: str = "F x", **labels: Any) -> World:
    file = EnvWorldFile.model_validate(
        {
            "env": {"id": "Fake-v0"},
            "labels": labels or {"x": {"obs": [0]}},
            "spec": {"formula": formula},
            "horizon": 5,
        }
    )
    return build_world(
        file, env, name="fake", spec=formula, spec_source="<inline>", propositions=("x",)
    )


def test_duplicates_merge_and_generic_names_and_layout() -> None:
    table = {
        0: {0: [(0.25, 1, 0, False), (0.5, 1, 0, False), (0.25, 0, 0, False)], 1: [(1, 2, 0, 1)]},
        1: {0: [(1.0, 0, 0, False)], 1: [(1.0, 1, 0, False)]},
        2: {0: [(1.0, 2, 0, False)], 1: [(1.0, 0, 0, False)]},
    }
    world = convert(FakeEnv(table, [0.25, 0.5, 0.25], 3, 2))
    assert world.actions == ("a0", "a1")
    assert world_row(world, 0, 0) == {0: 0.25, 1: 0.75}
    assert world_row(world, 2, 1) == {2: 1.0}  # entered by an ending step: absorbing
    assert (world.rows, world.cols, world.cells) == (1, 3, ((0, 0), (0, 1), (0, 2)))
    assert world.start == 1 and world.start_distribution == ((0, 0.25), (1, 0.5), (2, 0.25))


def test_a_state_entered_with_and_without_ending_is_refused() -> None:
    table = {
        0: {0: [(0.5, 1, 0, True), (0.5, 0, 0, False)], 1: [(1.0, 1, 0, False)]},
        1: {0: [(1.0, 1, 0, True)], 1: [(1.0, 1, 0, True)]},
    }
    with pytest.raises(GymWorldError, match="action 1 in state 0 enters state 1 without ending"):
        convert(FakeEnv(table, [1.0, 0.0], 2, 2))


def test_a_malformed_table_is_refused() -> None:
    with pytest.raises(GymWorldError, match=r"P\[0\]\[0\] sums to 0.5, not 1"):
        convert(FakeEnv({0: {0: [(0.5, 0, 0, False)]}}, [1.0], 1, 1))
    with pytest.raises(GymWorldError, match=r"P\[0\]\[0\] is malformed"):
        convert(FakeEnv({0: {0: [(1.0, 3, 0, False)]}}, [1.0], 1, 1))
    with pytest.raises(GymWorldError, match="initial_state_distrib is not a distribution"):
        convert(FakeEnv({0: {0: [(1.0, 0, 0, False)]}}, [0.5], 1, 1))
    env = FakeEnv({0: {0: [(1.0, 0, 0, False)]}}, [1.0], 1, 1)
    env.P = None
    with pytest.raises(NotFiniteError, match="has no transition table"):
        convert(env)


# --- errors ----------------------------------------------------------------------------------

BAD: dict[str, tuple[dict[str, Any], str]] = {
    "unknown id": (
        {"env": {"id": "FrozenLak-v1"}},
        "env.id: no gymnasium environment 'FrozenLak-v1'; did you mean 'FrozenLake-v1'?",
    ),
    "old taxi": (
        {"env": {"id": "Taxi-v3"}, "labels": {"goal": {"obs": [1]}, "hole": {"obs": [2]}}},
        "env.id: no gymnasium environment 'Taxi-v3'; did you mean 'Taxi-v4'?",
    ),
    "bad kwargs": (
        {"env": {"id": "FrozenLake-v1", "kwargs": {"map_name": "5x5"}}},
        "env.kwargs: FrozenLake-v1 cannot be made: KeyError: '5x5'",
    ),
    "unknown kwarg": (
        {"env": {"id": "FrozenLake-v1", "kwargs": {"slippery": True}}},
        "env.kwargs: FrozenLake-v1 cannot be made: TypeError: FrozenLakeEnv.__init__() got "
        "an unexpected keyword argument 'slippery'",
    ),
    "unknown env field": (
        {"env": {"id": "FrozenLake-v1", "kwarg": {}}},
        "env.kwarg: unknown field; did you mean 'kwargs'?",
    ),
    "bad label": (
        {"labels": {"goal": {"cells": [[3, 3]]}, "hole": {"obs": [5]}}},
        "labels.goal: expected {obs: [...]}, {decoded: {...}}, {box: {...}}, {disc: {...}}, "
        "{info: path}, {attr: path}, {reward: {...}}, {terminated: true} or a list of them, "
        'got {"cells": [[3, 3]]}',
    ),
    "obs out of range": (
        {"labels": {"goal": {"obs": [16]}, "hole": {"obs": [5]}}},
        "labels.goal.obs[0]: observation 16 is outside the env's 16 (0 to 15)",
    ),
    "obs not integers": (
        {"labels": {"goal": {"obs": ["15"]}, "hole": {"obs": [5]}}},
        'labels.goal.obs: expected a list of observations (integers from 0), got ["15"]',
    ),
    "obs twice": (
        {"labels": {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 5]}}},
        "labels.hole.obs[2]: observation 5 is listed twice (also labels.hole.obs[0])",
    ),
    "radices": (
        {
            "labels": {
                "goal": {"obs": [15]},
                "hole": {"decoded": {"radices": [4, 5], "fields": ["r", "c"], "where": {}}},
            }
        },
        "labels.hole.decoded.radices: the radices [4, 5] encode 20 states, the env has 16 "
        "observations",
    ),
    "decoded field": (
        {
            "labels": {
                "goal": {"obs": [15]},
                "hole": {"decoded": {"radices": [4, 4], "fields": ["r", "c"], "where": {"x": [1]}}},
            }
        },
        'labels.hole.decoded.where.x: unknown field "x" (fields: r, c)',
    ),
    "decoded value": (
        {
            "labels": {
                "goal": {"obs": [15]},
                "hole": {"decoded": {"radices": [4, 4], "fields": ["r", "c"], "where": {"r": [4]}}},
            }
        },
        "labels.hole.decoded.where.r[0]: value 4 is outside the field's 4 values (0 to 3)",
    ),
    "decoded fields": (
        {
            "labels": {
                "goal": {"obs": [15]},
                "hole": {"decoded": {"radices": [4, 4], "fields": ["r"], "where": {}}},
            }
        },
        "labels.hole.decoded.fields: 1 fields for 2 radices: give one each",
    ),
    "decoded unknown key": (
        {
            "labels": {
                "goal": {"obs": [15]},
                "hole": {"decoded": {"radices": [16], "fields": ["s"], "where": {}, "feilds": 1}},
            }
        },
        "labels.hole.decoded.feilds: unknown field; did you mean 'fields'?",
    ),
    "unlabelled": (
        {"labels": {"goal": {"obs": [15]}}},
        "spec: proposition 'hole' holds in no state (labels: goal)",
    ),
    "actions": (
        {"actions": ["w", "s", "e"]},
        "actions: 3 names for FrozenLake-v1's 4 actions: give one each",
    ),
    "not finite": (
        {"env": {"id": "CartPole-v1"}},
        "env.id: CartPole-v1 has no transition table (env.unwrapped.P): not a finite world, "
        "so there is no exact optimum to check; mitlc train learns it through the task "
        "wrapper",
    ),
    "compatibility layer": (
        {"env": {"id": "GymV26Environment-v0", "kwargs": {"env_id": "os:system"}}},
        "env.id: GymV26Environment-v0 makes another environment by name; name that "
        "environment's id",
    ),
    "grid and env": (
        {"grid": {"rows": 4, "cols": 4}},
        "grid: a world has either grid: or env:, not both",
    ),
    "grid field": ({"start": [0, 0]}, "start: unknown field (known: "),
}


@pytest.mark.parametrize("case", BAD)
def test_bad_env_world_is_one_line_with_the_field_path(case: str, tmp_path: Path) -> None:
    changes, expected = BAD[case]
    path = write(tmp_path, {**FROZEN, **changes})
    with pytest.raises(WorldError) as info:
        load_world(path)
    text = info.value.render()
    assert len(text.splitlines()) == 1, text
    assert text.startswith(f"{path}:"), text
    message = text.split(": ", 1)[1]
    assert message.startswith(expected), (message, expected)


def test_kwargs_are_plain_yaml(tmp_path: Path) -> None:
    path = tmp_path / "world.yaml"
    text = yaml.safe_dump(FROZEN, sort_keys=False)
    path.write_text(text.replace("map_name: 4x4", "map_name: 2001-01-01"), encoding="utf-8")
    with pytest.raises(WorldError, match=r"env\.kwargs\.map_name: expected a YAML scalar, list"):
        load_world(path)


def test_check_command_on_a_bad_env_world_exits_1(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(
        "env: {id: FrozenLake-v1}\n"
        "labels:\n"
        "  goal: {obs: [15, 99]}\n"
        "  hole: {obs: [5]}\n"
        'spec: {formula: "!hole U[0,12] goal"}\n'
        "horizon: 14\n",
        encoding="utf-8",
    )
    result = CliRunner().invoke(app, ["check", str(path)])
    assert result.exit_code == 1
    assert "Traceback" not in result.output
    assert result.output.strip().splitlines() == [
        f"{path}:3:20: labels.goal.obs[1]: observation 99 is outside the env's 16 (0 to 15)"
    ]
    missing = write(tmp_path, {**FROZEN, "env": {"id": "NoSuchEnv-v0"}}, "missing.yaml")
    result = CliRunner().invoke(app, ["check", str(missing)])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert "env.id: no gymnasium environment 'NoSuchEnv-v0'" in result.output


def test_check_command_on_frozenlake(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["check", str(write(tmp_path, FROZEN)), "--json"])
    assert result.exit_code == 0, result.output
    assert '"pmax"' in result.output


def test_grid_readers_and_any_reader(tmp_path: Path) -> None:
    path = write(tmp_path, FROZEN)
    with pytest.raises(WorldError, match=r"env: this is a gymnasium env world"):
        read_world_file(path)
    assert isinstance(read_any_world_file(path), EnvWorldFile)
    assert read_any_world_file(ROOT / "specs" / "paper" / "case1.yaml").grid.rows == 5  # type: ignore[union-attr]


def test_making_the_env_is_quiet(tmp_path: Path) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_world(write(tmp_path, FROZEN))
    assert caught == []


def test_gymnasium_is_imported_only_for_env_worlds() -> None:
    code = (
        "import sys; from mitlc.worlds import load_world; "
        "load_world('specs/paper/case1.yaml'); print('gymnasium' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "False"


# --- the wrapper on the real env achieves the converted world's optimum ------------------------


def test_the_checked_optimum_is_what_the_wrapped_env_achieves() -> None:
    """The finite-horizon optimal policy of the converted FrozenLake world, followed in
    ``TaskWrapper(gym.make("FrozenLake-v1"))`` (the real env, its own randomness, the
    wrapper's labels), succeeds as often as ``pmax_horizon`` says (within 4 standard errors)."""
    from mitlc.gym import TaskWrapper
    from mitlc.product import ProductEnv
    from tests.test_env import assert_agrees, optimal_actions

    path = ROOT / "specs" / "gym" / "frozenlake4x4.yaml"
    world = replace(load_world(path), horizon=30)
    automaton = translate(parse("!hole U[0,25] goal"))
    exact, history = pmax_horizon(build_product(world, automaton), world.horizon)
    table, ids = optimal_actions(ProductEnv(world, automaton), history)
    labels = {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 11, 12]}}
    inner = gym.make("FrozenLake-v1", map_name="4x4", is_slippery=True)
    env = TaskWrapper(inner, automaton, labels, horizon=world.horizon)
    episodes, wins, num_q = 3000, 0, len(automaton.states)
    for episode in range(episodes):
        obs, info = env.reset(seed=episode)
        while True:
            x = ids[obs["env"] * num_q + obs["automaton"]]
            action = table[world.horizon - env.steps][obs["frontier"]][x]
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        wins += info["success"]
    assert 0.2 < exact < 0.9
    assert_agrees(exact, wins / episodes, episodes)
