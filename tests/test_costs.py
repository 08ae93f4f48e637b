"""World costs: the ``costs:`` section (shape, whole-file checks, errors with their field's
path), obligation patterns, and the cost of every product transition, by hand."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from mitlc.automata import translate
from mitlc.automata.patterns import ObligationPattern, letter_formula, letter_holds
from mitlc.product.costs import product_costs
from mitlc.product.explicit import SATISFIED, build_product
from mitlc.syntax import parse
from mitlc.task.costs import CostError
from mitlc.worlds import load_world
from mitlc.worlds.costs import Costs, PropositionCost, TransitionCost
from mitlc.worlds.load import WorldError
from mitlc.worlds.schemas import world_json_schema
from tests.conftest import ROOT
from tests.test_worlds import schema_errors

CORRIDOR: dict[str, Any] = {
    "grid": {"rows": 1, "cols": 4},
    "labels": {"g": [[0, 0], [0, 3]], "mud": [[0, 0]], "ice": [[0, 2]]},
    "start": [0, 1],
    "actions": ["left", "right", "stay"],
    "motion": {"intended": 0.8, "sideways": 0.1},
    "spec": {"formula": "F[0,2] g"},
    "horizon": 3,
}
"""A 1x4 corridor: g at both ends, mud on the left one; moves slip (stay) w.p. 0.2."""


def write(tmp_path: Path, costs: Any, **changes: Any) -> Path:
    path = tmp_path / "world.yaml"
    path.write_text(yaml.safe_dump(CORRIDOR | changes | {"costs": costs}), encoding="utf-8")
    return path


def problems(tmp_path: Path, costs: Any, **changes: Any) -> list[str]:
    """Each problem as ``w:LINE:COL: path: message``, the line and column checked to be
    there and then left out (``yaml.safe_dump`` lays the file out)."""
    with pytest.raises(WorldError) as info:
        load_world(write(tmp_path, costs, **changes))
    rendered = [p.render("w") for p in info.value.problems]
    assert all(re.match(r"w:\d+:\d+: ", r) for r in rendered), rendered
    return [re.sub(r"^w:\d+:\d+: ", "", r) for r in rendered]


# --- the section --------------------------------------------------------------------------


def test_costs_are_read_with_every_kind(tmp_path: Path) -> None:
    costs = {
        "step": 1,
        "actions": {"left": 2},
        "propositions": {"mud": 5, "ice": {"start": 3, "hold": -1}},
        "transitions": [{"from": "F[0,2]@x0 g", "when": "g & !mud", "to": "true", "cost": -7}],
    }
    world = load_world(write(tmp_path, costs))
    assert world.costs is not None
    where = world.costs.transitions[0].where
    assert world.costs == Costs(
        step=1.0,
        actions=(("left", 2.0),),
        propositions=(PropositionCost("ice", -1.0, 3.0), PropositionCost("mud", 5.0)),
        transitions=(TransitionCost("F[0,2]@x0 g", "g & !mud", "true", -7.0, where),),
    )
    assert where.startswith(f"{tmp_path / 'world.yaml'}:")
    assert where.endswith(": costs.transitions[0]")
    # the priced propositions are the world's too, beside the task's
    assert world.propositions == ("g", "ice", "mud")


def test_a_world_without_costs_has_none_and_only_the_task_propositions(tmp_path: Path) -> None:
    path = tmp_path / "world.yaml"
    path.write_text(yaml.safe_dump(CORRIDOR), encoding="utf-8")
    world = load_world(path)
    assert world.costs is None and world.propositions == ("g",)


def test_unknown_proposition(tmp_path: Path) -> None:
    found = problems(tmp_path, {"propositions": {"lava": 1}})
    assert found == ["costs.propositions.lava: unknown proposition 'lava' (labels: g, ice, mud)"]


def test_unknown_proposition_in_when(tmp_path: Path) -> None:
    found = problems(tmp_path, {"transitions": [{"when": "g | lava", "cost": 1}]})
    assert len(found) == 1 and "costs.transitions[0].when: unknown proposition 'lava'" in found[0]


def test_obligation_naming_a_proposition_outside_the_task(tmp_path: Path) -> None:
    found = problems(tmp_path, {"transitions": [{"from": "F[0,2] mud", "cost": 1}]})
    assert found == [
        "costs.transitions[0].from: proposition 'mud' is not in the task (its propositions: g)"
    ]


def test_obligation_that_does_not_parse_shows_where(tmp_path: Path) -> None:
    found = problems(tmp_path, {"transitions": [{"from": "F[0,2 g", "cost": 1}]})
    assert found[0].startswith("costs.transitions[0].from: the obligation does not parse")
    assert "F[0,2 g\n" in found[0] and "^" in found[0]


def test_when_with_a_temporal_operator(tmp_path: Path) -> None:
    found = problems(tmp_path, {"transitions": [{"when": "F g", "cost": 1}]})
    assert found == [
        "costs.transitions[0].when: a letter formula has no temporal operator, found F"
    ]


def test_unknown_action(tmp_path: Path) -> None:
    found = problems(tmp_path, {"actions": {"jump": 1}})
    assert found == ["costs.actions.jump: unknown action 'jump' (actions: left, right, stay)"]


@pytest.mark.parametrize(
    ("costs", "expected"),
    [
        ({"step": float("nan")}, "costs.step: expected a number, got NaN"),
        ({"step": float("inf")}, "costs.step: expected a number, got Infinity"),
        ({"step": "one"}, 'costs.step: expected a number, got "one"'),
        ({"step": True}, "costs.step: expected a number, got true"),
        ({"actions": {"left": None}}, "costs.actions.left: expected a number, got null"),
        ({"propositions": {"mud": float("-inf")}}, "costs.propositions.mud: expected a number"),
        ({"propositions": {"mud": [5]}}, "costs.propositions.mud: expected a number (its hold "),
        ({"propositions": {"mud": {"hod": 5}}}, "unknown field; did you mean 'hold'?"),
        ({"transitions": [{"from": "g"}]}, "costs.transitions[0].cost: required field is missing"),
        ({"transitions": [{"frm": "g", "cost": 1}]}, "unknown field; did you mean 'from'?"),
        ({"transitions": [{"from": 3, "cost": 1}]}, "costs.transitions[0].from: expected a string"),
        ({"transitions": {"from": "g"}}, "costs.transitions: expected a list"),
        ({"steps": 1}, "costs.steps: unknown field; did you mean 'step'?"),
        ([1, 2], "costs: expected a mapping"),
    ],
)
def test_bad_values_are_world_errors(tmp_path: Path, costs: Any, expected: str) -> None:
    found = problems(tmp_path, costs)
    assert len(found) == 1 and expected in found[0], found


def test_every_problem_is_reported_at_once(tmp_path: Path) -> None:
    costs = {"actions": {"jump": 1}, "propositions": {"lava": 1}}
    assert len(problems(tmp_path, costs)) == 2


# --- obligation patterns ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("pattern", "obligation", "matches"),
    [
        ("F[0,5]@x0 b", "F[0,5] b", True),
        ("F[0,5]@x0 b", "F[0,0] b", True),  # the clock at its bound
        ("F[0,5] b", "F[0,6] b", False),  # time does not run backwards
        ("F[2,5] b", "F[0,2] b", True),  # shifted by 3: [max(2 - 3, 0), 5 - 3]
        ("F[2,5] b", "F[0,4] b", False),  # [0,4] is no shift of [2,5]
        ("F[0,5]@x0 a & F[0,5]@x0 b", "F[0,3] b & F[0,3] a", True),  # any order
        ("F[0,5]@x0 a & F[0,5]@x0 b", "F[0,3] a & F[0,4] b", False),  # one clock, one shift
        ("F[0,5] a & F[0,5] b", "F[0,3] a & F[0,4] b", True),  # no clocks: shifts apart
        ("F[0,5] b", "F[0,3] b & F[0,2] a", False),
        ("F[1,3]@x0 b & G (a -> F[2,4] b)", "G (!a | F[2,4] b) & F[0,2] b", True),
        ("F[1,3]@x0 b & G (!a | F[2,4] b)", "G (!a | F[1,3] b) & F[0,2] b", False),  # nested
        ("F[1,3] b & G (!a | F[2,4] b)", "G (!a | F[2,4] b) & F[1,3] b & F[0,2] b", False),
        ("!(a U[0,3] b)", "!a R[0,2] !b", True),  # negation normal form
        ("true", "true", True),
        ("false", "true", False),
    ],
)
def test_obligation_patterns(pattern: str, obligation: str, matches: bool) -> None:
    assert ObligationPattern.parse(pattern).matches(obligation) is matches


def test_letter_formulas() -> None:
    when = letter_formula("g & !(mud | ice) -> true")
    assert letter_holds(when, {"g"}) and letter_holds(when, set())
    assert letter_holds(letter_formula("a <-> b"), {"a", "b"})
    assert not letter_holds(letter_formula("a & !b"), {"a", "b"})
    with pytest.raises(ValueError, match="found U"):
        letter_formula("a U b")


# --- the cost of every product transition ------------------------------------------------


def corridor_product(tmp_path: Path, costs: Any) -> tuple[Any, Any, Any]:
    world = load_world(write(tmp_path, costs))
    automaton = translate(parse(world.spec))
    return world, automaton, build_product(world, automaton)


def late_state(automaton: Any) -> int:
    """The automaton state of the last moment, ``F[0,0] g``."""
    (late,) = [q for q in range(len(automaton.states)) if automaton.obligation(q) == "F[0,0] g"]
    return late


def choice_of(product: Any, world: Any, cell: tuple[int, int], q: int, action: str) -> int:
    s, a = world.state_of(cell), world.actions.index(action)
    (x,) = np.flatnonzero((product.world_state == s) & (product.automaton_state == q))
    return int(product.choice_ptr[x]) + int(a)


def test_product_costs_by_hand(tmp_path: Path) -> None:
    costs = {
        "step": 1,
        "actions": {"left": 2, "right": 2},
        "propositions": {"mud": 5, "ice": {"start": 3}},
        "transitions": [{"from": "F[0,0] g", "when": "g", "cost": -2}],
    }
    world, automaton, product = corridor_product(tmp_path, costs)
    found = product_costs(world, automaton, product)
    t = product.transitions
    # From the start (0, 1), automaton state 0 (F[0,2] g), right: to (0, 2) w.p. 0.8 (ice
    # starts: 1 + 2 + 3) or stay (1 + 2).
    c = choice_of(product, world, (0, 1), 0, "right")
    entries = range(int(t.indptr[c]), int(t.indptr[c + 1]))
    by_cell = {
        world.cells[int(product.world_state[t.targets[j]])]: found.transition[j] for j in entries
    }
    assert by_cell == {(0, 1): 3.0, (0, 2): 6.0}
    assert found.choice[c] == pytest.approx(0.8 * 6 + 0.2 * 3)
    # Staying on ice pays no start again (it held where the step came from).
    q1 = int(product.automaton_state[t.targets[int(t.indptr[c])]])
    assert found.choice[choice_of(product, world, (0, 2), q1, "stay")] == 1.0
    # Reading g in F[0,0] g (the last moment): satisfied, all successors merged into one
    # transition costing their expectation; the rule pays -2. Right from the mud: 1 + 2 - 2,
    # and 5 more if the robot stays in the mud (w.p. 0.2).
    late = late_state(automaton)
    c = choice_of(product, world, (0, 0), late, "right")
    assert t.targets[int(t.indptr[c])] == SATISFIED and t.indptr[c + 1] - t.indptr[c] == 1
    assert found.choice[c] == pytest.approx(1 + 2 - 2 + 0.2 * 5)
    # The absorbing states' loops cost nothing.
    sat = slice(int(product.choice_ptr[SATISFIED]), int(product.choice_ptr[SATISFIED + 1]))
    assert not found.choice[sat].any()


def test_a_rule_that_matches_nothing_is_refused(tmp_path: Path) -> None:
    rule = {"from": "F[0,2] g", "when": "mud & !g", "cost": 1}  # the mud is where g is
    world, automaton, product = corridor_product(tmp_path, {"transitions": [rule]})
    with pytest.raises(CostError, match=r"costs.transitions\[0\]: matches no transition"):
        product_costs(world, automaton, product)
    lenient = product_costs(world, automaton, product, strict=False)
    assert not lenient.choice.any()


def test_rules_add_up_and_to_names_the_target(tmp_path: Path) -> None:
    rules = [
        {"when": "g", "to": "true", "cost": 10},  # any state reading g: into satisfied
        {"from": "F[0,2]@x0 g", "when": "g", "cost": 1},  # the same transitions, again
        {"to": "false", "cost": 100},  # into violated
    ]
    world, automaton, product = corridor_product(tmp_path, {"transitions": rules})
    found = product_costs(world, automaton, product)
    late = late_state(automaton)
    assert found.choice[choice_of(product, world, (0, 0), late, "stay")] == 11.0
    assert found.choice[choice_of(product, world, (0, 1), late, "stay")] == 100.0
    assert found.choice[choice_of(product, world, (0, 1), 0, "stay")] == 0.0


def test_an_env_world_has_costs_too(tmp_path: Path) -> None:
    pytest.importorskip("gymnasium")
    data = {
        "env": {"id": "FrozenLake-v1", "kwargs": {"map_name": "4x4", "is_slippery": True}},
        "labels": {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 11, 12]}, "corner": {"obs": [3]}},
        "spec": {"formula": "!hole U[0,100] goal"},
        "horizon": 110,
        "costs": {"actions": {"left": 0.5}, "propositions": {"corner": 3}},
    }
    path = tmp_path / "lake.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    world = load_world(path)
    assert world.costs is not None and world.costs.actions == (("left", 0.5),)
    assert world.propositions == ("corner", "goal", "hole")
    data["costs"] = {"actions": {"jump": 1}}
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(
        WorldError, match=r"costs.actions.jump: unknown action 'jump' \(actions: left"
    ):
        load_world(path)


def test_the_json_schema_accepts_the_shipped_example() -> None:
    schema = world_json_schema()
    data = yaml.safe_load(
        (ROOT / "specs" / "costs" / "trm-orders.yaml").read_text(encoding="utf-8")
    )
    assert schema_errors(data, schema, schema) == []
    data["costs"]["propositions"] = {"a": "five"}
    assert schema_errors(data, schema, schema) != []
