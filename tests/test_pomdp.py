"""Storm's belief-exploration bounds on POMDP worlds (skipped without ``stormpy.pomdp``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.check import check
from mitlc.check.pomdp import pomdp_bounds, to_pomdp_drn
from mitlc.product.explicit import build_product
from mitlc.syntax import parse
from mitlc.worlds import load_world
from mitlc.worlds.model import Observations, Sparse, World

pytest.importorskip("stormpy.pomdp")

ROOT = Path(__file__).resolve().parents[1]


def guessing_world() -> World:
    """Start 0 moves to room 1 or room 2 w.p. 1/2 each, whatever the action. In room 1 action
    ``a0`` reaches the goal 3 and ``a1`` the trap 4; in room 2 the other way round. Room 1 always
    shows ``x``; room 2 shows ``x`` or ``y`` w.p. 1/2 each. Goal and trap are absorbing.

    Fully observable: 1. Observation-based: on ``y`` the room is 2 (win); on ``x`` (w.p. 3/4)
    room 1 has posterior 2/3, so the best is 1/4 + 3/4 * 2/3 = 3/4."""
    rows: list[dict[int, float]] = [
        {1: 0.5, 2: 0.5},
        {1: 0.5, 2: 0.5},
        {3: 1.0},
        {4: 1.0},
        {4: 1.0},
        {3: 1.0},
        {3: 1.0},
        {3: 1.0},
        {4: 1.0},
        {4: 1.0},
    ]
    return World(
        name="guessing",
        rows=1,
        cols=5,
        cells=tuple((0, c) for c in range(5)),
        actions=("a0", "a1"),
        start=0,
        transitions=Sparse.from_rows(rows),
        propositions=("g",),
        letters=np.array([0, 0, 0, 1, 0], dtype=np.int64),
        spec="F g",
        spec_source="<inline>",
        horizon=5,
        discount=0.99,
        observations=Observations(
            names=("start", "x", "y", "goal", "trap"),
            model=Sparse.from_rows([{0: 1.0}, {1: 1.0}, {1: 0.5, 2: 0.5}, {3: 1.0}, {4: 1.0}]),
        ),
    )


def test_guessing_world_bounds_bracket_hand_value() -> None:
    world = guessing_world()
    automaton = translate(parse(world.spec, world.spec_source))
    full = check(world, automaton).pmax
    assert full == pytest.approx(1.0)
    result = pomdp_bounds(world, automaton, resolution=3)
    assert result is not None
    assert result["lower"] <= 0.75 + 1e-9
    assert 0.75 - 1e-9 <= result["upper"] <= full + 1e-9
    assert result["lower"] == pytest.approx(0.75, abs=1e-9)
    assert result["lower_complete"]


def test_guessing_world_drn_is_a_pomdp() -> None:
    world = guessing_world()
    automaton = translate(parse(world.spec, world.spec_source))
    text = to_pomdp_drn(world, build_product(world, automaton))
    assert "@type: POMDP" in text
    assert "state 0 {0} init" in text


@pytest.mark.parametrize("horizon_success", [False, True])
def test_case3_office_bounds(horizon_success: bool) -> None:
    world = load_world(ROOT / "specs" / "paper" / "case3-office.yaml")
    automaton = translate(parse(world.spec, world.spec_source))
    report = check(world, automaton)
    result = pomdp_bounds(
        world, automaton, horizon_success=horizon_success, max_exploration_time=20
    )
    assert result is not None
    assert result["lower"] <= result["upper"] + 1e-9
    assert result["upper"] <= report.pmax + 1e-9
    if horizon_success:
        assert result["upper"] <= report.pmax_horizon + 1e-9


def test_check_command_reports_bounds_for_a_pomdp() -> None:
    import json

    from typer.testing import CliRunner

    from mitlc.cli import app
    from tests.conftest import ROOT

    world = str(ROOT / "specs" / "paper" / "case3-office.yaml")
    result = CliRunner().invoke(app, ["check", world, "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.output[result.output.index("{") :])
    bounds = report["bounds"]
    assert bounds["lower"] <= bounds["upper"] <= report["pmax"] + 1e-9
    assert abs(bounds["lower"] - report["pmax"]) < 1e-6  # case 3's observations suffice
