"""Timed shields (mitlc.check.shield): their guarantees checked exactly on random finite worlds
by an evaluator written here (state by state in Python, not the shield's own pass), a
hand-worked world where the shield must block one action, and the settings' errors."""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.check.shield import Shield, ShieldError, shield
from mitlc.check.solve import pmax_horizon
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, build_product, recursion_ends
from mitlc.syntax import parse
from mitlc.worlds.model import World
from tests.test_check import random_world
from tests.test_env import corridor as env_corridor

SPECS = [
    "!a U[2,6] b",
    "F[0,5] (a & F[0,4] b)",
    "(!a U[1,4] a) & F[0,8] b",
    "G (a -> F[0,3] b)",
    "G[0,6] !a & F[2,7] b",
    "F G a",
    "G F a & G F b",
]

Policy = Callable[[int, int, int, list[int]], dict[int, float]]
"""``policy(r, mask, x, allowed)``: a distribution over the allowed choices of ``x``."""


def allowed_choices(product: Product, s: Shield, r: int, mask: int, x: int) -> list[int]:
    lo, hi = int(product.choice_ptr[x]), int(product.choice_ptr[x + 1])
    cs = np.arange(lo, hi)
    ok = s.allowed(np.full(len(cs), r), np.full(len(cs), mask), cs)
    return cs[ok].tolist()


def evaluate(product: Product, s: Shield, policy: Policy, violation: bool) -> float:
    """The probability of success (or, with ``violation``, of entering the violated state)
    within ``s.horizon`` steps from the start, following ``policy`` among the shield's allowed
    choices: backward induction, one state at a time (saturated frontier masks, jumps take no
    step)."""
    n, masks, t = product.num_states, 1 << product.num_sets, product.transitions
    if violation:
        value = np.zeros((masks, n))
        value[:, VIOLATED] = 1.0
    else:
        value = recursion_ends(product).copy()
    jump_sources = {int(product.choice_ptr.searchsorted(c, "right") - 1)
                    for c in np.flatnonzero(product.action < 0)}  # fmt: skip
    order = [x for x in range(n) if x not in jump_sources] + sorted(jump_sources)
    for r in range(1, s.horizon + 1):
        new = np.zeros_like(value)
        for mask in range(masks):
            for x in order:
                if x in (SATISFIED, VIOLATED):
                    new[mask, x] = float(x == VIOLATED) if violation else float(x == SATISFIED)
                    continue
                allowed = allowed_choices(product, s, r, mask, x)
                assert allowed, f"no choice allowed at r={r}, mask={mask}, x={x}"
                total = 0.0
                for c, weight in policy(r, mask, x, allowed).items():
                    lo, hi = t.indptr[c], t.indptr[c + 1]
                    if product.action[c] < 0:
                        total += weight * new[mask, t.targets[lo]]
                        continue
                    after = mask | int(product.marks[c])
                    after = min(after, masks - 1) if product.num_sets else 0
                    total += weight * sum(
                        float(p) * value[after, int(y)]
                        for y, p in zip(t.targets[lo:hi], t.probs[lo:hi], strict=True)
                    )
                new[mask, x] = total
        value = new
    return float(sum(p * value[0, x] for x, p in product.starts))


def uniform(r: int, mask: int, x: int, allowed: list[int]) -> dict[int, float]:
    return {c: 1.0 / len(allowed) for c in allowed}


def random_deterministic(seed: int) -> Policy:
    def policy(r: int, mask: int, x: int, allowed: list[int]) -> dict[int, float]:
        return {random.Random(hash((seed, r, mask, x))).choice(allowed): 1.0}

    return policy


def product_of(seed: int) -> tuple[World, Product]:
    rng = random.Random(seed)
    spec = SPECS[seed % len(SPECS)]
    world = random_world(rng, spec)
    return world, build_product(world, translate(parse(spec)))


@pytest.mark.parametrize("seed", range(14))
@pytest.mark.parametrize("theta", [1.0, 0.7])
def test_every_shielded_policy_keeps_theta_of_the_optimum(seed: int, theta: float) -> None:
    world, product = product_of(seed)
    optimum, _ = pmax_horizon(product, world.horizon)
    s = shield(product, world.horizon, theta=theta)
    assert s.optimum == pytest.approx(optimum, abs=1e-12)
    assert s.success >= theta * optimum - 1e-9
    for policy in (uniform, random_deterministic(seed), random_deterministic(seed + 100)):
        value = evaluate(product, s, policy, violation=False)
        assert value >= s.success - 1e-9 >= theta * optimum - 2e-9
    if theta == 1.0:  # only optimal choices: every shielded policy is optimal
        assert evaluate(product, s, uniform, violation=False) == pytest.approx(optimum, abs=1e-9)


@pytest.mark.parametrize("seed", range(14))
@pytest.mark.parametrize("delta", [0.0, 0.15])
def test_every_shielded_policy_violates_at_most_delta_more_than_the_least(
    seed: int, delta: float
) -> None:
    world, product = product_of(seed)
    s = shield(product, world.horizon, delta=delta)
    assert s.violation <= s.least_violation + delta + 1e-9
    for policy in (uniform, random_deterministic(seed)):
        value = evaluate(product, s, policy, violation=True)
        assert value <= s.violation + 1e-9
    everything = shield(product, world.horizon, delta=1.0)  # allows every choice
    worst_any = everything.violation
    assert s.least_violation <= s.violation <= worst_any + 1e-12


@pytest.mark.parametrize("seed", range(14))
def test_both_together_keep_the_violation_bound(seed: int) -> None:
    world, product = product_of(seed)
    s = shield(product, world.horizon, theta=0.9, delta=0.05)
    assert s.violation <= s.least_violation + 0.05 + 1e-9
    assert evaluate(product, s, uniform, violation=True) <= s.violation + 1e-9
    assert evaluate(product, s, uniform, violation=False) >= s.success - 1e-9


def corridor() -> World:
    """Three cells in a row, ``hole | start | goal`` (tests/test_env.py's); ``left`` and
    ``right`` move one cell surely, ``stay`` stays; the task: ``!hole U[0,3] goal``."""
    world = env_corridor({"hole": [0], "goal": [2]}, start=1, horizon=3)
    return replace(world, spec="!hole U[0,3] goal")


def test_the_corridor_blocks_the_hole_and_waiting_too_long() -> None:
    """Worked by hand. A step reads the position it leaves (docs/episodes.md), so the goal
    must be entered within 2 steps of the horizon's 3 to be read. From the start (3 steps
    left) ``right`` reaches it, ``stay`` too (then ``right``), ``left`` falls in the hole:
    theta = 1 allows right and stay. After one ``stay`` (2 steps left) only ``right`` still
    reaches it in time: the shield blocks ``stay`` there. delta = 0 blocks ``left`` (the hole
    is a violation) but not a wait that makes the episode fail pending at the horizon."""
    world = corridor()
    product = build_product(world, translate(parse(world.spec)))
    s = shield(product, world.horizon, theta=1.0)
    start = product.initial
    names = ["left", "right", "stay"]
    t = product.transitions

    def allowed(shielded: Shield, r: int, x: int) -> set[str]:
        return {names[int(product.action[c])] for c in allowed_choices(product, shielded, r, 0, x)}

    def after(x: int, action: int) -> int:
        return int(t.targets[t.indptr[product.choice_ptr[x] + action]])

    assert s.optimum == 1.0 and s.success == 1.0
    assert allowed(s, 3, start) == {"right", "stay"}
    assert allowed(s, 2, after(start, 2)) == {"right"}
    assert allowed(s, 2, start) == {"right"}  # the same state, fewer steps left: no waiting
    safe = shield(product, world.horizon, delta=0.0)
    assert safe.least_violation == 0.0 and safe.violation == 0.0
    assert allowed(safe, 3, start) == {"right", "stay"}
    # waiting cannot be violated within the horizon any more (it fails at the horizon's end,
    # pending): a violation is the verdict, and delta bounds only violations
    assert allowed(safe, 2, after(start, 2)) == {"right", "stay"}


@pytest.mark.parametrize(
    ("theta", "delta", "message"),
    [(None, None, "needs theta"), (0.0, None, "theta must be"), (1.5, None, "theta must be"),
     (None, -0.1, "delta must be"), (None, 2.0, "delta must be")],
)  # fmt: skip
def test_settings_out_of_range_are_refused(
    theta: float | None, delta: float | None, message: str
) -> None:
    world = corridor()
    product = build_product(world, translate(parse(world.spec)))
    with pytest.raises(ShieldError, match=message):
        shield(product, world.horizon, theta=theta, delta=delta)
