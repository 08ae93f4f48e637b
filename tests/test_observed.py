"""The observation-based lower bound of a POMDP's optimum (mitlc.check.observed): a hand value,
the fully observable optimum when the observation is the cell, the Monte-Carlo success of the
policy it returns in the product environment, monotone sweeps, and its errors."""

from __future__ import annotations

import itertools
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from mitlc.automata import translate
from mitlc.check.observed import ObservedBound, ObservedBoundError, observed_bound
from mitlc.check.solve import pmax_horizon
from mitlc.cli import app
from mitlc.product import ProductEnv, build_product
from mitlc.syntax import parse
from mitlc.worlds import load_world
from mitlc.worlds.model import Observations, Sparse, World
from tests.conftest import ROOT
from tests.pomdp_worlds import guessing_world

PAPER = ROOT / "specs" / "paper"

NOISY = """
name: noisy-4x4
grid: {rows: 4, cols: 4}
blocked: [[1, 1]]
labels: {a: [[0, 3]], b: [[3, 0]]}
start: [3, 3]
actions: [up, down, left, right, stay]
motion: {intended: 0.8, sideways: 0.1}
observation: {type: noisy-cell, correct: 0.7, neighbourhood: 8}
spec: {formula: "(!a U[3,6] a) & (!b U[8,11] b)"}
horizon: 12
"""


def bound_of(world: World) -> tuple[float, float, ObservedBound]:
    """The observation-based bound, the fully observable ``pmax_horizon`` and the bound."""
    product = build_product(world, translate(parse(world.spec, world.spec_source)))
    found = observed_bound(world, product)
    return found.value, pmax_horizon(product, world.horizon)[0], found


def noisy_world(tmp_path: Path) -> World:
    path = tmp_path / "noisy.yaml"
    path.write_text(NOISY, encoding="utf-8")
    return load_world(path)


def test_guessing_world_hand_value() -> None:
    value, full, _ = bound_of(guessing_world())
    assert full == pytest.approx(1.0)
    assert value == pytest.approx(0.75, abs=1e-12)


@pytest.mark.parametrize("name", ["case1.yaml", "case1-cost.yaml"])
def test_observing_the_cell_gives_the_fully_observable_optimum(name: str) -> None:
    world = load_world(PAPER / name)
    cells = world.num_states
    identity = Sparse.from_rows([{s: 1.0} for s in range(cells)])
    seen = replace(world, observations=Observations(tuple(map(str, range(cells))), identity))
    value, full, _ = bound_of(seen)
    assert value == pytest.approx(full, abs=1e-12)


def test_bound_lies_below_the_fully_observable_optimum_and_sweeps_climb(tmp_path: Path) -> None:
    value, full, found = bound_of(noisy_world(tmp_path))
    assert all(b >= a - 1e-15 for a, b in itertools.pairwise(found.sweeps))
    assert 0.0 < value <= full + 1e-12
    assert value < full - 1e-3  # the noise costs something in this world


def test_policy_succeeds_in_the_environment_as_often_as_its_exact_value(tmp_path: Path) -> None:
    world = noisy_world(tmp_path)
    automaton = translate(parse(world.spec, world.spec_source))
    found = observed_bound(world, build_product(world, automaton))
    env = ProductEnv(world, automaton)
    episodes, successes = 20_000, 0
    for episode in range(episodes):
        obs, info = env.reset(seed=episode)
        t, done = 0, False
        while not done:
            action = found.action(t, int(obs["world"]), int(obs["automaton"]))
            obs, _, terminated, truncated, info = env.step(action)
            t, done = t + 1, terminated or truncated
        successes += bool(info["success"])
    rate = successes / episodes
    error = np.sqrt(found.value * (1 - found.value) / episodes)
    assert abs(rate - found.value) < 4 * error, (rate, found.value, error)


def test_case3_office_loses_nothing_to_its_observations() -> None:
    # Storm's belief exploration finds lower = upper = pmax on the office (tests/test_pomdp.py);
    # the memoryless (observation, automaton state, step) policy reaches it too.
    value, full, _ = bound_of(load_world(PAPER / "case3-office.yaml"))
    assert value == pytest.approx(full, abs=1e-8)


def test_mdp_worlds_jumps_and_large_problems_are_refused(tmp_path: Path) -> None:
    world = load_world(PAPER / "case1.yaml")
    product = build_product(world, translate(parse(world.spec, world.spec_source)))
    with pytest.raises(ObservedBoundError, match="no observation model"):
        observed_bound(world, product)
    noisy = noisy_world(tmp_path)
    jumpy = build_product(noisy, translate(parse("F G a & F b")))
    assert (jumpy.action < 0).any()
    with pytest.raises(ObservedBoundError, match="epsilon jumps"):
        observed_bound(noisy, jumpy)
    plain = build_product(noisy, translate(parse(noisy.spec, noisy.spec_source)))
    with pytest.raises(ObservedBoundError, match="past the limit of 1,000"):
        observed_bound(noisy, plain, max_cells=1_000)


def test_check_command_reports_the_bound_for_a_pomdp() -> None:
    result = CliRunner().invoke(
        app, ["check", str(PAPER / "case2.yaml"), "--json", "--no-pomdp-bounds"]
    )
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert 0.9 < data["pmax_horizon_observed"] <= data["pmax_horizon"]


def test_rows_list_the_keys_met_with_their_actions(tmp_path: Path) -> None:
    _, _, found = bound_of(noisy_world(tmp_path))
    rows = found.rows()
    assert rows == sorted(rows)
    assert {t for t, *_ in rows} == set(range(found.policy.shape[0]))
    assert all(found.action(t, o, q) == a for t, o, q, a in rows)
    assert len({q for t, _, q, _ in rows if t == 0}) == 1  # the start's automaton state


def test_check_policy_of_a_pomdp_is_observation_based(tmp_path: Path) -> None:
    out = tmp_path / "policy.json"
    world = PAPER / "case3-office.yaml"
    result = CliRunner().invoke(
        app, ["check", str(world), "--json", "--no-pomdp-bounds", "--policy", str(out)]
    )
    assert result.exit_code == 0, result.output
    policy = json.loads(out.read_text(encoding="utf-8"))
    assert policy["kind"] == "observation-based"
    assert policy["pmax_horizon_observed"] == json.loads(result.stdout)["pmax_horizon_observed"]
    loaded = load_world(world)
    assert loaded.observations is not None
    for row in policy["rows"]:
        assert row["action"] in loaded.actions
        assert row["observation"] in loaded.observations.names
        assert 0 <= row["step"] < loaded.horizon
