"""Shields over a POMDP's observations (mitlc.check.shield_observed): the guarantees it reports
checked exactly on random POMDPs by an evaluator written here (over product states and the
observations drawn on entering them), the fully observable case, and the simulator keeping
to it."""

from __future__ import annotations

import random
from dataclasses import replace

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.check.observed import observed_bound
from mitlc.check.shield import ShieldError
from mitlc.check.shield_observed import ObservedShield, observed_shield
from mitlc.check.solve import pmax_horizon
from mitlc.learn.envs.vec import VecProduct, tables
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, build_product, recursion_ends
from mitlc.syntax import parse
from mitlc.worlds import load_world
from mitlc.worlds.model import Observations, Sparse, World
from tests.conftest import ROOT
from tests.test_check import random_world
from tests.test_shield_train import uniform_shielded_success

SPECS = ["!a U[2,6] b", "F[0,5] (a & F[0,4] b)", "G[0,6] !a & F[2,7] b", "G (a -> F[0,3] b)"]


def random_pomdp(seed: int) -> tuple[World, Product]:
    rng = random.Random(seed)
    spec = SPECS[seed % len(SPECS)]
    world = random_world(rng, spec)
    count = rng.randint(2, 3)
    rows = []
    for _ in range(world.num_states):
        seen = sorted(rng.sample(range(count), rng.randint(1, count)))
        weights = [rng.randint(1, 3) for _ in seen]
        rows.append({o: w / sum(weights) for o, w in zip(seen, weights, strict=True)})
    names = tuple(f"o{i}" for i in range(count))
    world = replace(world, observations=Observations(names, Sparse.from_rows(rows)))
    return world, build_product(world, translate(parse(spec)))


def evaluate(world: World, product: Product, s: ObservedShield, pick: str, risk: bool) -> float:
    """The success (or with ``risk`` the violation) probability within the horizon of the
    policy that picks ``"uniform"``-ly among the allowed actions of its key, or the
    ``"first"`` or ``"last"`` of them: backward induction over (mask, state, observation)."""
    assert world.observations is not None
    model = world.observations.model
    n, masks, t = product.num_states, 1 << product.num_sets, product.transitions

    def seen(x: int) -> dict[int, float]:
        if x in (SATISFIED, VIOLATED):
            return {0: 1.0}
        w = int(product.world_state[x])
        lo, hi = model.indptr[w], model.indptr[w + 1]
        return {
            int(o): float(p) for o, p in zip(model.targets[lo:hi], model.probs[lo:hi], strict=True)
        }

    value = np.zeros((masks, n))  # averaged over the observation drawn on entering
    value[:] = recursion_ends(product) if not risk else 0.0
    if risk:
        value[:, VIOLATED] = 1.0
    for r in range(1, s.horizon + 1):
        new = np.zeros_like(value)
        for mask in range(masks):
            for x in range(n):
                if x in (SATISFIED, VIOLATED):
                    new[mask, x] = float(x == (VIOLATED if risk else SATISFIED))
                    continue
                q = int(product.automaton_state[x])
                total = 0.0
                for o, p_o in seen(x).items():
                    allowed = s.actions(np.array([r]), np.array([mask]), np.array([o]),
                                        np.array([q]))[0, : world.num_actions]  # fmt: skip
                    actions = np.flatnonzero(allowed).tolist()
                    assert actions
                    if pick != "uniform":
                        actions = [actions[0] if pick == "first" else actions[-1]]
                    for a in actions:
                        c = int(product.choice_ptr[x]) + a
                        after = min(mask | int(product.marks[c]), masks - 1)
                        lo, hi = t.indptr[c], t.indptr[c + 1]
                        pairs = zip(t.targets[lo:hi], t.probs[lo:hi], strict=True)
                        q_value = sum(float(p) * value[after, int(y)] for y, p in pairs)
                        total += p_o * q_value / len(actions)
                new[mask, x] = total
        value = new
    return float(sum(p * value[0, x] for x, p in product.starts))


@pytest.mark.parametrize("seed", range(10))
@pytest.mark.parametrize(("theta", "delta"), [(1.0, None), (0.6, None), (None, 0.0), (0.8, 0.1)])
def test_every_shielded_observation_policy_keeps_the_reported_guarantee(
    seed: int, theta: float | None, delta: float | None
) -> None:
    world, product = random_pomdp(seed)
    s = observed_shield(world, product, world.horizon, theta=theta, delta=delta)
    found = observed_bound(world, product)
    assert s.reference == pytest.approx(found.value, abs=1e-9)  # the analysis' own figure
    assert 0.0 <= s.success <= s.optimum + 1e-12
    assert s.least_violation <= s.violation + 1e-12
    if delta is None and theta is not None:  # theta times the observation-based bound
        assert s.success >= theta * found.value - 1e-9
    for pick in ("uniform", "first", "last"):
        assert evaluate(world, product, s, pick, risk=False) >= s.success - 1e-9
        assert evaluate(world, product, s, pick, risk=True) <= s.violation + 1e-9


def test_on_case2_every_shielded_agent_keeps_the_observation_based_bound() -> None:
    """The paper's case 2 (noisy cells): with theta = 1 every shielded agent succeeds at
    least as often as the best observation-based policy found (0.9636), exactly."""
    world = load_world(ROOT / "specs" / "paper" / "case2.yaml")
    product = build_product(world, translate(parse(world.spec)))
    s = observed_shield(world, product, world.horizon, theta=1.0)
    assert s.success >= s.reference - 1e-9 > 0.9


def test_seeing_the_cell_it_is_the_mdps_optimal_shield() -> None:
    """With the cell as the observation, theta = 1 allows the optimal actions only: every
    shielded policy reaches the fully observable optimum."""
    world = load_world(ROOT / "specs" / "paper" / "case1.yaml")
    cells = world.num_states
    identity = Sparse.from_rows([{s: 1.0} for s in range(cells)])
    world = replace(world, observations=Observations(tuple(map(str, range(cells))), identity))
    product = build_product(world, translate(parse(world.spec)))
    s = observed_shield(world, product, world.horizon, theta=1.0)
    optimum, _ = pmax_horizon(product, world.horizon)
    assert s.success == pytest.approx(optimum, abs=1e-9)


def test_the_simulator_keeps_to_the_observed_shield() -> None:
    world, product = random_pomdp(3)
    s = observed_shield(world, product, world.horizon, theta=1.0)
    t = replace(tables(product, world), shield=s)
    env = VecProduct(t, 5000, np.random.default_rng(0))
    success = uniform_shielded_success(env, np.random.default_rng(1))
    exact = evaluate(world, product, s, "uniform", risk=False)
    error = max(np.sqrt(exact * (1 - exact) / env.num_envs), 1e-3)
    assert abs(success.mean() - exact) < 4.5 * error


def test_an_mdp_and_a_task_with_jumps_are_refused() -> None:
    world, product = random_pomdp(0)
    with pytest.raises(ShieldError, match="not a POMDP"):
        observed_shield(replace(world, observations=None), product, 5, theta=1.0)
    jumping = build_product(world, translate(parse("F G a")))
    with pytest.raises(ShieldError, match="epsilon jumps"):
        observed_shield(world, jumping, 5, theta=1.0)
