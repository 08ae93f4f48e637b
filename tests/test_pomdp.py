"""Storm's belief-exploration bounds on POMDP worlds (skipped without ``stormpy.pomdp``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from mitlc.automata import translate
from mitlc.check import check
from mitlc.check.pomdp import pomdp_bounds, to_pomdp_drn
from mitlc.product.explicit import build_product
from mitlc.syntax import parse
from mitlc.worlds import load_world
from tests.pomdp_worlds import guessing_world

pytest.importorskip("stormpy.pomdp")

ROOT = Path(__file__).resolve().parents[1]


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
