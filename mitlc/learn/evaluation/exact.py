"""The exact success probability of a memoryless policy on an MDP's product: the Markov chain
it induces, solved by backward induction over the horizon.

The event is the episode's success (:func:`mitlc.task.rules.success`): never *violated* within
``horizon`` world actions, and *satisfied*, a completed round of all acceptance sets, or the
end value of the state it stops in (a violation after a completed round is a failure); no jump
is taken once the horizon is reached. The
policy may depend on the frontier mask, so the values are indexed ``[mask, product state]``
like those of :func:`mitlc.check.solve.pmax_horizon` (its optimum is the same recursion with a
maximum over the choices); epsilon jumps take no step.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix

from mitlc.product.explicit import Product, product_ends, product_verdicts, start_average
from mitlc.task import rules
from mitlc.worlds.model import FloatArray, IntArray

Plan = tuple[list[tuple[IntArray, csr_matrix, int]], IntArray, IntArray]
"""Per mask: (states, their world-action choices' rows, the mask after), jump sources and
targets."""


def policy_success(product: Product, choices: IntArray, horizon: int) -> float:
    """The probability that following ``choices[mask, x]`` (a product choice of state ``x``
    when the frontier is ``mask``; -1 at the absorbing states) from the initial state succeeds
    within ``horizon`` world actions."""
    all_sets = (1 << product.num_sets) - 1
    n = product.num_states
    if choices.shape != (all_sets + 1, n):
        raise ValueError(f"choices has shape {choices.shape}, expected {(all_sets + 1, n)}")
    t = product.transitions
    matrix = csr_matrix((t.probs, t.targets, t.indptr), shape=(product.num_choices, n))
    owner = np.repeat(np.arange(n), np.diff(product.choice_ptr))
    live = product.world_state >= 0
    chosen = choices[:, live]
    if (chosen < 0).any() or (owner[np.maximum(chosen, 0)] != np.flatnonzero(live)).any():
        raise ValueError("choices must give each pending state one of its own choices")
    is_jump = product.action < 0
    jump_target = t.targets[t.indptr[:-1]]
    plans: list[
        Plan
    ] = []  # per mask: (world-action states, their choices grouped by the mask after)
    popcount = np.asarray(rules.popcounts(product.num_sets), dtype=np.int64)
    for mask in range(all_sets if product.num_sets else 1):
        states = np.flatnonzero(live)
        picked = choices[mask, states]
        walk = ~is_jump[picked]
        marks = product.marks[picked[walk]]
        after, _, complete = rules.account(mask, marks, all_sets, popcount)
        key = np.where(complete, -1 - after, after)  # a completed round: done, frontier after
        groups = [
            (states[walk][key == k], matrix[picked[walk][key == k]], int(k))
            for k in np.unique(key).tolist()
        ]
        plans.append((groups, states[~walk], jump_target[picked[~walk]]))
    # pending[mask, x]: success from x with no round completed yet; done[mask, x]: a round was
    # completed. Both start as the success of an episode that ends there (mitlc.task.rules),
    # and a round that completes empties the frontier, as in every run of the task monitor.
    # With no step left the episode is over: no jump is taken there.
    pending, done = _ends(product, rounds=0), _ends(product, rounds=1)
    end_pending, end_done = pending.copy(), done.copy()
    for _ in range(horizon):
        next_pending, next_done = end_pending.copy(), end_done.copy()
        for mask, (groups, _, _) in enumerate(plans):
            for states, rows, key in groups:
                if key < 0:
                    next_pending[mask, states] = next_done[mask, states] = rows @ done[-1 - key]
                else:
                    next_pending[mask, states] = rows @ pending[key]
                    next_done[mask, states] = rows @ done[key]
        pending, done = _jump(next_pending, plans), _jump(next_done, plans)
    return start_average(product, pending[0])


def _ends(product: Product, rounds: int) -> FloatArray:
    """``values[mask, x]``: the success of an episode that ends in ``x`` with ``rounds``
    completed rounds (every mask alike)."""
    success = rules.success(product_verdicts(product), rounds, product_ends(product))
    values: FloatArray = np.tile(success.astype(np.float64), ((1 << product.num_sets), 1))
    return values


def _jump(values: FloatArray, plans: list[Plan]) -> FloatArray:
    """States whose policy jumps take their target's value (chains followed to the end)."""
    for mask, (_, sources, targets) in enumerate(plans):
        for _ in range(len(sources)):
            if not len(sources):
                break
            updated = values[mask, targets]
            if np.array_equal(values[mask, sources], updated):
                break
            values[mask, sources] = updated
    return values
