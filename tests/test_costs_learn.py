"""Costs in learning (issue 27): the simulator takes each transition's cost (the one
definition, mitlc.product.costs) off the reward and reports what episodes cost; the product
env (SB3) and counterfactual experience price steps alike; tabular Q-learning on the TRM
example learns the cheaper order, with and without counterfactuals; eval reports the mean
cost beside the least one."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.learn.envs.vec import VecProduct, tables
from mitlc.learn.evaluation.evaluate import evaluate
from mitlc.learn.learners.base import random_valid
from mitlc.learn.run import train
from mitlc.product.costs import product_costs
from mitlc.product.explicit import build_product
from mitlc.syntax import parse
from mitlc.worlds import load_world
from tests.conftest import ROOT
from tests.test_learn import config

TRM = ROOT / "specs" / "costs" / "trm-orders.yaml"


def test_the_simulator_takes_each_transitions_cost_off_the_reward() -> None:
    """Random walks on the TRM world: every step's reward is the task's less the cost of the
    product transition drawn, and an episode's cost is the sum of its steps' costs."""
    world = load_world(TRM)
    automaton = translate(parse(world.spec))
    product = build_product(world, automaton)
    costs = product_costs(world, automaton, product)
    plain = tables(product, world)
    priced = replace(plain, cost=costs.transition)
    envs = [VecProduct(t, 64, np.random.default_rng(5)) for t in (plain, priced)]
    rng = np.random.default_rng(6)
    paid = np.zeros(64)
    for _ in range(200):
        actions = random_valid(rng, envs[0].valid_actions())
        free, charged = (env.step(actions) for env in envs)
        assert np.array_equal(free.next_state, charged.next_state)  # the same draws
        assert charged.episode_cost is not None and free.episode_cost is None
        step_cost = free.reward - charged.reward
        assert (step_cost >= 0).all()
        paid += step_cost
        assert np.allclose(charged.episode_cost, paid)
        paid[charged.done] = 0.0
    assert paid.max() > 0


def test_q_learning_learns_the_cheaper_order_and_eval_reports_the_cost(tmp_path: Path) -> None:
    run = train(TRM, config({"episodes": 300_000, "log_every": 30_000}), tmp_path / "trm")
    lines = [json.loads(line) for line in (run.directory / "metrics.jsonl").open()]
    assert all("cost" in line for line in lines)
    report = evaluate(run.directory, episodes=500)
    assert report.exact == pytest.approx(1.0)
    assert report.min_cost == pytest.approx(1611.0)
    assert report.mean_cost is not None and 1611.0 <= report.mean_cost < 1700.0  # b then a


def test_counterfactuals_pay_what_the_simulator_pays(tmp_path: Path) -> None:
    """Counterfactual experience prices each counterfactual step by the same definition: for
    the experienced steps themselves (not into an absorbing state, where the product prices
    the world's successors merged there by their expectation) the counterfactual's reward is
    the simulator's; and Q-learning with it learns the cheaper order."""
    from mitlc.learn.learners.crm import Counterfactuals

    world = load_world(TRM)
    automaton = translate(parse(world.spec))
    product = build_product(world, automaton)
    t = replace(tables(product, world), cost=product_costs(world, automaton, product).transition)
    crm = Counterfactuals.build(product, world, automaton)
    env = VecProduct(t, 256, np.random.default_rng(2))
    rng = np.random.default_rng(3)
    compared = 0
    for _ in range(100):
        state, mask = env.state.copy(), env.mask.copy()
        actions = random_valid(rng, env.valid_actions())
        step = env.step(actions)
        batch = crm.of(state, actions, step.next_state)
        for i in np.flatnonzero(product.world_state[step.next_state] >= 0).tolist():
            same = (batch.state == state[i]) & (batch.mask == mask[i])
            same &= (batch.next_state == step.next_state[i]) & (batch.action == actions[i])
            if same.any():
                assert batch.reward[same][0] == pytest.approx(step.reward[i])
                compared += 1
    assert compared > 1000
    run = train(TRM, config({"episodes": 300_000, "q": {"crm": True}}), tmp_path / "crm")
    report = evaluate(run.directory, episodes=200)
    assert report.exact == pytest.approx(1.0)
    assert report.mean_cost is not None and 1611.0 <= report.mean_cost < 1700.0


def test_the_product_env_pays_what_the_simulator_pays() -> None:
    """SB3 learns on the product env: a step's ``info["cost"]`` there is the cost of the
    product transition it made (a certain world: one transition per choice), and the reward
    has it taken off."""
    from mitlc.product.env import ProductEnv

    world = load_world(TRM)
    automaton = translate(parse(world.spec))
    product = build_product(world, automaton)
    costs = product_costs(world, automaton, product)
    env = ProductEnv(world, automaton)
    plain = ProductEnv(replace(world, costs=None), automaton)
    rng = np.random.default_rng(0)
    env.reset(seed=1)
    plain.reset(seed=1)
    pairs = zip(product.world_state, product.automaton_state, strict=True)
    states = {(int(w), int(q)): x for x, (w, q) in enumerate(pairs)}
    total = 0.0
    for _ in range(300):
        x = states.get((env.world_state, env.automaton_state))
        a = int(rng.integers(world.num_actions))
        _, reward, terminated, truncated, info = env.step(a)
        _, free, *_ = plain.step(a)
        if x is not None:
            assert info["cost"] == pytest.approx(costs.choice[product.choice_ptr[x] + a])
        assert reward == pytest.approx(free - info["cost"])
        total += info["cost"]
        if terminated or truncated:
            env.reset()
            plain.reset()
    assert total > 0
