"""The least cost is lexicographic (issue 42): ``least_cost`` against a brute force over every
deterministic policy of tiny products with epsilon jumps and acceptance sets, and the policy it
returns (and ``check --policy`` prints) evaluated on its own.

The brute force shares nothing with the backward induction of :mod:`mitlc.check.costs` but the
product, its costs and the one success rule (:func:`mitlc.product.explicit.recursion_ends`):
it enumerates the policies with a choice per (step, frontier, product state) that the policy
reaches, layer by layer, carries each one's distribution forward (jumps take no step and cost
nothing, the decided states pay nothing more) and keeps the lexicographic best: the highest
success (within 1e-9), then the least expected cost.
"""

from __future__ import annotations

import json
import random
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from mitlc.automata import LazyAutomaton, translate
from mitlc.check.costs import LeastCost, least_cost, policy_data
from mitlc.check.solve import pmax_horizon
from mitlc.cli import app
from mitlc.product.costs import product_costs
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, build_product, recursion_ends
from mitlc.syntax import parse
from mitlc.task import rules
from mitlc.worlds import load_world
from mitlc.worlds.costs import Costs, PropositionCost, TransitionCost
from mitlc.worlds.model import FloatArray, World

SUCCESS_TIE = 1e-9
"""Two policies' successes this close are the same success (the worlds' probabilities are
tenths, over at most six steps: distinct successes differ by far more)."""

POLICY_LIMIT = 3000
"""An instance with more policies than this is skipped by the brute force."""

FORMULAS = (
    "F G a & F[0,3] b",
    "G F a | F G b",
    "F G a | G F b",
    "G F a & F[0,2] b",
    "F G a",
    "G F a",
    "G F a & G F b",
    "F G !b & F[0,4] a",
    "F G a | F[0,2] b",
    "G F b | F[1,3] a",
    "F G (a | b) & G F b",
    "G F (a & b) | F G !a",
    "F[0,2] a | F[1,4] b",
    "G (a -> F[0,2] b)",
    "(F G a) & (F[0,1] b | F[2,3] !a)",
)
"""Persistence (F G: an epsilon jump), recurrence (G F: acceptance sets), deadlines and
disjunctions of them."""

Point = tuple[int, int]
"""``(frontier mask, product state)``."""


class TooManyPolicies(Exception):
    """The brute force gave up: more policies than its limit."""


# --- the instances ------------------------------------------------------------------------


@dataclass(frozen=True)
class Instance:
    """A tiny world and task, its product and each choice's expected immediate cost."""

    text: str
    world: World
    product: Product
    costs: FloatArray
    path: Path


def random_instance(rng: random.Random, folder: Path, index: int) -> Instance:
    """A 1x2, 1x3 or 2x2 grid with a and b on random cells, 2-3 actions, certain or slipping
    moves, a task of :data:`FORMULAS`, and random costs (some negative: rewards) per step, per
    action, per proposition and per automaton transition (rules on the obligations the product
    reaches)."""
    rows, cols = rng.choice([(1, 2), (1, 3), (2, 2)])
    cells = [(r, c) for r in range(rows) for c in range(cols)]
    moves = ["left", "right"] if rows == 1 else rng.choice([["down", "right"], ["up", "left"]])
    actions = moves + (["stay"] if rng.random() < 0.4 else [])
    intended = rng.choice([1.0, 1.0, 0.8, 0.6])
    text = rng.choice(FORMULAS)
    data: dict[str, Any] = {
        "name": f"lex{index}",
        "grid": {"rows": rows, "cols": cols},
        "labels": {
            "a": [list(c) for c in rng.sample(cells, rng.randint(1, len(cells)))],
            "b": [list(c) for c in rng.sample(cells, rng.randint(1, len(cells)))],
        },
        "start": list(rng.choice(cells)),
        "actions": actions,
        "motion": {"intended": intended, "sideways": round((1 - intended) / 2, 10)},
        "spec": {"formula": text},
        "horizon": 6,
    }
    path = folder / f"lex{index}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    world = load_world(path)
    automaton = translate(parse(text))
    product = build_product(world, automaton)
    reached = sorted({automaton.obligation(int(q)) for q in product.automaton_state if q >= 0})
    transitions = tuple(
        TransitionCost(
            rng.choice(reached),
            rng.choice(["true", *world.propositions, f"!{world.propositions[0]}"]),
            rng.choice([None, None, "true", "false"]),
            float(rng.randint(-3, 12)),
        )
        for _ in range(rng.randint(1, 3))
    )
    step = float(rng.randint(0, 3))
    priced = tuple((a, float(rng.randint(0, 2))) for a in actions if rng.random() < 0.3)
    held = tuple(
        PropositionCost(name, float(rng.randint(-1, 3)), float(rng.randint(0, 2)))
        for name in world.propositions
        if rng.random() < 0.3
    )
    world = replace(world, costs=Costs(step, priced, held, transitions))
    costs = product_costs(world, automaton, product, strict=False).choice
    return Instance(text, world, product, costs, path)


def instances(seed: int, count: int, folder: Path) -> Iterator[Instance]:
    rng = random.Random(seed)
    for index in range(count):
        yield random_instance(rng, folder, index)


# --- the brute force ----------------------------------------------------------------------


DECIDED = frozenset((SATISFIED, VIOLATED))
"""The absorbing states: the task is decided, the episode over."""


class Forward:
    """Forward propagation of a policy's distribution over (frontier, product state), step by
    step: what a step of given choices costs and where it leads (nothing of ``least_cost``)."""

    def __init__(self, product: Product, costs: FloatArray) -> None:
        t, ptr = product.transitions, product.choice_ptr
        self.starts = product.starts
        self.ends = recursion_ends(product).tolist()
        self.all_sets = (1 << product.num_sets) - 1
        self.options = [list(range(int(ptr[x]), int(ptr[x + 1]))) for x in range(len(ptr) - 1)]
        self.jump = (product.action < 0).tolist()
        self.cost = costs.tolist()
        self.marks = product.marks.tolist()
        self.rows = [
            list(
                zip(
                    t.targets[t.indptr[c] : t.indptr[c + 1]].tolist(),
                    t.probs[t.indptr[c] : t.indptr[c + 1]].tolist(),
                    strict=True,
                )
            )
            for c in range(product.num_choices)
        ]

    def start(self) -> dict[Point, float]:
        return {(0, x): p for x, p in self.starts}

    def jump_target(self, point: Point, c: int) -> Point:
        return point[0], self.rows[c][0][0]

    def step(
        self, layer: Mapping[Point, float], policy: Mapping[Point, int]
    ) -> tuple[dict[Point, float], float] | None:
        """One step from ``layer`` by ``policy`` (a choice per point it reaches, jumps
        followed within the step): the next layer and the step's expected cost; ``None`` when
        the policy's jumps go round in a circle."""
        after: dict[Point, float] = {}
        cost = 0.0
        for point, p in layer.items():
            if point[1] in DECIDED:  # nothing more is paid
                after[point] = after.get(point, 0.0) + p
                continue
            c = policy[point]
            if self.jump[c]:
                followed = self.follow(point, policy)
                if followed is None:
                    return None
                point, c = followed
                if c < 0:  # jumped into a decided state
                    after[point] = after.get(point, 0.0) + p
                    continue
            cost += p * self.cost[c]
            moved = rules.saturate(point[0], self.marks[c], self.all_sets)
            for y, q in self.rows[c]:
                after[(moved, y)] = after.get((moved, y), 0.0) + p * q
        return after, cost

    def follow(self, point: Point, policy: Mapping[Point, int]) -> tuple[Point, int] | None:
        """The point ``policy``'s jumps from ``point`` lead to and its world choice (``-1`` in
        a decided state); ``None`` for a circle of jumps."""
        seen = set()
        while point[1] not in DECIDED:
            c = policy[point]
            if not self.jump[c]:
                return point, c
            if point in seen:
                return None
            seen.add(point)
            point = self.jump_target(point, c)
        return point, -1

    def success(self, layer: Mapping[Point, float]) -> float:
        """The success of stopping with ``layer`` (the one rule, read through
        ``recursion_ends``)."""
        ends = self.ends
        return sum(p * ends[mask][x] for (mask, x), p in layer.items())


def brute_force(
    product: Product, costs: FloatArray, horizon: int, limit: int = POLICY_LIMIT
) -> tuple[float, float, int]:
    """``(best success, least cost among the policies of best success, policies)`` over every
    deterministic policy with a choice per (steps left, frontier, product state) it reaches;
    :class:`TooManyPolicies` past ``limit`` policies."""
    forward = Forward(product, costs)
    leaves: list[tuple[float, float]] = []

    def assignments(layer: Mapping[Point, float]) -> Iterator[dict[Point, int]]:
        """Every choice per point of ``layer``, and per point its jumps reach."""
        todo = sorted(point for point in layer if point[1] not in DECIDED)

        def extend(policy: dict[Point, int], pending: list[Point]) -> Iterator[dict[Point, int]]:
            while pending and (pending[0] in policy or pending[0][1] in DECIDED):
                pending = pending[1:]
            if not pending:
                yield policy
                return
            point = pending[0]
            for c in forward.options[point[1]]:
                more = [forward.jump_target(point, c)] if forward.jump[c] else []
                yield from extend({**policy, point: c}, pending[1:] + more)

        yield from extend({}, todo)

    def search(layer: Mapping[Point, float], left: int, paid: float) -> None:
        if left == 0:  # the horizon: no step and no jump any more
            leaves.append((forward.success(layer), paid))
            if len(leaves) > limit:
                raise TooManyPolicies
            return
        for policy in assignments(layer):
            stepped = forward.step(layer, policy)
            if stepped is not None:
                search(stepped[0], left - 1, paid + stepped[1])

    search(forward.start(), horizon, 0.0)
    best = max(s for s, _ in leaves)
    return best, min(c for s, c in leaves if s >= best - SUCCESS_TIE), len(leaves)


def evaluate(forward: Forward, policy_at: Any, horizon: int) -> tuple[float, float]:
    """The success and expected cost of the policy ``policy_at(step, point) -> choice``."""
    layer, paid = forward.start(), 0.0
    for step in range(horizon):
        reached = _Lazy(lambda point, step=step: policy_at(step, point))
        stepped = forward.step(layer, reached)
        assert stepped is not None, "the policy's jumps go round in a circle"
        layer, paid = stepped[0], paid + stepped[1]
    return forward.success(layer), paid


class _Lazy(dict[Point, int]):
    """A policy's choices at one step, asked for as the propagation reaches each point."""

    def __init__(self, ask: Any) -> None:
        super().__init__()
        self.ask = ask

    def __missing__(self, point: Point) -> int:
        self[point] = choice = int(self.ask(point))
        return choice


def returned_policy(found: LeastCost) -> Any:
    """``least_cost``'s choices as ``policy_at(step, point)``."""
    return lambda step, point: found.choices[found.horizon - step][point]


def printed_policy(data: dict[str, Any], world: World, product: Product) -> Any:
    """The rows ``policy_data`` writes (``check --policy``'s file) as ``policy_at``: each
    reached point's row read back to the product's choice by cell, automaton state, frontier
    and action name."""
    table = {
        (r["step"], tuple(r["cell"]), r["automaton_state"], r.get("frontier", 0)): r["action"]
        for r in data["rows"]
    }
    ptr = product.choice_ptr

    def policy_at(step: int, point: Point) -> int:
        mask, x = point
        q = int(product.automaton_state[x])
        cell = tuple(world.cells[int(product.world_state[x])])
        name = table[(step, cell, q, mask)]
        if name.startswith("jump:"):
            action = -1 - int(name.removeprefix("jump:"))
        else:
            action = world.actions.index(name)
        (c,) = [c for c in range(int(ptr[x]), int(ptr[x + 1])) if product.action[c] == action]
        return c

    return policy_at


# --- the comparison -----------------------------------------------------------------------


@dataclass
class Tally:
    """What a run compared: instances per horizon, compared and skipped (too many policies);
    among the compared, those with jumps, with acceptance sets, and those whose lexicographic
    policy takes a jump; and the policies enumerated."""

    compared: dict[int, int] = field(default_factory=dict)
    skipped: dict[int, int] = field(default_factory=dict)
    with_jumps: int = 0
    with_sets: int = 0
    jumped: int = 0
    policies: int = 0


def close(a: float, b: float) -> bool:
    """Two expected costs equal up to rounding (relative 1e-9)."""
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


def compare(instance: Instance, horizon: int, tally: Tally, limit: int) -> list[str]:
    """The mismatches of ``least_cost`` with the brute force on one instance and horizon, and
    of the returned policy's own success and cost with ``least_cost``'s figures."""
    product, costs = instance.product, instance.costs
    found = least_cost(product, costs, horizon)
    best = pmax_horizon(product, horizon)[0]
    where = f"{instance.path.name} {instance.text!r} H={horizon}"
    problems = []
    forward = Forward(product, costs)
    data = policy_data(found, product, instance.world)
    printed = printed_policy(data, instance.world, product)
    for name, policy in (("returned", returned_policy(found)), ("printed", printed)):
        success, cost = evaluate(forward, policy, horizon)
        if abs(success - best) > SUCCESS_TIE or not close(cost, found.value):
            problems.append(
                f"{where}: the {name} policy gives ({success}, {cost}), not ({best}, {found.value})"
            )
    try:
        brute_success, brute_cost, count = brute_force(product, costs, horizon, limit)
    except TooManyPolicies:
        tally.skipped[horizon] = tally.skipped.get(horizon, 0) + 1
        return problems
    tally.compared[horizon] = tally.compared.get(horizon, 0) + 1
    tally.policies += count
    tally.with_jumps += bool((product.action < 0).any())
    tally.with_sets += bool(product.num_sets)
    tally.jumped += any(row["action"].startswith("jump:") for row in data["rows"])
    if abs(brute_success - best) > SUCCESS_TIE:
        problems.append(f"{where}: pmax_horizon {best}, brute force {brute_success}")
    if not close(brute_cost, found.value):
        problems.append(
            f"{where}: least cost {found.value}, brute force ({brute_success}, {brute_cost})"
        )
    return problems


def run(
    seed: int, count: int, folder: Path, horizons: range, limit: int = POLICY_LIMIT
) -> tuple[list[str], Tally]:
    """Every mismatch over ``count`` seeded instances and ``horizons``, and the tally."""
    tally, problems = Tally(), []
    for instance in instances(seed, count, folder):
        for horizon in horizons:
            problems += compare(instance, horizon, tally, limit)
    return problems, tally


# --- the tests ----------------------------------------------------------------------------


JUMP_NEEDED: dict[str, Any] = {
    "name": "jump-needed",
    "grid": {"rows": 1, "cols": 2},
    "labels": {"a": [[0, 0], [0, 1]], "b": [[0, 1]]},
    "start": [0, 1],
    "actions": ["left"],
    "motion": {"intended": 1.0, "sideways": 0.0},
    "spec": {"formula": "F G a & G F b"},
    "horizon": 2,
    "costs": {"step": 1, "transitions": [{"from": "G a & G F b", "when": "b", "cost": 9}]},
}
"""Issue 42's reproduction in the finite reading: ``a`` on both cells, ``b`` at (0, 1), the
start; the one action moves left for sure. Without the jump the episode ends having read
``b`` then ``a`` (the recurrence's last ``b`` is not the last letter: a failure); after the
jump to ``G a & G F b`` the first step
completes a round and the second keeps ``G a``: success 1. That first step pays 1 + 9, the
second 1: (1.0, 11.0). The code before the fix reported (1.0, 2.0) with a policy of success 0
(no jump: the jump was taken only when cheaper than the best world choice)."""


def write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / f"{data['name']}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_the_optimum_needs_a_jump(tmp_path: Path) -> None:
    """``check --policy`` reports (1.0, 11.0) and writes a policy that jumps and attains both,
    evaluated from the file on its own; the brute force agrees."""
    path, policy = write(tmp_path, JUMP_NEEDED), tmp_path / "policy.json"
    done = CliRunner().invoke(app, ["check", str(path), "--json", "--policy", str(policy)])
    assert done.exit_code == 0, done.output
    summary = json.loads(done.output)
    assert (summary["pmax_horizon"], summary["min_cost_horizon"]) == (1.0, 11.0)
    data = json.loads(policy.read_text(encoding="utf-8"))
    assert data["rows"][0]["action"].startswith("jump:")
    world = load_world(path)
    automaton = LazyAutomaton(parse(world.spec))  # as check makes it: the same state ids
    product = build_product(world, automaton)
    costs = product_costs(world, automaton, product).choice
    forward = Forward(product, costs)
    assert evaluate(forward, printed_policy(data, world, product), 2) == (1.0, 11.0)
    assert brute_force(product, costs, 2)[:2] == (1.0, 11.0)


def test_the_issue_world_as_written(tmp_path: Path) -> None:
    """The issue's own world (``F G a & F[0,3] b`` from (0, 0), the rule on ``G a & F[0,3]
    b``) at horizons 1-5: ``check``'s figures are the brute force's whatever the success rule
    makes them, and the policy it prints attains them."""
    data = JUMP_NEEDED | {
        "name": "issue",
        "start": [0, 0],
        "actions": ["up", "down", "left", "right", "stay"],
        "spec": {"formula": "F G a & F[0,3] b"},
        "costs": {"step": 1, "transitions": [{"from": "G a & F[0,3] b", "cost": 10}]},
    }
    path = write(tmp_path, data)
    world = load_world(path)
    automaton = translate(parse(world.spec))
    product = build_product(world, automaton)
    costs = product_costs(world, automaton, product).choice
    instance = Instance(world.spec, world, product, costs, path)
    tally = Tally()
    problems = [p for h in range(1, 6) for p in compare(instance, h, tally, 100_000)]
    assert not problems, "\n".join(problems)
    assert sum(tally.compared.values()) == 5


def test_a_sample_agrees_with_the_brute_force(tmp_path: Path) -> None:
    """50 seeded tiny worlds, horizons 1-4: the least cost is the brute force's and both the
    returned and the printed policy attain it; jumps and acceptance sets among them, and
    optima that take a jump (the code before the fix failed 3 of these instances)."""
    problems, tally = run(5, 50, tmp_path, range(1, 5))
    assert not problems, "\n".join(problems)
    assert sum(tally.compared.values()) >= 150, tally
    assert tally.with_jumps >= 80 and tally.with_sets >= 100 and tally.jumped >= 15, tally


@pytest.mark.slow
def test_many_worlds_agree_with_the_brute_force(tmp_path: Path) -> None:
    """500 seeded tiny worlds, horizons 1-6 (an instance with more than 10,000 policies is
    skipped by the brute force, not by the policies' own evaluation; the code before the fix
    failed 13 of these instances, in 3 worlds)."""
    problems, tally = run(2024, 500, tmp_path, range(1, 7), limit=10_000)
    assert not problems, "\n".join(problems[:20]) + f"\n({len(problems)} in all)"
    assert sum(tally.compared.values()) >= 2000 and tally.compared.get(6, 0) >= 150, tally
    assert tally.jumped >= 200, tally
