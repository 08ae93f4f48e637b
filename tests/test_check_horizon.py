"""``pmax_horizon``'s incremental backward induction against a plain one, state by state."""

from __future__ import annotations

import random

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.check import solve
from mitlc.check.solve import pmax_horizon
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, build_product, product_ends
from mitlc.syntax import to_text
from mitlc.task import rules
from mitlc.worlds.model import FloatArray, Sparse
from tests.test_check import formulas, random_world


def plain_horizon(product: Product, horizon: int) -> list[FloatArray]:
    """Every table of the finite-horizon recursion, each state and choice in turn."""
    masks, n = 1 << product.num_sets, product.num_states
    t, ptr = product.transitions, product.choice_ptr
    jumps = [
        (x, int(t.targets[t.indptr[c]]))
        for x in range(n)
        for c in range(ptr[x], ptr[x + 1])
        if product.action[c] < 0
    ]

    def settle(values: FloatArray) -> FloatArray:
        values[:, SATISFIED], values[:, VIOLATED] = 1.0, 0.0
        for source, target in jumps:
            values[:, source] = np.maximum(values[:, source], values[:, target])
        return values

    # an episode that stops pending succeeds by the one rule (mitlc.task.rules.success) of its
    # state's end code and the sets seen (the mask)
    seen = np.arange(masks, dtype=np.int64)[:, None]
    start = rules.success(rules.PENDING, seen, product_ends(product)[None, :]).astype(np.float64)
    start[:, SATISFIED], start[:, VIOLATED] = 1.0, 0.0
    tables = [start]  # no step left: the episode is over, no jump is taken
    for _ in range(horizon):
        last, step = tables[-1], np.full((masks, n), -1.0)
        for mask in range(masks):
            for x in range(n):
                for c in range(ptr[x], ptr[x + 1]):
                    if product.action[c] >= 0:
                        row = slice(t.indptr[c], t.indptr[c + 1])
                        after = mask | int(product.marks[c])
                        q = float(t.probs[row] @ last[after, t.targets[row]])
                        step[mask, x] = max(step[mask, x], q)
        tables.append(settle(step))
    return tables


@pytest.mark.parametrize("full_step", [0.0, 0.25, 2.0])
def test_incremental_steps_give_the_plain_tables(
    full_step: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Full steps only (0), the default mix, and no full step at all (2) give the same tables
    as the plain recursion, on products with epsilon jumps and acceptance sets among them."""
    monkeypatch.setattr(solve, "FULL_STEP", full_step)
    rng = random.Random(31)
    jumps = sets = 0
    for formula in formulas(11, 30):
        product = build_product(random_world(rng, to_text(formula)), translate(formula))
        horizon = rng.randint(1, 9)
        value, history = pmax_horizon(product, horizon)
        expected = plain_horizon(product, horizon)
        assert len(history) == horizon + 1
        for mine, theirs in zip(history, expected, strict=True):
            np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-12)
        assert value == pytest.approx(expected[-1][0, product.initial], abs=1e-12)
        jumps += bool((product.action < 0).any())
        sets += product.num_sets > 0
    assert jumps >= 3 and sets >= 3


def test_a_jump_passes_a_late_change_back(monkeypatch: pytest.MonkeyPatch) -> None:
    """``x -> s``, and ``s`` jumps to a chain ``t -> u -> w -> violated`` (its own move is to
    violated too): with no sets and every state's end value true (a safety task), success is
    not being violated within the horizon, which ``s`` loses through the jump at three steps,
    and ``x`` at four, although nothing ``s`` moves to has changed then."""
    monkeypatch.setattr(solve, "FULL_STEP", 2.0)
    # states: violated, satisfied, x, s, t, u, w; choices: one each, s a move and a jump
    targets = np.array([VIOLATED, SATISFIED, 3, VIOLATED, 4, 5, 6, VIOLATED])
    product = Product(
        world_state=np.array([-1, -1, 0, 1, 1, 2, 3]),
        automaton_state=np.array([0, 1, 2, 2, 3, 3, 3]),
        initial=2,
        choice_ptr=np.array([0, 1, 2, 3, 5, 6, 7, 8]),
        action=np.array([0, 0, 0, 0, -4, 0, 0, 0]),
        marks=np.zeros(8, dtype=np.int64),
        transitions=Sparse(np.arange(9), targets, np.ones(8)),
        num_sets=0,
        end=np.array([False, True, True, True, True, True, True]),
    )
    _, history = pmax_horizon(product, 6)
    assert [float(h[0, 3]) for h in history] == [1, 1, 1, 0, 0, 0, 0]
    assert [float(h[0, 2]) for h in history] == [1, 1, 1, 1, 0, 0, 0]
    for mine, theirs in zip(history, plain_horizon(product, 6), strict=True):
        assert np.array_equal(mine, theirs)
