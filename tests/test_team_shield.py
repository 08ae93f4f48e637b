"""Per-robot (decentralised) team shields (:mod:`mitlc.check.team_shield`), against an
independent evaluation: on random small two-robot worlds, the joint actions allowed at every
step are exactly the products of the per-robot masks, and the least success of any policy that
keeps to the masks (a plain minimising recursion over the allowed joint choices, written here)
is the shield's reported guarantee and at least ``theta`` times the optimum."""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.check.shield import shield
from mitlc.check.solve import pmax_horizon
from mitlc.check.team_shield import rectangles, robot_masks, team_shield
from mitlc.product.explicit import SATISFIED, Product, build_product, product_ends
from mitlc.syntax import parse
from mitlc.worlds.kinds.team import load_team_world
from mitlc.worlds.model import World

FORMULAS = (
    "F[0,3] a_robot_0 & F[0,4] b_robot_1 & G !collide",
    "(!a_robot_0 U[1,3] a_robot_0) & G !collide",
    "F[0,4] (a_robot_0 & b_robot_1)",
    "G[0,4] !collide & F[2,4] a",
    "F[0,3] b_robot_0 | F[0,2] a_robot_1",
)


def random_world(tmp_path: Path, rng: random.Random, i: int) -> World:
    cells = [(r, c) for r in range(2) for c in range(3)]
    a, b, s0, s1 = rng.sample(cells, 4)
    slip = rng.choice(["{intended: 1.0, sideways: 0.0}", "{intended: 0.8, sideways: 0.1}"])
    text = f"""
grid: {{rows: 2, cols: 3}}
labels: {{a: [{list(a)}], b: [{list(b)}]}}
actions: [up, down, left, right, stay]
motion: {slip}
robots:
  robot_0: {{start: {list(s0)}}}
  robot_1: {{start: {list(s1)}, actions: [up, down, stay]}}
collisions: {{label: collide, block: {rng.choice(["true", "false"])}}}
spec: {{formula: "{rng.choice(FORMULAS)}"}}
horizon: {rng.randint(3, 5)}
"""
    path = tmp_path / f"team{i}.yaml"
    path.write_text(text)
    return load_team_world(path)


def least_success(
    product: Product, horizon: int, allowed: dict[tuple[int, int], set[int]]
) -> float:
    """The least success within ``horizon`` steps of any policy that takes, with ``r`` steps
    left in state ``x``, a choice of ``allowed[r, x]`` (tasks with no acceptance sets: success
    is reaching the satisfied state, or stopping where the finite trace holds)."""
    ends = product_ends(product)
    value = np.array([1.0 if x == SATISFIED or ends[x] >= 1 else 0.0
                      for x in range(product.num_states)])  # fmt: skip
    t = product.transitions
    for r in range(1, horizon + 1):
        after = value.copy()
        for x in range(product.num_states):
            lo, hi = int(product.choice_ptr[x]), int(product.choice_ptr[x + 1])
            options = [c for c in range(lo, hi) if c in allowed.get((r, x), set(range(lo, hi)))]
            worth = []
            for c in options:
                targets, probs = t.row(c)
                worth.append(float(np.dot(probs, value[targets])))
            after[x] = min(worth)
        value = after
    return float(value[product.initial])


@pytest.mark.parametrize("seed", range(12))
def test_per_robot_masks_keep_the_guarantee_whatever_each_robot_picks(
    tmp_path: Path, seed: int
) -> None:
    rng = random.Random(seed)
    world = random_world(tmp_path, rng, seed)
    assert world.team is not None
    radices = tuple(len(a) for a in world.team.actions)
    product = build_product(world, translate(parse(world.spec)))
    assert product.num_sets == 0
    theta = rng.choice([1.0, 0.9, 0.5])
    made = team_shield(product, world.horizon, radices, theta=theta)
    optimum, _ = pmax_horizon(product, world.horizon)
    allowed: dict[tuple[int, int], set[int]] = {}
    for x in range(2, product.num_states):
        lo, hi = int(product.choice_ptr[x]), int(product.choice_ptr[x + 1])
        choices = np.arange(lo, hi)
        assert list(product.action[lo:hi]) == list(range(len(world.actions)))
        for r in range(1, world.horizon + 1):
            masks = robot_masks(made, choices, radices, r, 0)
            joint = made.allowed(np.full(hi - lo, r), np.zeros(hi - lo, dtype=np.int64), choices)
            product_of_masks = np.logical_and.outer(masks[0], masks[1]).ravel()
            assert np.array_equal(joint, product_of_masks)  # a rectangle: robots choose alone
            assert joint.any()
            allowed[(r, x)] = {int(c) for c in choices[joint]}
    worst = least_success(product, world.horizon, allowed)
    assert worst == pytest.approx(made.success, abs=1e-9)
    assert worst >= theta * float(optimum) - 1e-9
    central = shield(product, world.horizon, theta=theta)
    assert central.success >= theta * float(optimum) - 1e-9


def test_rectangles_grow_around_the_best_allowed_joint_action() -> None:
    ok = np.array(
        [
            # robot 0 has 2 actions, robot 1 has 3: rows are joint actions a0 * 3 + a1
            [True, True, False, True, True, True],  # {0,1} x {0,1}
            [False, False, False, False, False, False],  # nothing allowed: stays empty
            [True, False, False, False, True, False],  # a diagonal: a single joint action
        ]
    )
    score = np.array([[0.0, 1.0, 0.0, 0.0, 0.5, 0.0]] * 3)
    kept = rectangles(ok, score, (2, 3))
    assert kept[0].tolist() == [True, True, False, True, True, False]
    assert not kept[1].any()
    assert kept[2].sum() == 1 and kept[2][4]  # the better of the two
