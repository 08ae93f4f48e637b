"""The cost of every transition and choice of a product: ``product_costs(world, automaton,
product)``, the one definition of what a step costs (:mod:`mitlc.task.costs`) applied to the
product that :func:`mitlc.product.explicit.build_product` built. The checker reads it
(:mod:`mitlc.check.costs`), the DRN export writes it as Storm's reward model, and a learner on
the product reads the same arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mitlc.product.explicit import SATISFIED, VIOLATED, Product
from mitlc.task.costs import StepTable, TransitionCosts, world_cost
from mitlc.task.monitor import TaskAutomaton
from mitlc.worlds.model import FloatArray, World


@dataclass(frozen=True, slots=True)
class ProductCosts:
    """What each product transition and choice costs (see :func:`product_costs`)."""

    transition: FloatArray
    """``transition[j]``: the cost of product transition ``j`` (aligned with
    ``product.transitions.targets``). Where the world's successors of a step are merged into
    the absorbing ``satisfied`` or ``violated`` state, the one transition there costs the
    expectation of theirs."""
    choice: FloatArray
    """``choice[c]``: the expected immediate cost of choice ``c``, the sum over its
    transitions of probability times cost: what a step by ``c`` costs on average."""


def product_costs(
    world: World, automaton: TaskAutomaton, product: Product, *, strict: bool = True
) -> ProductCosts:
    """The cost of every transition and choice of ``product``, the product of ``world`` and
    ``automaton``, by ``world.costs`` (all zero without them): a world choice from ``(s, q)``
    by action ``a`` to ``(s', q')`` costs :func:`mitlc.task.costs.world_cost` of ``(a, L(s),
    L(s'))`` plus the transition rules' :meth:`mitlc.task.costs.TransitionCosts.cost` of
    ``(q, L(s))``; epsilon jumps and the absorbing states' loops cost nothing.

    With ``strict``, a transition rule that matches no world choice of the product is a
    :class:`mitlc.task.costs.CostError` (a rule that is never paid is a mistake: an obligation
    the task never owes in this world, or a letter it never reads there)."""
    t = product.transitions
    sizes = np.diff(product.choice_ptr)
    source = np.repeat(np.arange(product.num_states), sizes)  # per choice
    entry_choice = np.repeat(np.arange(product.num_choices), np.diff(t.indptr))
    s = product.world_state[source]
    action = product.action.astype(np.int64)
    live = (action >= 0) & (s >= 0)
    letters = world.letters
    table = StepTable.of(world)
    # the world part, per world transition: (s, a) -> s' where s' is known, else the
    # expectation over the world's successors of (s, a) (all merged into one absorbing state)
    x_entry = source[entry_choice]
    a_entry = np.maximum(action[entry_choice], 0)
    s_entry = np.maximum(product.world_state[x_entry], 0)
    y = t.targets.astype(np.int64)
    merged = (y == SATISFIED) | (y == VIOLATED)
    arrived = letters[np.maximum(product.world_state[y], 0)]
    cost = np.asarray(world_cost(table, a_entry, letters[s_entry], arrived), dtype=np.float64)
    if merged.any():
        expected = _expected_rows(world, table)
        rows = s_entry * world.num_actions + a_entry
        cost = np.where(merged, expected[rows], cost)
    # the automaton part, per choice: once per distinct (automaton state, letter)
    rules = TransitionCosts(world, automaton)
    automaton_part = np.zeros(product.num_choices)
    if rules.rules:
        q = product.automaton_state[source].astype(np.int64)
        letter = letters[np.maximum(s, 0)]
        pairs, inverse = np.unique(np.stack([q[live], letter[live]]), axis=1, return_inverse=True)
        values = np.array([rules.cost(int(a), int(b)) for a, b in pairs.T], dtype=np.float64)
        automaton_part[np.flatnonzero(live)] = values[inverse.ravel()]
        error = rules.unmatched_error(sorted({automaton.obligation(int(a)) for a in pairs[0]}))
        if strict and error is not None:
            raise error
    cost = np.where(live[entry_choice], cost + automaton_part[entry_choice], 0.0)
    return ProductCosts(cost, choice_costs(product, cost))


def choice_costs(product: Product, transition: FloatArray) -> FloatArray:
    """The expected immediate cost of every choice of ``product`` from the cost of every
    transition (:attr:`ProductCosts.transition`): the sum over its transitions of probability
    times cost."""
    t = product.transitions
    entry_choice = np.repeat(np.arange(product.num_choices), np.diff(t.indptr))
    choice = np.bincount(entry_choice, weights=t.probs * transition, minlength=product.num_choices)
    expected: FloatArray = choice.astype(np.float64)
    return expected


def _expected_rows(world: World, table: StepTable) -> FloatArray:
    """Per world row ``s * num_actions + a``, the expected world part of a step's cost."""
    w = world.transitions
    rows = np.repeat(np.arange(w.num_rows), np.diff(w.indptr))
    s, a = rows // world.num_actions, rows % world.num_actions
    each = world_cost(table, a, world.letters[s], world.letters[w.targets])
    expected = np.bincount(rows, weights=w.probs * each, minlength=w.num_rows)
    return expected.astype(np.float64)
