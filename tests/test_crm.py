"""Counterfactual experience (CRM) against a hand-worked example, and its learning effect.

The world has two states, ``s0`` (no label) and ``s1`` (``a``), and two certain actions,
``toggle`` (to the other state) and ``stay``. The hand-made automaton has two states that
count rising edges of ``a``: ``q0`` reads ``a`` into ``q1`` with the mark of its one acceptance
set; ``q1`` reads ``a`` into ``q1`` without it; either reads no ``a`` into ``q0``. The product
from ``(s0, q0)`` reaches all four pairs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mitlc.automata.digital import DigitalAutomaton, DigitalState
from mitlc.learn.config import resolve
from mitlc.learn.envs.vec import VecProduct, tables
from mitlc.learn.learners.crm import Counterfactuals
from mitlc.learn.learners.qlearning import QLearner
from mitlc.product.explicit import build_product
from mitlc.worlds.model import Rewards, Sparse, World
from tests.conftest import ROOT

TOGGLE, STAY = 0, 1
REWARDS = Rewards(accept=10.0, satisfied=0.0, violated=0.0, move=-1.0)


def two_state_world() -> World:
    return World(
        name="two",
        rows=1,
        cols=2,
        cells=((0, 0), (0, 1)),
        actions=("toggle", "stay"),
        start=0,
        transitions=Sparse(np.arange(5), np.array([1, 0, 0, 1]), np.ones(4)),
        propositions=("a",),
        letters=np.array([0, 1], dtype=np.int64),
        spec="<hand-made>",
        spec_source="<test>",
        horizon=10,
        discount=0.5,
        rewards=REWARDS,
    )


def rising_edges() -> DigitalAutomaton:
    return DigitalAutomaton.from_table(
        source="<rising edges of a>",
        formula="<rising edges of a>",
        propositions=("a",),
        states=(
            DigitalState("q0", "initial", "pending"),
            DigitalState("q1", "initial", "pending"),
        ),
        initial=0,
        delta=((0, 1), (0, 1)),
        marks=((0, 1), (0, 0)),
        num_sets=1,
    )


def pair_ids(product) -> dict[tuple[int, int], int]:  # type: ignore[no-untyped-def]
    return {
        (int(s), int(q)): x
        for x, (s, q) in enumerate(zip(product.world_state, product.automaton_state, strict=True))
        if s >= 0
    }


def test_counterfactuals_of_one_world_step_by_hand() -> None:
    """The experienced step ``(s1, q0) --stay--> (s1, q1)`` tells about ``stay`` in ``s1``
    from both automaton states: from ``q0`` it reads ``a`` into ``q1`` with the mark (a
    completed round: reward 10, the frontier back to empty, an accepting step); from ``q1`` it
    reads ``a`` into ``q1`` with none (reward 0). ``stay`` costs no move."""
    world, automaton = two_state_world(), rising_edges()
    product = build_product(world, automaton)
    ids = pair_ids(product)
    assert set(ids) == {(0, 0), (1, 0), (0, 1), (1, 1)}
    crm = Counterfactuals.build(product, world, automaton)
    batch = crm.of(np.array([ids[1, 0]]), np.array([STAY]), np.array([ids[1, 1]]))
    got = {
        (int(x), int(m), int(a), float(r), bool(acc), bool(t), int(m2), int(y))
        for x, m, a, r, acc, t, m2, y in zip(
            batch.state,
            batch.mask,
            batch.action,
            batch.reward,
            batch.accepting,
            batch.terminated,
            batch.next_mask,
            batch.next_state,
            strict=True,
        )
    }
    assert got == {
        (ids[1, 0], 0, STAY, 10.0, True, False, 0, ids[1, 1]),
        (ids[1, 1], 0, STAY, 0.0, False, False, 0, ids[1, 1]),
    }
    # a toggle from s0 tells about both automaton states too, and pays the move
    batch = crm.of(np.array([ids[0, 1]]), np.array([TOGGLE]), np.array([ids[1, 0]]))
    got_toggle = {(int(x), float(r), int(y)) for x, r, y in
                  zip(batch.state, batch.reward, batch.next_state, strict=True)}  # fmt: skip
    assert got_toggle == {(ids[0, 0], -1.0, ids[1, 0]), (ids[0, 1], -1.0, ids[1, 0])}
    # a jump or a step into an absorbing state tells nothing
    assert len(crm.of(np.array([ids[1, 0]]), np.array([5]), np.array([ids[1, 1]])).state) == 0


def test_one_crm_update_by_hand() -> None:
    """With alpha 1, gamma 0.5 and a table of zeros but ``Q(s1, q1, stay) = 4`` (and toggles at
    -5, so that the greedy episode stays), one step from ``(s1, q0)`` sets ``Q(s1, q0, stay)`` to
    ``10 + 0.5 * 4 = 12``; with CRM it also sets ``Q(s1, q1, stay)`` to ``0 + 0.5 * 4 = 2``
    (the counterfactual from ``q1``), and nothing else moves."""
    world, automaton = two_state_world(), rising_edges()
    product = build_product(world, automaton)
    ids = pair_ids(product)
    t = tables(product, world)
    overrides = {"q.num_envs": 1, "q.alpha": 1.0, "q.alpha_end": 1.0, "q.initial_value": 0.0,
                 "q.epsilon_start": 0.0, "q.epsilon_end": 0.0}  # fmt: skip
    for crm_on in (False, True):
        config = resolve({}, {**overrides, "q.crm": crm_on}, discount=0.5, pomdp=False)
        crm = Counterfactuals.build(product, world, automaton) if crm_on else None
        learner = QLearner(t, config, np.random.default_rng(0), None, crm)
        env = VecProduct(t, 1, np.random.default_rng(0))
        env.state[:] = ids[1, 0]
        learner.q_table[0, :, TOGGLE] = -5.0
        learner.q_table[0, ids[1, 1], STAY] = 4.0
        before = learner.q_table.copy()
        learner.train_step(env, 0.0)
        moved = np.nonzero(learner.q_table != before)
        changed = {(int(m), int(x), int(a)) for m, x, a in zip(*moved, strict=True)}
        expected = {(0, ids[1, 0], STAY)} | ({(0, ids[1, 1], STAY)} if crm_on else set())
        assert changed == expected
        assert learner.q_table[0, ids[1, 0], STAY] == pytest.approx(12.0)
        assert learner.q_table[0, ids[1, 1], STAY] == pytest.approx(2.0 if crm_on else 4.0)


@pytest.mark.parametrize("crm", [False, True])
def test_q_learning_with_and_without_crm_reaches_case1(crm: bool, tmp_path: Path) -> None:
    """Both reach 0.98 of the optimum on case 1 (CRM in fewer episodes: bench/crm_bench.py)."""
    from mitlc.check.solve import pmax_horizon
    from mitlc.learn.evaluation.exact import policy_success
    from mitlc.learn.run import make_learner, prepare
    from mitlc.worlds.load import read_any_world_file

    path = ROOT / "specs" / "paper" / "case1.yaml"
    raw = read_any_world_file(path)
    episodes = 60_000 if crm else 120_000
    config = resolve(raw.training, {"q.crm": crm, "episodes": episodes}, discount=raw.discount,
                     pomdp=False)  # fmt: skip
    setting = prepare(path, config)
    learner = make_learner(setting, np.random.default_rng(0))
    env = VecProduct(setting.tables, learner.num_envs, np.random.default_rng(1))
    done = 0
    while done < episodes:
        done += int(learner.train_step(env, done / episodes).done.sum())
    optimum, _ = pmax_horizon(setting.product, setting.world.horizon, keep_history=False)
    assert isinstance(learner, QLearner)
    value = policy_success(setting.product, learner.policy().choices(), setting.world.horizon)
    assert value >= 0.98 * optimum
