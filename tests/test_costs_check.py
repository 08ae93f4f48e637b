"""The least expected cost among the policies of best success (``mitlc.check.costs``): by hand,
against a plain recursion written from the definition, against Storm's multi-objective
queries, on the shipped example, and through ``mitlc check``."""

from __future__ import annotations

import json
import random
import re
import time
from dataclasses import replace
from functools import cache
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from mitlc.automata import translate
from mitlc.check import check
from mitlc.check.costs import least_cost, policy_data
from mitlc.check.drn import storm_label, to_drn
from mitlc.check.solve import pmax_horizon
from mitlc.cli import app
from mitlc.limits import Deadline, LimitError
from mitlc.product.costs import product_costs
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, build_product, recursion_ends
from mitlc.syntax import parse, to_text
from mitlc.worlds import load_world
from mitlc.worlds.costs import Costs, PropositionCost, TransitionCost
from mitlc.worlds.model import FloatArray, World
from tests.conftest import ROOT
from tests.test_check import formulas, random_world
from tests.test_costs import CORRIDOR

TRM = ROOT / "specs" / "costs" / "trm-orders.yaml"
HAND_COSTS: dict[str, Any] = {
    "step": 1,
    "actions": {"left": 2, "right": 2},
    "propositions": {"mud": 5},
    "transitions": [{"from": "F[0,0] g", "when": "g", "cost": -2}],
}
"""The corridor's costs worked by hand below."""


def corridor(tmp_path: Path, costs: Any = HAND_COSTS) -> Path:
    path = tmp_path / "corridor.yaml"
    data = CORRIDOR | ({"costs": costs} if costs is not None else {})
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def checked(path: Path) -> tuple[World, Any]:
    world = load_world(path)
    automaton = translate(parse(world.spec))
    return world, check(world, automaton)


# --- by hand ------------------------------------------------------------------------------


def test_corridor_by_hand(tmp_path: Path) -> None:
    """The corridor c0 c1 c2 c3, g at both ends, mud (5) on c0, start c1; a move slips (stays)
    w.p. 0.2; every step costs 1 and a move 2 more; reading g in the last moment (F[0,0] g)
    pays -2; the task F[0,2] g within 3 steps.

    Success first: left twice at most (0.8 + 0.2 * 0.8 = 0.96) beats right (0.64) and waiting.
    Then cost. On c0 with a step to spare, any action succeeds: right (3 + 0.2 * 5 = 4) beats
    staying in the mud (1 + 5) and left (3 + 5). Back on c1 after a slip: left again, 3 + 0.8
    * 5 = 7, then on c0 right with the late reward (4 - 2 = 2), or on c1 anything fails and
    staying is cheapest (1): 7 + 0.8 * 2 + 0.2 * 1 = 8.8. From the start: 7 + 0.8 * 4 + 0.2
    * 8.8 = 11.96."""
    world, report = checked(corridor(tmp_path))
    assert report.pmax_horizon == pytest.approx(0.96, abs=1e-12)
    assert report.cost.value == pytest.approx(11.96, abs=1e-12)
    assert report.summary()["min_cost_horizon"] == report.cost.value
    data = policy_data(report.cost, report.product, world)
    rows = [(r["step"], tuple(r["cell"]), r["action"]) for r in data["rows"]]
    assert rows == [
        (0, (0, 1), "left"),
        (1, (0, 0), "right"),
        (1, (0, 1), "left"),
        (2, (0, 0), "right"),
        (2, (0, 1), "stay"),
    ]
    assert [r["cost"] for r in data["rows"]] == pytest.approx([11.96, 4.0, 8.8, 2.0, 1.0])
    assert [r["success"] for r in data["rows"]] == pytest.approx([0.96, 1.0, 0.8, 1.0, 0.0])
    assert data["kind"] == "lexicographic" and data["horizon"] == 3


def test_success_comes_first(tmp_path: Path) -> None:
    """The cheapest policy stays put and fails (3 steps of 1): the lexicographic one pays more
    to succeed."""
    world, report = checked(corridor(tmp_path))
    costs = product_costs(world, translate(parse(world.spec)), report.product).choice
    _, plain_cost = plain_lexicographic(report.product, costs, 3, success_first=False)
    assert plain_cost == pytest.approx(3.0) and report.cost.value > 11


def test_the_trm_example_by_hand() -> None:
    """specs/costs/trm-orders.yaml: b then a (10 moves, done on step 11) costs 1600 + 11;
    a then b (8 moves) 2000 + 9. Both succeed surely, so the cost decides."""
    world, report = checked(TRM)
    assert report.pmax_horizon == 1.0 and report.cost.value == pytest.approx(1600 + 11)
    first = policy_data(report.cost, report.product, world)["rows"][0]
    assert first["action"] == "down"  # towards b
    # The file's comment states the figures.
    text = TRM.read_text(encoding="utf-8")
    assert "pmax_horizon 1.000000 and min_cost_horizon 1611.000000" in " ".join(text.split())
    # Priced alike, the orders differ by their steps: a then b, 2000 + 9.
    assert world.costs is not None
    rules = tuple(replace(r, cost=2000.0) for r in world.costs.transitions)
    same = replace(world, costs=replace(world.costs, transitions=rules))
    again = check(same, translate(parse(world.spec)))
    assert again.cost is not None and again.cost.value == pytest.approx(2000 + 9)


def test_a_world_without_costs_reports_none(tmp_path: Path) -> None:
    _, report = checked(corridor(tmp_path, costs=None))
    assert report.cost is None and "min_cost_horizon" not in report.summary()


# --- against a plain recursion, with jumps and acceptance sets -----------------------------


def plain_lexicographic(
    product: Product, costs: FloatArray, horizon: int, *, success_first: bool = True
) -> tuple[float, float]:
    """``(best success, least cost among the policies reaching it)`` from the start, by a
    memoised recursion over (steps left, frontier, state) read off the definition (jumps take
    no step and cost nothing; nothing is paid once decided); without ``success_first``, the
    least cost of any policy."""
    ends, t, ptr = recursion_ends(product), product.transitions, product.choice_ptr

    @cache
    def value(r: int, mask: int, x: int) -> tuple[float, float]:
        if x in (SATISFIED, VIOLATED):
            return (1.0 if x == SATISFIED else 0.0), 0.0
        if r == 0:
            return float(ends[mask, x]), 0.0
        options = []
        for c in range(int(ptr[x]), int(ptr[x + 1])):
            row = range(int(t.indptr[c]), int(t.indptr[c + 1]))
            if product.action[c] < 0:
                options.append(value(r, mask, int(t.targets[row[0]])))
                continue
            after = [
                (float(t.probs[j]), value(r - 1, mask | int(product.marks[c]), int(t.targets[j])))
                for j in row
            ]
            success = sum(p * v for p, (v, _) in after)
            options.append((success, float(costs[c]) + sum(p * k for p, (_, k) in after)))
        best = max(v for v, _ in options)
        if not success_first:
            return best, min(k for _, k in options)
        return best, min(k for v, k in options if v >= best * (1 - 1e-12))

    found = [(p, value(horizon, 0, x)) for x, p in product.starts]
    return sum(p * v for p, (v, _) in found), sum(p * k for p, (_, k) in found)


def random_costs(rng: random.Random, world: World, obligations: list[str], low: float) -> Costs:
    """Random costs of every kind, from ``low`` up; transition rules from the ``obligations``
    reached (each one's own text), on random letters."""
    props = [
        PropositionCost(p, rng.uniform(low, 3), rng.uniform(low, 3)) for p in world.propositions
    ]
    rules = [
        TransitionCost(
            rng.choice(obligations),
            rng.choice(["true", *world.propositions, "!a"]),
            rng.choice([None, "true", "false"]),
            rng.uniform(low, 5),
        )
        for _ in range(rng.randint(0, 3) if obligations else 0)
    ]
    rules = [r for r in rules if "a" in world.propositions or r.when != "!a"]
    actions = tuple((a, rng.uniform(low, 2)) for a in world.actions if rng.random() < 0.5)
    return Costs(rng.uniform(low, 1), actions, tuple(props), tuple(rules))


def with_random_costs(rng: random.Random, formula: Any, low: float) -> tuple[World, Any, Product]:
    automaton = translate(formula)
    world = random_world(rng, to_text(formula))
    product = build_product(world, automaton)
    reached = sorted({automaton.obligation(int(q)) for q in product.automaton_state if q >= 0})
    world = replace(world, costs=random_costs(rng, world, reached, low))
    return world, automaton, product


@pytest.mark.parametrize("seed", [1, 2])
def test_agrees_with_a_plain_recursion(seed: int) -> None:
    rng = random.Random(300 + seed)
    kinds = set()
    for formula in formulas(seed, 25):
        world, automaton, product = with_random_costs(rng, formula, low=-2.0)
        costs = product_costs(world, automaton, product, strict=False).choice
        horizon = rng.randint(0, 6)
        found = least_cost(product, costs, horizon)
        success, cost = plain_lexicographic(product, costs, horizon)
        assert found.value == pytest.approx(cost, abs=1e-9), to_text(formula)
        assert pmax_horizon(product, horizon)[0] == pytest.approx(success, abs=1e-12)
        kinds |= {"jumps"} if (product.action < 0).any() else set()
        kinds |= {"sets"} if product.num_sets else set()
    assert kinds == {"jumps", "sets"}


# --- against Storm ------------------------------------------------------------------------


def storm_least_cost(product: Product, costs: FloatArray, horizon: int, tmp: Path) -> float:
    """Storm's least expected cost within ``horizon`` steps among the policies that reach
    "satisfied" within them with probability at least a hair below the best (a threshold at
    the best itself may be missed by rounding; a policy may then trade that hair of success
    for cost, so Storm's value is at most ours and only just below)."""
    stormpy = pytest.importorskip("stormpy")
    environments = pytest.importorskip("stormpy.environments")
    path = tmp / "product.drn"
    path.write_text(to_drn(product, costs), encoding="utf-8")
    model = stormpy.build_model_from_drn(str(path))
    env = stormpy.Environment()
    env.modelchecker().multi().precision = environments.Rational("1/1000000000")
    best = storm_reach(model, product, horizon)
    goal = f"F<={horizon} {storm_label(product, 'satisfied')}"
    prop = f'multi(P>={max(best - 1e-9, 0.0)!r} [{goal}], R{{"cost"}}min=? [C<={horizon}])'
    result = stormpy.model_checking(model, stormpy.parse_properties(prop)[0], environment=env)
    return float(result.get_value_vector()[model.initial_states[0]])


def storm_reach(model: Any, product: Product, horizon: int) -> float:
    """Storm's best probability of reaching "satisfied" within ``horizon`` steps."""
    stormpy = pytest.importorskip("stormpy")
    prop = stormpy.parse_properties(f"Pmax=? [F<={horizon} {storm_label(product, 'satisfied')}]")
    return float(stormpy.model_checking(model, prop[0]).get_value_vector()[model.initial_states[0]])


def test_the_corridor_and_the_example_agree_with_storm(tmp_path: Path) -> None:
    """Success here is reaching the satisfied state within the horizon (a deadline still open
    at the end fails): Storm's bounded reachability."""
    for path in (corridor(tmp_path), TRM):
        world, report = checked(path)
        assert report.cost is not None
        theirs = storm_least_cost(report.product, report.cost.immediate, world.horizon, tmp_path)
        assert theirs == pytest.approx(report.cost.value, rel=1e-5)
        assert theirs <= report.cost.value + 1e-6


COSAFE = [
    "F[0,3] a & F[0,3] b",
    "!a U[0,4] b",
    "F[0,4] (a & F[0,2] b)",
    "F[1,3] a | F[0,2] (b & !a)",
    "(!b U[0,3] a) & F[0,5] b",
]
"""Tasks whose success is entering the satisfied state (deadlines: one still open at the
end fails), so that pmax_horizon's success is Storm's bounded reachability of it."""


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_worlds_agree_with_storm(seed: int, tmp_path: Path) -> None:
    stormpy = pytest.importorskip("stormpy")
    rng = random.Random(400 + seed)
    for text in COSAFE:
        world, automaton, product = with_random_costs(rng, parse(text), low=0.0)
        costs = product_costs(world, automaton, product, strict=False).choice
        horizon = rng.randint(2, 7)
        found = least_cost(product, costs, horizon)
        drn = tmp_path / "p.drn"
        drn.write_text(to_drn(product), encoding="utf-8")
        model = stormpy.build_model_from_drn(str(drn))
        reach = storm_reach(model, product, horizon)
        assert found.values[horizon][0, product.initial] == pytest.approx(reach, abs=1e-9)
        theirs = storm_least_cost(product, costs, horizon, tmp_path)
        assert theirs == pytest.approx(found.value, rel=1e-5, abs=1e-6), (text, horizon)


# --- limits -------------------------------------------------------------------------------


def test_the_deadline_is_read_at_every_step(tmp_path: Path) -> None:
    _, report = checked(corridor(tmp_path))
    assert report.cost is not None
    deadline = Deadline(1e-6, "check", memory=None)
    time.sleep(0.01)
    with pytest.raises(LimitError, match="time limit"):
        least_cost(
            report.product, report.cost.immediate, 3, values=report.cost.values, deadline=deadline
        )
    tiny = Deadline(None, "check", memory=1e-9)
    with pytest.raises(LimitError, match="the cost tables"):
        least_cost(
            report.product, report.cost.immediate, 3, values=report.cost.values, deadline=tiny
        )


# --- the command --------------------------------------------------------------------------


def test_check_prints_the_cost_line_and_writes_the_policy(tmp_path: Path) -> None:
    runner = CliRunner()
    path = corridor(tmp_path)
    text = runner.invoke(app, ["check", str(path)])
    assert text.exit_code == 0, text.output
    assert re.search(r"^min_cost_horizon\s+11\.960000$", text.output, re.M)
    policy, drn = tmp_path / "policy.json", tmp_path / "p.drn"
    args = ["check", str(path), "--json", "--policy", str(policy), "--export-drn", str(drn)]
    done = runner.invoke(app, args)
    assert done.exit_code == 0, done.output
    assert json.loads(done.output)["min_cost_horizon"] == pytest.approx(11.96)
    data = json.loads(policy.read_text(encoding="utf-8"))
    assert data["kind"] == "lexicographic" and data["rows"][0]["obligation"] == "F[0,2] g"
    assert "@reward_models\ncost\n" in drn.read_text(encoding="utf-8")


def test_check_without_costs_prints_no_cost_line(tmp_path: Path) -> None:
    runner = CliRunner()
    policy, drn = tmp_path / "policy.json", tmp_path / "p.drn"
    path = corridor(tmp_path, costs=None)
    done = runner.invoke(
        app, ["check", str(path), "--policy", str(policy), "--export-drn", str(drn)]
    )
    assert done.exit_code == 0 and "min_cost_horizon" not in done.output
    assert isinstance(json.loads(policy.read_text(encoding="utf-8")), list)
    assert "@reward_models\n\n" in drn.read_text(encoding="utf-8")


def test_check_refuses_a_rule_that_matches_nothing(tmp_path: Path) -> None:
    costs = {"transitions": [{"from": "F[0,2] g", "when": "mud & !g", "cost": 1}]}
    done = CliRunner().invoke(app, ["check", str(corridor(tmp_path, costs))])
    assert done.exit_code == 1 and "Traceback" not in done.output
    assert "costs.transitions[0]: matches no transition the world can take" in done.output
