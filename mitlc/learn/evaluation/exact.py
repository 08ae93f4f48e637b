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
    """The probability that following ``choices`` from the initial state succeeds within
    ``horizon`` world actions: ``choices[mask, x]``, a product choice of state ``x`` when the
    frontier is ``mask`` (-1 at the absorbing states), or, for a policy that also reads the
    steps left and whether a round was completed (a shielded one), ``choices[r - 1, done,
    mask, x]`` for ``r`` steps left and ``done`` 0 or 1."""
    all_sets = (1 << product.num_sets) - 1
    n = product.num_states
    if choices.shape not in ((all_sets + 1, n), (horizon, 2, all_sets + 1, n)):
        raise ValueError(
            f"choices has shape {choices.shape}, expected {(all_sets + 1, n)} or "
            f"{(horizon, 2, all_sets + 1, n)}"
        )
    t = product.transitions
    matrix = csr_matrix((t.probs, t.targets, t.indptr), shape=(product.num_choices, n))
    owner = np.repeat(np.arange(n), np.diff(product.choice_ptr))
    live = product.world_state >= 0
    chosen = choices[..., live]
    if (chosen < 0).any() or (owner[np.maximum(chosen, 0)] != np.flatnonzero(live)).any():
        raise ValueError("choices must give each pending state one of its own choices")
    plan = _Planner(product, matrix)
    # pending[mask, x]: success from x with no round completed yet; done[mask, x]: a round was
    # completed. Both start as the success of an episode that ends there (mitlc.task.rules),
    # and a round that completes empties the frontier, as in every run of the task monitor.
    # With no step left the episode is over: no jump is taken there.
    pending, done = _ends(product, done=False), _ends(product, done=True)
    end_pending, end_done = pending.copy(), done.copy()
    for r in range(1, horizon + 1):
        plans = [plan(choices if choices.ndim == 2 else choices[r - 1, d]) for d in (0, 1)]
        next_pending, next_done = end_pending.copy(), end_done.copy()
        for mask in range(len(plans[0])):
            for states, rows, key in plans[0][mask][0]:
                source = done[-1 - key] if key < 0 else pending[key]
                next_pending[mask, states] = rows @ source
            for states, rows, key in plans[1][mask][0]:
                next_done[mask, states] = rows @ done[-1 - key if key < 0 else key]
        pending, done = _jump(next_pending, plans[0]), _jump(next_done, plans[1])
    return start_average(product, pending[0])


class _Planner:
    """Per mask, a policy's world-action states grouped by the frontier after their choice
    (``-1 - after`` where the choice completes a round), with those choices' rows, and its
    jump sources and targets; the last plan is kept for a policy that repeats it."""

    def __init__(self, product: Product, matrix: csr_matrix) -> None:
        self.product, self.matrix = product, matrix
        self.is_jump = product.action < 0
        self.jump_target = product.transitions.targets[product.transitions.indptr[:-1]]
        self.popcount = np.asarray(rules.popcounts(product.num_sets), dtype=np.int64)
        self.states = np.flatnonzero(product.world_state >= 0)
        self.last: tuple[IntArray, list[Plan]] | None = None

    def __call__(self, choices: IntArray) -> list[Plan]:
        if self.last is not None and np.array_equal(self.last[0], choices):
            return self.last[1]
        p, states = self.product, self.states
        all_sets = (1 << p.num_sets) - 1
        plans: list[Plan] = []
        for mask in range(all_sets if p.num_sets else 1):
            picked = choices[mask, states]
            walk = ~self.is_jump[picked]
            marks = p.marks[picked[walk]]
            after, _, complete = rules.account(mask, marks, all_sets, self.popcount)
            key = np.where(complete, -1 - after, after)  # a completed round: done, frontier after
            groups = [
                (states[walk][key == k], self.matrix[picked[walk][key == k]], int(k))
                for k in np.unique(key).tolist()
            ]
            plans.append((groups, states[~walk], self.jump_target[picked[~walk]]))
        self.last = (choices, plans)
        return plans


def _ends(product: Product, done: bool) -> FloatArray:
    """``values[mask, x]``: the success of an episode that ends in ``x`` with the frontier
    ``mask``, and with (``done``) or without a completed round."""
    all_sets = (1 << product.num_sets) - 1
    masks = np.arange(all_sets + 1, dtype=np.int64)[:, None]
    seen = rules.seen_sets(masks, np.int64(done), all_sets)
    verdicts, ends = product_verdicts(product)[None, :], product_ends(product)[None, :]
    success = rules.success(verdicts, seen, ends)
    values: FloatArray = np.asarray(success, dtype=np.float64)
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
